"""Small pieces in the metric or left out: TOSCA's gorillas, with and without their 37 pieces.

Run:  .venv/bin/python benchmarks/studies/small_pieces.py [--data DIR] [--json OUT]

TOSCA's gorilla meshes hold, beside the body, 37 small connected pieces (eyes, teeth; 2% of
the area, 36% of the vertices). For gorilla pose pairs (same triangulation: vertex i <-> i) this
matches each pair with the library's default (``gromov.match(X, Y, dense=True)``) twice: with
every piece in the working mesh and metric (``gromov.resolution.MIN_PIECE = 0``) and with the
pieces under 1% of the area left out, moving with the surface nearest to them (the default).
It reports the samples on the pieces, the diffusion diameter over the body's, and the dense
error x 100 / sqrt(area) (geodesic on the input mesh of Y, :func:`gromov.evaluate.dense_errors`)
on the body's vertices and on the pieces' vertices (an image on another piece than the truth's
has no finite geodesic error: counted apart, as "elsewhere"; the straight-line error of every
image is reported beside it).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import gromov
import gromov.resolution as resolution
from gromov.evaluate import dense_errors

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument, write_results  # noqa: E402

PAIRS = [("gorilla1", "gorilla5"), ("gorilla8", "gorilla14"), ("gorilla5", "gorilla1"), ("gorilla14", "gorilla8")]


def one_pair(X: gromov.Mesh, Y: gromov.Mesh, min_piece: float) -> dict:
    resolution.MIN_PIECE = min_piece
    t = time.perf_counter()
    sx, sy = gromov.ShapeMetric(X), gromov.ShapeMetric(Y)
    r = gromov.match(sx, sy, dense=True)
    seconds = time.perf_counter() - t
    labels = sx.mesh.component_labels
    body = np.argmax(np.bincount(labels, weights=sx.mesh.vertex_areas))
    on_pieces = int(np.sum(labels[sx.samples(100)] != body))
    ok = np.flatnonzero(r.x_to_y_dense_face >= 0)          # file ids of X kept on loading ...
    ok = ok[Y.file_index[ok] >= 0]                           # ... and of Y: the truth is the same id
    e = dense_errors(r.x_to_y_dense_face[ok], r.x_to_y_dense_bary[ok], Y, ok)
    e *= 100 / np.sqrt(Y.area)
    main = resolution.main_pieces(X, 0.01)[X.file_index[ok]]
    out = {"min_piece": min_piece, "samples_on_pieces": on_pieces, "seconds": seconds,
           "diameter_over_body": float(sx.diameter / np.max(sx.distances[np.ix_(labels == body, labels == body)])),
           "gh": float(r.distance)}
    image = Y.vertices[Y.from_input_ids(r.x_to_y_dense_vertex[ok])]
    straight = np.linalg.norm(image - Y.vertices[Y.file_index[ok]], axis=1) * 100 / np.sqrt(Y.area)
    for name, m in (("body", main), ("pieces", ~main)):
        fin = np.isfinite(e[m])
        out[name] = {"vertices": int(m.sum()), "mean": float(e[m][fin].mean()), "median": float(np.median(e[m][fin])),
                     "elsewhere": int((~fin).sum()), "euclidean_mean": float(straight[m].mean()),
                     "euclidean_median": float(np.median(straight[m]))}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--json", default=str(Path(__file__).with_suffix(".json")))
    args = ap.parse_args(argv)
    rows = []
    for a, b in PAIRS:
        X = gromov.load(f"{args.data}/tosca/{a}.off.gz")
        Y = gromov.load(f"{args.data}/tosca/{b}.off.gz")
        for min_piece in (0.0, 0.01):
            row = {"pair": f"{a}->{b}", **one_pair(X, Y, min_piece)}
            rows.append(row)
            print(f"{row['pair']:20s} pieces {'in ' if min_piece == 0 else 'out'}: samples on pieces "
                  f"{row['samples_on_pieces']:3d}, diameter/body {row['diameter_over_body']:6.1f}, body "
                  f"{row['body']['mean']:6.2f} / {row['body']['median']:5.2f}, pieces {row['pieces']['mean']:6.2f} / "
                  f"{row['pieces']['median']:5.2f} ({row['pieces']['elsewhere']} elsewhere; straight "
                  f"{row['pieces']['euclidean_mean']:5.2f} / {row['pieces']['euclidean_median']:5.2f}), {row['seconds']:.0f} s",
                  flush=True)
    write_results(args.json, {"command": "benchmarks/studies/small_pieces.py", "pairs": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
