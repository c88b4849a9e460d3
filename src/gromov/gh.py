r"""The Gromov-Hausdorff distance between two shapes: :func:`match`.

:math:`\hat d_{GH}(X, Y) = \tfrac12 \min_C \mathrm{dis}(C)` over two-sided correspondences
between farthest-point samples, minimised by symmetric GMDS (:mod:`gromov.gmds`) from a
global initial guess (Bronstein et al., IJCV 2010, §2 and §4). ``solver="gw"`` instead
takes the Gromov-Wasserstein coupling of the two sample distance matrices (POT) and reads a
correspondence off it, so both are judged by the same distortion. The prepared shape is
:class:`~gromov.shape_metric.ShapeMetric` and the outcome
:class:`~gromov.match_result.MatchResult` (both importable from here too).
"""

from __future__ import annotations

import inspect
import logging
import numbers
import os
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ._arrays import one_blas_thread
from .errors import GromovWarning, MetricError
from .gmds import SurfacePoints, SymmetricGMDS, log_ratio_residuals, norm_value, parse_norm, trimmed_rms
from .match_result import MatchResult
from .mesh import as_shape
from .metrics.diffusion import correspondence_options
# the initial search (its names stay importable from here)
from .search import (DEFAULT_COARSE_STAGES, DEFAULT_N_EXTEND, DEFAULT_N_STARTS,  # noqa: F401
                     DEFAULT_SEARCH_VERTICES, EXTEND_KEEP, EXTEND_ROUNDS, INVOLUTION_REPAIRS, INVOLUTION_TOL,
                     SIGNATURE_STARTS, SIGNATURE_WEIGHT, SYMMETRY_TOL, SearchOptions, _at_vertices,
                     _anchor_rows, _candidates, _on_subset, _orient, _Search, _self_reflection, _Starts,
                     _trimmed_descent, anchored_images, greedy_init, initial_pairs, pair_orientation,
                     pairs_orientation, search_subsets, signature_mismatch)
from .shape_metric import ShapeMetric

__all__ = ["ShapeMetric", "MatchResult", "match", "SearchOptions"]

logger = logging.getLogger(__name__)

from ._defaults import DEFAULT_RESOLUTION  # noqa: E402
#: ``match(..., orientation="prefer")`` keeps an orientation-preserving correspondence when its
#: distortion is at most this much (relative) above the best one found.
ORIENTATION_TOL = 0.1
#: A map counts as clearly direct when its orientation agreement is above 1/2 + this; "prefer"
#: takes a clearly direct alternative before one that is direct only just. A map direct on one
#: part of the shapes and mirrored on the rest (a *partial* flip: one leg sent to the other
#: side) has an agreement near 1/2 (held-out TOSCA, diffusion: 0.54-0.58; the right direct maps
#: 0.69-0.93) -- but so do some noisy right maps (geodesic: down to 0.54), hence only a preference.
DIRECT_MARGIN = 0.15
#: A direct map is also weighed against the other clearly direct starts of the search whose
#: distortion is at most this much (relative) above its own: a body's half turn about its long
#: axis (left to right and front to back) keeps the orientation and nearly the distances
#: (:mod:`gromov.curvature`) ...
TURN_TOL = 0.1
#: ... and replaced by the one whose images keep the smoothed mean curvature best, when that
#: one's mismatch is lower by at least this fraction (docs/design/initial-search.md, "Half turns").
TURN_MARGIN = 0.1
#: ... and a map obtained by composing the mirrored one with a reflection of either shape
#: (:meth:`ShapeMetric.symmetry`) when within this much; chosen on the held-out classes.
FLIP_TOL = 0.25
#: A direct map's samples whose images landed on the wrong part of the target are moved where
#: the other samples place them (:mod:`gromov.reseat`), then GMDS again, at most this many
#: times while the distortion falls (0: never; docs/design/initial-search.md, "Samples re-seated").
RESEAT_ROUNDS = 3
#: Recognition (:func:`gromov.experiments.gh_matrix`) ranks a pair of shapes by the trimmed
#: distortion of the correspondence found with the heat-kernel diffusion metric at time
#: ``tau``, *measured* with the heat distance at ``RANK_TAU_SCALE * tau`` (a finer scale) on
#: the same eigenpairs (:meth:`HeatDiffusionSolver.at_tau
#: <gromov.metrics.diffusion.HeatDiffusionSolver.at_tau>`); see
#: :func:`gromov.experiments.gh_matrix`'s ``rank_tau_scale``. Chosen on the validation sets: the margin of the diffusion ranking rises
#: in six readings of seven, e.g. synthetic welds 0.988 -> 1.427 (``.venv/bin/python
#: benchmarks/studies/bench_rank_residual.py``, "difference @1" against "@0.5"; see
#: docs/design/recognition.md).
from ._defaults import RANK_TAU_SCALE  # noqa: E402, F401 (documented here)
#: How recognition summarises the residuals of a correspondence (see
#: :func:`gromov.experiments.gh_matrix`'s ``rank_residual``): ``"log"``, the trimmed RMS of the log ratios of corresponding distances
#: (:func:`gromov.gmds.log_ratio_residuals`, a multiplicative distortion), or
#: ``"difference"``, that of their differences over the larger diameter (the additive form).
#: Chosen on the validation sets: the diffusion margin is larger in seven readings of eight and
#: equal in the eighth (``.venv/bin/python benchmarks/studies/bench_rank_residual.py``; see
#: docs/design/recognition.md).
from ._defaults import RANK_RESIDUAL  # noqa: E402, F401 (documented here)
from ._defaults import RANK_RESIDUALS  # noqa: E402
#: The floor of :func:`gromov.gmds.log_ratio_residuals` in recognition, a fraction of the larger
#: diameter: keeps the ratio finite where two points coincide (0.01-0.1 changed no validation
#: margin by more than 3%).
RANK_LOG_FLOOR = 0.01


# ----------------------------------------------------------------------------- match
@dataclass
class _Fit:
    """A two-sided correspondence during :func:`match`: the images of P on Y and of Q on X
    (surface points, or vertex ids where a point cloud keeps the maps discrete), with the
    GMDS run that gave it."""

    img_p: SurfacePoints | np.ndarray
    img_q: SurfacePoints | np.ndarray
    n_iter: int = 0
    converged: bool = True
    history: list = field(default_factory=list)
    orientation: float = float("nan")


def match(X, Y, metric: str | None = None, *, n_samples: int = 100, norm="l2", solver: str = "gmds",
          init: str = "greedy", seed: int = 0, resolution: int | None = DEFAULT_RESOLUTION,
          metric_options: dict | None = None, radius: float | None = None, orientation: str = "prefer",
          search: SearchOptions | None = None, dense: bool | str = False, partial: bool = False,
          **deprecated) -> MatchResult:
    r"""Gromov-Hausdorff distance and correspondence between two shapes.

    Minimises the distortion of a two-sided correspondence C between farthest point samples,
    :math:`\hat d_{GH}(X, Y) = \tfrac12 \min_C \mathrm{dis}_p(C)`, by symmetric GMDS from a
    multi-start initial search (Bronstein et al., IJCV 2010, §2 and §4): the metrics, the
    samples, the search (:mod:`gromov.search`), GMDS, the distortion, the images.

    Parameters
    ----------
    X : Mesh, PointCloud, path, (vertices, faces), (n, 3) array, trimesh.Trimesh or ShapeMetric
        The first shape. A :class:`ShapeMetric` reuses its working mesh and, when its options
        are the correspondence's, its metric (see ``metric_options``). With a point cloud on
        either side the map is the search's discrete one: images at points.
    Y : same as X
        The second shape.
    metric : {"diffusion", "geodesic", "euclidean"}, optional
        Default "diffusion"; with ``partial=True`` "geodesic" (or a prepared shape's metric).
    n_samples : int, default 100
        Farthest point samples per shape.
    norm : {"l2", "linf"} or "p:VALUE", default "l2"
        Norm of the distortion that is minimised and reported as ``distance``.
    solver : {"gmds", "gw"}, default "gmds"
        Symmetric GMDS, or the Gromov-Wasserstein coupling (POT) read off as a map.
    init : {"greedy", "gw"}, default "greedy"
        GMDS's start: the initial search, or the argmax of the Gromov-Wasserstein coupling.
    seed : int, default 0
        Seeds the farthest point sampling; the rest is deterministic.
    resolution : int or None, default 3000
        Working mesh size for shapes not prepared already (None: the input as it is).
    metric_options : dict, optional
        Passed through :func:`~gromov.metrics.diffusion.correspondence_options`, as is every
        ShapeMetric's own (so a prepared shape and its file give the same match). Default:
        those of a prepared shape, else the correspondence's (normalised heat units).
    radius : float, optional
        Partial matching: only pairs of samples closer than ``radius`` count.
    orientation : {"prefer", "ignore"}, default "prefer"
        "prefer": a mirrored map is replaced by an orientation-preserving one within
        ``ORIENTATION_TOL`` (10%) of its distortion, or by its composition with a reflection
        within ``FLIP_TOL`` (25%), clearly direct maps first (:mod:`gromov.orientation`),
        failing those by the clearly direct one of them within ``FLIP_TOL``; a
        direct map by another within ``TURN_TOL`` (10%) that keeps the smoothed mean
        curvature better by ``TURN_MARGIN``, or by a mirrored one composed with a reflection
        (a body turned half about its long axis against the right map: :mod:`gromov.curvature`);
        then the direct map's samples that another place fits far better, with every other
        pair fixed, moved there and GMDS run again while the distortion falls
        (:mod:`gromov.reseat`, ``RESEAT_ROUNDS``). "ignore": the lowest distortion the search
        and GMDS find, mirror images included, without those steps (the re-seating can lower
        the distortion: a "prefer" map may be the less distorted).
    search : SearchOptions, optional
        The initial search's options and GMDS's stopping rule (default: ``SearchOptions()``).
    dense : bool, "input", "zoomout" or "placed", default False
        Also map every input vertex (:mod:`gromov.dense`). True or "input": placed from the
        samples, refined by ZoomOut on the input meshes, then made locally isometric
        (:data:`gromov.dense.DENSE_RELAX`); "zoomout": refined on the working meshes instead;
        "placed": not refined.
    partial : bool, default False
        X is a part of Y (given, not detected): only X's samples are embedded into Y, the
        part measured in Y's metric, samples near X's boundary down-weighted; the result also
        holds the region of Y the part covers (``y_covered``, ``covered_fraction``). See
        :func:`gromov.partial.match_partial` (which takes ``metric``, ``n_samples``, ``seed``,
        ``resolution``, ``metric_options``, ``search`` and ``dense``: True or "input", the part's
        dense map refined by ZoomOut with a rectangular functional map, or "placed"; the other
        options are for two whole shapes).

    Returns
    -------
    MatchResult

    Examples
    --------
    >>> r = match("cat0.off.gz", "cat1.off.gz")                 # doctest: +SKIP
    >>> r.relative_distance, r.x_to_y_vertex[:3]                # doctest: +SKIP
    """
    options = _upgrade_options({**deprecated, "search": search}, "match")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if partial:
        from .partial import PARTIAL_METRIC, match_partial

        if metric is None:
            prepared = [s.metric for s in (X, Y) if isinstance(s, ShapeMetric)]
            metric = prepared[0] if prepared else PARTIAL_METRIC
        _check_choices(solver, init, orientation, dense, None, "difference")
        if solver != "gmds" or init != "greedy" or radius is not None or parse_norm(norm) != 2.0:
            raise ValueError("partial=True takes the L2 norm, GMDS from the initial search and no radius")
        return match_partial(X, Y, metric, n_samples=n_samples, seed=seed, resolution=resolution,
                             metric_options=metric_options, search=options.get("search", SearchOptions()),
                             dense=dense)
    if metric is None:
        metric = "diffusion"
    return _match(X, Y, metric, n_samples=n_samples, norm=norm, solver=solver, init=init, seed=seed,
                  resolution=resolution, metric_options=metric_options, radius=radius,
                  orientation=orientation, dense=dense, interval=True, **options)


#: Keywords of :func:`match` that moved into :class:`SearchOptions`.
_MOVED_TO_SEARCH = ("n_starts", "n_extend", "coarse_stages", "search_vertices", "extend_keep",
                    "signature_weight", "max_iter", "tol")
#: Keywords of :func:`match` that belong to recognition's ranking
#: (:func:`gromov.experiments.gh_matrix`).
_MOVED_TO_RANKING = ("rank_tau_scale", "rank_residual")


def _upgrade_options(options: dict, caller: str = "match", stacklevel: int = 3) -> dict:
    """``options`` of :func:`match` with the keywords that moved, for one release: those of
    the search into ``search`` (a :class:`SearchOptions`), each with a ``DeprecationWarning``
    that names the replacement; ``search=None`` is dropped. ``TypeError`` for any other
    unknown keyword."""
    options = dict(options)
    if options.get("search") is None:
        options.pop("search", None)
    elif not isinstance(options["search"], SearchOptions):
        raise TypeError(f"search must be a gromov.SearchOptions, got {type(options['search']).__name__}")
    moved = {k: options.pop(k) for k in _MOVED_TO_SEARCH if k in options}
    if moved:
        names = ", ".join(f"{k}=..." for k in moved)
        warnings.warn(f"{caller}({names}) is deprecated: use {caller}(search=gromov.SearchOptions({names}))",
                      DeprecationWarning, stacklevel=stacklevel)
        options["search"] = replace(options.get("search", SearchOptions()), **moved)
    ranked = [k for k in _MOVED_TO_RANKING if k in options]
    if ranked:
        names = ", ".join(f"{k}=..." for k in ranked)
        warnings.warn(f"{caller}({names}) is deprecated: recognition's ranking is set on "
                      f"gromov.experiments.gh_matrix({names})", DeprecationWarning, stacklevel=stacklevel)
    known = set(inspect.signature(_match).parameters) - {"X", "Y", "metric", "as_prepared"}
    unknown = sorted(set(options) - known)
    if unknown:
        raise TypeError(f"{caller}() got an unexpected keyword argument {unknown[0]!r}")
    return options


def _match(X, Y, metric: str = "diffusion", *, n_samples: int = 100, norm="l2", solver: str = "gmds",
           init: str = "greedy", seed: int = 0, resolution: int | None = DEFAULT_RESOLUTION,
           metric_options: dict | None = None, radius: float | None = None, orientation: str = "prefer",
           search: SearchOptions = SearchOptions(), dense: bool | str = False,
           rank_tau_scale: float | None = None, rank_residual: str = "difference",
           as_prepared: bool = False, interval: bool = False, signature: bool = False) -> MatchResult:
    """:func:`match`, and what recognition ranks by (:func:`gromov.experiments.gh_matrix`):
    ``ranking_distance`` measured with the heat distance at ``rank_tau_scale`` times the
    diffusion time, of ``rank_residual`` (:func:`ranking_value`). ``as_prepared``: use prepared
    shapes in their own metric (recognition's units) instead of the correspondence's.
    ``interval``: compute :attr:`MatchResult.gh_interval`. ``signature``: compute
    :attr:`MatchResult.signature_distortion`."""
    t0 = time.perf_counter()
    p = parse_norm(norm)
    _check_choices(solver, init, orientation, dense, rank_tau_scale, rank_residual)
    # the metrics, and farthest point samples of each shape
    sx, sy = _prepared_pair(X, Y, metric, resolution, metric_options, as_prepared)
    discrete = _check_pair(sx, sy, n_samples, radius)
    P, Q, gm, fit = two_sided_fit(sx, sy, n_samples, seed, p, solver, init, search, radius, orientation, discrete)
    # the distortion of the final correspondence, and its images on the input meshes
    dx, dy = discrete_blocks(sx.distances, sy.distances, P, Q, fit.img_p, fit.img_q) if discrete else \
        gm.blocks(fit.img_p, fit.img_q)
    residual, r = pair_residuals(dx, dy)
    dis, diam, d_trim = norm_value(r, p), max(sx.diameter, sy.diameter), trimmed_rms(r)
    ranking = _ranking(sx, sy, P, Q, fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual)
    locate = _images_at_points if discrete else lambda s, img: s.locate(img)
    xy_face, xy_bary, xy_vertex = locate(sy, fit.img_p)
    yx_face, yx_bary, yx_vertex = locate(sx, fit.img_q)
    extra = _dense_fields(sx, sy, P, Q, fit, dense) if dense else {}
    if interval:
        extra["gh_interval"] = _gh_interval(sx, sy, P, Q, fit, discrete)
    if signature:
        extra["signature_distortion"] = _signature_distortion(sx, sy, P, Q, fit, discrete)
    norm_name = "l2" if p == 2 else ("linf" if np.isinf(p) else f"p:{p:g}")
    return MatchResult(
        distance=0.5 * dis, relative_distance=0.5 * dis / diam, distortion=dis,
        distortion_l2=norm_value(r, 2.0), distortion_linf=norm_value(r, np.inf), norm=norm_name,
        metric=metric, solver=solver, n_samples=int(n_samples),
        x_samples=sx.working.to_input_ids(P), x_to_y_face=xy_face, x_to_y_bary=xy_bary, x_to_y_vertex=xy_vertex,
        y_samples=sy.working.to_input_ids(Q), y_to_x_face=yx_face, y_to_x_bary=yx_bary, y_to_x_vertex=yx_vertex,
        n_iter=int(fit.n_iter), converged=bool(fit.converged), seconds=time.perf_counter() - t0,
        orientation=fit.orientation, distortion_trimmed=d_trim, relative_trimmed=0.5 * d_trim / diam,
        ranking_distance=ranking, pair_distortion=residual, history=np.asarray(fit.history), **extra)


def two_sided_fit(sx: ShapeMetric, sy: ShapeMetric, n_samples: int, seed: int, p: float = 2.0,
                  solver: str = "gmds", init: str = "greedy", search: SearchOptions = SearchOptions(),
                  radius: float | None = None, orientation: str = "prefer", discrete: bool = False):
    """``(P, Q, gm, fit)``: the samples of two prepared shapes, the GMDS solver (None for a
    discrete map) and the two-sided correspondence :func:`match` reports: the initial search,
    then GMDS, mirror images replaced by direct maps where nearly as good, half turns undone,
    misplaced samples re-seated."""
    P, Q = sx.samples(n_samples, seed), sy.samples(n_samples, seed)
    gm = None if discrete else SymmetricGMDS(sx.surface, sy.surface, P, Q, p=p, max_iter=search.max_iter,
                                             tol=search.tol, radius=radius)
    prefer = _prefers_direct(sx, sy, orientation, solver, init, discrete)
    # (BLAS on one thread: small products, and one summation order whatever the machine's threads)
    with one_blas_thread():
        starts, img_p0, img_q0 = _initial_images(sx, sy, P, Q, gm, solver, init, search, discrete)
        fit = _refine(sx, sy, P, Q, gm, img_p0, img_q0, solver, discrete)
        if prefer:
            candidates = _direct_candidates(sx, sy, P, Q, gm, starts, more=not fit.orientation > 0.5)
            if not fit.orientation > 0.5:
                fit = _prefer_direct(sx, sy, P, Q, gm, candidates, fit, n_samples, seed)
            if fit.orientation > 0.5:
                fit = _prefer_curvature(sx, sy, P, Q, gm, candidates, fit, n_samples, seed)
            if fit.orientation > 0.5 and radius is None:   # (a partial match weighs pairs by radius)
                fit = _reseat(sx, sy, P, Q, gm, fit)
    return P, Q, gm, fit


def pair_residuals(dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(D_X(C) - D_Y(C)`` with a zero diagonal, its off-diagonal entries``)``: the diagonal is
    not a pair (an interpolated self-distance need not be 0)."""
    residual = dx - dy
    np.fill_diagonal(residual, 0.0)
    return residual, residual[~np.eye(len(dx), dtype=bool)]


def _gh_interval(sx, sy, P, Q, fit: _Fit, discrete: bool) -> tuple[float, float]:
    """:func:`gromov.bounds.sample_gh_interval` of the samples, each image snapped to the
    nearest sample of the other shape (in that shape's metric)."""
    from .bounds import sample_gh_interval

    DX, DY = sx.distances, sy.distances

    def vertices(s, img):
        return np.asarray(img, dtype=np.int64) if discrete else img.vertex(s.mesh.faces)

    p_to_q = np.argmin(DY[np.ix_(vertices(sy, fit.img_p), Q)], axis=1)
    q_to_p = np.argmin(DX[np.ix_(vertices(sx, fit.img_q), P)], axis=1)
    lower, upper = sample_gh_interval(DX[np.ix_(P, P)], DY[np.ix_(Q, Q)], p_to_q, q_to_p)
    return float(lower), float(upper)


def _signature_distortion(sx, sy, P, Q, fit: _Fit, discrete: bool) -> float:
    """:func:`gromov.spectrum.signature_distortion` of the final correspondence: each shape's
    heat kernel signature at its samples and, interpolated on the working faces, at the other
    shape's samples' images."""
    from .spectrum import heat_signature, signature_distortion

    hx, hy = heat_signature(sx), heat_signature(sy)

    def at(s, h, img):
        return h[np.asarray(img, dtype=np.int64)] if discrete else img.positions(h, s.mesh.faces)

    return signature_distortion(np.vstack([hx[P], at(sx, hx, fit.img_q)]),
                                np.vstack([at(sy, hy, fit.img_p), hy[Q]]))


def _check_choices(solver, init, orientation, dense, rank_tau_scale, rank_residual) -> None:
    """``ValueError`` for an option of :func:`match` that names no method."""
    if solver not in ("gmds", "gw"):
        raise ValueError(f"solver must be 'gmds' or 'gw', got {solver!r}")
    if init not in ("greedy", "gw"):
        raise ValueError(f"init must be 'greedy' or 'gw', got {init!r}")
    if orientation not in ("ignore", "prefer"):
        raise ValueError(f"orientation must be 'ignore' or 'prefer', got {orientation!r}")
    if dense and dense not in (True, "input", "zoomout", "placed"):
        raise ValueError(f"dense must be True, False, 'input', 'zoomout' or 'placed', got {dense!r}")
    check_rank_tau_scale(rank_tau_scale)
    check_rank_residual(rank_residual)


def _prepared_pair(X, Y, metric, resolution, metric_options, as_prepared) -> tuple[ShapeMetric, ShapeMetric]:
    """The two shapes with their metrics (:func:`match_options_for`), and a warning where the
    two measure distances differently."""
    metric_options = match_options_for((X, Y), metric, metric_options)
    sx = _as_shape(X, metric, resolution, metric_options, "X", as_prepared)
    sy = _as_shape(Y, metric, resolution, metric_options, "Y", as_prepared)
    if sx.has_faces != sy.has_faces and metric != "euclidean":   # (straight lines: the same either way)
        warnings.warn(f"{'Y' if sx.has_faces else 'X'} is a point cloud and the other a mesh: their "
                      f"{metric} distances are computed differently (a mesh's own construction, a "
                      "cloud's from its nearest neighbours), so the distortion compares two metrics; "
                      "for comparable distances match the mesh's vertices as a point cloud too",
                      GromovWarning, stacklevel=4)
    elif _metric_signature(sx) != _metric_signature(sy):
        warnings.warn(f"X and Y measure distances differently ({_metric_signature(sx)} vs "
                      f"{_metric_signature(sy)}): their distortion compares two different metrics; "
                      f"prepare both ShapeMetrics with the same metric_options", GromovWarning, stacklevel=4)
    return sx, sy


def _check_pair(sx: ShapeMetric, sy: ShapeMetric, n_samples: int, radius) -> bool:
    """Whether the maps stay discrete (a point cloud on either side: images at points), after
    the checks that the pair can be matched with these options."""
    for name, s in (("X", sx), ("Y", sy)):
        if n_samples > s.mesh.n_vertices:
            raise ValueError(f"n_samples={n_samples} exceeds the {s.mesh.n_vertices} working vertices of {name}")
    if n_samples < 3:
        raise ValueError(f"n_samples must be at least 3, got {n_samples}")
    discrete = not (sx.has_faces and sy.has_faces)
    if discrete and radius is not None:
        raise ValueError("radius (partial matching) weighs the GMDS refinement on the surfaces, which "
                         "needs triangle meshes; X or Y is a point cloud")
    for name, s in (("X", sx), ("Y", sy)):
        if discrete and not s.finite:   # (on meshes SurfaceDistance says so)
            raise MetricError(f"{name}: matching needs finite distances, got inf or NaN (a shape in "
                              f"pieces: a point cloud whose {s.metric} neighbour graph falls apart -- "
                              "more neighbours (--neighbors K, metric_options={'k': ...}), or --metric "
                              "diffusion, which measures across the pieces; a mesh in several "
                              "components: keep its largest, Mesh.largest_component())")
    return discrete


def _prefers_direct(sx, sy, orientation, solver, init, discrete) -> bool:
    """Whether ``orientation="prefer"`` applies: GMDS from the initial search on two orientable
    meshes (a warning where a working mesh is not orientable)."""
    prefer = orientation == "prefer" and solver == "gmds" and init == "greedy" and not discrete
    if prefer and not (sx.normals[1] and sy.normals[1]):
        warnings.warn("orientation='prefer' needs orientable working meshes (a Moebius-like "
                      "piece cannot be given an outward side); ignored", GromovWarning, stacklevel=5)
        return False
    return prefer


def _initial_images(sx, sy, P, Q, gm, solver, init, search, discrete):
    """``(search or None, images of P on Y, images of Q on X)``: GMDS's start, vertex ids.

    The initial search (:class:`gromov.search._Starts`): each direction on its own, then the
    other direction anchored on it; the consistent pair of lower two-sided L2 distortion is
    kept. With ``init="gw"`` or ``solver="gw"``: the argmax of the Gromov-Wasserstein coupling.
    """
    DX, DY = sx.distances, sy.distances
    if solver == "gw" or init == "gw":
        T = gw_coupling(DX[np.ix_(P, P)], DY[np.ix_(Q, Q)])
        return None, Q[np.argmax(T, axis=1)], P[np.argmax(T, axis=0)]

    def score(a, b):   # the two-sided L2 distortion of a start (vertex images)
        if discrete:
            ex, ey = discrete_blocks(DX, DY, P, Q, a, b)
            return norm_value((ex - ey)[~np.eye(len(ex), dtype=bool)], 2.0)
        return gm.distortion(*_at_vertices(sx, sy, a, b), 2.0)

    starts = _Starts(sx, sy, P, Q, search)
    pairs = starts.plain(all_starts=False)
    from ._arrays import argmin_stable

    img_p0, img_q0 = pairs[argmin_stable([score(a, b) for a, b in pairs])]
    return starts, img_p0, img_q0


def _refine(sx, sy, P, Q, gm, img_p0, img_q0, solver, discrete) -> _Fit:
    """GMDS from the start (``solver="gmds"``), and the orientation agreement of the result; a
    discrete map (point clouds) as it is."""
    if discrete:
        return _Fit(img_p0, img_q0)
    img_p, img_q = _at_vertices(sx, sy, img_p0, img_q0)
    n_iter, converged = 0, True
    if solver == "gmds":
        img_p, img_q, n_iter, converged = gm.solve(img_p, img_q)
    return _Fit(img_p, img_q, n_iter, converged, list(gm.history),
                pair_orientation(sx, sy, P, Q, img_p, img_q))


def _prefer_direct(sx, sy, P, Q, gm, candidates, fit: _Fit, n_samples: int, seed: int) -> _Fit:
    """``orientation="prefer"`` for a mirrored (or scrambled) ``fit``: GMDS from the best
    orientation-preserving start too, among the extended starts and more preserving ones
    (within ``ORIENTATION_TOL`` of its distortion), then from its compositions with a
    reflection of X or Y (:meth:`ShapeMetric.symmetry`, within ``FLIP_TOL``). A clearly direct
    map (agreement above 1/2 + ``DIRECT_MARGIN``) is taken at once; one direct only on part of
    the shapes (agreement near 1/2) only if no clearly direct one turns up. Failing both, the
    clearly direct map of lowest distortion among those runs within ``FLIP_TOL`` (the
    preserving start's beyond ``ORIENTATION_TOL``); ``fit`` if none."""
    from ._arrays import argmin_stable

    at, agreement, scores = candidates
    keep = agreement > 0.5
    d_first = gm.distortion(fit.img_p, fit.img_q, 2.0)
    clear = []   # (distortion, fit): the clearly direct maps within FLIP_TOL, in run order

    def attempt(start, tol_k):
        out = _gmds_from(sx, sy, P, Q, gm, start)
        d_alt = gm.distortion(out.img_p, out.img_q, 2.0)
        if out.orientation > 0.5 + DIRECT_MARGIN and d_alt <= (1.0 + FLIP_TOL) * d_first:
            clear.append((d_alt, out))
        if out.orientation > 0.5 and d_alt <= (1.0 + tol_k) * d_first:
            return out
        return None

    found = partial = None
    if keep.any():  # the best orientation-preserving start
        alt = attempt(at[int(np.flatnonzero(keep)[argmin_stable(scores[keep])])], ORIENTATION_TOL)
        if alt is not None and alt.orientation > 0.5 + DIRECT_MARGIN:
            found = alt
        else:
            partial = alt
    if found is None:  # the mirrored map composed with a reflection of X, then of Y
        for start in _reflected(sx, sy, P, Q, fit.img_p, fit.img_q, n_samples, seed):
            alt = attempt(start, FLIP_TOL)
            if alt is not None and alt.orientation > 0.5 + DIRECT_MARGIN:
                found = alt
                break
            if partial is None:
                partial = alt
    if found is None and partial is None and clear:
        # every alternative was beyond its own tolerance: the clearly direct one of lowest
        # distortion within FLIP_TOL (a body against its own copy at another density: the
        # mirrored and the direct maps differ by less than the two meshes' own discrepancy)
        found = min(clear, key=lambda c: c[0])[1]   # the first run of them on a tie
    return found or partial or fit


def _reseat(sx, sy, P, Q, gm, fit: _Fit) -> _Fit:
    """``orientation="prefer"`` for a direct ``fit``: the images that another place fits far
    better, with every other pair fixed, moved there (:func:`gromov.reseat.reseat_start`), then
    GMDS; the result replaces the fit while it stays direct and lowers the two-sided L2
    distortion, at most ``RESEAT_ROUNDS`` times."""
    from .reseat import reseat_start

    d_fit = gm.distortion(fit.img_p, fit.img_q, 2.0)
    for _ in range(RESEAT_ROUNDS):
        start = reseat_start(gm.X, gm.Y, P, Q, fit.img_p, fit.img_q, *gm.blocks(fit.img_p, fit.img_q))
        if start is None:
            break
        alt = _gmds_from(sx, sy, P, Q, gm, start)
        d_alt = gm.distortion(alt.img_p, alt.img_q, 2.0)
        if not (alt.orientation > 0.5 and d_alt < d_fit):
            break
        fit, d_fit = alt, d_alt
    return fit


def _gmds_from(sx, sy, P, Q, gm, start) -> _Fit:
    """GMDS from ``start`` (surface points of both sides): the :class:`_Fit` with its run's
    history and its orientation agreement."""
    h0 = len(gm.history)
    img_p, img_q, n_iter, converged = gm.solve(*start)
    return _Fit(img_p, img_q, n_iter, converged, gm.history[h0:], pair_orientation(sx, sy, P, Q, img_p, img_q))


def _reflected(sx, sy, P, Q, img_p, img_q, n_samples: int, seed: int):
    """The two-sided correspondence ``(img_p, img_q)`` composed with a reflection of X, then
    with one of Y (:meth:`ShapeMetric.symmetry`, each computed once per shape, when first
    needed): a generator of starts as surface points, none for a shape without a reflection."""
    DX, DY = sx.distances, sy.distances
    fp, gq = img_p.vertex(sy.mesh.faces), img_q.vertex(sx.mesh.faces)
    for s_ in (sx, sy):
        sym = s_.symmetry(n_samples, seed)
        if sym is None:
            continue
        if s_ is sx:  # f o S_X on P (f carried to S_X(P) by its distances), S_X o g on Q
            start = (anchored_images(DY, fp, DX[np.ix_(sym[P], P)]), sym[gq])
        else:         # S_Y o f on P, g o S_Y on Q
            start = (sym[fp], anchored_images(DX, gq, DY[np.ix_(sym[Q], Q)]))
        yield _at_vertices(sx, sy, *start)


def _direct_candidates(sx, sy, P, Q, gm, starts, more: bool):
    """``(starts as surface points, their orientation agreements, their two-sided L2
    distortions)`` that ``orientation="prefer"`` weighs: every extended start of the search and,
    with ``more`` (a mirrored first map), more orientation-preserving ones (half as many per
    stage as it extends)."""
    pairs = starts.plain(all_starts=True)
    if more:
        pairs += starts.preserving(-(-starts.fwd.per_stage // 2))
    at = [_at_vertices(sx, sy, a, b) for a, b in pairs]
    return at, pairs_orientation(sx, sy, P, Q, at), np.array([gm.distortion(a, b, 2.0) for a, b in at])


def curvature_mismatch(sx, sy, P, Q, img_p, img_q) -> float:
    """How far a two-sided correspondence is from keeping the smoothed mean curvature
    (:attr:`ShapeMetric.curvature`): the median of ``|H_X(p) - H_Y(f(p))|`` over X's samples,
    averaged with the same from Y's. Images inside faces are read at their nearest corner."""
    hx, hy = sx.curvature, sy.curvature
    fp, gq = img_p.vertex(sy.mesh.faces), img_q.vertex(sx.mesh.faces)
    return 0.5 * float(np.median(np.abs(hx[P] - hy[fp])) + np.median(np.abs(hy[Q] - hx[gq])))


def _prefer_curvature(sx, sy, P, Q, gm, candidates, fit: _Fit, n_samples: int, seed: int) -> _Fit:
    """``orientation="prefer"`` for a direct ``fit``: a half turn against the right map.

    Among the clearly direct starts (agreement above 1/2 + ``DIRECT_MARGIN``) whose distortion
    is within ``TURN_TOL`` of the fit's, the one whose images keep the smoothed mean curvature
    best (:func:`curvature_mismatch`); if it beats the fit's mismatch by ``TURN_MARGIN``, GMDS
    from it, and its result replaces the fit when it is still clearly direct, within
    ``TURN_TOL`` of the distortion and ``TURN_MARGIN`` of the mismatch (:mod:`gromov.curvature`).
    Failing that, the same among the clearly mirrored starts, each composed with a reflection
    of X, then of Y (:func:`_reflected`) before GMDS: a reflection keeps the curvature, so a
    mirrored start that keeps it well is the mirror image of a direct map that does.
    """
    from ._arrays import argmin_stable

    at, agreement, scores = candidates
    d_fit = gm.distortion(fit.img_p, fit.img_q, 2.0)
    c_fit = curvature_mismatch(sx, sy, P, Q, fit.img_p, fit.img_q)
    within = scores <= (1.0 + TURN_TOL) * d_fit

    def attempt(start):
        alt = _gmds_from(sx, sy, P, Q, gm, start)
        if (alt.orientation > 0.5 + DIRECT_MARGIN
                and gm.distortion(alt.img_p, alt.img_q, 2.0) <= (1.0 + TURN_TOL) * d_fit
                and curvature_mismatch(sx, sy, P, Q, alt.img_p, alt.img_q) < (1.0 - TURN_MARGIN) * c_fit):
            return alt
        return None

    for mirrored in (False, True):
        # the clearly direct starts; then the clearly mirrored ones, through a reflection
        # (which keeps the curvature: a start's mismatch is its composition's)
        side = agreement < 0.5 - DIRECT_MARGIN if mirrored else agreement > 0.5 + DIRECT_MARGIN
        near = np.flatnonzero(side & within)
        if not len(near):
            continue
        mismatch = np.array([curvature_mismatch(sx, sy, P, Q, *at[i]) for i in near])
        if not mismatch.min() < (1.0 - TURN_MARGIN) * c_fit:
            continue
        best = at[int(near[argmin_stable(mismatch)])]
        for start in (_reflected(sx, sy, P, Q, *best, n_samples, seed) if mirrored else (best,)):
            alt = attempt(start)
            if alt is not None:
                return alt
    return fit


def _ranking(sx, sy, P, Q, fit: _Fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual) -> float:
    """``MatchResult.ranking_distance``: :func:`ranking_value` of the final correspondence, in
    the heat distance at ``rank_tau_scale`` times the diffusion time where that applies (the
    heat kernel), else in the match's metric (``dx``, ``dy``)."""
    mx = my = None
    if rank_tau_scale is not None:
        mx, my = sx.ranking_surface(rank_tau_scale), sy.ranking_surface(rank_tau_scale)
    if mx is None or my is None:
        return ranking_value(dx, dy, diam, rank_residual)
    if discrete:
        ex, ey = mx[0].block(np.r_[P, fit.img_q]), my[0].block(np.r_[fit.img_p, Q])
    else:
        ex, ey = SymmetricGMDS(mx[0], my[0], P, Q).blocks(fit.img_p, fit.img_q)
    return ranking_value(ex, ey, max(mx[1], my[1]), rank_residual)


def _dense_fields(sx, sy, P, Q, fit: _Fit, dense) -> dict:
    """The dense maps' fields of :class:`MatchResult` (:func:`gromov.dense.dense_maps`)."""
    from .dense import dense_maps

    refine = {True: "input", "placed": None}.get(dense, dense)
    mxy, myx = dense_maps(sx, sy, (P, fit.img_q), (fit.img_p, Q), refine=refine)
    return {"x_to_y_dense_face": mxy.face, "x_to_y_dense_bary": mxy.bary, "x_to_y_dense_vertex": mxy.vertex,
            "y_to_x_dense_face": myx.face, "y_to_x_dense_bary": myx.bary, "y_to_x_dense_vertex": myx.vertex,
            "input_faces": (_file_faces(sx), _file_faces(sy))}


def gw_coupling(dx: np.ndarray, dy: np.ndarray, *, max_iter: int = 1000) -> np.ndarray:
    """Gromov-Wasserstein coupling (M, K) of two distance matrices with uniform weights (POT)."""
    try:
        import ot
    except ImportError:  # pragma: no cover
        raise ImportError("the Gromov-Wasserstein solver needs POT: pip install pot") from None
    a = np.full(len(dx), 1.0 / len(dx))
    b = np.full(len(dy), 1.0 / len(dy))
    return ot.gromov.gromov_wasserstein(dx, dy, a, b, loss_fun="square_loss", max_iter=max_iter)

def discrete_blocks(DX: np.ndarray, DY: np.ndarray, P: np.ndarray, Q: np.ndarray, img_p: np.ndarray,
                    img_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`SymmetricGMDS.blocks` of a correspondence whose images are vertices (or points of
    a cloud): the distances on X between ``[P, img_q]`` and on Y between ``[img_p, Q]``, read
    off the dense matrices (the same values the interpolation gives at vertices)."""
    a, b = np.r_[P, img_q].astype(np.int64), np.r_[img_p, Q].astype(np.int64)
    return DX[np.ix_(a, a)], DY[np.ix_(b, b)]


def _images_at_points(s: "ShapeMetric", images: np.ndarray):
    """``(face, bary, vertex)`` in input terms of images at working vertices: on a mesh the
    input point there (:meth:`ShapeMetric.locate`), on a point cloud the input point itself with
    face -1 and NaN coordinates (a cloud has no faces)."""
    if s.has_faces:
        return s.locate(SurfacePoints.at_vertices(s.mesh, images))
    n = len(images)
    return np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan), s.working.to_input_ids(images)

def check_rank_tau_scale(value) -> float | None:
    """``rank_tau_scale`` as a float (or None), or ``ValueError`` unless a positive finite number."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not 0.0 < value < np.inf:
        raise ValueError(f"rank_tau_scale must be a positive number or None, got {value!r}")
    return float(value)


def check_rank_residual(value) -> str:
    """``rank_residual`` if it is one of :data:`RANK_RESIDUALS`, else ``ValueError``."""
    if not isinstance(value, str) or value not in RANK_RESIDUALS:
        raise ValueError(f"rank_residual must be one of {RANK_RESIDUALS}, got {value!r}")
    return value


def ranking_value(dx: np.ndarray, dy: np.ndarray, diameter: float, residual: str = "difference") -> float:
    """Half the trimmed RMS (:func:`gromov.gmds.trimmed_rms`) of a correspondence's residuals:
    ``(dx - dy) / diameter`` (``"difference"``) or :func:`gromov.gmds.log_ratio_residuals` with
    the floor ``RANK_LOG_FLOOR * diameter`` (``"log"``). ``dx``, ``dy``: the distances between
    corresponding points (diagonal ignored); ``diameter``: the larger of the two shapes'."""
    check_rank_residual(residual)
    if residual == "log":
        return 0.5 * trimmed_rms(log_ratio_residuals(dx, dy, RANK_LOG_FLOOR * diameter))
    off = ~np.eye(len(dx), dtype=bool)
    return 0.5 * trimmed_rms((dx - dy)[off]) / diameter


def _metric_signature(s: "ShapeMetric") -> str:
    """The solver's type and parameters (not its size): what two shapes must share for their
    distances to be compared. A hole-filling wrapper is looked through (it is there or not
    depending on the mesh, not on the options)."""
    import re

    solver = getattr(s.solver, "inner", s.solver)
    return re.sub(r"n_vertices=\d+,? ?", "", repr(solver))


def match_options_for(shapes, metric: str, metric_options: dict | None) -> dict:
    """Metric options for the shapes of a correspondence that are not prepared yet.

    :func:`~gromov.metrics.diffusion.correspondence_options` of ``metric_options``, or when
    not given of those of the first prepared :class:`ShapeMetric` among ``shapes`` (so that
    both sides of a match measure in the same metric, the one :func:`match` measures the
    prepared shape in), else the correspondence's defaults (normalised heat distributions for
    the heat kernel).
    """
    if metric_options is None:
        for s in shapes:
            if isinstance(s, ShapeMetric) and s.metric == metric:
                return correspondence_options(metric, s.metric_options)
    return correspondence_options(metric, metric_options)


def _as_shape(s, metric, resolution, metric_options, name: str, as_prepared: bool = False) -> ShapeMetric:
    """``s`` with its metric: a prepared shape in the correspondence's metric
    (:meth:`ShapeMetric.for_correspondence`) or, ``as_prepared``, in its own."""
    if isinstance(s, ShapeMetric):
        if s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        return s if as_prepared else s.for_correspondence()
    if not isinstance(s, (str, os.PathLike)):
        s = as_shape(s, name=name)   # arrays and mesh objects: errors and warnings name X or Y
    return ShapeMetric(s, metric, resolution=resolution, metric_options=metric_options)


def _file_faces(s: "ShapeMetric") -> np.ndarray | None:
    """Faces of the input mesh in file vertex ids (None for a point cloud)."""
    return s.input.input_ids[s.input.faces] if s.has_faces else None
