"""How far the part's refinement goes: ZoomOut to k_X = 80 or 120, on the parts of bench_partial.py.

Run:  .venv/bin/python benchmarks/studies/probe_partial_steps.py [--data DIR] [--per-class 4]
                                                                 [--vertices 4000] [--remeshed DIR]
                                                                 [--json OUT]

``benchmarks/bench_partial.py``'s parts (every TOSCA class, ``--per-class`` plane cuts keeping
40-80% of the area and as many parts with holes removing 20-40%, each matched into the next
pose), each matched once with ``gromov.match(part, whole, partial=True, dense="placed")``; the
placed map, and it refined by :func:`gromov.partial.partial_zoomout` from k_X = 10 by 4 up to
``k_end`` = 80 and 120 (k_Y = k_X / area ratio, at most 160), scored as the benchmark scores
them: :func:`gromov.evaluate.dense_error` on every vertex of the part, x 100 / sqrt(area of
the whole), the better of the direct and mirrored readings, an image on another piece counted
as the diameter, pooled over the pairs' points per kind; ``gross``: pairs whose mean error
exceeds a quarter of the whole's diameter.

``--remeshed DIR``: the same, on the copies ``benchmarks/remesh.py --out DIR --densities ""``
makes of 8 classes (pose 0 and one other, each remeshed on its own: no shared vertex or
triangle, so no refinement can snap to the truth's vertices): the parts are cut from the copy
of pose 0 (seeds and keeps as above) and matched into the other copy, the truth carried by the
nearest original vertex (``remesh.true_images``), the mirrored truth by the class's reflection.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import gromov
from gromov.evaluate import GeodesicReference, dense_error
from gromov.experiments import datasets
from gromov.experiments.reproduce import reflection_map
from gromov.partial import partial_zoomout
from gromov.perturb import cut
from gromov.shape_metric import ShapeMetric

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/
from _common import add_data_argument, write_results  # noqa: E402
from bench_dense import GROSS, at_vertices  # noqa: E402
from bench_partial import CUT_PATCHES, ClassPoses, keeps  # noqa: E402
from remesh import POSES, true_images  # noqa: E402

HERE = Path(__file__).resolve().parent
K_ENDS = (80, 120)
#: The cap on the whole's eigenfunctions (``probe_partial_cap.py``).
KY_MAX = 160


def pairs(tosca, per_class: int, vertices: int, remeshed: Path | None):
    """``(name, kind, part, truth, whole, sy, fmm, symmetry)`` for every part."""
    for cls in tosca.classes:
        if remeshed is None:
            poses = ClassPoses(tosca, cls, vertices)
        elif cls in POSES:
            copies = {p: (gromov.load(remeshed / f"{cls}{p}.off"),
                          np.loadtxt(remeshed / f"{cls}{p}.ids.txt", dtype=np.int64)) for p in (0, POSES[cls])}
            (x0, ids_x), (y, ids_y) = copies[0], copies[POSES[cls]]
            x0, y = gromov.Mesh(x0.vertices, x0.faces), gromov.Mesh(y.vertices, y.faces)
            original_y = tosca.load(cls, POSES[cls]).vertices
            refl = reflection_map(tosca.load(cls, 0))
            symmetry = true_images(refl[ids_y], original_y, y.vertices)
            sy, fmm = ShapeMetric(y, "geodesic"), GeodesicReference(y)
        else:
            continue
        for kind in ("plane", "holes"):
            for k, keep in enumerate(keeps(kind, per_class)):
                if remeshed is None:
                    a, b = poses.poses[k % len(poses.poses)], poses.poses[(k + 1) % len(poses.poses)]
                    source, whole = poses.mesh(a), poses.mesh(b)
                else:
                    a, b, source, whole = 0, POSES[cls], x0, y
                try:
                    p = cut(source, keep, kind=kind, seed=k, **({"count": CUT_PATCHES} if kind == "holes" else {}))
                except ValueError:
                    continue
                part = gromov.Mesh(p.mesh.vertices, p.mesh.faces)
                if remeshed is None:
                    truth, sy, fmm, symmetry = (p.vertex_map, poses.prepared(b, "geodesic")[0],
                                                poses.prepared(b, "fmm")[0], poses.symmetry)
                else:
                    truth = true_images(ids_x[p.vertex_map], original_y, y.vertices)
                yield f"{cls}{a}-{kind}{k}->{cls}{b}", kind, part, truth, whole, sy, fmm, symmetry


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--per-class", type=int, default=4)
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--remeshed", default=None, help="the folder of benchmarks/remesh.py's copies")
    ap.add_argument("--json", default=None, help="default: probe_partial_steps[_remeshed].json beside this file")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    remeshed = None if args.remeshed is None else Path(args.remeshed)
    out = args.json or str(HERE / f"probe_partial_steps{'' if remeshed is None else '_remeshed'}.json")
    variants = ["placed", *(f"k_X to {k}" for k in K_ENDS)]
    rows = []
    for name, kind, part, truth, whole, sy, fmm, symmetry in pairs(tosca, args.per_class, args.vertices, remeshed):
        sx = ShapeMetric(part, "geodesic")
        r = gromov.match(sx, sy, partial=True, dense="placed")
        placed = sy.input.from_input_ids(r.x_to_y_dense_vertex)
        row = {"pair": name, "kind": kind, "ratio": float(part.area / whole.area),
               "part_vertices": part.n_vertices, "whole_vertices": whole.n_vertices}
        for variant in variants:
            t = time.perf_counter()
            if variant == "placed":
                T = placed
            else:
                T = partial_zoomout(sx, sy, placed, k_end=int(variant.split()[-1]), ky_max=KY_MAX)
            seconds = time.perf_counter() - t
            e = dense_error(*at_vertices(whole, T), whole, truth, symmetry, fmm=fmm)
            cap = e.diameter / np.sqrt(e.area)
            err = np.where(np.isfinite(e.errors), e.errors, cap)
            row[variant] = {"errors": 100 * err, "mean": 100 * float(err.mean()),
                            "median": 100 * float(np.median(err)), "gross": bool(err.mean() / cap > GROSS),
                            "seconds": seconds}
        rows.append(row)
        print(f"{row['pair']:<28}", "  ".join(f"{v}: {row[v]['mean']:6.2f} / {row[v]['median']:5.2f}"
                                             for v in variants), flush=True)
    summary = {}
    for kind in ("plane", "holes"):
        have = [r for r in rows if r["kind"] == kind]
        summary[kind] = {v: {"pairs": len(have),
                             "mean": float(np.concatenate([r[v]["errors"] for r in have]).mean()),
                             "median": float(np.median(np.concatenate([r[v]["errors"] for r in have]))),
                             "gross": int(sum(r[v]["gross"] for r in have)),
                             "worse_than_placed": int(sum(r[v]["mean"] > r["placed"]["mean"] + 1e-9 for r in have)),
                             "seconds_per_pair": float(np.mean([r[v]["seconds"] for r in have]))}
                         for v in variants}
        print(kind, {v: f"{s['mean']:.2f} / {s['median']:.2f}, gross {s['gross']}, worse {s['worse_than_placed']}"
                     for v, s in summary[kind].items()})
    for r in rows:
        for v in variants:
            del r[v]["errors"]
    command = "python benchmarks/studies/probe_partial_steps.py" + ("" if remeshed is None else " --remeshed DIR")
    write_results(out, {"command": command, "vertices": None if remeshed else args.vertices,
                        "per_class": args.per_class, "summary": summary, "pairs": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
