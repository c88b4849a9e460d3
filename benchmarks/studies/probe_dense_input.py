"""ZoomOut at the input resolution, started from gromov's dense map: what it gains and costs.

Run:  .venv/bin/python benchmarks/studies/probe_dense_input.py [--data DIR] [--classes wolf,centaur,horse]
      [--json OUT]

For pose 0 -> the next pose of each TOSCA class: ``gromov.match(x, y, dense=True)``, then
ZoomOut (Melzi et al., SIGGRAPH Asia 2019) on the Laplace-Beltrami eigenfunctions of the
*input* meshes (cotangent Laplacian, ``scipy.sparse.linalg.eigsh`` in shift-invert mode), from
40 (or 20) to 60 (or 100) eigenfunctions, seeded by gromov's dense vertex map. Every map is
scored on the input mesh by :func:`gromov.evaluate.dense_error` (x 100 / sqrt(area), the
better of the direct and the mirrored ground truth). It prints the eigensolve's seconds per
shape: the cost that keeps this refinement out of ``gromov.match``'s default.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import eigsh
from scipy.spatial import cKDTree

import gromov
from gromov.evaluate import GeodesicReference, dense_error
from gromov.experiments import datasets
from gromov.experiments.reproduce import reflection_map
from gromov.metrics.diffusion import cotan_laplacian

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument  # noqa: E402

HERE = Path(__file__).resolve().parent

POSES = {"wolf": 1, "centaur": 1, "horse": 5, "cat": 1, "dog": 1, "david": 1, "michael": 1, "victoria": 1}
RUNS = ((20, 60), (40, 60), (20, 100), (40, 100))


def eigenbasis(mesh, k: int):
    """``(phi (n, k), mass (n,), seconds)`` of the cotangent Laplacian of ``mesh``."""
    L, M = cotan_laplacian(mesh)
    t = time.perf_counter()
    lam, phi = eigsh(L, k, M=M, sigma=-1e-8 / mesh.area)
    return phi[:, np.argsort(lam)], np.asarray(M.diagonal()), time.perf_counter() - t


def vertex_error(T, y, truth, sym, ref):
    """:func:`dense_error` of images at vertices ``T`` of ``y``."""
    face = np.full(y.n_vertices, -1)
    for c in range(3):
        face[y.faces[:, c]] = np.arange(len(y.faces))
    f = face[T]
    bary = np.zeros((len(T), 3))
    bary[np.arange(len(T)), np.argmax(y.faces[f] == T[:, None], axis=1)] = 1.0
    return dense_error(f, bary, y, truth, sym, fmm=ref)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default="wolf,centaur,horse")
    ap.add_argument("--json", default=str(HERE / "probe_dense_input.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    rows = {}
    for cls in args.classes.split(","):
        x, y = tosca.load(cls, 0), tosca.load(cls, POSES[cls])
        truth, sym, ref = np.arange(x.n_vertices), reflection_map(y), GeodesicReference(y)
        t = time.perf_counter()
        T0 = gromov.match(x, y, dense=True).x_to_y_dense_vertex
        row = {"n": int(x.n_vertices), "match_s": time.perf_counter() - t}
        e = vertex_error(T0, y, truth, sym, ref)
        row["gromov"] = {"mean": 100 * e.mean, "median": 100 * float(np.median(e.errors))}
        K = max(k for _, k in RUNS)
        px, mx, row["eigsh_x_s"] = eigenbasis(x, K)
        py, _, row["eigsh_y_s"] = eigenbasis(y, K)
        for k0, k1 in RUNS:
            T, t = T0.copy(), time.perf_counter()
            for k in range(k0, k1 + 1, 4 if k1 <= 60 else 5):
                C = px[:, :k].T @ (mx[:, None] * py[T, :k])
                T = cKDTree(py[:, :k]).query(px[:, :k] @ C)[1]
            e = vertex_error(T, y, truth, sym, ref)
            row[f"input zoomout {k0}-{k1}"] = {"mean": 100 * e.mean, "median": 100 * float(np.median(e.errors)),
                                               "seconds": time.perf_counter() - t}
        rows[f"{cls}0-{POSES[cls]}"] = row
        print(f"{cls}: {json.dumps(row)}", flush=True)
    Path(args.json).write_text(json.dumps({"command": "python benchmarks/studies/probe_dense_input.py --classes "
                                           + args.classes, "pairs": rows}, indent=1))
    print("wrote", args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
