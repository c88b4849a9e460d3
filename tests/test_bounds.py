"""The certified interval around the GH distance of two finite metric spaces."""

import itertools

import numpy as np
import pytest

from gromov.bounds import gh_lower_bound, local_hausdorff, sample_gh_interval


def _metric(rng, m):
    """A random finite metric: shortest paths of a random complete graph."""
    w = rng.uniform(0.2, 2.0, (m, m))
    d = np.triu(w, 1) + np.triu(w, 1).T
    for k in range(m):   # Floyd-Warshall
        d = np.minimum(d, d[:, [k]] + d[[k], :])
    return d


def _gh_brute(dx, dy):
    """½ min dis R over every correspondence R (every relation covering both sets)."""
    m, n = len(dx), len(dy)
    cells = list(itertools.product(range(m), range(n)))
    best = np.inf
    for bits in range(1, 1 << len(cells)):
        R = [c for k, c in enumerate(cells) if bits >> k & 1]
        a = np.array([r[0] for r in R])
        b = np.array([r[1] for r in R])
        if len(set(a)) < m or len(set(b)) < n:
            continue
        best = min(best, np.abs(dx[np.ix_(a, a)] - dy[np.ix_(b, b)]).max())
    return 0.5 * best


@pytest.mark.parametrize("seed", range(12))
def test_interval_contains_the_exact_distance(seed):
    rng = np.random.default_rng(seed)
    m, n = rng.integers(2, 4, 2)
    dx, dy = _metric(rng, m), _metric(rng, n)
    exact = _gh_brute(dx, dy)
    lo, hi = sample_gh_interval(dx, dy, rng.integers(0, n, m), rng.integers(0, m, n))
    assert lo <= exact + 1e-15 and exact <= hi + 1e-15
    assert lo > 0 or np.isclose(exact, 0)


def test_one_point_against_a_space_is_half_its_diameter():
    rng = np.random.default_rng(3)
    d = _metric(rng, 6)
    assert gh_lower_bound(np.zeros((1, 1)), d) == pytest.approx(0.5 * d.max(), rel=1e-11)
    lo, hi = sample_gh_interval(np.zeros((1, 1)), d, [0], np.zeros(6, int))
    assert lo == pytest.approx(hi, rel=1e-11)


def test_an_isometric_copy_has_the_interval_zero_with_the_right_map():
    rng = np.random.default_rng(4)
    d = _metric(rng, 40)
    perm = rng.permutation(40)
    dy = d[np.ix_(perm, perm)]            # point k of Y is point perm[k] of X
    inv = np.argsort(perm)
    lo, hi = sample_gh_interval(d, dy, inv, perm)
    assert lo == 0.0 and hi == 0.0
    lo2, hi2 = sample_gh_interval(d, dy, rng.integers(0, 40, 40), rng.integers(0, 40, 40))
    assert lo2 == 0.0 and hi2 > 0.1


def test_local_hausdorff_against_a_direct_computation():
    rng = np.random.default_rng(5)
    dx, dy = _metric(rng, 7), _metric(rng, 9)
    h = local_hausdorff(dx, dy)
    for a in range(7):
        for b in range(9):
            diff = np.abs(dx[a][:, None] - dy[b][None, :])
            assert h[a, b] == max(diff.min(axis=1).max(), diff.min(axis=0).max())


def test_lower_bound_beats_the_diameter_and_eccentricity_bounds():
    rng = np.random.default_rng(6)
    for _ in range(20):
        dx, dy = _metric(rng, 12), _metric(rng, 15)
        lo = gh_lower_bound(dx, dy)
        ecc = lambda d: np.sort(d.max(axis=1))   # noqa: E731
        ex, ey = ecc(dx), ecc(dy)
        hd = max(np.abs(ex[:, None] - ey[None]).min(1).max(), np.abs(ex[:, None] - ey[None]).min(0).max())
        assert lo >= 0.5 * abs(dx.max() - dy.max()) * (1 - 1e-9)
        assert lo >= 0.5 * hd * (1 - 1e-9)


def test_shapes_are_checked():
    with pytest.raises(ValueError, match="p_to_q"):
        sample_gh_interval(np.zeros((3, 3)), np.zeros((2, 2)), [0, 1], [0, 1])


def test_match_reports_the_interval_of_its_samples():
    """``MatchResult.gh_interval``: the lower bound of the two sample sets' distance matrices,
    below half the distortion of the correspondence found, snapped to the samples."""
    import gromov
    from gromov.gh import ShapeMetric
    from gromov.shapes import grid, rolled_grid

    x = ShapeMetric(grid(16, 16), "geodesic", resolution=None)
    y = ShapeMetric(rolled_grid(16, 16), "geodesic", resolution=None)
    r = gromov.match(x, y, "geodesic", n_samples=30)
    lo, hi = r.gh_interval
    P, Q = x.samples(30, 0), y.samples(30, 0)
    assert lo == gh_lower_bound(x.distances[np.ix_(P, P)], y.distances[np.ix_(Q, Q)])
    assert 0.0 <= lo <= hi < 0.5 * max(x.diameter, y.diameter)
    from gromov.experiments.pairwise import gh_matrix

    g = gh_matrix([x, y], "geodesic", n_samples=30, keep=[(0, 1)])
    assert np.isnan(g.results[0, 1].gh_interval[0])
