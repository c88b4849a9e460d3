"""Which metric survives topological noise? Measured on TOSCA classes the paper did not use.

Run:  .venv/bin/python benchmarks/bench_heldout.py [--data DIR] [--classes horse,centaur,wolf,michael]
                                                  [--json OUT]

The paper's claim (Bronstein et al. 2010, §5) is that diffusion distances barely move under
topology changes where geodesic distances change drastically. This benchmark measures it on
the held-out TOSCA classes (horse, centaur, wolf, michael: none is in the paper's
experiments, so choices made from these numbers are not tuned on the test classes), with the
shapes built exactly as ``gromov reproduce`` builds them: per class the reference pose 0 and
two deformations at 3,000 vertices, every pose simplified identically, each deformation
clean, with 3 welds (merged vertices by default, ``--weld-join tube`` for handles), with 10
and with 20 holes.

1. **Ground-truth distortion** (no optimiser involved): 100 farthest-point samples of the
   reference, their ground-truth images on the deformed shape (same input vertex; samples
   removed by a hole are dropped); RMS of ``|d_X(p_i, p_j) - d_Y(p'_i, p'_j)|`` divided by the
   larger diameter, and the median ratio ``d_Y / d_X`` (a global scale change).
2. **GMDS** (``gromov.match``, 100 samples, L2): d(C, C0) as in ``gromov reproduce`` (geodesic
   error on the clean shapes / diameter, both directions, the mirrored map counted as correct),
   and the one-sided distortion of the found map beside that of the ground truth: where the
   found map has *lower* distortion than the truth, the metric -- not the optimiser -- is at
   fault.

Metrics: geodesic (fast marching), heat-kernel diffusion at tau = 0.005 (the default) and
0.02, the biharmonic distance, and the paper's connectivity-kernel graph diffusion (m = 50).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from gromov import farthest_point_sampling
from gromov.experiments.datasets import TOSCA, experiment1, experiment2
from gromov.experiments.reproduce import _pair_quality, _Shapes
from gromov.gh import SearchOptions, ShapeMetric, match
from gromov.gmds import TRIM_KEEP, trimmed_rms
from gromov.perturb import WELD_JOINS

HERE = Path(__file__).resolve().parent
METRICS = {
    "geodesic": ("geodesic", {}),
    "heat 0.005": ("diffusion", {"kernel": "heat", "tau": 0.005}),
    "heat 0.005 length": ("diffusion", {"kernel": "heat", "tau": 0.005, "units": "length"}),
    "heat 0.02": ("diffusion", {"kernel": "heat", "tau": 0.02}),
    "heat normalized": ("diffusion", {"kernel": "heat", "units": "normalized"}),  # tau 0.01
    "biharmonic": ("diffusion", {"kernel": "biharmonic"}),
    "connectivity m=50": ("diffusion", {"kernel": "connectivity"}),
}
KINDS = ("clean", "weld", "holes10", "holes20")


def _kind(shape) -> str:
    if shape.kind == "holes":
        return "holes" + str(shape.info["holes"])
    return shape.kind


def _rows_of(mesh, input_ids) -> np.ndarray:
    """Working vertex of ``mesh`` with each input id (-1 where it is gone)."""
    pos = {int(v): i for i, v in enumerate(mesh.input_ids)}
    return np.array([pos.get(int(v), -1) for v in input_ids], dtype=np.int64)


def _distortion(dx, p, dy, q, diam, keep: float = 1.0) -> float:
    """One-sided distortion ÷ ``diam``: RMS, or with ``keep < 1`` the RMS of the best-fitting
    fraction ``keep`` of the pairs (:func:`gromov.gmds.trimmed_rms`)."""
    ok = (p >= 0) & (q >= 0)
    a, b = dx[np.ix_(p[ok], p[ok])], dy[np.ix_(q[ok], q[ok])]
    off = ~np.eye(int(ok.sum()), dtype=bool)
    return float(trimmed_rms((a - b)[off], keep) / diam)


def round_metrics_to_float32() -> None:
    """From now on, every dense metric matrix is rounded to float32 once computed (and read as
    float64): what keeping the matrices in float32 would give the matches."""
    from gromov.metrics import _base, _fmm, diffusion

    def rounded(pairwise):
        def wrapper(self, *args, **kwargs):
            d = pairwise(self, *args, **kwargs)
            if not getattr(self, "_rounded_to_float32", False):
                d.flags.writeable = True
                d[...] = d.astype(np.float32)
                d.flags.writeable = False
                self._rounded_to_float32 = True
            return d
        return wrapper

    for cls in {c for m in (_base, _fmm, diffusion) for c in vars(m).values()
                if isinstance(c, type) and "pairwise" in vars(c)}:
        cls.pairwise = rounded(vars(cls)["pairwise"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[1] / "shared" / "data")))
    ap.add_argument("--classes", default="horse,centaur,wolf,michael")
    ap.add_argument("--metrics", default=",".join(METRICS))
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--weld-join", choices=WELD_JOINS, default="pinch",
                    help="welds merge two vertices (pinch, as gromov reproduce) or add a handle (tube)")
    ap.add_argument("--fill-holes", type=float, default=None, metavar="F",
                    help="diffusion metrics: close loops shorter than F sqrt(area) (default: the "
                         "library's, 0.5; 0 leaves holes open)")
    ap.add_argument("--search-vertices", type=int, default=None, metavar="K",
                    help="restrict GMDS's initial search to K farthest point samples of the target "
                         "(gromov.match's search_vertices; default: the library's)")
    ap.add_argument("--orientation", choices=("ignore", "prefer"), default=None,
                    help="gromov.match's orientation option (default: the library's, prefer)")
    ap.add_argument("--radius", type=float, default=None, metavar="F",
                    help="partial matching: GMDS counts only sample pairs closer than F times the "
                         "larger diameter (gromov.match's radius; default: all pairs)")
    ap.add_argument("--float32", action="store_true",
                    help="round every dense metric matrix to float32 (what float32 storage would give)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    if args.float32:
        round_metrics_to_float32()
    tosca = TOSCA(Path(args.data) / "tosca")
    shapes = _Shapes(tosca, 3000, args.weld_join)
    names = args.metrics.split(",")
    rows = []
    t_start = time.perf_counter()
    for cls in args.classes.split(","):
        entries = [shapes.entry(e) for e in experiment1(tosca, {cls: 2}) + experiment2(tosca, {cls: 2})]
        ref = entries[0]
        others = [e for e in entries[1:] if e.label != ref.label]
        for name in names:
            metric, opts = METRICS[name]
            if metric == "diffusion" and args.fill_holes is not None:
                opts = {**opts, "fill_holes": args.fill_holes or None}
            t = time.perf_counter()
            sx = ShapeMetric(ref.mesh, metric, resolution=None, metric_options=opts)
            P = farthest_point_sampling(sx.distances, args.samples, seed=0).indices
            ids = ref.mesh.input_ids[P]
            for y in others:
                sy = ShapeMetric(y.mesh, metric, resolution=None, metric_options=opts)
                diam = max(sx.diameter, sy.diameter)
                truth = _rows_of(y.mesh, ids)
                ok = truth >= 0
                scale = float(np.median(sy.distances[np.ix_(truth[ok], truth[ok])][~np.eye(ok.sum(), dtype=bool)]
                                        / sx.distances[np.ix_(P[ok], P[ok])][~np.eye(ok.sum(), dtype=bool)]))
                extra = ({} if args.search_vertices is None else
                         {"search": SearchOptions(search_vertices=args.search_vertices)})
                if args.orientation is not None:
                    extra["orientation"] = args.orientation
                if args.radius is not None:
                    extra["radius"] = args.radius * diam
                r = match(sx, sy, metric, n_samples=args.samples, **extra)
                q = _pair_quality(r, shapes, ref, y)
                # the match's samples are these same P (ShapeMetric.samples: FPS, seed 0)
                xs, found = _rows_of(ref.mesh, r.x_samples), _rows_of(y.mesh, r.x_to_y_vertex)
                assert np.array_equal(xs, P)
                row = {"class": cls, "metric": name, "shape": y.label, "kind": _kind(y),
                       "truth_distortion": _distortion(sx.distances, P, sy.distances, truth, diam),
                       "scale": scale, "d_c_c0": q["best"], "d_c_c0_direct": q["direct"],
                       "found_distortion": _distortion(sx.distances, xs, sy.distances, found, diam),
                       "truth_trimmed": _distortion(sx.distances, P, sy.distances, truth, diam, TRIM_KEEP),
                       "found_trimmed": _distortion(sx.distances, xs, sy.distances, found, diam, TRIM_KEEP),
                       "orientation": r.orientation, "branch": q["branch"]}
                rows.append(row)
            print(f"  {cls:<8} {name:<18} {time.perf_counter() - t:6.1f} s", flush=True)

    print(f"\nheld-out classes {args.classes}; {args.samples} samples; mean over "
          f"{len(args.classes.split(','))} classes x 2 deformations ({time.perf_counter() - t_start:.0f} s)")
    summary = defaultdict(dict)
    for what, key in (("ground-truth distortion (RMS / diameter)", "truth_distortion"),
                      ("median scale d_Y / d_X", "scale"),
                      ("GMDS d(C, C0), best", "d_c_c0"),
                      ("GMDS d(C, C0), direct (the mirrored map counted as wrong)", "d_c_c0_direct"),
                      ("wrong maps (d(C, C0) > 0.05) / of them with lower distortion than the truth", None),
                      ("wrong maps / of them with lower trimmed distortion (best-fitting 80% of pairs) "
                       "than the truth", "trimmed")):
        print(f"\n{what}")
        print(f"  {'metric':<18}" + "".join(f"{k:>10}" for k in KINDS))
        for name in names:
            cells = []
            for kind in KINDS:
                sel = [r for r in rows if r["metric"] == name and r["kind"] == kind]
                if key is None or key == "trimmed":
                    wrong = [r for r in sel if r["d_c_c0"] > 0.05]
                    f, t = ("found_distortion", "truth_distortion") if key is None else ("found_trimmed", "truth_trimmed")
                    lower = sum(r[f] < r[t] for r in wrong)
                    summary["wrong_maps" if key is None else "wrong_maps_trimmed"][f"{name}/{kind}"] = [
                        len(wrong), lower, len(sel)]
                    cells.append(f"{len(wrong)}/{lower}")
                else:
                    v = statistics.mean(r[key] for r in sel)
                    summary[key][f"{name}/{kind}"] = v
                    cells.append(f"{v:.3f}")
            print(f"  {name:<18}" + "".join(f"{c:>10}" for c in cells))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"date": time.strftime("%Y-%m-%d"), "classes": args.classes,
                                               "weld_join": args.weld_join, "fill_holes": args.fill_holes,
                                               "search_vertices": args.search_vertices,
                                               "orientation": args.orientation, "radius": args.radius,
                                               "float32": args.float32,
                                               "samples": args.samples, "summary": summary, "rows": rows},
                                              indent=1))


if __name__ == "__main__":
    main()
