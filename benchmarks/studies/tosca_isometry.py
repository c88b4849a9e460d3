"""How isometric are TOSCA's poses? Geodesic distances of two poses at full resolution.

Run:  .venv/bin/python benchmarks/studies/tosca_isometry.py [--data DIR] [--classes cat,dog,...] [--json OUT]

GMDS with the geodesic metric can only find the ground-truth map if the two poses are nearly
isometric. For each class this takes its first two poses (same triangulation, vertex i <-> i),
100 random vertices (seed 1), and compares their geodesic distances on the full-resolution
meshes (our fast marching, ~0.2% mean error): RMS of ``d_0(p_i, p_j) - d_1(p_i, p_j)`` over
the largest distance from the sampled vertices on either pose (close to the diameter), the
median relative change ``|d_1 - d_0| / d_0``, and the median
ratio ``d_1 / d_0`` (a global scale change). No optimiser and no simplification are involved:
these are properties of the data.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from gromov.experiments.datasets import TOSCA
from gromov.metrics import GeodesicSolver

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument, write_results  # noqa: E402


def pose_pair(tosca: TOSCA, cls: str, n: int = 100, seed: int = 1) -> dict:
    p0, p1 = tosca.poses(cls)[:2]
    a, b = tosca.load(cls, p0), tosca.load(cls, p1)
    s = np.random.default_rng(seed).choice(a.n_vertices, n, replace=False)
    A, B = GeodesicSolver(a).from_sources(s), GeodesicSolver(b).from_sources(s)
    off = ~np.eye(n, dtype=bool)
    a_ss, b_ss = A[:, s][off], B[:, s][off]
    return {"class": cls, "poses": [p0, p1], "n_vertices": a.n_vertices,
            "rms_over_diameter": float(np.sqrt(np.mean((a_ss - b_ss) ** 2)) / max(A.max(), B.max())),
            "median_relative_change": float(np.median(np.abs(b_ss - a_ss) / a_ss)),
            "median_scale": float(np.median(b_ss / a_ss))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default="cat,dog,david,victoria,horse,centaur,wolf,michael")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    tosca = TOSCA(Path(args.data) / "tosca")
    t0 = time.perf_counter()
    rows = []
    print(f"{'class':<10}{'poses':>8}{'vertices':>10}{'RMS/diam':>10}{'median |dd|/d':>15}{'median scale':>14}")
    for cls in args.classes.split(","):
        r = pose_pair(tosca, cls)
        rows.append(r)
        print(f"{cls:<10}{'%d,%d' % tuple(r['poses']):>8}{r['n_vertices']:>10}{r['rms_over_diameter']:>10.4f}"
              f"{r['median_relative_change']:>15.3f}{r['median_scale']:>14.3f}", flush=True)
    print(f"({time.perf_counter() - t0:.0f} s)")
    write_results(args.json, {"rows": rows})


if __name__ == "__main__":
    main()
