"""Matching point clouds: the same TOSCA pairs as meshes and as clouds of their vertices.

Run:  .venv/bin/python benchmarks/bench_point_clouds.py [--data DIR] [--json OUT] [--diagnostics]
      .venv/bin/python benchmarks/bench_point_clouds.py --pairs wolf0-wolf1,wolf0-wolf2,horse0-horse5,\
          horse0-horse6,centaur0-centaur1,centaur0-centaur5,michael0-michael1,michael0-michael6 \
          --metrics diffusion --kinds cloud --neighbors 10,20,30      (how POINT_CLOUD_NEIGHBORS was chosen)

``gromov.match`` takes point clouds (an ``(n, 3)`` array, a :class:`gromov.PointCloud`, a file
without faces). A cloud's working set is 3,000 farthest points in space; the geodesic metric is
Dijkstra on its 10-nearest-neighbour graph, the diffusion metric the heat kernel of the robust
point-cloud Laplacian (Sharp & Crane 2020); the images stay at points (the initial search's
discrete maps, no GMDS refinement inside triangles; no orientation preference, since a cloud
has no outward side). For cls0 -> cls1 (cat, dog, david, victoria; ground truth vertex i <->
vertex i), matched as meshes and as the clouds of the same vertices, and as clouds of half the
vertices of each pose drawn at random (different points on the two shapes; ground truth by
vertex index): the mean geodesic error of the 100 sample images over cls1's geodesic diameter,
on cls1's working mesh (fast marching), of the direct and the mirrored reading ("best": the
better of the two, as in ``bench_match.py``) and the seconds of the whole ``match`` call
(working set, metric, match). Means over the pairs per metric and input.

``--topkids N`` matches kid01..kidN of SHREC'16 TOPKIDS (real topological noise) to kid00, as
meshes and as clouds of their vertices, with the metrics of ``--metrics``: the error against the
given ground truth, the better of the direct and the symmetric reading (``kid00_sym.txt``), as
``gromov reproduce``'s TOPKIDS table measures it.

``--diagnostics`` adds two measurements of where the clouds lose accuracy: the meshes matched
with their images kept at vertices (the discrete maps a cloud gets; ``ShapeMetric.has_faces``
patched to False), and, for david0, david1, victoria1 and cat1, how the geodesic distances of
the cloud (Dijkstra on its k-nearest-neighbour graph, k = 4, 6, 10) between 200 random working
points compare with the surface's (the heat method on the input mesh): the median ratio and
the share of pairs shortened by more than 20% (shortcuts between parts that pass close in space).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from _common import add_data_argument, write_results

import gromov
from gromov.evaluate import correspondence_error
from gromov.experiments.reproduce import reflection_map
from gromov.gh import ShapeMetric, match
from gromov.metrics.diffusion import correspondence_options
from gromov.mesh import PointCloud

CLASSES = ("cat", "dog", "david", "victoria")
KINDS = ("mesh", "cloud", "half cloud")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--pairs", default=",".join(f"{c}0-{c}1" for c in CLASSES),
                    help="pairs X-Y of TOSCA shapes of one class (default: cls0-cls1 of cat, dog, david, victoria)")
    ap.add_argument("--metrics", default="geodesic,diffusion")
    ap.add_argument("--kinds", default=",".join(KINDS), help="of: " + ", ".join(KINDS))
    ap.add_argument("--neighbors", default=None,
                    help="diffusion on clouds with each of these neighbour counts of the robust Laplacian, "
                         "e.g. 10,20,30 (default: the library's default)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--diagnostics", action="store_true")
    ap.add_argument("--topkids", type=int, default=0, metavar="N")
    args = ap.parse_args(argv)
    if args.topkids:
        res = {"samples": args.samples, "topkids": _topkids(Path(args.data) / "topkids", args.topkids,
                                                          args.metrics.split(","), args.samples)}
        write_results(args.json, res)
        return res
    tosca = Path(args.data) / "tosca"
    kinds = args.kinds.split(",")
    neighbors = [None] if args.neighbors is None else [int(k) for k in args.neighbors.split(",")]
    res = {"samples": args.samples, "pairs": args.pairs, "rows": {}}
    print(f"{'pair':<24}{'metric':<11}{'input':<18}{'direct':>9}{'mirrored':>10}{'best':>8}{'rel. GH':>9}{'seconds':>9}")
    for pair in args.pairs.split(","):
        a, b = pair.split("-")
        x_in, y_in = gromov.load(tosca / f"{a}.off.gz"), gromov.load(tosca / f"{b}.off.gz")
        sym = reflection_map(x_in)
        ywork = ShapeMetric(y_in, "geodesic")   # where errors are measured
        rng = np.random.default_rng(0)
        half_x = np.sort(rng.choice(x_in.n_vertices, x_in.n_vertices // 2, replace=False))
        half_y = np.sort(rng.choice(y_in.n_vertices, y_in.n_vertices // 2, replace=False))
        inputs = {"mesh": (x_in, y_in),
                  "cloud": (x_in.vertices, y_in.vertices),
                  "half cloud": (PointCloud(x_in.vertices[half_x], input_ids=half_x),
                                 PointCloud(y_in.vertices[half_y], input_ids=half_y))}
        for metric in args.metrics.split(","):
            for kind in kinds:
                x, y = inputs[kind]
                for nb in (neighbors if metric == "diffusion" and kind != "mesh" else [None]):
                    opts = correspondence_options(metric, None if nb is None else {"neighbors": nb})
                    label = kind if nb is None else f"{kind} n={nb}"
                    t = time.perf_counter()
                    r = match(x, y, metric, n_samples=args.samples, metric_options=opts)
                    dt = time.perf_counter() - t
                    # input ids of the clouds are vertex ids of the meshes: the truth is the identity
                    err = correspondence_error(r, ywork, symmetry=sym)
                    row = {"direct": err.mean, "mirrored": err.mirrored_mean, "best": err.best,
                           "relative_distance": r.relative_distance, "seconds": dt}
                    res["rows"][f"{pair}/{metric}/{label}"] = row
                    print(f"{a + ' -> ' + b:<24}{metric:<11}{label:<18}{row['direct']:>9.4f}"
                          f"{row['mirrored']:>10.4f}{row['best']:>8.4f}{r.relative_distance:>9.4f}{dt:>9.2f}",
                          flush=True)
    for key in sorted({k.split("/", 1)[1] for k in res["rows"]}):
        vals = [v["best"] for k, v in res["rows"].items() if k.split("/", 1)[1] == key]
        res.setdefault("mean_best", {})[key] = float(np.mean(vals))
        print(f"mean best, {key}: {np.mean(vals):.4f}")
    if args.diagnostics:
        res["discrete_mesh_maps"] = _discrete_mesh_maps(tosca, args.samples)
        res["shortcuts"] = _shortcuts(tosca)
    write_results(args.json, res)
    return res


def _discrete_mesh_maps(tosca: Path, samples: int) -> dict:
    """The meshes' correspondences with the images kept at vertices (no GMDS refinement)."""
    out = {}
    for cls in CLASSES:
        x_in, y_in = gromov.load(tosca / f"{cls}0.off.gz"), gromov.load(tosca / f"{cls}1.off.gz")
        sym, ywork = reflection_map(x_in), ShapeMetric(y_in, "geodesic")
        for metric in ("geodesic", "diffusion"):
            opts = correspondence_options(metric, None)
            sx, sy = (ShapeMetric(m, metric, metric_options=opts) for m in (x_in, y_in))
            ShapeMetric.has_faces = property(lambda s: False)   # match's path for point clouds
            try:
                r = match(sx, sy, metric, n_samples=samples)
            finally:
                del ShapeMetric.has_faces
                ShapeMetric.has_faces = _HAS_FACES
            out[f"{cls}/{metric}"] = best = correspondence_error(r, ywork, symmetry=sym).best
            print(f"discrete map on the meshes, {cls}, {metric}: best {best:.4f}", flush=True)
    return out


def _shortcuts(tosca: Path) -> dict:
    """Cloud geodesics (k-NN Dijkstra) against surface geodesics between 200 working points."""
    from gromov.metrics import metric_solver

    out = {}
    for name in ("david0", "david1", "victoria1", "cat1"):
        m = gromov.load(tosca / f"{name}.off.gz")
        cloud = ShapeMetric(m.vertices, "geodesic")
        sub = np.random.default_rng(0).choice(cloud.mesh.n_vertices, 200, replace=False)
        ids = cloud.working.vertex_ids[sub]
        surface = metric_solver(m, "geodesic", method="heat").from_sources(ids)[:, ids]
        off = ~np.eye(200, dtype=bool)
        for k in (4, 6, 10):
            d = metric_solver(cloud.mesh, "geodesic", k=k).from_sources(sub)[:, sub]
            ratio = d[off] / surface[off]
            out[f"{name}/k{k}"] = row = {"median_ratio": float(np.median(ratio)),
                                         "shortened_20pct": float((ratio < 0.8).mean())}
            print(f"{name}, k = {k}: median cloud / surface geodesic {row['median_ratio']:.3f}, "
                  f"pairs shortened by > 20%: {100 * row['shortened_20pct']:.1f}%", flush=True)
    return out


def _topkids(root: Path, n: int, metrics, samples: int) -> dict:
    """kid01..kidN -> kid00 as meshes and as clouds of their vertices: best error per shape."""
    from gromov.experiments.datasets import TopKids

    kids = TopKids(root)
    ref = kids.reference
    names = [k for k in kids.names if k != ref][:n]
    y_in = kids.load(ref)
    ywork = ShapeMetric(y_in, "geodesic")
    sym = kids.symmetry(ref)
    sym = np.where(sym < 0, np.arange(len(sym)), sym)   # unknown mirror: the vertex itself
    out = {}
    for metric in metrics:
        opts = correspondence_options(metric, None)
        for kind in ("mesh", "cloud"):
            y = y_in if kind == "mesh" else y_in.vertices
            sy = ShapeMetric(y, metric, metric_options=opts)
            errs, t = [], time.perf_counter()
            for name in names:
                x_in = kids.load(name)
                r = match(x_in if kind == "mesh" else x_in.vertices, sy, metric, n_samples=samples)
                errs.append(correspondence_error(r, ywork, kids.ground_truth(name), sym).best)
            out[f"{metric}/{kind}"] = row = {"mean_best": float(np.mean(errs)),
                                             "per_shape": dict(zip(names, map(float, errs))),
                                             "seconds": round(time.perf_counter() - t, 1)}
            print(f"TOPKIDS {names[0]}..{names[-1]} -> {ref}, {metric}, {kind}: mean best error "
                  f"{row['mean_best']:.4f} ({row['seconds']:.0f} s)", flush=True)
    return out


_HAS_FACES = ShapeMetric.has_faces


if __name__ == "__main__":
    main()
