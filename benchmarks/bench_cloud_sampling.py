"""Farthest point sampling of a large point cloud: ours against fpsample, side by side.

Run:  .venv/bin/python benchmarks/bench_cloud_sampling.py [--points 100000,1000000] [--samples 3000]
                                                          [--json benchmarks/results/cloud_sampling.json]

A point cloud larger than the working resolution is matched on its ``resolution`` farthest
points in space (:func:`gromov.resolution.working_cloud`), chosen by
:func:`gromov.sampling.farthest_point_sampling` with a :class:`gromov.metrics.EuclideanSolver`.
Timed on random normal clouds, one run each after a warm-up (numba compiled and cached):

- ``ours``: the fused numba pass per sample (in numba threads from 50,000 points);
- ``ours, general loop``: the same algorithm through the solver's rows (numpy; what every
  other metric uses) -- the same samples to the bit;
- ``fpsample`` (anchor; Rust/C++, single-threaded, float32): its vanilla FPS and its
  bucket-based QuickFPS (``bucket_fps_kdline_sampling``, h = 7; Han et al., IEEE TCAD 2023).
  Both compute in float32, so their samples differ from ours (float64) on large clouds; the
  covering radius they reach is printed beside ours.

Ratios are ours / anchor (below 1: ours faster).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import write_results

from gromov.mesh import PointCloud
from gromov.metrics import EuclideanSolver
from gromov.sampling import farthest_point_sampling


class _Rows(EuclideanSolver):
    """EuclideanSolver, but not exactly: :func:`farthest_point_sampling` takes its general loop."""


def _covering_radius(V: np.ndarray, idx: np.ndarray) -> float:
    from scipy.spatial import cKDTree

    return float(cKDTree(V[idx]).query(V)[0].max())


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def run(n_points: int, n_samples: int, seed: int = 0) -> dict:
    V = np.random.default_rng(seed).normal(size=(n_points, 3))
    cloud = PointCloud(V)
    farthest_point_sampling(EuclideanSolver(cloud), 3, first=0)   # warm-up: numba
    ours, t_ours = _timed(lambda: farthest_point_sampling(EuclideanSolver(cloud), n_samples, first=0))
    loop, t_loop = _timed(lambda: farthest_point_sampling(_Rows(cloud), n_samples, first=0))
    row = {"points": n_points, "samples": n_samples,
           "ours_s": t_ours, "ours_general_loop_s": t_loop,
           "identical_to_general_loop": bool(np.array_equal(ours.indices, loop.indices)
                                             and np.array_equal(ours.distance, loop.distance)),
           "radius_ours": float(ours.radius)}
    try:
        import fpsample
    except ImportError:
        print("  (fpsample not installed: pip install fpsample, or the bench extra)")
        return row
    van, t_van = _timed(lambda: fpsample.fps_sampling(V, n_samples, start_idx=0))
    quick, t_quick = _timed(lambda: fpsample.bucket_fps_kdline_sampling(V, n_samples, h=7, start_idx=0))
    row.update(fpsample_vanilla_s=t_van, fpsample_quickfps_s=t_quick,
               radius_fpsample_vanilla=_covering_radius(V, np.asarray(van)),
               radius_fpsample_quickfps=_covering_radius(V, np.asarray(quick)))
    return row


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", default="100000,1000000")
    ap.add_argument("--samples", type=int, default=3000)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = []
    for n in (int(x) for x in a.points.split(",")):
        r = run(n, a.samples)
        rows.append(r)
        line = (f"{n:>9,} points -> {a.samples} samples: ours {r['ours_s']:.2f} s "
                f"(general loop {r['ours_general_loop_s']:.2f} s, x{r['ours_general_loop_s'] / r['ours_s']:.1f}; "
                f"identical {r['identical_to_general_loop']}; radius {r['radius_ours']:.4f})")
        if "fpsample_vanilla_s" in r:
            line += (f"\n    fpsample vanilla {r['fpsample_vanilla_s']:.2f} s (ours / it "
                     f"{r['ours_s'] / r['fpsample_vanilla_s']:.2f}; radius {r['radius_fpsample_vanilla']:.4f}), "
                     f"QuickFPS {r['fpsample_quickfps_s']:.2f} s (ours / it "
                     f"{r['ours_s'] / r['fpsample_quickfps_s']:.1f}; radius {r['radius_fpsample_quickfps']:.4f})")
        print(line, flush=True)
    write_results(a.json, {"rows": rows})


if __name__ == "__main__":
    main()
