"""Pairwise Gromov-Hausdorff distances over a set of shapes (recognition, Bronstein et al. 2010, §5).

Each shape's working mesh and dense metric are computed once (:class:`gromov.ShapeMetric`),
then every unordered pair is matched. Pairs run in worker processes that inherit the prepared
shapes by ``fork`` (no copying of the distance matrices); with ``jobs=1`` everything runs in
this process; with a Dask ``client``, the workers prepare the shapes, keep them and run the pairs
where their shapes are (:mod:`gromov._dask`).
"""

from __future__ import annotations

import itertools
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

from .._defaults import RANK_RESIDUAL, RANK_TAU_SCALE
from ..gh import _match, _upgrade_options, check_rank_residual, match_options_for
from ..search import SearchOptions, search_subsets
from ..shape_metric import ShapeMetric

__all__ = ["RANK_BY", "PairwiseGH", "available_cpus", "gh_matrix", "match_pairs", "prepare"]

logger = logging.getLogger(__name__)

_SHAPES: list[ShapeMetric] = []   # set before forking workers
_OPTIONS: dict = {}
_KEEP: frozenset = frozenset()
_MATRIX = False                   # gh_matrix: distances with orientation="ignore"
_RECORD = None                    # gh_matrix with a store: records each pair as it finishes
#: What recognition can rank pairs by (:meth:`PairwiseGH.ranked`).
RANK_BY = ("trimmed", "gh", "combined")


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
    skipped: int = 0
    """Pairs not matched (``gh_matrix(k=...)``: they could not be among the k nearest); their
    entries are NaN."""
    spectral: np.ndarray | None = None
    """Distances between the shapes' spectral signatures (:func:`gromov.spectrum.spectrum`,
    Shape-DNA of the working meshes); None with a Dask client."""
    signature: np.ndarray | None = None
    """Each pair's heat kernel signature distortion along its correspondence
    (:attr:`gromov.MatchResult.signature_distortion`); None without spectral signatures."""

    @property
    def combined(self) -> np.ndarray | None:
        r"""The combined ranking :math:`(S^w\, G^{1-w})^{1-v}\, H^v` of ``spectral``,
        ``trimmed`` and ``signature`` (:func:`gromov.spectrum.combined`, w =
        :data:`~gromov.spectrum.SPECTRUM_WEIGHT`, v = :data:`~gromov.spectrum.SIGNATURE_WEIGHT`);
        None without ``spectral``."""
        return _ranked_values("combined", self.spectral, self.relative, self.trimmed, self.signature)

    def ranked(self, rank_by: str = "trimmed") -> np.ndarray:
        """The matrix recognition ranks by: ``"trimmed"``, ``"gh"`` (``relative``) or
        ``"combined"``."""
        if rank_by not in RANK_BY:
            raise ValueError(f"rank_by must be one of {RANK_BY}, got {rank_by!r}")
        out = _ranked_values(rank_by, self.spectral, self.relative, self.trimmed, self.signature)
        if out is None:
            raise ValueError(f"rank_by={rank_by!r}: this matrix has no {rank_by} values (no spectral "
                             "signatures: not computed with a Dask client)")
        return out


def _pair(ij):
    i, j = ij
    return _pair_of(_SHAPES[i], _SHAPES[j], ij, _OPTIONS, matrix=_MATRIX, keep=ij in _KEEP, record=_RECORD)


def _pair_of(x: ShapeMetric, y: ShapeMetric, ij, options: dict, *, matrix: bool, keep: bool, record=None):
    """``(distance, relative, trimmed, signature distortion, MatchResult or None)`` of one pair;
    ``record(ij, result)`` is given the matrix's result as soon as it is found."""
    if not matrix:
        r = _match(x, y, x.metric, **options)
        return r.distance, r.relative_distance, r.relative_trimmed, r.signature_distortion, r
    # the GH estimate: the lowest distortion found, mirror images included
    options = dict(options)
    orientation = options.pop("orientation", "prefer")
    r = _match(x, y, x.metric, orientation="ignore", as_prepared=True, **options)
    if record is not None:
        record(ij, r)
    full = None
    if keep:
        full = r
        # the map "prefer" gives: a mirror image replaced by a direct map, a half turn by the
        # right map (NaN -- a point cloud, a non-orientable mesh -- has no orientation to
        # prefer, and "prefer" would give the same map)
        if orientation == "prefer" and np.isfinite(r.orientation):
            full = _match(x, y, x.metric, orientation="prefer", as_prepared=True, **options)
    return r.distance, r.relative_distance, r.ranking_distance, r.signature_distortion, full


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
            subsets=tuple(search_subsets()), rank_tau_scale: float | None = None,
            jobs: int = 1, spectral: bool = False) -> list[ShapeMetric]:
    """Each shape's working mesh, dense metric, diameter, descriptors and samples, once.

    ``shapes`` are meshes, point clouds, paths or :class:`ShapeMetric` objects (whose metric must be
    ``metric``); returns the prepared ``ShapeMetric`` objects in the same order. ``subsets``:
    sizes of the vertex subsets the initial search runs on (:func:`gromov.search.search_subsets`).
    ``rank_tau_scale``: also the heat distance recognition measures with
    (:meth:`ShapeMetric.ranking_surface <gromov.shape_metric.ShapeMetric.ranking_surface>`).
    ``jobs``: with the diffusion metric, shapes are prepared in that many forked worker
    processes (:data:`PARALLEL_PREPARE`), with the same values as in this one. ``spectral``:
    also each shape's spectral signatures (:func:`gromov.spectrum.spectrum` and
    :func:`gromov.spectrum.heat_signature`).
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
    work = (n_samples, seed, tuple(subsets), rank_tau_scale, bool(spectral))
    todo = [i for i, s in enumerate(out) if s.solver._pairwise is None]
    done = set()
    with tqdm(total=len(out), desc=f"{metric} metrics", disable=not progress, leave=False) as bar:
        if (metric in PARALLEL_PREPARE and jobs > 1 and len(todo) > 1
                and "fork" in mp.get_all_start_methods()):
            global _PREPARE
            _PREPARE = [out[i] for i in todo]
            try:
                with ProcessPoolExecutor(min(jobs, len(todo)), mp_context=mp.get_context("fork"),
                                         initializer=_init_worker, initargs=(os.getpid(),)) as pool:
                    for i, state in zip(todo, pool.map(_prepared_state, range(len(todo)),
                                                       itertools.repeat(work))):
                        _install(out[i], state)
                        done.add(i)
                        bar.update(1)
            finally:
                _PREPARE = []
        for i, s in enumerate(out):   # the others here; a worker's shapes have it all cached
            _prepare_one(s, *work)
            if i not in done:
                bar.update(1)
    return out


#: Metrics whose shapes :func:`prepare` computes in forked workers when given ``jobs > 1``:
#: the diffusion metric's eigensolver runs on one thread. (The geodesic metric's marches
#: already fill the cores in numba threads.)
PARALLEL_PREPARE = ("diffusion",)
_PREPARE: list[ShapeMetric] = []   # set before forking the preparing workers


def _prepare_one(s: ShapeMetric, n_samples, seed, subsets, rank_tau_scale, spectral=False) -> None:
    """What :func:`prepare` computes of one shape (each part once: cached on ``s``)."""
    s.distances, s.diameter, s.descriptors, s.samples(n_samples, seed)  # per shape, once
    for k in subsets:
        s.subset(k)
    if rank_tau_scale is not None:
        s.ranking_surface(rank_tau_scale)
    if spectral:
        from ..spectrum import heat_signature, spectrum

        spectrum(s)
        heat_signature(s)


#: The attributes of a :class:`ShapeMetric` that :func:`_prepare_one` fills, carried back from
#: a worker (the solver holds the distances and the eigenpairs).
_PREPARED = ("solver", "_diameter", "_finite", "_descriptors", "_samples", "_ranking", "_spectrum")


def _prepared_state(k: int, work) -> bytes:
    """In a worker: prepare the ``k``-th shape of ``_PREPARE`` and return what was computed,
    pickled with protocol 5 (read-only arrays come back read-only)."""
    import pickle

    given = _PREPARE[k]   # prepared afresh, so that nothing stays in the worker once sent
    s = ShapeMetric(given.input, given.metric, metric_options=given.metric_options, working=given.working)
    _prepare_one(s, *work)
    # the dense matrix is made again from the embedding where it is installed (a product
    # of 0.1 s against 72 MB to send at 3,000 vertices): the same numbers
    for solver in (s.solver, getattr(s.solver, "inner", None)):
        if solver is not None:
            solver._pairwise = None
    return pickle.dumps({name: getattr(s, name) for name in _PREPARED}, protocol=5)


def _install(s: ShapeMetric, state: bytes) -> None:
    import pickle

    for name, value in pickle.loads(state).items():
        setattr(s, name, value)
    s.distances   # noqa: B018 - from the embedding the worker computed


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
    """``(distance, relative, trimmed, signature distortion, MatchResult or None)`` per pair, in
    the order of ``pairs``."""
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
    (:meth:`ShapeMetric.for_correspondence <gromov.shape_metric.ShapeMetric.for_correspondence>`), and
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
                       subsets=_subsets(match_options), jobs=jobs)
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
              rank_residual: str = RANK_RESIDUAL, store=None, client=None, k: int | None = None,
              candidates: int | None = None, spectral: bool = False, rank_by: str = "trimmed",
              **match_options) -> PairwiseGH:
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
        not available). Ignored with ``client``.
    progress : bool, default False
        Show a progress bar (tqdm) on stderr.
    keep : iterable of (int, int), optional
        Pairs ``(i, j)`` with ``i < j`` whose full :class:`gromov.MatchResult` (the
        correspondence, not only the distance) is returned in ``results``: the result of
        ``match`` with the given ``orientation`` (default "prefer", the direct map of a
        symmetric body rather than its mirror image).
    known : dict, optional
        Pairs computed before with the same shapes, options and order (e.g. the shapes two
        sets share): ``{(i, j): (distance, relative, trimmed, result)}`` or ``(distance,
        relative, trimmed, signature, result)``, ``result`` the ``MatchResult`` (required for
        a pair in ``keep``, else may be None), ``signature`` its signature distortion (NaN when
        not given; with ``spectral``, a pair without it is run again). Others are not run
        again.
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
    client : distributed.Client, optional
        Run on the workers of a Dask cluster (``pip install 'gromov[dask]'``) instead of
        local processes, with the same results bit for bit. Each shape is prepared (or read
        from ``store``) on one worker and stays there; each pair runs on a worker that holds
        one of its shapes, or both (:mod:`gromov._dask`); a task runs on one thread. Shapes
        given as files are read by the workers, which must see them at the same absolute
        path, as they must see ``store``'s folder; pair results are recorded in the store by
        this process. The workers' shapes are released when the matrix is done.
    k : int, optional
        Only each shape's ``k`` nearest others (:func:`gromov.retrieval.knn_pairs`): the pairs
        are taken in order of a per-shape estimate, and a pair that cannot enter the k nearest
        of either of its shapes is not matched; its entries are NaN, and ``skipped`` counts
        them. The pruning is :func:`gromov.retrieval.knn_pairs`' default (``prune="profile"``:
        the profile gap, and the triangle estimates from the pairs matched, given in ``known``
        or recorded in ``store``; recall 1.0 on the validation sets: docs/guide/retrieval.md).
        Not with ``client``.
    candidates : int, optional
        A two-stage search: only the pairs in which one shape is among the other's
        ``candidates`` nearest by spectral distance (``spectral``) are matched, all of them; the
        others are NaN and counted in ``skipped``. With ``k`` too, each shape's k nearest are
        then searched by neighbour descent (Dong, Moses & Li, WWW 2011): in rounds, each pair
        ``(i, l)`` with ``l`` among the ``ceil(DESCENT * k)`` nearest found of one of the as
        many nearest found of ``i`` is matched, until a round adds none (``k`` then prunes
        nothing; the ranking is ``rank_by``). Not exact; with ``candidates = 2 k`` and the
        combined ranking every shape's 10 nearest were brute force's on the collections
        measured (docs/design/recognition.md, "Neighbour descent"). Not with ``client``.
    spectral : bool, default False
        Also the distances between the shapes' spectral signatures (``PairwiseGH.spectral``,
        :func:`gromov.spectrum.spectral_distances`) and each pair's heat kernel signature
        distortion (``PairwiseGH.signature``, :func:`gromov.spectrum.signature_distortion`):
        two sparse eigendecompositions per shape, which the ``combined`` ranking needs;
        always with ``candidates``. Not with ``client``.
    rank_by : {"trimmed", "gh", "combined"}, default "trimmed"
        The ranking the neighbour descent (``candidates`` and ``k``) follows
        (:meth:`PairwiseGH.ranked`).
    **match_options
        Passed to :func:`gromov.match` (``norm``, ``solver``, ``init``, ``orientation``, ``search``...).

    Returns
    -------
    PairwiseGH
        The diagonal is zero; entry (i, j) is the estimate of ``match(shapes[i], shapes[j],
        orientation="ignore")`` for i < j, mirrored to (j, i) (GH is symmetric; the two-sided
        GMDS treats both directions). The distance is the lowest distortion that search finds, a
        mirror image being as good a correspondence as any: ``orientation`` only decides which
        map ``results`` holds (``match`` runs again with ``orientation="prefer"``, whose first
        steps are the same run; its re-seating of misplaced samples can lower the distortion, so
        a kept result may be below its matrix entry, which does not depend on what is kept). ``trimmed`` holds
        the trimmed distortion of the same correspondence (:func:`gromov.gmds.trimmed_rms`),
        measured as ``rank_tau_scale`` and ``rank_residual`` say.
    """
    shapes = list(shapes)
    n = len(shapes)
    if n < 2:
        raise ValueError(f"need at least two shapes, got {n}")
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    check_rank_residual(rank_residual)
    if k is not None and client is not None:
        raise ValueError("k (nearest neighbours only) is not available with a Dask client")
    if rank_by not in RANK_BY:
        raise ValueError(f"rank_by must be one of {RANK_BY}, got {rank_by!r}")
    if candidates is not None:
        if isinstance(candidates, bool) or not isinstance(candidates, (int, np.integer)) or candidates < 1:
            raise ValueError(f"candidates must be an integer >= 1, got {candidates!r}")
        if k is not None and candidates < k:
            raise ValueError(f"candidates ({candidates}) must be at least k ({k})")
        spectral = True
    if spectral and client is not None:
        raise ValueError("spectral signatures (candidates, the combined ranking) are not available with a "
                         "Dask client")
    match_options = _upgrade_options(match_options, "gh_matrix")
    keep = frozenset((int(i), int(j)) for i, j in keep)
    bad = [ij for ij in keep if not 0 <= ij[0] < ij[1] < n]
    if bad:
        raise ValueError(f"keep needs pairs (i, j) with 0 <= i < j < {n}, got {sorted(bad)[:3]}")
    known = {(int(i), int(j)): _five(v) for (i, j), v in (known or {}).items()}
    bad = [ij for ij in known if not 0 <= ij[0] < ij[1] < n]
    if bad:
        raise ValueError(f"known needs pairs (i, j) with 0 <= i < j < {n}, got {sorted(bad)[:3]}")
    if spectral:   # the combined ranking needs each pair's signature distortion
        known = {ij: v for ij, v in known.items() if np.isfinite(v[3])}
    missing = [ij for ij in keep if ij in known and known[ij][4] is None]
    if missing:
        raise ValueError(f"known pairs in keep need their MatchResult, missing for {sorted(missing)[:3]}")
    options = dict(n_samples=n_samples, seed=seed, rank_tau_scale=rank_tau_scale,
                   rank_residual=rank_residual, signature=bool(spectral), **match_options)
    per_shape = {"n_samples": n_samples, "seed": seed, "resolution": resolution, "metric_options": metric_options,
                 "subsets": _subsets(match_options), "rank_tau_scale": rank_tau_scale}
    fill = 0.0 if k is None and candidates is None else np.nan   # NaN where a pair was not matched
    dist = np.full((n, n), fill)
    rel = np.full((n, n), fill)
    trim = np.full((n, n), fill)
    sig = np.full((n, n), fill if spectral else np.nan)
    for a in (dist, rel, trim, sig):
        np.fill_diagonal(a, 0.0)
    kept = {}
    skipped = 0

    def put(ij, value):   # one pair's (distance, relative, trimmed, signature, MatchResult or None)
        (i, j), (d, r, t, h, full) = ij, value
        dist[i, j] = dist[j, i] = d
        rel[i, j] = rel[j, i] = r
        trim[i, j] = trim[j, i] = t
        sig[i, j] = sig[j, i] = h
        if full is not None and (i, j) in keep:
            kept[i, j] = full

    t0 = time.perf_counter()
    if store is not None:
        from ..store import as_store

        store = as_store(store)
    held = None
    S = None
    try:
        if client is None:
            if store is not None:
                shapes = store.shapes(shapes, metric, resolution=resolution, metric_options=metric_options,
                                      rank_tau_scale=rank_tau_scale, progress=progress)
            prepared = prepare(shapes, metric, progress=progress, jobs=jobs, spectral=spectral, **per_shape)
            keys = None if store is None else [store.key_of(s) for s in prepared]
            if spectral:
                from ..spectrum import spectral_distances

                S = spectral_distances(prepared)
        else:
            held, keys = _dask_prepare(client, shapes, metric, store, per_shape, progress)
        t1 = time.perf_counter()
        done = np.zeros((n, n), dtype=bool)   # the pairs known, given or recorded
        for ij, value in known.items():
            put(ij, value)
            done[ij] = True
        record = None
        if store is not None:
            record = _stored_pairs(store, keys, done, keep, options, put)
        pairs = np.argwhere(np.triu(~done, 1))   # (i, j), i < j, in row order
        desc = f"{metric} GH pairs"
        if len(pairs) and client is None:
            pairs = [(int(i), int(j)) for i, j in pairs]
            global _RECORD
            _RECORD = record
            try:
                if candidates is not None:   # the first stage's candidates, all matched
                    first = _candidate_pairs(S, candidates) | keep
                    todo = [ij for ij in pairs if ij in first]
                    runs = _run(prepared, todo, keep, jobs, progress, f"{desc} (candidates {candidates})",
                                options, matrix=True)
                    skipped = len(pairs) - len(todo)
                    pairs = todo
                    if k is not None:   # then the neighbours' neighbours, until none is new
                        for ij, value in zip(pairs, runs):
                            put(ij, value)
                            done[ij] = done[ij[::-1]] = True
                        searched = np.eye(n, dtype=bool)   # the first stage's pairs, known or run
                        for i, j in first:
                            searched[i, j] = searched[j, i] = True
                        skipped -= _descent_runs(prepared, k, searched, done, lambda: _ranked_values(
                            rank_by, S, rel, trim, sig), keep, jobs, progress, desc, options, put)
                        pairs, runs = [], []   # every pair put already
                elif k is None:
                    runs = _run(prepared, pairs, keep, jobs, progress, desc, options, matrix=True)
                else:   # only the pairs that can be among some shape's k nearest
                    got, skipped = _knn_runs(prepared, k, pairs, done, (dist, rel, trim, sig), keep, jobs,
                                             progress, desc, options, match_options)
                    pairs = [ij for ij in got if not done[ij]]
                    runs = [got[ij] for ij in pairs]
            finally:
                _RECORD = None
            for ij, value in zip(pairs, runs):
                put(ij, value)
        elif len(pairs):
            _dask_pairs(client, held, pairs, keep, options, record, progress, desc, put)
    finally:
        if held is not None:
            client.cancel(held)   # the workers drop the shapes
    return PairwiseGH(dist, rel, metric, n_samples, t1 - t0, time.perf_counter() - t1, kept, trim,
                      rank_tau_scale, rank_residual, skipped, S, sig if spectral else None)


def _five(value) -> tuple:
    """A known pair's ``(distance, relative, trimmed, signature, result)`` from 4 values (no
    signature distortion: NaN) or 5."""
    value = tuple(value)
    if len(value) == 4:
        return (*value[:3], float("nan"), value[3])
    if len(value) != 5:
        raise ValueError(f"a known pair needs 4 or 5 values (distance, relative, trimmed, [signature,] "
                         f"result), got {len(value)}")
    return value


def _candidate_pairs(S: np.ndarray, c: int) -> set:
    """The unordered pairs ``(i, j)``, ``i < j``, in which one shape is among the other's ``c``
    nearest by ``S`` (ties by index)."""
    n = len(S)
    out = set()
    for i in range(n):
        others = np.r_[0:i, i + 1:n]
        for j in others[np.argsort(S[i, others], kind="stable")[:c]].tolist():
            out.add((min(i, j), max(i, j)))
    return out


#: The neighbour descent of a two-stage search (``gh_matrix(candidates=..., k=...)``) looks at
#: this many times k nearest of each shape and of each of them (docs/design/recognition.md,
#: "Neighbour descent").
DESCENT = 1.5


def _ranked_values(rank_by: str, S, rel, trim, sig=None) -> np.ndarray | None:
    """The matrix ranked by ``rank_by`` (:meth:`PairwiseGH.ranked`; the neighbour descent's),
    NaN where a pair is not matched; None for ``"combined"`` without ``S`` or ``trim``."""
    if rank_by == "combined":
        if S is None or trim is None:
            return None
        from ..spectrum import combined

        return combined(S, trim, signature=sig)
    return rel if rank_by == "gh" else trim


def _descent_pairs(R: np.ndarray, matched: np.ndarray, m: int) -> list[tuple[int, int]]:
    """The unmatched pairs ``(i, l)``, ``i < l``, with ``l`` among the ``m`` nearest (by ``R``,
    over the matched pairs) of one of the ``m`` nearest of ``i``: a round of the neighbour
    descent of Dong, Moses & Li ("Efficient k-nearest neighbor graph construction for generic
    similarity measures", WWW 2011): a neighbour of a neighbour is likely a neighbour."""
    n = len(R)
    off = matched & ~np.eye(n, dtype=bool)
    near = np.argsort(np.where(off, R, np.inf), axis=1, kind="stable")[:, :m]
    ok = np.take_along_axis(off, near, axis=1)   # a row with fewer than m matched pairs
    new = np.zeros((n, n), dtype=bool)
    for i in range(n):
        hop = near[i][ok[i]]
        reach = near[hop][ok[hop]]
        new[i, reach] = True
    new |= new.T
    new &= ~matched
    np.fill_diagonal(new, False)
    return [(int(i), int(j)) for i, j in np.argwhere(np.triu(new, 1))]


def _descent_runs(prepared, k, searched, done, ranked, keep, jobs, progress, desc, options, put) -> int:
    """The neighbour descent's rounds (:func:`_descent_pairs` with ``m = ceil(DESCENT k)``) from
    the first stage's pairs ``searched``, until a round finds none: each round's pairs marked
    ``searched``, those not ``done`` (known or recorded before) matched, ``put`` and marked
    ``done`` before the next round is chosen. The rounds follow the searched pairs only, so a
    run resumed from a store that holds some of its pairs (or more) searches the same pairs.
    Returns how many pairs the rounds matched."""
    m = min(int(np.ceil(DESCENT * k)), len(done) - 1)
    matched, rounds = 0, 0
    while True:
        todo = _descent_pairs(ranked(), searched, m)
        if not todo:
            return matched
        rounds += 1
        for ij in todo:
            searched[ij] = searched[ij[::-1]] = True
        todo = [ij for ij in todo if not done[ij]]
        got = _run(prepared, todo, keep, jobs, progress, f"{desc} (neighbour descent, round {rounds})",
                   options, matrix=True) if todo else []
        for ij, value in zip(todo, got):
            put(ij, value)
            done[ij] = done[ij[::-1]] = True
        matched += len(todo)


def _knn_runs(prepared, k, pairs, done, matrices, keep, jobs, progress, desc, options, match_options):
    """``({(i, j): worker result}, skipped)``: :func:`gromov.retrieval.knn_pairs` over the
    prepared shapes, the pairs ``done`` already given as known (their values in ``matrices``:
    distance, relative, trimmed, signature), the others run by :func:`_run` ``2 * jobs`` at a
    time."""
    from tqdm import tqdm

    from ..retrieval import knn_pairs

    known = {(int(i), int(j)): (*(m[i, j] for m in matrices), None) for i, j in zip(*np.nonzero(np.triu(done, 1)))}
    # the bar counts the pairs matched against all that could be; the skipped ones close it
    with tqdm(total=len(pairs), desc=f"{desc} (k = {k})", disable=not progress, leave=False) as bar:
        def run(batch):
            out = _run(prepared, batch, keep, jobs, False, desc, options, matrix=True)
            bar.update(len(batch))
            return out

        got = knn_pairs(prepared, k, run, n_samples=options["n_samples"], seed=options["seed"],
                        rank_tau_scale=options["rank_tau_scale"], rank_residual=options["rank_residual"],
                        norm=match_options.get("norm", "l2"), known=known, force=keep, batch=2 * jobs)
        bar.set_postfix(skipped=int(got.skipped))
        bar.update(len(pairs) - bar.n)
    return got.results, int(got.skipped)


#: Pairs looked up in a store at a time.
STORE_CHUNK = 10_000


def _stored_pairs(store, keys: list[str], done: np.ndarray, keep: frozenset, options: dict, put):
    """``put`` the pairs the store has recorded (not those in ``keep``: their full result is
    not stored) and mark them in ``done``; returns the function that records each pair run
    now. ``keys``: the shapes' entry keys; ``done``: ``(n, n)`` bool, the pairs known already."""
    from ..store import match_options_key

    rest = {k: v for k, v in options.items() if k not in ("n_samples", "seed", "orientation")}
    key_options = match_options_key(options["n_samples"], options["seed"], rest)
    need_signature = bool(options.get("signature"))
    n = len(keys)

    def pair_key(i, j):
        return store.pair_key(keys[i], keys[j], key_options)

    todo = ((i, j) for i in range(n) for j in range(i + 1, n) if not done[i, j])
    while chunk := list(itertools.islice(todo, STORE_CHUNK)):   # in chunks: no key kept per pair
        chunk_keys = {ij: pair_key(*ij) for ij in chunk}
        found = store.pair_values(chunk_keys.values())
        for ij, k in chunk_keys.items():
            # (a pair recorded without its signature distortion is run again where it is needed)
            if k in found and ij not in keep and not (need_signature and np.isnan(found[k][3])):
                put(ij, (*found[k], None))
                done[ij] = True
                store.pairs_reused += 1
    logger.info("store %s: %d of %d pairs recorded before", store.root, store.pairs_reused, n * (n - 1) // 2)

    def record(ij, result):   # in the worker that found it (with Dask, in this process)
        store.record_pair(pair_key(*ij), keys[ij[0]], keys[ij[1]], key_options, result)

    return record


# ----------------------------------------------------------------------------- Dask
def _dask_module():
    try:
        from .. import _dask
    except ImportError as exc:
        raise ImportError(str(exc)) from None   # one line: what to install
    return _dask


def _blas_threads() -> dict:
    """``{library prefix: threads}`` of this process's BLAS libraries."""
    from threadpoolctl import threadpool_info

    return {d["prefix"]: d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"}


def _dask_shape(source, label: str, metric: str, store, per_shape: dict, blas: dict):
    """On a worker: ``(ShapeMetric, info)`` of one shape, prepared as :func:`prepare` does
    (read from or added to the store ``(folder, load)`` if given), with ``blas`` threads
    (:func:`_blas_threads` of the calling process), as that process would compute it.
    ``info``: its working vertices and, with a store, its entry key, whether it was read back
    and the store's warnings."""
    from threadpoolctl import threadpool_limits

    from .. import _dask

    _dask.one_thread()
    with threadpool_limits(limits=blas or None, user_api=None if blas else "blas"):
        return _dask_shape_here(source, label, metric, store, per_shape)


def _dask_shape_here(source, label: str, metric: str, store, per_shape: dict):
    per_shape = dict(per_shape)
    n_samples, rank_tau_scale = per_shape["n_samples"], per_shape["rank_tau_scale"]
    info = {"key": None, "reused": False, "problems": []}
    if store is not None:
        from ..store import ShapeStore

        st = ShapeStore(store[0], load=store[1])
        log = logging.getLogger("gromov.store")   # its warnings: logged by the caller, not here too
        quiet, propagate = logging.NullHandler(), log.propagate
        log.addHandler(quiet)
        log.propagate = False
        try:
            source = st.shape(source, metric, resolution=per_shape["resolution"],
                              metric_options=per_shape["metric_options"], rank_tau_scale=rank_tau_scale)
            info.update(key=st.key_of(source), reused=st.reused > 0, problems=list(st.problems))
        finally:
            log.removeHandler(quiet)
            log.propagate = propagate
            st.close()
    if not isinstance(source, ShapeMetric):
        source = ShapeMetric(source, metric, resolution=per_shape["resolution"],
                             metric_options=per_shape["metric_options"])
    info["n_vertices"] = n = source.mesh.n_vertices
    if n_samples > n:   # a user error, raised by the caller (a worker would log it as a failure)
        info["error"] = f"{label}: {n_samples} samples are more than the {n} vertices of its working set"
        return source, info
    (s,) = prepare([source], metric, **per_shape)
    return s, info


def _dask_prepare(client, shapes: list, metric: str, store, per_shape: dict, progress: bool):
    """Each shape prepared on its home worker: ``(futures of (ShapeMetric, info), entry keys or
    None)``; the store's counters and warnings are updated here."""
    import operator
    import uuid

    from tqdm import tqdm

    _dask = _dask_module()
    _dask.prepare_workers(client)
    addresses = list(_dask.worker_threads(client))
    n = len(shapes)
    homes = _dask.spread(n, len(addresses))
    token = uuid.uuid4().hex[:8]
    sources, labels = [], []
    for i, s in enumerate(shapes):
        if isinstance(s, (str, os.PathLike)):   # read by the worker
            sources.append(os.path.abspath(os.fspath(s)))
            labels.append(os.fspath(s))
        else:
            sources.append(s)
            labels.append(f"shape {i}")
    # shapes this store returned already: their keys are known, the workers need not look
    given = [None if store is None or not isinstance(s, ShapeMetric) else store.key_of(s) for s in shapes]
    held, infos = [], []
    try:
        for w, addr in enumerate(addresses):   # objects: sent once, to their home
            idx = [i for i in range(n) if homes[i] == w and not isinstance(sources[i], str)]
            if idx:
                for i, f in zip(idx, client.scatter([sources[i] for i in idx], workers=[addr], hash=False)):
                    sources[i] = f
        spec = None if store is None else (str(store.root.resolve()), getattr(store, "_load", None))
        blas = _blas_threads()   # as this process would compute the metrics
        for i in range(n):
            held.append(client.submit(_dask_shape, sources[i], labels[i], metric,
                                      spec if given[i] is None else None, per_shape, blas,
                                      key=f"gromov-shape-{i}-{token}", workers=[addresses[homes[i]]],
                                      allow_other_workers=True, pure=False))
            infos.append(client.submit(operator.itemgetter(1), held[-1], key=f"gromov-shape-info-{i}-{token}",
                                       pure=False))
        del sources
        index = {f.key: i for i, f in enumerate(infos)}
        out = [None] * n
        with tqdm(total=n, desc=f"{metric} metrics", disable=not progress, leave=False) as bar:
            for f in _dask.distributed.as_completed(infos):
                out[index[f.key]] = f.result()
                bar.update(1)
    except BaseException:
        client.cancel(held + infos)
        raise
    client.cancel(infos)
    bad = [info["error"] for info in out if "error" in info]
    if bad:
        client.cancel(held)
        raise ValueError(bad[0])
    if store is None:
        return held, None
    log = logging.getLogger("gromov.store")
    for info, key in zip(out, given):
        if key is not None:
            info["key"] = key
            continue
        store.reused += info["reused"]
        store.computed += not info["reused"]
        for message in info["problems"]:
            store.problems.append(message)
            log.warning("%s", message)
    return held, [info["key"] for info in out]


def _dask_pair(x, y, ij, options: dict, keep: bool, record: bool):
    """On a worker: :func:`_pair_of` of two held shapes, and with ``record`` the result to
    record in the store (without the arrays the store does not keep)."""
    import dataclasses

    from .. import _dask

    _dask.one_thread()
    found = []
    d, rel, t, h, full = _pair_of(x[0], y[0], ij, options, matrix=True, keep=keep,
                                  record=(lambda _, r: found.append(r)) if record else None)
    light = None
    if found:
        light = dataclasses.replace(found[0], pair_distortion=np.zeros((0, 0)), history=np.zeros(0))
    return d, rel, t, h, full, light


def _dask_pairs(client, held: list, pairs: list, keep: frozenset, options: dict, record, progress: bool,
                desc: str, put) -> None:
    """:func:`_run` on the Dask workers, each pair where its shapes are (:func:`gromov._dask.plan`):
    ``put(ij, (distance, relative, trimmed, signature, MatchResult or None))`` as each finishes."""
    import uuid

    from tqdm import tqdm

    _dask = _dask_module()
    threads = _dask.worker_threads(client)
    who = client.who_has(held)
    addresses = list(threads)
    at = {a: w for w, a in enumerate(addresses)}
    homes = [next((at[a] for a in who.get(f.key, ()) if a in at), i % len(addresses))
             for i, f in enumerate(held)]
    token = uuid.uuid4().hex[:8]

    def submit(ij, addr):
        i, j = ij
        return client.submit(_dask_pair, held[i], held[j], ij, options, ij in keep, record is not None,
                             key=f"gromov-pair-{i}-{j}-{token}", workers=[addr], allow_other_workers=True,
                             pure=False)

    with tqdm(total=len(pairs), desc=desc, disable=not progress, leave=False) as bar:
        def done(ij, fut):
            d, rel, t, h, full, light = fut.result()
            if record is not None:
                record(ij, light)
            put(ij, (d, rel, t, h, full))
            bar.update(1)

        _dask.run_pinned(client, _dask.plan(pairs, homes, len(addresses)), addresses, submit, done)
