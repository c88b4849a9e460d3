"""Farthest point sampling in any metric (Bronstein et al. 2010, footnote 6).

Greedy: start from one vertex, repeatedly add the vertex farthest from the samples so
far. After ``k`` samples the covering radius ``r_k = max_x min_i d(x, p_i)`` is within a
factor two of the best possible k-point covering (Gonzalez, TCS 38, 1985), and the samples
are ``r_k``-separated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .metrics import MetricSolver

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

    indices = [int(first)]
    dist = np.array(row(first), dtype=float)
    dist[first] = 0.0
    nearest = np.zeros(n, dtype=np.int64)
    radii = [float(dist.max())]
    while len(indices) < limit and not (radius is not None and radii[-1] <= radius):
        nxt = int(np.argmax(dist))
        if dist[nxt] <= 0.0:  # every vertex is a sample already (duplicates)
            break
        r = np.asarray(row(nxt), dtype=float)
        closer = r < dist
        nearest[closer] = len(indices)
        dist = np.where(closer, r, dist)
        dist[nxt] = 0.0
        nearest[nxt] = len(indices)
        indices.append(nxt)
        radii.append(float(dist.max()))
    return Samples(np.asarray(indices, dtype=np.int64), radii[-1], np.asarray(radii), dist, nearest)
