"""Matching point clouds: the same TOSCA pairs as meshes and as clouds of their vertices.

Run:  .venv/bin/python benchmarks/bench_point_clouds.py [--data DIR] [--json OUT]

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
(working set, metric, match).
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    tosca = Path(args.data) / "tosca"
    res = {"samples": args.samples, "rows": {}}
    print(f"{'pair':<22}{'metric':<11}{'input':<13}{'direct':>9}{'mirrored':>10}{'best':>8}{'rel. GH':>9}{'seconds':>9}")
    for cls in CLASSES:
        x_in, y_in = gromov.load(tosca / f"{cls}0.off.gz"), gromov.load(tosca / f"{cls}1.off.gz")
        sym = reflection_map(x_in)
        ywork = ShapeMetric(y_in, "geodesic")   # where errors are measured
        rng = np.random.default_rng(0)
        half_x = np.sort(rng.choice(x_in.n_vertices, x_in.n_vertices // 2, replace=False))
        half_y = np.sort(rng.choice(y_in.n_vertices, y_in.n_vertices // 2, replace=False))
        inputs = {"mesh": (x_in, y_in),
                  "cloud": (x_in.vertices, y_in.vertices),
                  "half cloud": (PointCloud(x_in.vertices[half_x], input_ids=half_x),
                                 PointCloud(y_in.vertices[half_y], input_ids=half_y))}
        for metric in ("geodesic", "diffusion"):
            opts = correspondence_options(metric, None)
            for kind, (x, y) in inputs.items():
                t = time.perf_counter()
                r = match(x, y, metric, n_samples=args.samples, metric_options=opts)
                dt = time.perf_counter() - t
                # input ids of the clouds are vertex ids of the meshes: ground truth is the identity
                err = correspondence_error(r, ywork, symmetry=sym)
                row = {"direct": err.mean, "mirrored": err.mirrored_mean, "best": err.best,
                       "relative_distance": r.relative_distance, "seconds": dt}
                res["rows"][f"{cls}/{metric}/{kind}"] = row
                print(f"{cls + '0 -> ' + cls + '1':<22}{metric:<11}{kind:<13}{row['direct']:>9.4f}"
                      f"{row['mirrored']:>10.4f}{row['best']:>8.4f}{r.relative_distance:>9.4f}{dt:>9.2f}",
                      flush=True)
    for metric in ("geodesic", "diffusion"):
        for kind in ("mesh", "cloud", "half cloud"):
            vals = [v["best"] for k, v in res["rows"].items() if k.endswith(f"/{metric}/{kind}")]
            res.setdefault("mean_best", {})[f"{metric}/{kind}"] = float(np.mean(vals))
            print(f"mean best, {metric}, {kind}: {np.mean(vals):.4f}")
    write_results(args.json, res)
    return res


if __name__ == "__main__":
    main()
