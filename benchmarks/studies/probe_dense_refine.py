"""Refining the dense map: on the working meshes, on the input meshes, with and without an
orthogonal functional map, and from the true map.

Run:  .venv/bin/python benchmarks/studies/probe_dense_refine.py [--data DIR] [--points 1500] [--json OUT]

Pairs: TOSCA cat1 -> cat0, centaur1 -> centaur0, dog0 -> dog1 (shared triangulation), TOPKIDS
kid01, kid03, kid05, kid12 -> kid00. For each, ``gromov.match(x, y, dense=...)`` with
``"placed"`` (no refinement), ``"zoomout"`` (ZoomOut on the working meshes' 20..60
eigenfunctions) and then :func:`gromov.dense.input_zoomout` from the placed map on the input
meshes (20..100 eigenfunctions by 4, 2-ring search), with and without the orthogonal
projection; on TOSCA also from the *true* map, which tells where each refinement drifts to by
itself. Scored on the same ``--points`` random vertices of X (seed 0) by
:func:`gromov.evaluate.dense_error` on Y's input mesh, x 100 / sqrt(area), the better of the
direct and mirrored readings: mean / median.
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

TOSCA_PAIRS = (("cat", 1, 0), ("centaur", 1, 0), ("dog", 0, 1))
KIDS = ("kid01", "kid03", "kid05", "kid12")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--json", default=str(HERE / "probe_dense_refine.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    root = Path(args.data)
    tosca, kids = datasets.TOSCA(root / "tosca"), datasets.TopKids(root / "topkids")
    cases = [(f"{c}{p}->{c}{q}", tosca.load(c, p), tosca.load(c, q), None, True) for c, p, q in TOSCA_PAIRS]
    cases += [(f"{k}->{kids.reference}", kids.load(k), kids.load(kids.reference), kids.ground_truth(k), False)
              for k in KIDS]
    rows = {}
    for name, x, y, truth, same_numbering in cases:
        sym = reflection_map(y) if same_numbering else kids.symmetry(kids.reference)
        truth = np.arange(x.n_vertices) if truth is None else truth
        pts = np.random.default_rng(0).choice(x.n_vertices, min(args.points, x.n_vertices), replace=False)
        fmm = GeodesicReference(y)

        def score(face, bary):
            e = dense_error(face[pts], bary[pts], y, truth[pts], sym, fmm=fmm)
            return {"mean": 100 * e.mean, "median": 100 * float(np.median(e.errors))}

        def score_vertices(T):
            return score(*at_vertices(y, T))

        opts = correspondence_options("diffusion", None)
        sx, sy = ShapeMetric(x, "diffusion", metric_options=opts), ShapeMetric(y, "diffusion", metric_options=opts)
        row = {}
        for mode in ("placed", "zoomout"):
            r = gromov.match(sx, sy, dense=mode, seed=0)
            row[mode] = score(r.x_to_y_dense_face, r.x_to_y_dense_bary)
            if mode == "placed":
                placed = y.from_input_ids(r.x_to_y_dense_vertex)
        starts = {"placed": placed} | ({"truth": np.arange(x.n_vertices)} if same_numbering else {})
        for start, T in starts.items():
            for ortho in (False, True):
                label = f"input from {start}" + (", orthogonal" if ortho else "")
                row[label] = score_vertices(input_zoomout(sx, sy, T, orthogonal=ortho))
        rows[name] = row
        print(name, {k: f"{v['mean']:.2f} / {v['median']:.2f}" for k, v in row.items()}, flush=True)
    Path(args.json).write_text(json.dumps({"command": "python benchmarks/studies/probe_dense_refine.py", "points": args.points,
                                           "pairs": rows}, indent=1))
    print("wrote", args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
