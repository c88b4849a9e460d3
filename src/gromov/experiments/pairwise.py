"""Pairwise Gromov-Hausdorff distances over a set of shapes (recognition, Bronstein et al. 2010, §5).

Each shape's working mesh and dense metric are computed once (:class:`gromov.ShapeMetric`),
then every unordered pair is matched. Pairs run in worker processes that inherit the prepared
shapes by ``fork`` (no copying of the distance matrices); with ``jobs=1`` everything runs in
this process.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..gh import ShapeMetric, match

__all__ = ["PairwiseGH", "gh_matrix"]

logger = logging.getLogger(__name__)

_SHAPES: list[ShapeMetric] = []   # set before forking workers
_OPTIONS: dict = {}


@dataclass(frozen=True, eq=False)
class PairwiseGH:
    """Symmetric ``(n, n)`` matrices of GH estimates (``distance``) and relative ones."""

    distance: np.ndarray
    relative: np.ndarray
    metric: str
    n_samples: int
    seconds_prepare: float
    seconds_match: float


def _pair(ij):
    i, j = ij
    r = match(_SHAPES[i], _SHAPES[j], _SHAPES[i].metric, **_OPTIONS)
    return i, j, r.distance, r.relative_distance


def gh_matrix(shapes, metric: str = "diffusion", *, n_samples: int = 100, resolution: int | None = 3000,
              metric_options: dict | None = None, seed: int = 0, jobs: int = 1, progress: bool = False,
              **match_options) -> PairwiseGH:
    """GH distances between all pairs of ``shapes``.

    Parameters
    ----------
    shapes : list of Mesh, paths or ShapeMetric
        Prepared ``ShapeMetric`` objects are used as they are (their metric must be ``metric``).
    metric, n_samples, resolution, metric_options, seed
        As in :func:`gromov.match`.
    jobs : int, default 1
        Worker processes for the pairs (fork start method; falls back to 1 where fork is
        not available).
    progress : bool, default False
        Show a progress bar (tqdm) on stderr.
    **match_options
        Passed to :func:`gromov.match` (``norm``, ``solver``, ``init``...).

    Returns
    -------
    PairwiseGH
        The diagonal is zero; entry (i, j) is the estimate of ``match(shapes[i], shapes[j])``
        for i < j, mirrored to (j, i) (GH is symmetric; the two-sided GMDS treats both
        directions).
    """
    global _SHAPES, _OPTIONS
    from tqdm import tqdm

    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    shapes = list(shapes)
    if len(shapes) < 2:
        raise ValueError(f"need at least two shapes, got {len(shapes)}")
    t0 = time.perf_counter()
    prepared = []
    for s in tqdm(shapes, desc=f"{metric} metrics", disable=not progress, leave=False):
        if not isinstance(s, ShapeMetric):
            s = ShapeMetric(s, metric, resolution=resolution, metric_options=metric_options)
        elif s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        s.distances, s.diameter, s.descriptors, s.samples(n_samples, seed)  # per shape, once
        prepared.append(s)
    t1 = time.perf_counter()
    n = len(prepared)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    dist = np.zeros((n, n))
    rel = np.zeros((n, n))
    _SHAPES, _OPTIONS = prepared, dict(n_samples=n_samples, seed=seed, **match_options)
    try:
        bar = tqdm(total=len(pairs), desc=f"{metric} GH pairs", disable=not progress, leave=False)
        if jobs > 1 and "fork" in mp.get_all_start_methods():
            with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as pool:
                results = pool.map(_pair, pairs, chunksize=max(1, len(pairs) // (8 * jobs)))
                for i, j, d, r in results:
                    dist[i, j] = dist[j, i] = d
                    rel[i, j] = rel[j, i] = r
                    bar.update(1)
        else:
            for ij in pairs:
                i, j, d, r = _pair(ij)
                dist[i, j] = dist[j, i] = d
                rel[i, j] = rel[j, i] = r
                bar.update(1)
        bar.close()
    finally:
        _SHAPES, _OPTIONS = [], {}
    return PairwiseGH(dist, rel, metric, n_samples, t1 - t0, time.perf_counter() - t1)
