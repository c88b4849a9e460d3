"""What a welded vertex does to the heat-kernel diffusion distance: a few pairs, or whole rows?

Run:  .venv/bin/python benchmarks/studies/weld_rows.py [--data DIR] [--classes wolf,horse,centaur,michael]
                                               [--json OUT]

Held-out TOSCA classes (not the paper's), built exactly as ``gromov reproduce`` builds them:
the reference pose's working mesh (3,000 vertices) carried to deformations 1 and 2, each
clean and with 3 merged-vertex welds. For the *ground-truth* correspondence (same input
vertex; no optimiser), with the reference's 100 farthest point samples, the default diffusion
metric (heat kernel, tau = 0.005, holes filled) of the clean deformation and of the welded one
are compared pair by pair:

- the relative change ``(d_weld - d_clean) / d_clean`` of every sample pair, its sign, and
  how it depends on how close the pair's nearer sample is to a weld (geodesic, on the clean
  shape, / its diameter);
- the area, which sets the diffusion time ``t = tau * area``;
- the ground-truth correspondence's distortion (reference -> clean and reference -> welded),
  as RMS, as the RMS of the best-fitting 80% of pairs (``gromov.gmds.trimmed_rms``, what
  recognition ranks by) and as the RMS over the pairs of the best-fitting 70% of samples.

Between far points the diffusion distance is ``d_t^2 ~ k_2t(x, x) + k_2t(y, y)``: it depends
on each point's return probability, which a weld changes within about ``sqrt(8t)`` of it --
so the distances of a point near a weld to *all* points move, not only the pairs whose paths
run through the weld.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from gromov import farthest_point_sampling
from gromov.experiments.datasets import TOSCA, experiment1
from gromov.experiments.reproduce import _Shapes, _weld
from gromov.metrics import metric_solver

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import HEAT as OPTIONS, add_data_argument, residual_summaries, write_results  # noqa: E402

BANDS = ((0.0, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 1.01))


def _area(solver) -> float:
    return float(getattr(solver, "inner", solver).area)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default="wolf,horse,centaur,michael")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    tosca = TOSCA(Path(args.data) / "tosca")
    shapes = _Shapes(tosca, 3000, "pinch")
    rows = []
    t0 = time.perf_counter()
    for cls in args.classes.split(","):
        entries = [shapes.entry(e) for e in experiment1(tosca, {cls: 2})]
        ref = entries[0]
        sref = metric_solver(ref.mesh, "diffusion", **OPTIONS)
        P = farthest_point_sampling(metric_solver(ref.mesh, "geodesic"), 100, seed=0).indices
        A = sref.submatrix(P)
        for clean in (e for e in entries if e.kind == "clean" and e.pose != 0):
            weld = next(e for e in entries if e.kind == "weld" and e.pose == clean.pose)
            sc = metric_solver(clean.mesh, "diffusion", **OPTIONS)
            sw = metric_solver(weld.mesh, "diffusion", **OPTIONS)
            # every pose has the reference's vertex numbering; a weld merges vertices
            pos = {int(v): i for i, v in enumerate(weld.mesh.input_ids)}
            ids = ref.mesh.input_ids[P]
            q = np.array([pos.get(int(v), -1) for v in ids])
            ok = q >= 0
            C = sc.submatrix(P[ok])       # clean pose: same numbering as the reference
            W = sw.submatrix(q[ok])
            iu = np.triu_indices(int(ok.sum()), 1)
            rel = (W[iu] - C[iu]) / C[iu]
            geo = metric_solver(clean.mesh, "geodesic")
            # the welded vertices (both ends of each weld): the same weld again (deterministic)
            sites = _weld(clean.mesh, weld.info["welds"], weld.info["seed"], "pinch")[0].sites.ravel()
            near = geo.from_sources(sites).min(axis=0)[P[ok]] / geo.diameter()
            nearer = np.minimum.outer(near, near)[iu]
            diam_c = max(sref.pairwise().max(), sc.pairwise().max())
            diam_w = max(sref.pairwise().max(), sw.pairwise().max())
            row = {"shape": clean.label, "welds": int(weld.info["welds"]),
                   "area_change": _area(sw) / _area(sc) - 1.0,
                   "median_abs_rel_change": float(np.median(np.abs(rel))),
                   "fraction_rel_change_above_1pct": float(np.mean(np.abs(rel) > 0.01)),
                   "fraction_shorter": float(np.mean(rel < 0)),
                   "by_distance_to_weld": {f"{lo:.2f}-{min(hi, 1):.2f}": {
                       "pairs": int(((nearer >= lo) & (nearer < hi)).sum()),
                       "median_abs_rel_change": float(np.median(np.abs(rel[(nearer >= lo) & (nearer < hi)])))
                       if ((nearer >= lo) & (nearer < hi)).any() else None} for lo, hi in BANDS},
                   "truth_clean": residual_summaries(A[np.ix_(ok, ok)] - C, diam_c),
                   "truth_weld": residual_summaries(A[np.ix_(ok, ok)] - W, diam_w)}
            rows.append(row)
            bands = "  ".join(f"{k} {v['median_abs_rel_change']:.4f} ({v['pairs']})"
                              for k, v in row["by_distance_to_weld"].items() if v["pairs"])
            tc, tw = row["truth_clean"], row["truth_weld"]
            print(f"{clean.label:>8}: area {100 * row['area_change']:+.2f}%, |rel. change| median "
                  f"{row['median_abs_rel_change']:.4f}, > 1%: {row['fraction_rel_change_above_1pct']:.0%} "
                  f"of pairs, shorter: {row['fraction_shorter']:.1%}", flush=True)
            print(f"{'':>10}median |rel. change| by the nearer sample's distance to a weld: {bands}")
            print(f"{'':>10}ground truth clean / welded: RMS {tc['rms']:.4f} / {tw['rms']:.4f}, "
                  f"trimmed 80% {tc['trim80']:.4f} / {tw['trim80']:.4f}, "
                  f"best 70% of samples {tc['strim70']:.4f} / {tw['strim70']:.4f}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    write_results(args.json, {"options": OPTIONS, "rows": rows})
    return rows


if __name__ == "__main__":
    main()
