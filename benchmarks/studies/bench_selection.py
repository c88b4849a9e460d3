"""Is it the search or the selection? GMDS from every extended start, scored several ways.

Run:  .venv/bin/python benchmarks/studies/bench_selection.py [--data DIR] [--metric diffusion|geodesic]
                                                     [--classes horse,centaur,wolf,michael]
                                                     [--no-topkids] [--json OUT]

``gromov.match`` extends ``n_extend`` (8) coarse starts per direction to all samples, keeps the
best of each direction by its one-sided distortion, anchors the other side on it and runs GMDS
from the pair with the lower two-sided distortion. Here every one of the 16 two-sided starts
(``gromov.gh.initial_pairs(..., all_starts=True)``) is run to the end, and the final maps are
chosen by other criteria:

- ``match``: ``gromov.match``'s own result (for comparison; its map is one of the 16);
- ``final``: the lowest two-sided RMS distortion after GMDS (all 16);
- ``local r``: the lowest RMS distortion over the pairs of samples closer than ``r`` times the
  diameter (local pairs are less moved by a handle far away);
- ``trim 90%``: the lowest RMS over the 90% best-fitting pairs;
- ``oracle``: the lowest d(C, C0) among the 16 (what a perfect criterion could pick).

If the oracle is far below ``match``, a better criterion could help; if it is close, the
starts themselves are the limit. Data: the held-out TOSCA classes built as
``benchmarks/bench_heldout.py`` builds them (clean, 3 welds, 10 and 20 holes; d(C, C0) as
``gromov reproduce`` measures it) and TOPKIDS kid01-25 -> kid00 (d(C, C0) of the kid -> kid00
map against the given ground truth, the mirrored map counted as correct, as
``benchmarks/bench_topkids.py``).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from gromov import simplify
from gromov.experiments import datasets
from gromov.experiments.datasets import TOSCA, experiment1, experiment2
from gromov.experiments.reproduce import _geodesic_errors, _pair_quality, _Shapes
from gromov.gh import ShapeMetric, initial_pairs, match
from gromov.gmds import SurfacePoints, SymmetricGMDS
from gromov.metrics import metric_solver

HERE = Path(__file__).resolve().parent
RADII = (0.2, 0.3)
OPTIONS = {"geodesic": {}, "diffusion": {"kernel": "heat", "tau": 0.005}}


def candidates(sx: ShapeMetric, sy: ShapeMetric, n_samples: int = 100) -> list[dict]:
    """GMDS from each of the 16 starts, and ``gromov.match``'s own result (scored only by
    ``match``): scores and the results' sample maps (input ids)."""
    P, Q = sx.samples(n_samples, 0), sy.samples(n_samples, 0)
    gm = SymmetricGMDS(sx.surface, sy.surface, P, Q)
    diam = max(sx.diameter, sy.diameter)
    out = []
    for a, b in initial_pairs(sx, sy, P, Q, all_starts=True):
        img_p, img_q, _, _ = gm.solve(SurfacePoints.at_vertices(sy.mesh, a), SurfacePoints.at_vertices(sx.mesh, b))
        bx, by = gm.blocks(img_p, img_q)
        off = ~np.eye(len(bx), dtype=bool)
        r = bx - by
        scores = {"match": np.inf, "final": float(np.sqrt(np.mean(r[off] ** 2)))}
        for rad in RADII:
            m = off & (bx < rad * diam)
            scores[f"local {rad}"] = float(np.sqrt(np.mean(r[m] ** 2)))
        ar = np.sort(np.abs(r[off]))
        scores["trim 90%"] = float(np.sqrt(np.mean(ar[: int(0.9 * len(ar))] ** 2)))
        result = SimpleNamespace(x_samples=sx.working.to_input_ids(P), y_samples=sy.working.to_input_ids(Q),
                                 x_to_y_vertex=sy.locate(img_p)[2], y_to_x_vertex=sx.locate(img_q)[2])
        out.append({"scores": scores, "result": result})
    # match itself (its map is one of the 16: it runs GMDS from one of these starts)
    own = {k: np.inf for k in out[0]["scores"]}
    own["match"] = 0.0
    out.append({"scores": own, "result": match(sx, sy, sx.metric, n_samples=n_samples)})
    return out


def heldout(data: Path, metric: str, classes: list[str]) -> list[dict]:
    tosca = TOSCA(data / "tosca")
    shapes = _Shapes(tosca, 3000, "pinch")
    rows = []
    for cls in classes:
        entries = [shapes.entry(e) for e in experiment1(tosca, {cls: 2}) + experiment2(tosca, {cls: 2})]
        ref = entries[0]
        sx = ShapeMetric(ref.mesh, metric, resolution=None, metric_options=OPTIONS[metric])
        for y in [e for e in entries[1:] if e.label != ref.label]:
            sy = ShapeMetric(y.mesh, metric, resolution=None, metric_options=OPTIONS[metric])
            kind = "holes" + str(y.info["holes"]) if y.kind == "holes" else y.kind
            cands = [{"scores": c["scores"], "error": _pair_quality(c["result"], shapes, ref, y)["best"]}
                     for c in candidates(sx, sy)]
            rows.append({"pair": y.label, "kind": kind, "candidates": cands})
            print(f"  {y.label:<18} match {_pick(cands, 'match'):.3f} oracle {_pick(cands, 'oracle'):.3f}",
                  flush=True)
    return rows


def topkids(data: Path, metric: str) -> list[dict]:
    kids = datasets.TopKids(data / "topkids")
    ref = kids.reference
    m0 = kids.load(ref)
    w0 = simplify(m0, 3000)
    geo0 = metric_solver(w0.mesh, "geodesic")
    diam0 = float(np.max(geo0.pairwise()))
    sym0 = kids.symmetry(ref)
    s0 = ShapeMetric(m0, metric, working=w0, metric_options=OPTIONS[metric])
    rows = []
    for name in [n for n in kids.names if n != ref]:
        mesh = kids.load(name)
        sx = ShapeMetric(mesh, metric, working=simplify(mesh, 3000), metric_options=OPTIONS[metric])
        cands = []
        for c in candidates(sx, s0):
            r = c["result"]
            gt = kids.ground_truth(name)[r.x_samples]
            gm = np.where(sym0[gt] < 0, gt, sym0[gt])
            e = min(_geodesic_errors(w0, geo0, r.x_to_y_vertex, t).mean() for t in (gt, gm)) / diam0
            cands.append({"scores": c["scores"], "error": float(e)})
        rows.append({"pair": name, "kind": "topkids", "candidates": cands})
        print(f"  {name:<18} match {_pick(cands, 'match'):.3f} oracle {_pick(cands, 'oracle'):.3f}", flush=True)
    return rows


def _pick(cands: list[dict], criterion: str) -> float:
    if criterion == "oracle":
        return min(c["error"] for c in cands)
    return cands[int(np.argmin([c["scores"][criterion] for c in cands]))]["error"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[2] / "shared" / "data")))
    ap.add_argument("--metric", choices=tuple(OPTIONS), default="diffusion")
    ap.add_argument("--classes", default="horse,centaur,wolf,michael")
    ap.add_argument("--no-topkids", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    data = Path(args.data)
    rows = heldout(data, args.metric, args.classes.split(","))
    if not args.no_topkids:
        rows += topkids(data, args.metric)
    kinds = list(dict.fromkeys(r["kind"] for r in rows))
    criteria = ["match", "final", *[f"local {r}" for r in RADII], "trim 90%", "oracle"]
    print(f"\n{args.metric}: mean d(C, C0) / wrong maps (> 0.05) of the map each criterion picks among "
          f"16 GMDS runs ({time.perf_counter() - t0:.0f} s)")
    print(f"  {'criterion':<12}" + "".join(f"{k:>14}" for k in kinds))
    summary = {}
    for c in criteria:
        cells = []
        for k in kinds:
            errs = [_pick(r["candidates"], c) for r in rows if r["kind"] == k]
            summary[f"{c}/{k}"] = [float(np.mean(errs)), int(sum(e > 0.05 for e in errs)), len(errs)]
            cells.append(f"{np.mean(errs):.3f} / {sum(e > 0.05 for e in errs)}")
        print(f"  {c:<12}" + "".join(f"{x:>14}" for x in cells))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"date": time.strftime("%Y-%m-%d"), "metric": args.metric,
                                               "classes": args.classes, "summary": summary, "rows": rows},
                                              indent=1))


if __name__ == "__main__":
    main()
