"""Partial matching's curvature term: how much the smoothed mean curvature weighs beside the
distortion when the part's placement on the whole is searched and chosen.

Run:  .venv/bin/python benchmarks/studies/partial_curvature.py [--classes cat,dog,...]
                                                               [--weights 0,0.005,0.01,...]
                                                               [--json OUT]

The parts are those of ``benchmarks/bench_partial.py`` (the same seeded plane cuts and holes,
4 per class and kind, each cut from one pose and matched into the next, every pose simplified
to 4,000 vertices as the class's first is). Each weight is
``gromov.partial.match_partial(part, whole, curvature=weight)`` with everything else at its
default; per pair and weight: the error of the part's 100 sample images against the ground
truth (the mean geodesic distance on the whole ÷ its diameter, the best of the direct and the
mirrored truth), gross above a quarter of the diameter. Before it: the distortion (weighted
RMS ÷ the whole's diameter) and the median curvature mismatch of the found map beside those of
the ground truth (``--diagnose``: the found map distorts less and the truth keeps the curvature
better). Backs the section "Curvature beside the distortion" of docs/design/partial.md: the
weight is chosen on the classes cat, centaur, david and dog and then measured on the others.
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
from bench_partial import GROSS, ClassPoses, keeps, near_working  # noqa: E402
from gromov.experiments import datasets  # noqa: E402
from gromov.gh import ShapeMetric  # noqa: E402
from gromov.partial import match_partial, part_curvature  # noqa: E402
from gromov.perturb import CUT_PATCHES, cut  # noqa: E402

HERE = Path(__file__).resolve().parent


def parts(poses: ClassPoses):
    """The class's parts of bench_partial: ``(name, part, truth, whole pose)``."""
    for kind in ("plane", "holes"):
        for k, keep in enumerate(keeps(kind, 4)):
            a, b = poses.poses[k % len(poses.poses)], poses.poses[(k + 1) % len(poses.poses)]
            p = cut(poses.mesh(a), keep, kind=kind, seed=k, **({"count": CUT_PATCHES} if kind == "holes" else {}))
            yield f"{poses.cls}{a}-{kind}{k}->{poses.cls}{b}", gromov.Mesh(p.mesh.vertices, p.mesh.faces), \
                p.vertex_map, b


def sample_error(r, sy: ShapeMetric, truth: np.ndarray, symmetry: np.ndarray) -> tuple[float, dict]:
    """Mean geodesic error of the sample images ÷ the whole's diameter (best of direct and
    mirrored truth), and the truth's working images (direct, mirrored)."""
    tv = near_working(sy, truth[r.x_samples])
    tm = near_working(sy, symmetry[truth[r.x_samples]])
    v = near_working(sy, r.x_to_y_vertex)
    D = sy.distances
    return float(min(D[v, tv].mean(), D[v, tm].mean()) / sy.diameter), {"truth": tv, "mirror": tm, "found": v}


def diagnose(r, sx: ShapeMetric, sy: ShapeMetric, images: dict) -> dict:
    """Weighted distortion ÷ diameter and median curvature mismatch of the found map and of the truth."""
    P = sx.working.from_source(sx.input.from_input_ids(r.x_samples))
    dx = sx.distances[np.ix_(P, P)]
    W = np.outer(r.x_weight, r.x_weight)
    np.fill_diagonal(W, 0.0)
    hx, hy = part_curvature(sx, sy)[P], sy.curvature
    out = {}
    for name in ("found", "truth"):
        v = images[name]
        res = dx - sy.distances[np.ix_(v, v)]
        out[f"{name}_distortion"] = float(np.sqrt(np.sum(W * res**2) / W.sum()) / sy.diameter)
        out[f"{name}_curvature_mismatch"] = float(np.median(np.abs(hx - hy[v])))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default=None, help="TOSCA classes, comma-separated (default: all)")
    ap.add_argument("--weights", default="0,0.005,0.01,0.02,0.04", help="curvature weights to compare")
    ap.add_argument("--diagnose", action="store_true", help="also the truth's distortion and curvature "
                                                           "mismatch beside the found map's (weight 0)")
    ap.add_argument("--json", default=str(HERE / "partial_curvature.json"))
    args = ap.parse_args(argv)
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    classes = tosca.classes if args.classes is None else [c for c in args.classes.split(",") if c]
    weights = [float(w) for w in args.weights.split(",") if w]
    rows = []
    t0 = time.perf_counter()
    for cls in classes:
        poses = ClassPoses(tosca, cls, 4000)
        for name, part, truth, b in parts(poses):
            sy = poses.prepared(b, "geodesic")[0]
            sx = ShapeMetric(part, "geodesic")
            row = {"pair": name, "kind": "plane" if "-plane" in name else "holes"}
            for w in weights:
                t = time.perf_counter()
                r = match_partial(sx, sy, curvature=w)
                sec = time.perf_counter() - t
                e, images = sample_error(r, sy, truth, poses.symmetry)
                row[str(w)] = {"error": e, "seconds": sec, "relative_distance": float(r.relative_distance),
                               "covered_fraction": float(r.covered_fraction)}
                if args.diagnose and w == 0.0:
                    row["diagnostics"] = diagnose(r, sx, sy, images)
            rows.append(row)
            print(f"  {name:<28} " + "  ".join(f"{w:g}: {row[str(w)]['error']:.3f}" for w in weights), flush=True)
    summary = {}
    for w in weights:
        e = np.array([r[str(w)]["error"] for r in rows])
        summary[str(w)] = {"pairs": len(e), "mean": float(e.mean()), "median": float(np.median(e)),
                           "gross": int(np.sum(e > GROSS)), "above_0.1": int(np.sum(e > 0.1))}
        print(f"weight {w:g}: mean {e.mean():.4f}, median {np.median(e):.4f}, gross {summary[str(w)]['gross']} "
              f"of {len(e)}, above 0.1 {summary[str(w)]['above_0.1']}")
    write_results(args.json, {"run": {"classes": classes, "weights": weights, "vertices": 4000,
                                      "command": "benchmarks/studies/partial_curvature.py "
                                                 + " ".join(sys.argv[1:] if argv is None else argv)},
                              "summary": summary, "pairs": rows, "seconds": time.perf_counter() - t0})


if __name__ == "__main__":
    main()
