"""Partial matching's choices: which metric, the part at the whole's diffusion time or its own,
and how wide a band along the part's boundary is down-weighted.

Run:  .venv/bin/python benchmarks/studies/partial_choices.py [--classes wolf,centaur,...]
                                                             [--json OUT]

The pairs are those of ``benchmarks/bench_partial.py`` with one part per class and kind (part 0:
a plane cut keeping 60% of the area, holes keeping 70%, cut from the class's first pose and
matched to its second, every pose simplified to 4,000 vertices as the first is). Each variant
is ``gromov.partial.match_partial(part, whole, metric, dense=True, ...)``; per pair and variant:
the mean and median dense error x100 / sqrt(area of the whole) on the part's vertices (best of
the direct and the mirrored ground truth, as bench_partial measures it), the IoU of the covered
region it reports against the true one, and the distortion -- the weighted RMS ÷ the whole's
diameter, on the part's samples in the metric matched -- of the ground-truth map beside that of
the map found (the truth above the found: the objective itself prefers a wrong map). Backs
docs/design/partial.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import gromov  # noqa: E402
from _common import add_data_argument, write_results  # noqa: E402
from bench_partial import ClassPoses, grow, iou, near_working  # noqa: E402
from gromov.evaluate import dense_error  # noqa: E402
from gromov.experiments import datasets  # noqa: E402
from gromov.gh import ShapeMetric  # noqa: E402
from gromov.metrics.diffusion import correspondence_options  # noqa: E402
from gromov.partial import in_whole_metric, match_partial  # noqa: E402
from gromov.perturb import cut  # noqa: E402

HERE = Path(__file__).resolve().parent
CLASSES = ["wolf", "centaur", "cat", "dog", "horse", "michael"]
#: name: (metric, keyword arguments of match_partial)
VARIANTS = {
    "diffusion_own_time": ("diffusion", {"same_time": False}),
    "diffusion": ("diffusion", {}),
    "diffusion_no_band": ("diffusion", {"boundary": 0.0}),
    "geodesic_no_band": ("geodesic", {"boundary": 0.0}),
    "geodesic": ("geodesic", {}),
    "geodesic_band_0.2": ("geodesic", {"boundary": 0.2}),
}
KEEP = {"plane": 0.6, "holes": 0.7}


def measure(poses: ClassPoses, kind: str) -> dict:
    a, b = poses.poses[0], poses.poses[1]
    p = cut(poses.mesh(a), KEEP[kind], kind=kind, seed=0)
    part, truth, whole = gromov.Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map, poses.mesh(b)
    fmm = poses.prepared(b, "fmm")[0]
    true_region = grow(whole, truth)
    shapes = {"diffusion": (ShapeMetric(part, "diffusion", metric_options=correspondence_options("diffusion", None)),
                            poses.prepared(b, "metric")[0]),
              "geodesic": (ShapeMetric(part, "geodesic"), poses.prepared(b, "geodesic")[0])}
    row = {"pair": f"{poses.cls}{a}-{kind}0->{poses.cls}{b}", "kind": kind, "kept": p.params["kept"]}
    for name, (metric, kw) in VARIANTS.items():
        sx, sy = shapes[metric]
        t = time.perf_counter()
        r = match_partial(sx, sy, metric, dense=True, **kw)
        seconds = time.perf_counter() - t
        e = dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, whole, truth, poses.symmetry, fmm=fmm)
        cap = e.diameter / np.sqrt(e.area)
        err = np.where(np.isfinite(e.errors), e.errors, cap)
        # the weighted one-sided distortion of the truth and of the map found, in the metric matched
        sxx = in_whole_metric(sx, sy) if kw.get("same_time", True) else sx
        P = near_working(sxx, r.x_samples)
        W = np.outer(r.x_weight, r.x_weight)
        np.fill_diagonal(W, 0.0)
        dx = sxx.distances[np.ix_(P, P)]

        def distortion(images):
            Y = near_working(sy, images)
            return float(np.sqrt(np.sum(W * (dx - sy.distances[np.ix_(Y, Y)]) ** 2) / W.sum()) / sy.diameter)

        row[name] = {"mean": float(err.mean()), "median": float(np.median(err)),
                     "gross": bool(err.mean() / cap > 0.25), "iou": iou(r.y_covered, true_region),
                     "truth_distortion": distortion(truth[r.x_samples]), "found_distortion": distortion(r.x_to_y_vertex),
                     "seconds": seconds}
    print(f"  {row['pair']:<28} " + "  ".join(f"{n} {row[n]['mean'] * 100:5.1f}" for n in VARIANTS), flush=True)
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default=",".join(CLASSES))
    ap.add_argument("--json", default=str(HERE / "partial_choices.json"))
    args = ap.parse_args(argv)
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    rows = []
    t0 = time.perf_counter()
    for cls in [c for c in args.classes.split(",") if c]:
        poses = ClassPoses(tosca, cls, 4000)
        for kind in KEEP:
            rows.append(measure(poses, kind))
    summary = {}
    print(f"\n{len(rows)} pairs: mean / median of the pairs' mean error x100, gross pairs, IoU, "
          "truth's and found distortion")
    for name in VARIANTS:
        v = [r[name] for r in rows]
        summary[name] = {"mean": 100 * float(np.mean([x["mean"] for x in v])),
                         "median_of_means": 100 * float(np.median([x["mean"] for x in v])),
                         "median_of_medians": 100 * float(np.median([x["median"] for x in v])),
                         "gross": int(sum(x["gross"] for x in v)), "iou": float(np.mean([x["iou"] for x in v])),
                         "truth_distortion": float(np.mean([x["truth_distortion"] for x in v])),
                         "found_distortion": float(np.mean([x["found_distortion"] for x in v])),
                         "truth_worse": int(sum(x["truth_distortion"] > x["found_distortion"] for x in v)),
                         "seconds": float(np.mean([x["seconds"] for x in v]))}
        s = summary[name]
        print(f"  {name:<20} {s['mean']:6.2f} {s['median_of_means']:6.2f} {s['gross']:3d}/{len(v)} "
              f"IoU {s['iou']:.3f}  truth {s['truth_distortion']:.4f} found {s['found_distortion']:.4f} "
              f"(truth worse {s['truth_worse']}/{len(v)})  {s['seconds']:.1f} s")
    write_results(args.json, {"command": "benchmarks/studies/partial_choices.py " + " ".join(
        sys.argv[1:] if argv is None else argv), "gromov": gromov.__version__, "vertices": 4000, "keep": KEEP,
        "variants": {k: {"metric": m, **kw} for k, (m, kw) in VARIANTS.items()}, "summary": summary, "pairs": rows,
        "total_seconds": time.perf_counter() - t0})


if __name__ == "__main__":
    main()
