"""The dense placement's settings: heat scale and landmark trimming, on TOPKIDS.

Run:  .venv/bin/python benchmarks/studies/probe_dense.py [--data DIR] [--kids 8] [--json OUT]

kidXX -> kid00 for the first ``--kids`` kids, matched as ``gromov match`` does (diffusion,
3,000 working vertices, 100 samples). The working vertices of each kid are placed on kid00 by
their distances to the matched samples (:func:`gromov.dense.anchored_map`) with the heat
distance at several multiples of the match's diffusion time (``scale``) and with or without
trimming the landmarks (``keep``); each variant's working-level map is scored by the geodesic
distance on kid00's working mesh between image and true vertex (x 100 / sqrt(area), the
better of the direct and the left/right mirrored ground truth). ``oracle`` rows place the
vertices from the *true* images of the landmarks: how precise the metric itself is.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from pathlib import Path

import numpy as np

from gromov.dense import anchored_map, landmark_distances
from gromov.experiments import datasets
from gromov.gh import ShapeMetric, match
from gromov.metrics import metric_solver
from gromov.metrics.diffusion import correspondence_options

HERE = Path(__file__).resolve().parent
SCALES = (1.0, 0.5, 0.25, 0.1)
KEEPS = (1.0, 0.7)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[2] / "shared" / "data")))
    ap.add_argument("--kids", type=int, default=8)
    ap.add_argument("--json", default=str(HERE / "probe_dense.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    kids = datasets.TopKids(Path(args.data) / "topkids")
    opts = correspondence_options("diffusion", None)
    ref = kids.load("kid00")
    sy = ShapeMetric(ref, "diffusion", metric_options=opts)
    w0 = sy.working
    geo = metric_solver(w0.mesh, "geodesic").pairwise()
    unit = 100.0 / np.sqrt(ref.area)
    sym = kids.symmetry("kid00")

    def near(s, ids):
        return s.working.from_source(s.input.from_input_ids(ids))

    def score(img, truth):
        mt = np.where(sym[truth] < 0, truth, sym[truth])
        return min(geo[img, near(sy, truth)].mean(), geo[img, near(sy, mt)].mean()) * unit

    rows = {}
    for name in [n for n in kids.names if n != "kid00"][: args.kids]:
        sx = ShapeMetric(kids.load(name), "diffusion", metric_options=opts)
        r = match(sx, sy)
        gt = kids.ground_truth(name)
        P, fp = near(sx, r.x_samples), near(sy, r.x_to_y_vertex)
        Q, gq = near(sy, r.y_samples), near(sx, r.y_to_x_vertex)
        truth = gt[sx.input.from_input_ids(sx.working.to_input_ids(np.arange(sx.mesh.n_vertices)))]
        oracle = near(sy, truth[np.r_[P, gq]])
        row = {"samples": score(fp, gt[r.x_samples])}
        for scale in SCALES:
            ax = np.hstack([landmark_distances(sx, P, scale), landmark_distances(sx, gq, scale)])
            ay = np.hstack([landmark_distances(sy, fp, scale), landmark_distances(sy, Q, scale)])
            for keep in KEEPS:
                row[f"scale {scale} keep {keep}"] = score(anchored_map(ax, ay, keep=keep), truth)
            row[f"oracle scale {scale}"] = score(anchored_map(ax, landmark_distances(sy, oracle, scale),
                                                              keep=1.0), truth)
        rows[name] = row
        print(name, " ".join(f"{k}: {v:.2f}" for k, v in row.items()), flush=True)
    keys = list(next(iter(rows.values())))
    mean = {k: float(np.mean([row[k] for row in rows.values()])) for k in keys}
    print("\nmean error x100/sqrt(area) over", len(rows), "kids (working level)")
    for k, v in mean.items():
        print(f"  {k:28s} {v:6.2f}")
    Path(args.json).write_text(json.dumps({"kids": list(rows), "mean": mean, "per_kid": rows}, indent=1))
    print("wrote", args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
