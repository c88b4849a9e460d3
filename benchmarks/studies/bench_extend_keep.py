"""Sample-level least trimmed squares in the extension of GMDS's coarse starts: on or off.

Run:  .venv/bin/python benchmarks/studies/bench_extend_keep.py [--keep 0.7] [--metric diffusion|geodesic]
                                                      [--shapes horse6,centaur1+weld3,...] [--data DIR]

A welded vertex moves whole rows of the heat-kernel diffusion distances
(``benchmarks/studies/weld_rows.py``), and the RMS over the best-fitting 70% of *samples* prefers the
true map over every wrong held-out map (``benchmarks/studies/sample_trim_maps.py``).
``gromov.match(..., search=gromov.SearchOptions(extend_keep=K))`` with ``K < 1`` (opt-in) follows each extended
start's discrete descent by ``gromov.gh.EXTEND_ROUNDS`` rounds that descend on the
best-fitting fraction ``K`` of the samples and place the others given them. This compares it
with the default search (``--keep 1``) on the held-out TOSCA classes (reference pose 0 against
deformations 1 and 2, clean, 3 welds, 10 and 20 holes, built as ``bench_heldout.py`` builds
them): d(C, C0) (best of direct and mirrored) per pair and per condition.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import gromov.gh as gh
from gromov.experiments.datasets import TOSCA, experiment1, experiment2
from gromov.experiments.reproduce import _pair_quality, _Shapes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import HEAT as OPTIONS, add_data_argument  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--keep", type=float, default=0.7, help="extend_keep (1: the default search)")
    ap.add_argument("--shapes", default=None, help="only these deformed shapes, e.g. horse6,centaur1+weld3")
    ap.add_argument("--metric", choices=("diffusion", "geodesic"), default="diffusion")
    args = ap.parse_args(argv)
    only = set(args.shapes.split(",")) if args.shapes else None
    tosca = TOSCA(Path(args.data) / "tosca")
    shapes = _Shapes(tosca, 3000, "pinch")
    res, t0 = {}, time.perf_counter()
    for cls in ("horse", "centaur", "wolf", "michael"):
        entries = [shapes.entry(e) for e in experiment1(tosca, {cls: 2}) + experiment2(tosca, {cls: 2})]
        ref = entries[0]
        options = OPTIONS if args.metric == "diffusion" else {}
        sx = gh.ShapeMetric(ref.mesh, args.metric, resolution=None, metric_options=options)
        for y in entries[1:]:
            if y.label in res or y.pose == 0 or (only and y.label not in only):
                continue
            sy = gh.ShapeMetric(y.mesh, args.metric, resolution=None, metric_options=options)
            q = _pair_quality(gh.match(sx, sy, args.metric, n_samples=100,
                                       search=gh.SearchOptions(extend_keep=args.keep)),
                              shapes, ref, y)
            kind = y.kind if y.kind != "holes" else "holes" + str(y.info["holes"])
            res[y.label] = (kind, q["best"])
            print(f"{y.label:>18} {kind:8} d(C, C0) {q['best']:.3f}{'  wrong' if q['best'] > 0.05 else ''}",
                  flush=True)
    what = f"{args.metric}, extend_keep {args.keep}"
    for kind in ("clean", "weld", "holes10", "holes20"):
        v = [b for k, b in res.values() if k == kind]
        if v:
            print(f"{what}: {kind:8} mean {np.mean(v):.3f}, wrong (> 0.05) {sum(x > 0.05 for x in v)} of {len(v)}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
