"""Farthest point sampling: monotone covering radius, reproducibility, r-covering."""

import numpy as np
import pytest

from gromov import farthest_point_sampling
from gromov.metrics import GeodesicSolver, metric_solver
from gromov.shapes import icosphere, torus


@pytest.mark.parametrize("metric", ["geodesic", "diffusion", "euclidean"])
def test_covering_radius_never_increases(metric):
    s = metric_solver(torus(), metric)
    fps = farthest_point_sampling(s, 40, seed=3)
    assert len(np.unique(fps.indices)) == 40
    assert np.all(np.diff(fps.radii) <= 0)
    d = s.from_sources(fps.indices)
    np.testing.assert_allclose(fps.distance, d.min(0), atol=1e-12)
    np.testing.assert_array_equal(fps.indices[fps.nearest], fps.indices[d.argmin(0)])
    assert fps.radius == pytest.approx(d.min(0).max())
    # greedy samples are separated by at least the final covering radius
    sub = d[:, fps.indices] + np.eye(40) * 1e9
    assert sub.min() >= fps.radius - 1e-12


def test_reproducible_under_seed():
    s = GeodesicSolver(icosphere(3))
    a = farthest_point_sampling(s, 20, seed=7)
    b = farthest_point_sampling(s, 20, seed=7)
    c = farthest_point_sampling(s, 20, seed=8)
    np.testing.assert_array_equal(a.indices, b.indices)
    assert a.indices[0] != c.indices[0]
    np.testing.assert_array_equal(farthest_point_sampling(s, 5, first=11).indices[:1], [11])


def test_r_covering_and_matrix_input():
    s = GeodesicSolver(icosphere(3))
    fps = farthest_point_sampling(s, radius=0.5, seed=0)
    assert fps.radius <= 0.5 and fps.radii[-2] > 0.5
    # a dense matrix gives the same samples as the solver it came from (on an irregular mesh:
    # exact ties between rounding-different computations would make the choice arbitrary)
    from gromov import simplify

    diff = metric_solver(simplify(icosphere(4), 500).mesh, "diffusion")
    a = farthest_point_sampling(diff, 30, seed=0)
    b = farthest_point_sampling(diff.pairwise(), 30, seed=0)
    np.testing.assert_array_equal(a.indices, b.indices)
    capped = farthest_point_sampling(s, 3, radius=0.01, seed=0)
    assert len(capped) == 3


def test_errors():
    s = GeodesicSolver(icosphere(1))
    with pytest.raises(ValueError, match="n_samples, radius, or both"):
        farthest_point_sampling(s)
    with pytest.raises(ValueError, match=r"n_samples must be an integer in \[1, 42\]"):
        farthest_point_sampling(s, 43)
    with pytest.raises(ValueError, match="radius must be non-negative"):
        farthest_point_sampling(s, radius=-1)
    with pytest.raises(ValueError, match="square distance matrix"):
        farthest_point_sampling(np.zeros((3, 4)), 2)
    with pytest.raises(ValueError, match="first must be"):
        farthest_point_sampling(s, 2, first=99)


@pytest.mark.parametrize("threads, bucket", [(1, 256), (2, 256), (1, 7), (2, 7)])
def test_euclidean_fast_path_is_the_general_loop(monkeypatch, threads, bucket):
    """Point clouds sample in the Euclidean metric with buckets of points, most of which each
    new sample passes over (in threads from ``_PARALLEL_MIN`` points): the same samples, radii,
    distances and cells, to the bit, as the general loop over the solver's rows -- repeated
    points, ties and a radius included, whatever the bucket size and number of threads."""
    import numba

    import gromov.sampling as sampling
    from gromov.mesh import PointCloud
    from gromov.metrics import EuclideanSolver

    class Rows(EuclideanSolver):   # not exactly EuclideanSolver: the general loop
        pass

    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip("one numba thread on this machine")
    monkeypatch.setattr(sampling, "_PARALLEL_MIN", 100)
    monkeypatch.setattr(sampling, "_BUCKET", bucket)
    numba.set_num_threads(threads)
    try:
        pts = np.random.default_rng(4).normal(size=(3000, 3))
        pts[10:20] = pts[0]                    # ten repeats of one point
        pts[100:110] = np.round(pts[100:110])  # points on a grid: tied distances
        cloud = PointCloud(pts)
        for kwargs in ({"n_samples": 500}, {"radius": 0.3}, {"n_samples": 3000}):
            fast = farthest_point_sampling(EuclideanSolver(cloud), first=7, **kwargs)
            slow = farthest_point_sampling(Rows(cloud), first=7, **kwargs)
            for f in ("indices", "radii", "distance", "nearest"):
                np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f), err_msg=f"{f} {kwargs}")
            assert fast.radius == slow.radius
        assert len(fast) == len(np.unique(pts, axis=0))   # every place once: repeats are covered at 0
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
