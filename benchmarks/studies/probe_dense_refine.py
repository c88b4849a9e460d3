"""Refining the dense map on the input meshes: how the points are read off the functional
map, how many eigenfunctions, and whether early steps search all of Y.

Run:  .venv/bin/python benchmarks/studies/probe_dense_refine.py [--data DIR] [--remeshed DIR]
                                                                [--points 1500] [--json OUT]

Pairs: TOSCA cat1 -> cat0, dog0 -> dog1, david0 -> david1 (shared triangulation); with
``--remeshed DIR`` (made by ``benchmarks/remesh.py``) cat1 -> cat0, david0 -> david1,
victoria1 -> victoria0, centaur1 -> centaur0 remeshed each on its own (truth by the nearest
original vertex); TOPKIDS kid01, kid03, kid05, kid12, kid14 -> kid00. For each,
``gromov.match(x, y, dense=...)`` with ``"placed"`` (no refinement) and ``"zoomout"`` (ZoomOut
on the working meshes), then :func:`gromov.dense.input_zoomout` from the placed map:

- ``C on X, orthogonal, 100``: the functional map made orthogonal, each vertex's image the
  nearest of ``Phi_Y`` to ``Phi_X(v) C`` within two rings, eigenfunctions 20..100 (with C
  orthogonal this equals the recovery below);
- ``recovery, 100`` / ``recovery, 140``: ZoomOut's recovery, the nearest of ``Phi_Y(w) C^T``
  to ``Phi_X(v)``, C as computed, to 100 / 140 eigenfunctions, two rings;
- ``recovery, 140, global 32``: the same, and while k <= 32 the working vertices of Y are
  searched too (the default);

and where the truth is known also from the *true* map, which tells where each refinement
drifts to by itself. Scored on the same ``--points`` random vertices of X (seed 0) by
:func:`gromov.evaluate.dense_error` on Y's input mesh, x 100 / sqrt(area), the better of the
direct and mirrored readings: mean / median / 97th percentile.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

import gromov
from gromov.dense import input_zoomout
from gromov.evaluate import GeodesicReference, dense_error
from gromov.experiments import datasets
from gromov.experiments.reproduce import reflection_map
from gromov.gh import ShapeMetric
from gromov.metrics.diffusion import correspondence_options

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument  # noqa: E402
from bench_dense import at_vertices  # noqa: E402

HERE = Path(__file__).resolve().parent

TOSCA_PAIRS = (("cat", 1, 0), ("dog", 0, 1), ("david", 0, 1))
REMESHED_PAIRS = (("cat", 1, 0), ("david", 0, 1), ("victoria", 1, 0), ("centaur", 1, 0))
KIDS = ("kid01", "kid03", "kid05", "kid12", "kid14")
VARIANTS = {
    "C on X, orthogonal, 100": dict(k_end=100, global_k=0, orthogonal=True),
    "recovery, 100": dict(k_end=100, global_k=0),
    "recovery, 140": dict(k_end=140, global_k=0),
    "recovery, 140, global 32": dict(k_end=140, global_k=32),
}


def cases(root: Path, remeshed: Path | None):
    """``(name, x, y, truth or None, symmetric truth)`` for every pair."""
    tosca, kids = datasets.TOSCA(root / "tosca"), datasets.TopKids(root / "topkids")
    for c, p, q in TOSCA_PAIRS:
        x, y = tosca.load(c, p), tosca.load(c, q)
        yield f"{c}{p}->{c}{q}", x, y, np.arange(x.n_vertices), reflection_map(y)
    if remeshed is not None:
        from remesh import true_images

        for c, p, q in REMESHED_PAIRS:
            x, y = (gromov.load(remeshed / f"{c}{n}.off") for n in (p, q))
            ix, iy = (np.loadtxt(remeshed / f"{c}{n}.ids.txt", dtype=np.int64) for n in (p, q))
            orig_y = tosca.load(c, q).vertices
            sym = true_images(reflection_map(tosca.load(c, 0))[iy], orig_y, y.vertices)
            yield f"{c}{p}->{c}{q} remeshed", x, y, true_images(ix, orig_y, y.vertices), sym
    for k in KIDS:
        yield f"{k}->{kids.reference}", kids.load(k), kids.load(kids.reference), kids.ground_truth(k), \
            kids.symmetry(kids.reference)


def scorer(x, y, truth, sym, points: int):
    """``score(face, bary)`` of a map X -> Y: mean, median and 97th percentile of the error x 100
    / sqrt(area) at ``points`` random vertices of X (seed 0), the better of the direct and the
    mirrored reading (:func:`gromov.evaluate.dense_error`)."""
    pts = np.random.default_rng(0).choice(x.n_vertices, min(points, x.n_vertices), replace=False)
    fmm = GeodesicReference(y)

    def score(face, bary):
        e = 100 * dense_error(face[pts], bary[pts], y, truth[pts], sym, fmm=fmm).errors
        return {"mean": float(e.mean()), "median": float(np.median(e)), "p97": float(np.percentile(e, 97))}
    return score


def prepared(x, y):
    """Both shapes as ``gromov.match`` prepares them for a correspondence."""
    opts = correspondence_options("diffusion", None)
    return ShapeMetric(x, "diffusion", metric_options=opts), ShapeMetric(y, "diffusion", metric_options=opts)


def write_rows(args, script: str, rows: dict) -> None:
    """Write ``rows`` (per pair) to ``args.json`` with the command that made them."""
    Path(args.json).write_text(json.dumps({"command": f"python benchmarks/studies/{script}.py"
                                           + (" --remeshed R" if args.remeshed else ""),
                                           "points": args.points, "pairs": rows}, indent=1))
    print("wrote", args.json)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--remeshed", default=None, help="folder of benchmarks/remesh.py's copies")
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--json", default=str(HERE / "probe_dense_refine.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    rows = {}
    for name, x, y, truth, sym in cases(Path(args.data), Path(args.remeshed) if args.remeshed else None):
        score = scorer(x, y, truth, sym, args.points)
        sx, sy = prepared(x, y)
        row = {}
        for mode in ("placed", "zoomout"):
            r = gromov.match(sx, sy, dense=mode, seed=0)
            row[mode] = score(r.x_to_y_dense_face, r.x_to_y_dense_bary)
            if mode == "placed":
                placed = y.from_input_ids(r.x_to_y_dense_vertex)
        starts = {"placed": placed} | ({"truth": truth} if "kid" not in name else {})
        for start, T in starts.items():
            for label, kw in VARIANTS.items():
                row[f"from {start}: {label}"] = score(*at_vertices(y, input_zoomout(sx, sy, T, **kw)))
        rows[name] = row
        print(name, {k: "{mean:.2f} / {median:.2f} / {p97:.1f}".format(**v) for k, v in row.items()}, flush=True)
    write_rows(args, "probe_dense_refine", rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
