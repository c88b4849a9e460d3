"""Farthest point sampling in any metric (Bronstein et al. 2010, footnote 6).

Greedy: start from one vertex, repeatedly add the vertex farthest from the samples so
far. After ``k`` samples the covering radius ``r_k = max_x min_i d(x, p_i)`` is within a
factor two of the best possible k-point covering (Gonzalez, TCS 38, 1985), and the samples
are ``r_k``-separated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import get_num_threads, njit, prange

from .metrics import EuclideanSolver, MetricSolver

__all__ = ["Samples", "farthest_point_sampling"]


@dataclass(frozen=True, eq=False)
class Samples:
    """Result of :func:`farthest_point_sampling`.

    Attributes
    ----------
    indices : ndarray, shape (k,)
        Sampled vertex indices, in the order they were chosen.
    radius : float
        Covering radius after the last sample: every vertex lies within ``radius`` of a
        sample (``inf`` while a connected component has no sample).
    radii : ndarray, shape (k,)
        ``radii[i]`` is the covering radius after ``i + 1`` samples (non-increasing).
    distance : ndarray, shape (n,)
        Distance from each vertex to its nearest sample.
    nearest : ndarray, shape (n,)
        Position in ``indices`` of each vertex's nearest sample (its Voronoi cell).
    """

    indices: np.ndarray
    radius: float
    radii: np.ndarray
    distance: np.ndarray
    nearest: np.ndarray

    def __len__(self) -> int:
        return len(self.indices)


def farthest_point_sampling(metric, n_samples: int | None = None, *, radius: float | None = None,
                            seed: int | np.random.Generator | None = 0,
                            first: int | None = None) -> Samples:
    """Farthest point samples of a shape in the given metric.

    Parameters
    ----------
    metric : MetricSolver or ndarray of shape (n, n)
        Where distances come from (one row per new sample), or a dense distance matrix.
    n_samples : int, optional
        Number of samples. At least one of ``n_samples`` and ``radius`` is required.
    radius : float, optional
        r-covering: stop as soon as the covering radius is ``<= radius`` (and also at
        ``n_samples`` when both are given).
    seed : int, Generator or None, default 0
        Chooses the first sample when ``first`` is not given. The rest is deterministic.
    first : int, optional
        Index of the first sample.

    Returns
    -------
    Samples
    """
    if isinstance(metric, MetricSolver):
        n = metric.n_vertices
        row = lambda i: metric.from_sources([i])[0]  # noqa: E731
    else:
        d = np.asarray(metric, dtype=float)
        if d.ndim != 2 or d.shape[0] != d.shape[1]:
            raise ValueError(f"metric must be a MetricSolver or a square distance matrix, got shape {d.shape}")
        n = d.shape[0]
        row = lambda i: d[i]  # noqa: E731
    if n_samples is None and radius is None:
        raise ValueError("give n_samples, radius, or both")
    if n_samples is not None:
        if int(n_samples) != n_samples or not 1 <= n_samples <= n:
            raise ValueError(f"n_samples must be an integer in [1, {n}], got {n_samples}")
        n_samples = int(n_samples)
    if radius is not None and not radius >= 0:
        raise ValueError(f"radius must be non-negative, got {radius}")
    limit = n if n_samples is None else n_samples
    if first is None:
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        first = int(rng.integers(n))
    elif not 0 <= int(first) < n:
        raise ValueError(f"first must be a vertex index in [0, {n}), got {first}")

    dist = np.full(n, np.inf)          # to the nearest sample so far
    nearest = np.zeros(n, dtype=np.int64)
    if type(metric) is EuclideanSolver:   # point clouds: one fused pass per sample, in threads
        V = np.ascontiguousarray(metric.shape.vertices, dtype=np.float64)
        threads = get_num_threads() if n >= _PARALLEL_MIN else 1

        def add(i: int, k: int) -> tuple[float, int]:
            if threads > 1:
                best, j = _add_parallel(V, dist, nearest, i, k, threads)
            else:   # also in forked workers (one thread), which must not enter the threading layer
                best, j = _add_range(V, dist, nearest, 0, n, i, k)
            return float(best), int(j)
    else:
        def add(i: int, k: int) -> tuple[float, int]:
            """Sample ``i`` as the ``k``-th: update the distances and cells; the farthest vertex."""
            r = np.asarray(row(i), dtype=float)
            closer = r < dist
            nearest[closer] = k
            dist[closer] = r[closer]
            dist[i] = 0.0
            nearest[i] = k
            j = int(np.argmax(dist))
            return float(dist[j]), j

    indices = [int(first)]
    best, nxt = add(int(first), 0)
    radii = [best]
    while len(indices) < limit and not (radius is not None and radii[-1] <= radius):
        if dist[nxt] <= 0.0:  # every vertex is a sample already (duplicates)
            break
        indices.append(nxt)
        best, nxt = add(nxt, len(indices) - 1)
        radii.append(best)
    return Samples(np.asarray(indices, dtype=np.int64), radii[-1], np.asarray(radii), dist, nearest)


#: Points from which the Euclidean sampling's pass runs in numba threads.
_PARALLEL_MIN = 50_000


@njit(cache=True)
def _add_range(V, dist, nearest, lo, hi, i, k):
    """Point ``i`` as the ``k``-th sample, for the points ``lo:hi``: straight-line distance,
    cells, and the farthest point (the first of equals)."""
    x, y, z = V[i, 0], V[i, 1], V[i, 2]
    best, arg = -1.0, lo
    for p in range(lo, hi):
        dx, dy, dz = V[p, 0] - x, V[p, 1] - y, V[p, 2] - z
        d = np.sqrt(dx * dx + dy * dy + dz * dz)   # as scipy's cdist: the same values
        if d < dist[p]:
            dist[p] = d
            nearest[p] = k
        if p == i:
            dist[p] = 0.0
            nearest[p] = k
        if dist[p] > best:
            best, arg = dist[p], p
    return best, arg


@njit(cache=True, parallel=True)
def _add_parallel(V, dist, nearest, i, k, T):
    """:func:`_add_range` over all points in ``T`` chunks, one per thread; the chunks'
    farthest points combined in order, so the result does not depend on ``T``."""
    n = V.shape[0]
    bests = np.empty(T)
    args = np.empty(T, dtype=np.int64)
    for t in prange(T):
        bests[t], args[t] = _add_range(V, dist, nearest, t * n // T, (t + 1) * n // T, i, k)
    best, arg = -1.0, 0
    for t in range(T):
        if bests[t] > best:
            best, arg = bests[t], args[t]
    return best, arg
