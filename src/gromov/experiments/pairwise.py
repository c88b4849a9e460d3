"""Pairwise Gromov-Hausdorff distances over a set of shapes (recognition, Bronstein et al. 2010, §5).

Each shape's working mesh and dense metric are computed once (:class:`gromov.ShapeMetric`),
then every unordered pair is matched. Pairs run in worker processes that inherit the prepared
shapes by ``fork`` (no copying of the distance matrices); with ``jobs=1`` everything runs in
this process.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..gh import (RANK_RESIDUAL, RANK_TAU_SCALE, ShapeMetric, _match, _upgrade_options, check_rank_residual,
                  match_options_for, search_subsets)
from ..search import SearchOptions

__all__ = ["PairwiseGH", "available_cpus", "gh_matrix", "match_pairs", "prepare"]

logger = logging.getLogger(__name__)

_SHAPES: list[ShapeMetric] = []   # set before forking workers
_OPTIONS: dict = {}
_KEEP: frozenset = frozenset()
_MATRIX = False                   # gh_matrix: distances with orientation="ignore"
_RECORD = None                    # gh_matrix with a store: records each pair as it finishes


@dataclass(frozen=True, eq=False)
class PairwiseGH:
    """Symmetric ``(n, n)`` matrices of GH estimates (``distance``) and relative ones.

    ``trimmed``: what recognition ranks shapes by, the same correspondences' trimmed
    distortion (:attr:`gromov.MatchResult.ranking_distance`): of the log ratios of the
    distances (``rank_residual="log"``, dimensionless) or of their differences over the larger
    diameter (``"difference"``, relative like ``relative``); with the heat-kernel diffusion
    metric and ``rank_tau_scale``, measured at that times the diffusion time.
    """

    distance: np.ndarray
    relative: np.ndarray
    metric: str
    n_samples: int
    seconds_prepare: float
    seconds_match: float
    results: dict = field(default_factory=dict)
    """``{(i, j): MatchResult}`` for the pairs asked for with ``keep`` (``i < j``)."""
    trimmed: np.ndarray | None = None
    rank_tau_scale: float | None = None
    rank_residual: str = "difference"


def _pair(ij):
    i, j = ij
    x, y = _SHAPES[i], _SHAPES[j]
    if not _MATRIX:
        r = _match(x, y, x.metric, **_OPTIONS)
        return r.distance, r.relative_distance, r.relative_trimmed, r
    # the GH estimate: the lowest distortion found, mirror images included
    options = dict(_OPTIONS)
    orientation = options.pop("orientation", "prefer")
    r = _match(x, y, x.metric, orientation="ignore", as_prepared=True, **options)
    if _RECORD is not None:
        _RECORD(ij, r)
    full = None
    if (i, j) in _KEEP:
        full = r
        # mirrored: the same run, then more (NaN -- a point cloud, a non-orientable mesh --
        # has no orientation to prefer, and "prefer" would give the same map)
        if orientation == "prefer" and not r.orientation > 0.5 and np.isfinite(r.orientation):
            full = _match(x, y, x.metric, orientation="prefer", as_prepared=True, **options)
    return r.distance, r.relative_distance, r.ranking_distance, full


def available_cpus() -> int:
    """CPUs this process may run on (its affinity where the OS says it), at least 1: the
    default number of worker processes."""
    import os

    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)  # pragma: no cover - not on Linux

def _init_worker(parent: int) -> None:
    """Worker initializer: die with the parent (:func:`_die_with_parent`), one thread each
    (:func:`_one_thread_per_worker`)."""
    _die_with_parent(parent)
    _one_thread_per_worker()


#: Seconds between a worker's checks that its parent is alive (where the kernel cannot tell it).
PARENT_POLL_S = 1.0


def _die_with_parent(parent: int) -> None:
    """Make this worker process end when the process ``parent`` that started it ends.

    A pool's workers outlive a parent killed with SIGKILL (nothing runs in the parent to stop
    them): ``gromov pairwise --jobs 2`` left its two workers computing, 0.9 GB each. On Linux
    the kernel sends the worker SIGKILL when its parent exits (``prctl(PR_SET_PDEATHSIG)``);
    everywhere, a daemon thread checks every :data:`PARENT_POLL_S` seconds that the parent is
    still the worker's parent and ends the worker when it is not.
    """
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):   # pragma: no cover - no prctl: the thread below
            pass
    if os.getppid() != parent:   # the parent ended before the signal was asked for
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="gromov-parent-watch", daemon=True).start()


def _one_thread_per_worker():
    """Worker initializer: ``jobs`` processes already fill the cores.

    Numba's parallel kernels and the BLAS thread pool would otherwise each start one thread
    per core in every worker; spinning BLAS threads competing for the same cores slow every
    match several times over.
    """
    import numba
    from threadpoolctl import threadpool_limits

    numba.set_num_threads(1)
    threadpool_limits(limits=1)


def prepare(shapes, metric: str, *, n_samples: int = 100, seed: int = 0, resolution: int | None = 3000,
            metric_options: dict | None = None, progress: bool = False,
            subsets=tuple(search_subsets()), rank_tau_scale: float | None = None) -> list[ShapeMetric]:
    """Each shape's working mesh, dense metric, diameter, descriptors and samples, once.

    ``shapes`` are meshes, point clouds, paths or :class:`ShapeMetric` objects (whose metric must be
    ``metric``); returns the prepared ``ShapeMetric`` objects in the same order. ``subsets``:
    sizes of the vertex subsets the initial search runs on (:func:`gromov.gh.search_subsets`).
    ``rank_tau_scale``: also the heat distance recognition measures with
    (:meth:`ShapeMetric.ranking_surface <gromov.gh.ShapeMetric.ranking_surface>`).
    """
    from tqdm import tqdm

    out = []
    for s in shapes:   # working meshes first (cheap), so the memory can be told before the metrics
        if not isinstance(s, ShapeMetric):
            s = ShapeMetric(s, metric, resolution=resolution, metric_options=metric_options)
        elif s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        out.append(s)
    _warn_if_too_big(out)
    for s in tqdm(out, desc=f"{metric} metrics", disable=not progress, leave=False):
        s.distances, s.diameter, s.descriptors, s.samples(n_samples, seed)  # per shape, once
        for k in subsets:
            s.subset(k)
        if rank_tau_scale is not None:
            s.ranking_surface(rank_tau_scale)
    return out


def _available_memory() -> int | None:
    """Bytes of memory available to new allocations (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not on Linux
        pass
    return None


def _warn_if_too_big(prepared: list[ShapeMetric]) -> None:
    """Warn before computing metrics whose dense matrices (8 n^2 bytes per shape, all kept
    for the pairs) would not fit in the memory available."""
    need = sum(8 * s.mesh.n_vertices**2 for s in prepared if s.solver._pairwise is None)
    have = _available_memory()
    if have is not None and need > 0.8 * have:
        import warnings

        from ..errors import GromovWarning

        n = max(s.mesh.n_vertices for s in prepared)
        size = lambda b: f"{b / 1e9:.1f} GB" if b >= 1e9 else f"{b / 1e6:.1f} MB"  # noqa: E731
        warnings.warn(f"the {len(prepared)} shapes' distance matrices need about {size(need)} "
                      f"(up to {n} working vertices each) and {size(have)} are available: "
                      f"use a lower resolution or fewer shapes", GromovWarning, stacklevel=3)


def _subsets(match_options: dict) -> list[int]:
    return match_options.get("search", SearchOptions()).subsets


def _run(prepared, pairs, keep, jobs, progress, desc, options, matrix=False):
    """``(distance, relative, trimmed, MatchResult or None)`` per pair, in the order of ``pairs``."""
    global _SHAPES, _OPTIONS, _KEEP, _MATRIX
    from tqdm import tqdm

    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    out = []
    _SHAPES, _OPTIONS, _KEEP, _MATRIX = prepared, options, frozenset(keep), matrix
    try:
        with tqdm(total=len(pairs), desc=desc, disable=not progress, leave=False) as bar:
            if jobs > 1 and len(pairs) > 1 and "fork" in mp.get_all_start_methods():
                with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork"),
                                         initializer=_init_worker, initargs=(os.getpid(),)) as pool:
                    for r in pool.map(_pair, pairs, chunksize=max(1, len(pairs) // (8 * jobs))):
                        out.append(r)
                        bar.update(1)
            else:
                for ij in pairs:
                    out.append(_pair(ij))
                    bar.update(1)
    finally:
        _SHAPES, _OPTIONS, _KEEP, _MATRIX = [], {}, frozenset(), False
    return out


def match_pairs(shapes, pairs, metric: str = "diffusion", *, n_samples: int = 100, seed: int = 0,
                resolution: int | None = 3000, metric_options: dict | None = None, jobs: int = 1,
                progress: bool = False, **match_options) -> list:
    """:func:`gromov.match` on the given pairs ``(i, j)`` of ``shapes`` (X = ``shapes[i]``).

    Each shape is prepared once (as in :func:`gh_matrix`); pairs run in ``jobs`` forked
    worker processes. Returns the :class:`gromov.MatchResult` of each pair, in order. As in
    :func:`gromov.match`, prepared shapes are measured in the correspondence's metric
    (:meth:`ShapeMetric.for_correspondence <gromov.gh.ShapeMetric.for_correspondence>`), and
    shapes not prepared yet get the correspondence's metric options, or without
    ``metric_options`` those of the prepared ones (:func:`gromov.gh.match_options_for`).
    """
    match_options = _upgrade_options(match_options, "match_pairs")
    shapes = [s.for_correspondence() if isinstance(s, ShapeMetric) and s.metric == metric else s
              for s in shapes]
    pairs = [(int(i), int(j)) for i, j in pairs]
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    prepared = prepare(shapes, metric, n_samples=n_samples, seed=seed, resolution=resolution,
                       metric_options=match_options_for(shapes, metric, metric_options), progress=progress,
                       subsets=_subsets(match_options))
    n = len(prepared)
    bad = [ij for ij in pairs if not (0 <= ij[0] < n and 0 <= ij[1] < n)]
    if bad:
        raise ValueError(f"pairs must index the {n} shapes, got {bad[:3]}")
    runs = _run(prepared, pairs, set(pairs), jobs, progress, f"{metric} matches",
                dict(n_samples=n_samples, seed=seed, **match_options))
    return [full for *_, full in runs]


def gh_matrix(shapes, metric: str = "diffusion", *, n_samples: int = 100, resolution: int | None = 3000,
              metric_options: dict | None = None, seed: int = 0, jobs: int = 1, progress: bool = False,
              keep=(), known: dict | None = None, rank_tau_scale: float | None = RANK_TAU_SCALE,
              rank_residual: str = RANK_RESIDUAL, store=None, **match_options) -> PairwiseGH:
    """GH distances between all pairs of ``shapes``.

    Parameters
    ----------
    shapes : list of Mesh, PointCloud, (n, 3) arrays, paths or ShapeMetric
        Prepared ``ShapeMetric`` objects are used as they are (their metric must be ``metric``);
        point clouds are matched as :func:`gromov.match` matches them (images at points).
    metric, n_samples, resolution, metric_options, seed
        As in :func:`gromov.match`.
    jobs : int, default 1
        Worker processes for the pairs (fork start method; falls back to 1 where fork is
        not available).
    progress : bool, default False
        Show a progress bar (tqdm) on stderr.
    keep : iterable of (int, int), optional
        Pairs ``(i, j)`` with ``i < j`` whose full :class:`gromov.MatchResult` (the
        correspondence, not only the distance) is returned in ``results``: the result of
        ``match`` with the given ``orientation`` (default "prefer", the direct map of a
        symmetric body rather than its mirror image).
    known : dict, optional
        Pairs computed before with the same shapes, options and order (e.g. the shapes two
        sets share): ``{(i, j): (distance, relative, trimmed, result)}``, ``result`` the
        ``MatchResult`` (required for a pair in ``keep``, else may be None). They are not
        run again.
    rank_tau_scale : float or None, default RANK_TAU_SCALE (0.5)
        With the heat-kernel diffusion metric, ``trimmed`` measures each correspondence with
        the heat distance at this times the diffusion time (its
        :attr:`~gromov.MatchResult.ranking_distance`); None, or another metric: in the metric of the match. The GH
        estimates (``distance``, ``relative``) and the correspondences are the same either way.
    rank_residual : {"log", "difference"}, default RANK_RESIDUAL ("log")
        How ``trimmed`` summarises each correspondence's residuals
        (:func:`gromov.gh.ranking_value`): the log ratios of corresponding distances (a multiplicative
        distortion) or their differences over the larger diameter (the additive form).
    store : str, os.PathLike or gromov.store.ShapeStore, optional
        A shape store (:mod:`gromov.store`): each shape is read from it, or computed and
        added to it; each pair's result is recorded there as soon as it is found, and pairs
        recorded before (the same two entries in the same order, the same match options and
        gromov version) are not run again, so an interrupted run continues where it stopped
        and gives the same matrices. Pairs in ``keep`` are always run (their full
        ``MatchResult`` is not stored).
    **match_options
        Passed to :func:`gromov.match` (``norm``, ``solver``, ``init``, ``orientation``, ``search``...).

    Returns
    -------
    PairwiseGH
        The diagonal is zero; entry (i, j) is the estimate of ``match(shapes[i], shapes[j],
        orientation="ignore")`` for i < j, mirrored to (j, i) (GH is symmetric; the two-sided
        GMDS treats both directions). The distance is the lowest distortion found, a mirror
        image being as good a correspondence as any: ``orientation`` only decides which map
        ``results`` holds (where the map found reverses the orientation, ``match`` runs again
        with ``orientation="prefer"``, whose first steps are the same run). ``trimmed`` holds
        the trimmed distortion of the same correspondence (:func:`gromov.gmds.trimmed_rms`),
        measured as ``rank_tau_scale`` and ``rank_residual`` say.
    """
    shapes = list(shapes)
    if len(shapes) < 2:
        raise ValueError(f"need at least two shapes, got {len(shapes)}")
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    check_rank_residual(rank_residual)
    match_options = _upgrade_options(match_options, "gh_matrix")
    t0 = time.perf_counter()
    if store is not None:
        from ..store import as_store

        store = as_store(store)
        shapes = store.shapes(shapes, metric, resolution=resolution, metric_options=metric_options,
                              rank_tau_scale=rank_tau_scale, progress=progress)
    prepared = prepare(shapes, metric, n_samples=n_samples, seed=seed, resolution=resolution,
                       metric_options=metric_options, progress=progress,
                       subsets=_subsets(match_options), rank_tau_scale=rank_tau_scale)
    t1 = time.perf_counter()
    n = len(prepared)
    keep = frozenset((int(i), int(j)) for i, j in keep)
    bad = [ij for ij in keep if not 0 <= ij[0] < ij[1] < n]
    if bad:
        raise ValueError(f"keep needs pairs (i, j) with 0 <= i < j < {n}, got {sorted(bad)[:3]}")
    known = {(int(i), int(j)): v for (i, j), v in (known or {}).items()}
    bad = [ij for ij in known if not 0 <= ij[0] < ij[1] < n]
    if bad:
        raise ValueError(f"known needs pairs (i, j) with 0 <= i < j < {n}, got {sorted(bad)[:3]}")
    missing = [ij for ij in keep if ij in known and known[ij][3] is None]
    if missing:
        raise ValueError(f"known pairs in keep need their MatchResult, missing for {sorted(missing)[:3]}")
    options = dict(n_samples=n_samples, seed=seed, rank_tau_scale=rank_tau_scale,
                   rank_residual=rank_residual, **match_options)
    record = None
    if store is not None:
        known, record = _stored_pairs(store, prepared, known, keep, options)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if (i, j) not in known]
    dist = np.zeros((n, n))
    rel = np.zeros((n, n))
    trim = np.zeros((n, n))
    kept = {}
    global _RECORD
    _RECORD = record
    try:
        runs = _run(prepared, pairs, keep, jobs, progress, f"{metric} GH pairs", options,
                    matrix=True) if pairs else []
    finally:
        _RECORD = None
    for (i, j), (d, r, t, full) in zip(pairs + list(known), list(runs) + list(known.values())):
        if full is not None and (i, j) not in keep:
            full = None
        dist[i, j] = dist[j, i] = d
        rel[i, j] = rel[j, i] = r
        trim[i, j] = trim[j, i] = t
        if full is not None:
            kept[i, j] = full
    return PairwiseGH(dist, rel, metric, n_samples, t1 - t0, time.perf_counter() - t1, kept, trim,
                      rank_tau_scale, rank_residual)


def _stored_pairs(store, prepared, known: dict, keep: frozenset, options: dict):
    """``known`` with the pairs the store has recorded (not those in ``keep``: their full
    result is not stored), and the function that records each pair run now."""
    from ..store import match_options_key

    keys = [store.key_of(s) for s in prepared]
    rest = {k: v for k, v in options.items() if k not in ("n_samples", "seed", "orientation")}
    key_options = match_options_key(options["n_samples"], options["seed"], rest)
    n = len(prepared)
    todo = {(i, j): store.pair_key(keys[i], keys[j], key_options)
            for i in range(n) for j in range(i + 1, n) if (i, j) not in known}
    found = store.pair_values(todo.values())
    known = dict(known)
    for ij, k in todo.items():
        if k in found and ij not in keep:
            known[ij] = (*found[k], None)
            store.pairs_reused += 1
    logger.info("store %s: %d of %d pairs recorded before", store.root, len(known), n * (n - 1) // 2)

    def record(ij, result):   # in the worker that found it
        store.record_pair(todo[ij], keys[ij[0]], keys[ij[1]], key_options, result)

    return known, record
