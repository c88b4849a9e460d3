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
    if type(metric) is EuclideanSolver:   # point clouds: buckets of points, most passed over
        add = _EuclideanBuckets(metric.shape.vertices, dist, nearest).add
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


class _EuclideanBuckets:
    """Farthest point sampling's step in the Euclidean distance, with buckets of points.

    The points are ordered along a Morton (Z-order) curve of their coordinates, quantised to
    1,024 levels per axis, and cut into buckets of ``_BUCKET`` consecutive points with their
    bounding boxes. Adding a sample ``q`` can lower a point's distance only where
    ``|p - q| < dist[p]``; the distance from ``q`` to a bucket's box bounds ``|p - q|`` from
    below for every point in it, so a bucket whose box is at least as far as its largest
    ``dist`` is passed over whole (the bucket pruning of Han et al., "QuickFPS: architecture and
    algorithm co-design for farthest point sampling in large-scale point clouds", IEEE TCAD 2023,
    there with KD-tree buckets). Every other point is updated exactly as the general loop
    updates it, and the farthest point is the first of equals by index, so samples, radii,
    distances and cells are the general loop's, to the bit. Buckets are visited in numba threads
    from ``_PARALLEL_MIN`` points (each writes only its own points).
    """

    def __init__(self, vertices: np.ndarray, dist: np.ndarray, nearest: np.ndarray):
        V = np.asarray(vertices, dtype=np.float64)
        n = len(V)
        self.order = _morton_order(V)
        self.P = np.ascontiguousarray(V[self.order])
        self.start = np.append(np.arange(0, n, _BUCKET), n).astype(np.int64)
        self.bmin = np.minimum.reduceat(self.P, self.start[:-1], axis=0)
        self.bmax = np.maximum.reduceat(self.P, self.start[:-1], axis=0)
        self.maxd = np.full(len(self.start) - 1, np.inf)   # every bucket is visited first
        self.argd = np.zeros(len(self.start) - 1, dtype=np.int64)
        self.V, self.dist, self.nearest = V, dist, nearest
        self.parallel = get_num_threads() > 1 and n >= _PARALLEL_MIN   # one thread: forked workers

    def add(self, i: int, k: int) -> tuple[float, int]:
        """Point ``i`` as the ``k``-th sample; the covering radius and the farthest point."""
        visit = _visit_parallel if self.parallel else _visit_serial
        visit(self.P, self.order, self.dist, self.nearest, self.start, self.bmin, self.bmax,
              self.maxd, self.argd, i, k, self.V[i])
        best, j = _farthest_bucket(self.maxd, self.argd)
        return float(best), int(j)


#: Points per bucket of the Euclidean sampling (256: of 64-1,024, the fastest on normal and
#: torus clouds of a million points, 0.01 s behind 128 on a uniform one;
#: docs/design/point-clouds.md).
_BUCKET = 256
#: Points from which the Euclidean sampling visits its buckets in numba threads.
_PARALLEL_MIN = 50_000


def _morton_order(V: np.ndarray) -> np.ndarray:
    """The points in Z-order of their coordinates quantised to 1,024 levels per axis."""
    lo = V.min(axis=0)
    span = np.maximum(V.max(axis=0) - lo, np.finfo(float).tiny)
    q = np.minimum(((V - lo) / span * 1024).astype(np.uint64), np.uint64(1023))

    def spread(x):   # the 10 bits of x to every third bit
        for shift, mask in ((16, 0x030000FF), (8, 0x0300F00F), (4, 0x030C30C3), (2, 0x09249249)):
            x = (x | (x << np.uint64(shift))) & np.uint64(mask)
        return x

    code = spread(q[:, 0]) | (spread(q[:, 1]) << np.uint64(1)) | (spread(q[:, 2]) << np.uint64(2))
    return np.argsort(code, kind="stable")


@njit(cache=True)
def _visit(P, order, dist, nearest, start, bmin, bmax, maxd, argd, b, i, k, q):
    """Bucket ``b`` with point ``i`` (at ``q``) as the ``k``-th sample: its points' distances and
    cells, and its largest distance with the first point (by index) that has it."""
    e = 0.0   # squared distance from q to the bucket's box
    for a in range(3):
        g = max(bmin[b, a] - q[a], 0.0, q[a] - bmax[b, a])
        e += g * g
    if not np.sqrt(e) < maxd[b]:
        return   # no point of the bucket gets closer to the samples
    best, arg = -1.0, -1
    for s in range(start[b], start[b + 1]):
        p = order[s]
        dx, dy, dz = P[s, 0] - q[0], P[s, 1] - q[1], P[s, 2] - q[2]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)   # as scipy's cdist: the same values
        if d < dist[p]:
            dist[p] = d
            nearest[p] = k
        if p == i:
            dist[p] = 0.0
            nearest[p] = k
        if dist[p] > best or (dist[p] == best and p < arg):
            best, arg = dist[p], p
    maxd[b] = best
    argd[b] = arg


@njit(cache=True)
def _visit_serial(P, order, dist, nearest, start, bmin, bmax, maxd, argd, i, k, q):
    for b in range(len(start) - 1):
        _visit(P, order, dist, nearest, start, bmin, bmax, maxd, argd, b, i, k, q)


@njit(cache=True, parallel=True)
def _visit_parallel(P, order, dist, nearest, start, bmin, bmax, maxd, argd, i, k, q):
    for b in prange(len(start) - 1):
        _visit(P, order, dist, nearest, start, bmin, bmax, maxd, argd, b, i, k, q)


@njit(cache=True)
def _farthest_bucket(maxd, argd):
    best, arg = -1.0, -1
    for b in range(len(maxd)):
        if maxd[b] > best or (maxd[b] == best and argd[b] < arg):
            best, arg = maxd[b], argd[b]
    return best, arg
