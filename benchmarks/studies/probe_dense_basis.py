"""The input meshes' eigenpairs for the dense refinement: Lanczos on the input mesh, or the
working mesh's eigenpairs carried to it and improved by subspace iteration.

Run:  .venv/bin/python benchmarks/studies/probe_dense_basis.py [--data DIR] [--remeshed DIR]
                                                                [--points 1500] [--json OUT]

The pairs of ``probe_dense_refine.py`` (TOSCA cat, dog, david with their shared triangulation;
with ``--remeshed DIR`` cat, david, victoria, centaur remeshed each on its own) and TOPKIDS
kid01, kid05, kid12 -> kid00. For each, the placed map (``gromov.match(x, y, dense="placed")``)
refined by :func:`gromov.dense.input_zoomout` (its defaults but ``k_end``) on eigenpairs made
several ways:

- ``Lanczos, k``: :func:`gromov.dense.laplace_beltrami_basis` of the input mesh (shift-invert
  ARPACK, CHOLMOD), k = 140 and 180;
- ``prolonged g / i, k``: :func:`gromov.dense.prolonged_basis` with guard g (ceil(g k) working
  eigenvectors carried to the input mesh) and i subspace iterations.

Scored as ``probe_dense_refine.py`` scores (mean / median / 97th percentile of the error x 100 /
sqrt(area) on the same random vertices, the better of direct and mirrored); "seconds" is the
CPU time (``time.process_time``) of both shapes' eigenpairs, which other work on the machine
disturbs less than the wall time.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import gromov
from gromov.dense import input_zoomout, laplace_beltrami_basis, prolonged_basis

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # benchmarks/: _common and the comparisons
sys.path.insert(0, str(HERE))
from _common import add_data_argument  # noqa: E402
from bench_dense import at_vertices  # noqa: E402
import probe_dense_refine  # noqa: E402

KIDS = ("kid01", "kid05", "kid12")
#: label -> (k, None for Lanczos or (guard, iterations))
VARIANTS = {
    "Lanczos, 140": (140, None),
    "Lanczos, 180": (180, None),
    "prolonged 1.3 / 1, 140": (140, (1.3, 1)),
    "prolonged 1.3 / 1, 180": (180, (1.3, 1)),
    "prolonged 1.1 / 1, 180": (180, (1.1, 1)),
    "prolonged 1.1 / 2, 180": (180, (1.1, 2)),
    "prolonged 1.0 / 2, 180": (180, (1.0, 2)),
}


def basis(s, k: int, how):
    """``(phi, mass)`` of ``s``'s input mesh as ``how`` says (every input mesh here is one piece)."""
    if how is None:
        return laplace_beltrami_basis(s.input, k)
    return prolonged_basis(s.working, k, guard=how[0], iterations=how[1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--remeshed", default=None, help="folder of benchmarks/remesh.py's copies")
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--json", default=str(HERE / "probe_dense_basis.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    probe_dense_refine.KIDS = KIDS
    rows = {}
    for name, x, y, truth, sym in probe_dense_refine.cases(Path(args.data),
                                                           Path(args.remeshed) if args.remeshed else None):
        score = probe_dense_refine.scorer(x, y, truth, sym, args.points)
        sx, sy = probe_dense_refine.prepared(x, y)
        r = gromov.match(sx, sy, dense="placed", seed=0)
        placed = y.from_input_ids(r.x_to_y_dense_vertex)
        row = {}
        for label, (k, how) in VARIANTS.items():
            t = time.process_time()
            sx._input_basis, sy._input_basis = basis(sx, k, how), basis(sy, k, how)
            seconds = time.process_time() - t
            row[label] = score(*at_vertices(y, input_zoomout(sx, sy, placed, k_end=k))) | {"seconds": seconds}
        rows[name] = row
        print(name, {k: "{mean:.2f} / {median:.2f} ({seconds:.1f} s)".format(**v) for k, v in row.items()}, flush=True)
    probe_dense_refine.write_rows(args, "probe_dense_basis", rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
