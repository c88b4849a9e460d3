r"""Partial matching: a part of a shape matched into a whole one (``match(part, whole, partial=True)``).

A part (a shape cut by a plane, or with large holes) is isometric to a *region* of the whole,
not to all of it, so the two-sided Gromov-Hausdorff distortion of :func:`gromov.match` --
every point of either shape must have an image -- is the wrong objective: the whole's samples
outside the part have nowhere to go, and the best two-sided map folds the whole onto the
part. Partial similarity (Bronstein, Bronstein, Bruckstein & Kimmel, "Partial similarity of
objects, or how to compare a centaur to a horse", IJCV 84(2), 2009) instead measures how well
a part of one shape fits into the other. Here the part is *given*: the first shape is the
part, the second the whole, and

1. **one metric.** The part is measured in the whole's metric: with the heat-kernel
   diffusion distance the diffusion time is ``t = tau x area`` of each shape, so a part with
   60% of the area would diffuse for 60% of the time and all its distances change; the part
   takes the whole's absolute time ``t`` (and the same scale normalisation). Geodesic and
   Euclidean distances need nothing.
2. **one-sided distortion.** Only the part's samples are embedded into the whole (GMDS,
   Bronstein, Bronstein & Kimmel, PNAS 2006), minimising

   .. math:: \sigma(Q') = \frac{\sum_{i \ne j} w_i w_j \big(d_X(p_i, p_j) - d_Y(q'_i, q'_j)\big)^2}
                               {\sum_{i \ne j} w_i w_j} ,

   the partial distortion; its square root halved is :attr:`MatchResult.distance
   <gromov.match_result.MatchResult.distance>`.
3. **the cut down-weighted.** A cut changes the part's distances most near its new boundary
   (heat cannot cross it), so each sample weighs :math:`w_i = \min(1, b_i / \beta)^2`, with
   :math:`b_i` its distance to the part's boundary along the surface and :math:`\beta` =
   ``boundary`` x the whole's :math:`\sqrt{\text{area}}`. The initial search
   (:mod:`gromov.search`, one direction) places the interior samples first.
4. **curvature beside the distortion.** A one-sided map may shrink or stretch to fit, and the
   poses of a class are seldom isometric, so a wrong region of the whole can fit the part with
   less distortion than the right one. The search and the choice among its results also weigh
   how well each sample's image keeps its smoothed mean curvature (:func:`curvature_costs`,
   weight :data:`PARTIAL_CURVATURE`); the distance reported is the distortion alone.

The region of the whole the part covers is read off the dense map: the whole's vertices within
one edge length (along the whole's surface) of the image of a part vertex, gaps between images
closed (the placed map on the working mesh; with ``dense=True``, the refined images on the
input mesh). Its share of
the whole's area is reported with the distance. With ``dense=True`` the part's map is then
refined on the input meshes by ZoomOut with a rectangular functional map
(:func:`partial_zoomout`; Rodolà, Cosmo, Bronstein, Torsello & Cremers, CGF 2017). A part below :data:`SMALL_PART` of the whole's
area is matched all the same, with a :class:`~gromov.errors.SmallPartWarning`.
:func:`partial_matrix` matches every part into every whole, for ranking. A "part" with
nothing missing (closed, or with holes about one edge in radius at most: :func:`whole_shape`)
is matched as a whole, by the two-sided correspondence and distance of :func:`gromov.match`.
The measurements behind these choices are in docs/design/partial.md.
"""

from __future__ import annotations

import logging
import os
import time
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.sparse import csgraph

from ._arrays import one_blas_thread, readonly
from ._defaults import DEFAULT_RESOLUTION
from ._gmds_kernel import sweep
from .dense import (_at_vertices, _by_file_id, _input_basis, _input_images, _zoomout_steps,
                    local_anchored_map)
from .errors import GromovWarning, MetricError, SmallPartWarning
from .gmds import SurfacePoints, norm_value
from .match_result import MatchResult
from .mesh import Mesh, as_shape
from .metrics.diffusion import correspondence_options
from .search import (SIGNATURE_STARTS, SearchOptions, _candidates, _orient, _Search, anchored_images,
                     signature_mismatch)
from .shape_metric import ShapeMetric

__all__ = ["BOUNDARY_WIDTH", "PARTIAL_CURVATURE", "PARTIAL_DENSE", "PARTIAL_K_END", "PARTIAL_K_START",
           "BRIDGE_BOUNDARY", "PARTIAL_BRIDGE", "PARTIAL_RANK_BRIDGE", "PARTIAL_K_STEP", "PARTIAL_KY_MAX", "PARTIAL_METRIC", "PARTIAL_RINGS", "SMALL_PART", "HOLE_RADIUS", "PartialMatrix",
           "boundary_distance", "bridged_distances", "interval_misfit", "interval_residual", "covered_region", "curvature_costs", "in_whole_metric", "local_anchored_map",
           "match_partial", "part_curvature", "partial_matrix", "partial_zoomout", "sample_weights", "whole_shape"]

logger = logging.getLogger(__name__)

#: The metric of ``match(part, whole, partial=True)`` when none is named: geodesic distances,
#: which a cut changes only where shortest paths crossed the removed region (the heat-kernel
#: diffusion distance changes everywhere near the new boundary; docs/design/partial.md).
PARTIAL_METRIC = "geodesic"
#: Width of the band along the part's boundary that is down-weighted, ÷ sqrt(area of the whole)
#: (docs/design/partial.md).
BOUNDARY_WIDTH = 0.1
#: GMDS runs from this many of the initial search's extended starts (the lowest weighted
#: distortion after GMDS wins).
N_REFINE = 4
#: A mirrored map is replaced by an orientation-preserving one whose distortion is at most this
#: much (relative) above it, as :data:`gromov.gh.ORIENTATION_TOL`.
ORIENTATION_TOL = 0.1
#: ... or by its composition with the whole's reflection within this much, as
#: :data:`gromov.gh.FLIP_TOL`.
FLIP_TOL = 0.25
#: A direct map is weighed against clearly direct alternatives (orientation agreement above 1/2
#: + ``DIRECT_MARGIN``) within ``TURN_TOL`` of its distortion that keep the smoothed mean
#: curvature better by ``TURN_MARGIN`` (a body turned half about its long axis), as
#: :func:`gromov.match` does.
DIRECT_MARGIN, TURN_TOL, TURN_MARGIN = 0.15, 0.1, 0.1
#: With the geodesic metric and a part with a boundary: match with the part's own distances from
#: its samples (False), with distances halfway between them and a lower bound that lets a path
#: cross each hole (True, :func:`bridged_distances`; a hole lengthens every path around it on
#: the part and not on the whole), or with both, keeping the map whose distances on the whole
#: leave the interval between the two least (``"choose"``). Bridging alone places parts with
#: large holes far better and loses where a chord is a poor bound (a plane cut through a torus,
#: small parts); choosing keeps the better of the two (within 1 unit of the benchmark's error)
#: on 132 of its 144 parts, and betters both on the whole (docs/design/partial.md, "Paths across
#: the holes").
PARTIAL_BRIDGE = "choose"
#: :func:`bridged_distances` takes at most this many boundary vertices as the ends of its
#: chords (every k-th of each loop beyond it): its cost grows as their number cubed (under a
#: second for 600 beside 3,200 working vertices).
BRIDGE_BOUNDARY = 600
#: ``"choose"`` keeps the bridged map only when its interval misfit is below the part's own
#: map's and above ``BRIDGE_FLOOR`` x the whole's mean working edge length: misfits below what
#: the working mesh resolves are a tie, which the part's own distances win. A part whose
#: intervals are all narrower than the same floor (a mesh's few tiny holes) is searched once.
BRIDGE_FLOOR = 0.5
#: :func:`partial_matrix` (``gromov pairwise --partial``, ``gromov search --partial``) ranks with
#: this ``bridge``: the part's own distances. The distances of ``"choose"`` (how far a map
#: leaves the interval) rank parts with holes worse against the 80 TOSCA wholes (6 of 9 parts
#: nearest a whole of their class, against 8 of 9; docs/design/partial.md, "The partial
#: matrix"), and it searches a part with a boundary twice.
PARTIAL_RANK_BRIDGE = False
#: The dense map places each vertex by its distances to this many nearest samples
#: (:func:`gromov.dense.local_anchored_map`).
N_LOCAL = 16
#: The weight of the curvature term beside the distortion (:func:`curvature_costs`): a sample
#: whose smoothed mean curvature differs from its image's by 1 costs as much as distances off by
#: ``PARTIAL_CURVATURE`` x sqrt(area of the whole). The one-sided distortion alone prefers a wrong
#: region of a whole whose poses are not isometric (a cat's front half on its back half); the
#: truth keeps the curvature far better (docs/design/partial.md, "Curvature beside the
#: distortion").
PARTIAL_CURVATURE = 0.01
#: The covered region: the whole's vertices within ``COVER_RADIUS`` of its mean edge lengths of
#: the image of a part vertex, after a closing of ``COVER_CLOSE`` edge lengths
#: (:func:`covered_region`).
COVER_RADIUS, COVER_CLOSE = 1.0, 2.0
#: The dense map's refinement on the input meshes (:func:`partial_zoomout`): the part's
#: eigenfunctions from ``PARTIAL_K_START`` by ``PARTIAL_K_STEP`` up to ``PARTIAL_K_END``, each
#: image searched within ``PARTIAL_RINGS`` rings of the current one, the whole's eigenfunctions
#: capped at ``PARTIAL_KY_MAX`` (docs/design/partial.md).
PARTIAL_K_START, PARTIAL_K_END, PARTIAL_K_STEP, PARTIAL_RINGS, PARTIAL_KY_MAX = 10, 120, 4, 2, 160
#: The values of ``match_partial(..., dense=...)``: True or "input" (placed, then refined by
#: :func:`partial_zoomout`), "placed" (not refined).
PARTIAL_DENSE = (True, "input", "placed")
#: :func:`match_partial` warns (:class:`~gromov.errors.SmallPartWarning`) when the part's area is
#: below this fraction of the whole's: the parts measured hold 45-75% of it, and below a quarter
#: more than half of even a round part lies in the down-weighted band along its boundary
#: (docs/design/partial.md).
SMALL_PART = 0.25

#: A boundary loop shorter than :math:`2\pi` times this many mean edge lengths is a hole the
#: mesh does not resolve (:func:`whole_shape`): at most about one edge in radius, as far as the
#: covered region reaches around each image (``COVER_RADIUS``). TOSCA's whole meshes have such holes
#: (1-4.4 edges round at 4,000 vertices); a plane cut or a removed patch is many edges round.
HOLE_RADIUS = 1.0


def _heat(s: ShapeMetric):
    """The heat-kernel solver of ``s`` (looking through a hole-filling wrapper), or None."""
    solver = s.solver
    while solver is not None and not hasattr(solver, "t"):
        solver = getattr(solver, "inner", None)
    return solver if solver is not None and hasattr(solver, "area") else None


def _prepare(s, metric: str, resolution, options: dict, name: str) -> ShapeMetric:
    """``s`` as a ShapeMetric in ``options`` (a prepared one in its correspondence metric)."""
    if isinstance(s, ShapeMetric):
        if s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        return s.for_correspondence()
    if not isinstance(s, (str, os.PathLike)):
        s = as_shape(s, name=name)
    return ShapeMetric(s, metric, resolution=resolution, metric_options=options)


def in_whole_metric(sx: ShapeMetric, sy: ShapeMetric) -> ShapeMetric:
    """The part ``sx`` measured as the whole ``sy`` is: with the heat-kernel diffusion metric at
    the whole's absolute diffusion time (``tau = t_Y / area_X``, same units), else ``sx``."""
    hx, hy = _heat(sx), _heat(sy)
    if hx is None or hy is None:
        return sx
    tau = hy.t / hx.area
    if np.isclose(tau, hx.tau, rtol=1e-12, atol=0.0):
        return sx
    options = {**sx.metric_options, "tau": float(tau), "units": hy.units}
    return ShapeMetric(sx.input, sx.metric, metric_options=options, working=sx.working)


def boundary_distance(mesh: Mesh) -> np.ndarray:
    """``(n,)``: distance along the edges from each vertex to the mesh's boundary (inf on a
    closed mesh)."""
    bv = np.unique(mesh.boundary_edges.ravel())
    if not len(bv):
        return np.full(mesh.n_vertices, np.inf)
    return csgraph.dijkstra(mesh.adjacency, directed=False, indices=bv, min_only=True)


def sample_weights(distance_to_boundary: np.ndarray, width: float) -> np.ndarray:
    r""":math:`w = \min(1, b / \beta)^2` of distances ``b`` to the boundary, ``width`` :math:`\beta`
    (all ones for ``width = 0``)."""
    b = np.asarray(distance_to_boundary, dtype=float)
    if not width > 0:
        return np.ones_like(b)
    return np.minimum(1.0, b / width) ** 2


def bridged_distances(sx: ShapeMetric, P: np.ndarray) -> np.ndarray:
    r"""``(len(P), n)``: geodesic distances from the part's samples ``P`` to its working
    vertices, halfway between the part's own and a lower bound on the whole's.

    A path on the part is a path on the whole, so the part's distance :math:`d` bounds the
    whole's from above; a hole makes it go round. A path on the whole that crosses a hole
    leaves the part at one vertex ``a`` of the hole's boundary loop and comes back at another,
    ``b``, after at least the straight chord :math:`\lVert x_a - x_b \rVert`. With :math:`c^*`
    the shortest chains of such chords (within each boundary loop) and paths on the part
    between boundary vertices,

    .. math:: d_-(p, q) = \min\Big(d(p, q),\ \min_{a, b} d(p, a) + c^*(a, b) + d(b, q)\Big)

    bounds the whole's distance from below (where each missing piece is bounded by one loop,
    and up to the change of pose), and :math:`\tfrac12 (d_- + d)` is returned: the middle of the
    interval the whole's distance lies in. Bronstein, Bronstein & Kimmel ("Partial similarity
    of objects", IJCV 2009) set aside the pairs whose path a boundary may have lengthened; here
    they keep a target. On a closed part, ``d`` itself.
    """
    D = sx.distances
    P = np.asarray(P, dtype=np.int64)
    loops = [np.asarray(loop, dtype=np.int64) for loop in sx.mesh.boundary_loops]
    if not loops:
        return D[P].copy()
    total = sum(len(loop) for loop in loops)
    if total > BRIDGE_BOUNDARY:   # every k-th vertex of each loop: the chords' ends
        step = -(-total // BRIDGE_BOUNDARY)
        loops = [loop[::step] for loop in loops]
    B = np.concatenate(loops)
    label = np.repeat(np.arange(len(loops)), [len(loop) for loop in loops])
    V = sx.mesh.vertices[B]
    chord = np.linalg.norm(V[:, None, :] - V[None, :, :], axis=2)
    chord[label[:, None] != label[None, :]] = np.inf
    C = np.minimum(D[np.ix_(B, B)], chord)
    for k in range(len(B)):   # Floyd-Warshall over the boundary vertices
        np.minimum(C, C[:, k:k + 1] + C[k:k + 1, :], out=C)
    to_b = D[np.ix_(P, B)]
    # (len(P), len(B)): from p to b with the holes crossed, a row at a time
    via = np.stack([np.min(row[:, None] + C, axis=0) for row in to_b])
    low = D[P].copy()
    rows = D[B]
    for j in range(len(B)):
        np.minimum(low, via[:, j:j + 1] + rows[j:j + 1, :], out=low)
    return 0.5 * (low + D[P])


def interval_misfit(sy: ShapeMetric, img: SurfacePoints, low: np.ndarray, high: np.ndarray,
                    W: np.ndarray) -> float:
    r"""How far the whole's distances between the images ``img`` of the part's samples leave
    the interval ``[low, high]`` their true values lie in (:func:`bridged_distances`'s bound and
    the part's own distances): the weighted RMS of
    :math:`\max(0, d_-(p_i, p_j) - d_Y(y_i, y_j)) + \max(0, d_Y(y_i, y_j) - d(p_i, p_j))`,
    weights ``W``. 0 for any map that keeps every distance within its bounds."""
    r = interval_residual(_between(sy, img), low, high)
    return float(np.sqrt(np.sum(W * r**2) / W.sum()))


def interval_residual(dy: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """How far each of the distances ``dy`` lies outside ``[low, high]``, signed as a residual
    ``d_X - d_Y`` (positive where ``dy`` is below ``low``); 0 inside. With ``low = high`` the
    plain residual ``high - dy``."""
    return np.where(dy < low, low - dy, np.where(dy > high, high - dy, 0.0))


def _between(sy: ShapeMetric, img: SurfacePoints) -> np.ndarray:
    """The whole's distances between the points ``img``, symmetrised."""
    dy = sy.surface.between(img, np.zeros(0, dtype=np.int64))
    return 0.5 * (dy + dy.T)


def _bridged_rows(sx: ShapeMetric, P0: np.ndarray, n_samples: int, seed: int) -> np.ndarray:
    """:func:`bridged_distances` from the part's samples ``P0``, once per part and sampling (a
    part matched into many wholes, :func:`partial_matrix`, reuses them)."""
    cache = sx.__dict__.setdefault("_bridged", {})
    key = (int(n_samples), seed)
    if key not in cache:
        cache[key] = readonly(bridged_distances(sx, P0))
    return cache[key]


def _one_sided_gmds(sy: ShapeMetric, dx_pp: np.ndarray, W: np.ndarray, img: SurfacePoints,
                    max_iter: int, tol: float, n_newton: int = 3):
    """GMDS of the part's samples into Y: weighted L2 stress against ``dx_pp``; returns
    ``(images, n_iter, converged, history)``."""
    Y = sy.surface
    eps = 1e-9 * Y.max_distance
    pf, pb = img.face.copy(), img.bary.copy()
    fixed = np.zeros(0, dtype=np.int64)
    delta, w = np.ascontiguousarray(dx_pp), np.ascontiguousarray(W)

    def stress():
        dy = Y.between(SurfacePoints(pf, pb), fixed)
        dy = 0.5 * (dy + dy.T)
        return float(np.sum(w * (dx_pp - dy) ** 2))

    cur = stress()
    history, converged, n_iter = [cur], False, 0
    for n_iter in range(1, max_iter + 1):
        sweep(pf, pb, fixed, delta, w, Y.distances, Y.faces, Y.neighbours, n_newton, eps)
        new = stress()
        history.append(new)
        if cur - new <= tol * max(cur, 1e-300):
            converged, cur = True, new
            break
        cur = new
    return SurfacePoints(pf, pb), n_iter, converged, history


def covered_region(mesh: Mesh, images: np.ndarray, radius: float, close: float = 0.0) -> np.ndarray:
    """Mask of the vertices of ``mesh`` within ``radius`` (along its edges) of an image
    vertex, after a closing of width ``close``: the region grown by ``radius + close``, then
    the vertices within ``close`` of what is left outside removed (gaps narrower than about
    ``2 close`` between images filled, the outline kept)."""
    g = mesh.adjacency
    grow = radius + close
    d = csgraph.dijkstra(g, directed=False, indices=np.unique(images), min_only=True, limit=grow * 1.000001)
    region = d <= grow
    if close > 0 and not region.all():
        d_out = csgraph.dijkstra(g, directed=False, indices=np.flatnonzero(~region), min_only=True,
                                 limit=close * 1.000001)
        region &= ~(d_out < close)
    return region


def partial_zoomout(sx: ShapeMetric, sy: ShapeMetric, T: np.ndarray, *, k_start: int = PARTIAL_K_START,
                    k_end: int = PARTIAL_K_END, step: int = PARTIAL_K_STEP, rings: int = PARTIAL_RINGS,
                    ky_max: int = PARTIAL_KY_MAX) -> np.ndarray:
    r"""Refine a part's vertex map into the whole on the input meshes: ZoomOut with a
    rectangular functional map.

    ZoomOut (Melzi et al., SIGGRAPH Asia 2019) as :func:`gromov.dense.input_zoomout` runs it, on
    the Laplace-Beltrami eigenfunctions :math:`\Phi` of each input mesh, with the functional map
    of a part (Rodolà, Cosmo, Bronstein, Torsello & Cremers, "Partial functional
    correspondence", Computer Graphics Forum 36(1), 2017): the eigenvalues grow as
    :math:`4 \pi k / \text{area}` (Weyl's law), so the part's first :math:`k_X` eigenfunctions
    span about the frequencies of the whole's first :math:`k_Y = k_X / r`, :math:`r` the part's
    area over the whole's (at most 1), and its functional map is a :math:`k_X \times k_Y` band of slope
    :math:`r`, not a square. For :math:`k_X` = ``k_start``, ``k_start + step``, ... up to
    ``k_end``, with :math:`k_Y = \min(\operatorname{round}(k_X / r), \text{ky\_max})`,

    .. math:: C = \Phi_{X,k_X}^\top M_X \Phi_{Y,k_Y}[T], \qquad
              T(v) = \arg\min_{w \in N(T(v))} \lVert \Phi_{X,k_X}(v) - \Phi_{Y,k_Y}(w)\, C^\top \rVert ,

    each image searched in the ``rings``-ring :math:`N(T(v))` of the current one on Y's input
    mesh (the map is refined, never moved to another region). ``ky_max`` caps the whole's
    eigenfunctions: a part of 45% of the whole would take :math:`k_Y = 262` at :math:`k_X = 118`,
    and Y's eigensolve is the refinement's largest cost on a large mesh (computed once per shape
    and reused). Past the cap the last steps add the part's frequencies only; capping at 160 rather
    than 195 changed nothing measurable on the parts measured (docs/design/partial.md). The input vertices of X on pieces left out of its working mesh
    (:attr:`~gromov.resolution.WorkingMesh.source_kept`) keep their images. A point cloud has no
    Laplace-Beltrami operator here: ``T`` is returned as it is.

    Parameters
    ----------
    sx, sy : ShapeMetric
        The part and the whole.
    T : ndarray (n_X,) of int
        Vertex of Y's input mesh (index, not file id) for each vertex of X's input mesh.
    k_start, k_end, step, rings, ky_max : int, defaults PARTIAL_K_START (10), PARTIAL_K_END (120),
        PARTIAL_K_STEP (4), PARTIAL_RINGS (2), PARTIAL_KY_MAX

    Returns
    -------
    ndarray (n_X,) of int64
        The refined map (a new array).

    Examples
    --------
    >>> r = gromov.match(part, whole, partial=True, dense="placed")       # doctest: +SKIP
    >>> T = partial_zoomout(sx, sy, sy.input.from_input_ids(r.x_to_y_dense_vertex))  # doctest: +SKIP
    """
    T = np.array(T, dtype=np.int64)
    if T.shape != (sx.input.n_vertices,):
        raise ValueError(f"T must have one vertex of Y per input vertex of X, shape ({sx.input.n_vertices},), "
                         f"got {T.shape}")
    for name, value, low in (("k_start", k_start, 1), ("k_end", k_end, k_start), ("step", step, 1),
                             ("rings", rings, 0), ("ky_max", ky_max, 1)):
        if int(value) != value or value < low:
            raise ValueError(f"{name} must be an integer of at least {low}, got {value!r}")
    if not (sx.has_faces and sy.has_faces):
        return T
    ratio = min(area_ratio(sx, sy), 1.0)
    ks = list(range(int(k_start), int(k_end) + 1, int(step)))

    def k_y(k: int) -> int:
        return max(1, min(int(round(k / ratio)), int(ky_max)))

    phx, mx = _input_basis(sx, ks[-1])
    phy, _ = _input_basis(sy, k_y(ks[-1]))
    steps = [(min(k, phx.shape[1]), min(k_y(k), phy.shape[1])) for k in ks]
    # the bases as they are: the part is the whole's surface at its own scale, not a scaled copy
    return _zoomout_steps(sx, sy, T, phx, mx[:, None] * phx, phy, steps, rings=int(rings))


def match_partial(X, Y, metric: str = PARTIAL_METRIC, *, n_samples: int = 100, seed: int = 0,
                  resolution: int | None = DEFAULT_RESOLUTION, metric_options: dict | None = None,
                  search: SearchOptions | None = None, dense: bool | str = False,
                  boundary: float = BOUNDARY_WIDTH, same_time: bool = True,
                  n_refine: int = N_REFINE, interior_only: bool = True, n_local: int = N_LOCAL,
                  curvature: float = PARTIAL_CURVATURE, bridge: bool | None = None) -> MatchResult:
    r"""A part ``X`` matched into a whole shape ``Y``: :func:`gromov.match` with ``partial=True``.

    Parameters
    ----------
    X : mesh, path or ShapeMetric
        The part (given, not detected: the first shape is the part).
    Y : mesh, path or ShapeMetric
        The whole.
    metric, n_samples, seed, resolution, metric_options, search
        As :func:`gromov.match`.
    dense : bool, "input" or "placed", default False
        Also the image of every input vertex of X on Y. True or "input": placed from the
        samples, then refined on the input meshes by ZoomOut with a rectangular functional map
        (:func:`partial_zoomout`); "placed": not refined.
    boundary : float, default BOUNDARY_WIDTH
        Width of the down-weighted band along X's boundary, ÷ sqrt(area of Y); 0: no weights.
    same_time : bool, default True
        Measure X at Y's diffusion time (heat kernel); False: each at its own.
    n_refine : int, default N_REFINE
        GMDS from this many of the search's best starts; the lowest final distortion is kept.
    interior_only : bool, default True
        Run the initial search on the samples of weight at least 1/2 (the others placed after).
    n_local : int, default N_LOCAL
        The dense map places each vertex by its distances to this many nearest samples (0: to
        all of them, :func:`gromov.dense.anchored_map`).
    curvature : float, default PARTIAL_CURVATURE
        Weight :math:`\lambda` of the curvature term: the search and the choice among the GMDS
        results minimise the weighted stress plus
        :math:`\sum_i (\sum_j w_i w_j) \, \lambda^2 \, \text{area}(Y) \, (H_X(p_i) - H_Y(q_i))^2`
        over the smoothed mean curvatures (:func:`curvature_costs`); 0: the distortion alone.
        The distance reported is the distortion alone either way.
    bridge : bool or "choose", optional
        Default: :data:`PARTIAL_BRIDGE`, read at each call. With the geodesic metric and a
        part that has a boundary: True, the part's distances from its samples halfway between
        its own and a lower bound that lets paths cross its holes (:func:`bridged_distances`),
        in the search, GMDS and the dense placement; False: the part's own; "choose": both,
        and the map that keeps the whole's distances nearer their interval
        (:func:`interval_misfit`, ties below :data:`BRIDGE_FLOOR` to the part's own).

    Returns
    -------
    MatchResult
        ``x_to_y_*`` and the dense ``x_to_y_dense_*``: the part's samples and vertices on the
        whole; ``distance`` half the weighted RMS of the one-sided residuals (with
        ``bridge="choose"`` and a part with a boundary, of how far the whole's distances leave
        the interval between the bridged bound and the part's own, :func:`interval_residual`);
        ``y_covered``, ``covered_fraction``: the region of Y the part covers. Y's samples
        (``y_samples``) get images only inside that region (elsewhere face -1, vertex -1).
        A whole shape X (:func:`whole_shape`) gets :func:`gromov.match`'s two-sided
        correspondence, distance and ``(M+K, M+K)`` ``pair_distortion``; ``bridge``,
        ``boundary``, ``n_refine``, ``interior_only`` and ``curvature`` do not apply to it.
    """
    t0 = time.perf_counter()
    search = SearchOptions() if search is None else search
    if n_samples < 3:
        raise ValueError(f"n_samples must be at least 3, got {n_samples}")
    if not (np.isfinite(curvature) and curvature >= 0):
        raise ValueError(f"curvature must be a finite number >= 0, got {curvature!r}")
    if dense is not False and dense is not None and not any(dense is d or dense == d for d in PARTIAL_DENSE):
        raise ValueError(f"dense must be True, False, 'input' or 'placed' for a partial match (its dense map "
                         f"is refined on the input meshes), got {dense!r}")
    mode = PARTIAL_BRIDGE if bridge is None else bridge
    if not (mode == "choose" if isinstance(mode, str) else isinstance(mode, (bool, np.bool_))):
        raise ValueError(f"bridge must be True, False or 'choose', got {mode!r}")
    mode = mode if isinstance(mode, str) else bool(mode)
    options = correspondence_options(metric, metric_options)
    sy = _prepare(Y, metric, resolution, options, "Y")
    sx = _prepare(X, metric, resolution, options, "X")
    if not (sx.has_faces and sy.has_faces):
        raise ValueError("partial matching needs triangle meshes; X or Y is a point cloud")
    for name, s in (("X", sx), ("Y", sy)):
        if n_samples > s.mesh.n_vertices:
            raise ValueError(f"n_samples={n_samples} exceeds the {s.mesh.n_vertices} working vertices of {name}")
    share = area_ratio(sx, sy)
    if share < SMALL_PART:
        warnings.warn(f"the part keeps only {share:.1%} of the whole's area; its placement on the whole is "
                      f"unreliable below {SMALL_PART:.0%} (and a small part fits almost anywhere with a low "
                      "distance)", SmallPartWarning, stacklevel=2)
    if same_time:
        sx = in_whole_metric(sx, sy)
    if whole_shape(sx.mesh):   # nothing is missing: the two-sided match of gromov.match
        return _as_whole(sx, sy, n_samples, seed, search, dense, n_local, metric, t0)
    # samples of the part, the interior ones first (the coarse stages place the first ones)
    P0 = sx.samples(n_samples, seed)
    width = float(boundary) * np.sqrt(sy.mesh.area)
    b = boundary_distance(sx.mesh)
    wp0 = sample_weights(b[P0], width)
    order = np.argsort(-np.minimum(wp0, 1.0), kind="stable")
    P, wp = P0[order], wp0[order]
    Q = sy.samples(n_samples, seed)
    # a closed part has no hole to bridge; the diffusion metric is not a path length
    bridged = mode is not False and sx.metric == "geodesic" and len(sx.mesh.boundary_loops) > 0
    rows = _bridged_rows(sx, P0, n_samples, seed)[order] if bridged else None
    own = sx.distances[np.ix_(P, P)]
    W = np.outer(wp, wp)
    np.fill_diagonal(W, 0.0)
    if not W.sum() > 0:
        raise MetricError("every sample of X lies on its boundary: nothing to weigh (boundary=0 weighs "
                          "all samples alike)")
    floor = BRIDGE_FLOOR * sy.mesh.mean_edge_length
    low = 2.0 * rows[:, P] - own if bridged else own   # the interval [low, own] of the whole's distances
    if bridged and mode == "choose":
        # intervals all narrower than the mesh resolves (a mesh's few tiny holes) are none
        width = float(np.max(np.where(W > 0, own - low, 0.0)))
        logger.debug("partial: interval width %.4g (floor %.3g)", width, floor)
        bridged = width >= floor
    targets = ([own] if not bridged or mode == "choose" else []) + ([rows[:, P]] if bridged else [])
    with one_blas_thread():
        n_interior = int(np.sum(wp >= 0.5)) if interior_only else len(P)
        hx = part_curvature(sx, sy)[P] if curvature > 0 else None   # once for both searches
        fits = [_search_and_refine(sx, sy, P, dx, W, search, n_refine, n_interior, curvature=curvature, hx=hx)
                for dx in targets]
    k, high = 0, targets[0]
    if len(fits) > 1:   # "choose": the map whose distances on Y leave the interval least
        high = own
        misfit = [interval_misfit(sy, f[0], low, high, W) for f in fits]
        k = int(max(misfit[1], floor) < max(misfit[0], floor))
        logger.debug("partial: interval misfit own %.4g, bridged %.4g (floor %.3g)", *misfit, floor)
    else:
        low = high
    img, n_iter, converged, history, orientation = fits[k]
    bridged = bridged and targets[k] is not own
    # the residuals: outside the interval with "choose", else against the distances matched
    residual = interval_residual(_between(sy, img), low, high)
    np.fill_diagonal(residual, 0.0)
    off = ~np.eye(len(P), dtype=bool)
    stress = float(np.sum(W * residual**2))
    dis = float(np.sqrt(stress / W.sum()))
    r = residual[off]
    # the objective the search minimised, in the distance's units: what parts are ranked by
    bent = 0.0
    if hx is not None:
        costs = curvature_costs(sx, sy, P, curvature, hx)[np.arange(len(P)), img.vertex(sy.mesh.faces)]
        bent = float(np.sum(W.sum(axis=1) * costs))
    ranking = 0.5 * np.sqrt((stress + bent) / W.sum()) / sy.diameter
    T = _placed(sx, sy, P, img, wp, n_local, rows.T if bridged else None)
    return _result(sx, sy, P, Q, img, wp, T, None, residual, dis, r, dense, metric, t0, n_iter=int(n_iter),
                   converged=bool(converged), history=np.asarray(history), orientation=orientation,
                   diameter=sy.diameter, ranking_distance=float(ranking))


def _result(sx, sy, P, Q, img, wp, T, q_images, residual, dis, r, dense, metric, t0, *, diameter,
            **fit) -> MatchResult:
    """The partial :class:`MatchResult` of the part's sample images ``img`` and the placed map
    ``T``: the covered region, the dense maps, Y's samples' images inside the region
    (``q_images`` on X's working mesh, or else the part's vertex whose image is nearest);
    ``ranking_distance`` in ``fit``, else the relative distance."""
    xy_face, xy_bary, xy_vertex = sy.locate(img)
    # the dense map (working vertices of X -> working vertices of Y), the covered region
    h = sy.mesh.mean_edge_length
    covered_w = covered_region(sy.mesh, T, COVER_RADIUS * h, COVER_CLOSE * h)
    covered = covered_w[sy.working.source_nearest]   # each input vertex as its nearest working vertex
    extra = {}
    if dense:
        face, bary, vertex = _input_images(sx, sy, T)
        if dense != "placed":   # refined on the input meshes
            vertex = partial_zoomout(sx, sy, vertex)
            kept = sx.working.source_kept
            face, bary = face.copy(), bary.copy()
            face[kept], bary[kept] = _at_vertices(sy.input, vertex[kept])
            # the covered region read off the refined images, on the whole's input mesh
            hi = sy.input.mean_edge_length
            covered = covered_region(sy.input, vertex, COVER_RADIUS * hi, COVER_CLOSE * hi)
            covered_w = covered[sy.working.to_source(np.arange(sy.mesh.n_vertices))]
        m = _by_file_id(sx, face, bary, sy.input.input_ids[vertex])
        back = _covered_back(sx, sy, T, covered_w, covered)
        extra = {"x_to_y_dense_face": m.face, "x_to_y_dense_bary": m.bary, "x_to_y_dense_vertex": m.vertex,
                 "y_to_x_dense_face": back.face, "y_to_x_dense_bary": back.bary, "y_to_x_dense_vertex": back.vertex,
                 "input_faces": (sx.input.input_ids[sx.input.faces], sy.input.input_ids[sy.input.faces])}
    areas = sy.input.vertex_areas
    fraction = float(areas[covered].sum() / areas.sum())
    y_covered = sy.input.per_file_vertex(covered, fill=False)
    # Y's samples inside the region
    yx_face, yx_bary, yx_vertex = _back_images(sx, sy, Q, T, covered_w[Q], q_images)
    diam = diameter
    fit.setdefault("ranking_distance", 0.5 * dis / diam)   # nothing but the distortion was minimised
    return MatchResult(
        distance=0.5 * dis, relative_distance=0.5 * dis / diam, distortion=dis,
        distortion_l2=dis, distortion_linf=norm_value(r, np.inf), norm="l2", metric=metric, solver="gmds",
        n_samples=len(P), x_samples=sx.working.to_input_ids(P), x_to_y_face=xy_face,
        x_to_y_bary=xy_bary, x_to_y_vertex=xy_vertex, y_samples=sy.working.to_input_ids(Q),
        y_to_x_face=yx_face, y_to_x_bary=yx_bary, y_to_x_vertex=yx_vertex,
        seconds=time.perf_counter() - t0, pair_distortion=residual, partial=True, y_covered=y_covered,
        covered_fraction=fraction, x_weight=wp, **fit, **extra)


def area_ratio(sx: ShapeMetric, sy: ShapeMetric) -> float:
    """The part's area over the whole's (their input meshes)."""
    return float(sx.input.area / sy.input.area)


@dataclass(frozen=True, eq=False)
class PartialMatrix:
    """Every part matched into every whole: :func:`partial_matrix`.

    Attributes
    ----------
    distance : ndarray (n_parts, n_wholes)
        ``match_partial(parts[i], wholes[j]).distance``: row ``i`` a part, column ``j`` a whole.
        Not symmetric. With ``same`` its diagonal is 0 (each shape is a part of itself).
    relative_distance : ndarray (n_parts, n_wholes)
        ``distance`` ÷ the whole's diameter.
    ranking_distance : ndarray (n_parts, n_wholes)
        ``match_partial(parts[i], wholes[j]).ranking_distance``: the objective the search
        minimised (the distortion and the curvature term) in the same units, ÷ the whole's
        diameter; what :attr:`score` divides.
    covered_fraction : ndarray (n_parts, n_wholes)
        The share of the whole's area the part covers (1 on the diagonal with ``same``).
    area_ratio : ndarray (n_parts, n_wholes)
        The part's area over the whole's (input meshes); below :data:`SMALL_PART` the
        placement is unreliable and a low distance says little.
    same : bool
        The parts are the wholes (``partial_matrix(shapes)``): the diagonal is never nearest.
    parts, wholes : list of str
        Their names: the files, where given as paths, else ``"part i"`` / ``"whole j"``.
    metric : str
    n_samples : int
    seconds : float
        Preparing the shapes and matching the pairs.
    """

    distance: np.ndarray
    relative_distance: np.ndarray
    covered_fraction: np.ndarray
    area_ratio: np.ndarray
    same: bool
    parts: list
    wholes: list
    metric: str
    n_samples: int
    seconds: float
    ranking_distance: np.ndarray | None = None   # None: the relative distance

    def __post_init__(self):
        if self.ranking_distance is None:
            object.__setattr__(self, "ranking_distance", self.relative_distance)

    @cached_property
    def score(self) -> np.ndarray:
        r"""``(n_parts, n_wholes)``: the ranked value, the ranking distance per share of the
        whole covered, :math:`R_{ij} / c_{ij}` (inf where nothing is covered, NaN where not
        matched); :math:`R_{ij}` is half the root of the weighted squared residuals plus the
        curvature term over the weights, ÷ the whole's diameter (:attr:`ranking_distance`).
        A part matched into a shape it covers little of is not taken for a good match by
        fitting a small region well (docs/design/partial.md)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            s = self.ranking_distance / self.covered_fraction
        s[(self.covered_fraction == 0) & np.isfinite(self.ranking_distance)] = np.inf
        if self.same:
            np.fill_diagonal(s, 0.0)
        return s

    @cached_property
    def nearest(self) -> np.ndarray:
        """``(n_parts,)`` int: each part's nearest whole by :attr:`score` (another shape with
        ``same``)."""
        d = np.where(np.isnan(self.score), np.inf, self.score)
        if self.same:
            d = d + np.diag(np.full(len(d), np.inf))
        return np.argmin(d, axis=1)

    @cached_property
    def small(self) -> np.ndarray:
        """``(n_parts, n_wholes)`` bool: pairs whose part holds less than :data:`SMALL_PART` of the
        whole's area (the diagonal left out with ``same``)."""
        m = self.area_ratio < SMALL_PART
        if self.same:
            np.fill_diagonal(m, False)
        return m


def _names(shapes: list, what: str) -> list[str]:
    return [os.fspath(s) if isinstance(s, (str, os.PathLike)) else f"{what} {i}" for i, s in enumerate(shapes)]


def partial_matrix(parts, wholes=None, metric: str = PARTIAL_METRIC, *, n_samples: int = 100, seed: int = 0,
                   resolution: int | None = DEFAULT_RESOLUTION, metric_options: dict | None = None,
                   names: list | None = None, progress: bool = False, **match_options) -> PartialMatrix:
    r"""Each part matched into each whole (:func:`match_partial`), for ranking wholes by part.

    :math:`D_{ij} = ` ``match_partial(parts[i], wholes[j]).distance``, the half weighted RMS
    of the one-sided residuals of part ``i`` in whole ``j``. It is not symmetric: a part fits
    into its whole, not the whole into the part. Each shape is prepared once (its metric in
    the correspondence's options) and every ordered pair is matched, one after the other; no
    pair is pruned. Each part's nearest whole is the one of lowest ranking distance per
    share of the whole covered, :math:`\arg\min_j R_{ij} / c_{ij}` (:attr:`PartialMatrix.score`,
    :attr:`PartialMatrix.nearest`; :math:`R_{ij}` the objective of the search, distortion and
    curvature term, ÷ the whole's diameter): a part fits a region of many shapes well, and the
    share it covers tells its own whole from the others. Read
    :attr:`PartialMatrix.area_ratio` beside it -- a small part fits almost anywhere. The pairs whose part holds less than :data:`SMALL_PART` of the whole's area are
    named in one :class:`~gromov.errors.SmallPartWarning` (not one per pair).

    Parameters
    ----------
    parts : sequence of meshes, paths or ShapeMetric
        The parts (rows).
    wholes : sequence of meshes, paths or ShapeMetric, optional
        The wholes (columns), each also as a function of no arguments that returns it (called
        when its column is matched, and let go after: a store's entries read one at a time).
        None: ``parts`` against each other (``same``), ``n (n - 1)`` ordered pairs, the
        diagonal 0 with a covered fraction and an area ratio of 1. A whole that is a point
        cloud is left out: its column is NaN (a GromovWarning says so).
    metric, n_samples, seed, resolution, metric_options
        As :func:`match_partial` (a ShapeMetric must be in ``metric``).
    names : list of str, optional
        The wholes' names, or with ``wholes=None`` the shapes' (default: the paths, else
        ``"whole j"`` / ``"shape i"``), in the warnings and :attr:`PartialMatrix.wholes`.
    progress : bool, default False
        A progress bar (tqdm) on stderr.
    **match_options
        Passed to :func:`match_partial` (``search``, ``boundary``...; not ``dense``);
        ``bridge`` defaults to :data:`PARTIAL_RANK_BRIDGE` here.

    Returns
    -------
    PartialMatrix

    Examples
    --------
    >>> m = partial_matrix(["cat0_part.off", "dog3_part.off"], ["cat1.off", "dog4.off"])  # doctest: +SKIP
    >>> m.nearest, m.covered_fraction                                                    # doctest: +SKIP
    """
    from tqdm import tqdm

    t0 = time.perf_counter()
    if "dense" in match_options:
        raise ValueError("partial_matrix keeps no maps: dense is not taken")
    match_options = {"bridge": PARTIAL_RANK_BRIDGE, **match_options}
    same = wholes is None
    parts = list(parts)
    wholes = parts if same else list(wholes)
    if len(parts) < (2 if same else 1) or not wholes:
        raise ValueError(f"partial_matrix needs a part and a whole (two shapes without wholes), got "
                         f"{len(parts)} part(s) and {0 if same else len(wholes)} whole(s)")
    options = correspondence_options(metric, metric_options)
    if same:
        names_p = names_w = _names(parts, "shape")
    else:
        names_p, names_w = _names(parts, "part"), _names(wholes, "whole")
    if names is not None:
        if len(names) != len(wholes):
            what = "shape" if same else "whole"
            raise ValueError(f"names needs one name per {what} ({len(wholes)}), got {len(names)}")
        names_w = [str(x) for x in names]
        names_p = names_w if same else names_p
    sp = [_prepare(s, metric, resolution, options, n) for s, n in zip(parts, names_p)]
    shape = (len(parts), len(wholes))
    dist, rel, rank, cover, ratio = (np.full(shape, np.nan) for _ in range(5))
    if same:
        for a in (dist, rel, rank):
            np.fill_diagonal(a, 0.0)
        for a in (cover, ratio):
            np.fill_diagonal(a, 1.0)
    small, clouds = [], []
    n_pairs = shape[0] * shape[1] - (shape[0] if same else 0)
    with tqdm(total=n_pairs, desc=f"{metric} partial matches", disable=not progress, leave=False) as bar:
        for j in range(shape[1]):   # one whole at a time: a whole given by a function is let go after its column
            if same:
                whole = sp[j]
            else:
                w = wholes[j]() if callable(wholes[j]) else wholes[j]
                whole = _prepare(w, metric, resolution, options, names_w[j])
            if not whole.has_faces:   # (a part that is one is refused by match_partial)
                clouds.append(names_w[j])
                bar.update(shape[0] - (1 if same else 0))
                continue
            for i in range(shape[0]):
                if same and i == j:
                    continue
                if sp[i].has_faces:
                    ratio[i, j] = area_ratio(sp[i], whole)
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    try:
                        r = match_partial(sp[i], whole, metric, n_samples=n_samples, seed=seed, **match_options)
                    except ValueError as exc:   # say which pair
                        exc.args = (f"{names_p[i]} as a part of {names_w[j]}: {exc}",) + exc.args[1:]
                        raise
                for w in caught:   # the small parts said once, below; the others passed on
                    if issubclass(w.category, SmallPartWarning):
                        small.append((i, j))
                    else:
                        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
                dist[i, j], rel[i, j], cover[i, j] = r.distance, r.relative_distance, r.covered_fraction
                rank[i, j] = r.ranking_distance
                logger.info("%s as a part of %s: %.6g (covers %.1f%%)", names_p[i], names_w[j], r.distance,
                            100 * r.covered_fraction)
                bar.update(1)
            del whole
    if clouds:
        warnings.warn(f"{len(clouds)} whole(s) left out (NaN): partial matching needs triangle meshes, and "
                      f"{', '.join(clouds[:5])}{' ...' if len(clouds) > 5 else ''} are point clouds", GromovWarning,
                      stacklevel=2)
    if small:
        listed = "; ".join(f"{names_p[i]} in {names_w[j]} ({ratio[i, j]:.1%})" for i, j in small[:5])
        more = f" and {len(small) - 5} more" if len(small) > 5 else ""
        warnings.warn(f"{len(small)} of {n_pairs} pairs: the part keeps less than {SMALL_PART:.0%} of the "
                      f"whole's area, where its placement is unreliable: {listed}{more}", SmallPartWarning,
                      stacklevel=2)
    return PartialMatrix(dist, rel, cover, ratio, same, names_p, names_w, metric, int(n_samples),
                         time.perf_counter() - t0, rank)


def curvature_costs(sx: ShapeMetric, sy: ShapeMetric, P: np.ndarray, weight: float,
                    hx: np.ndarray | None = None) -> np.ndarray:
    r"""``(len(P), n_Y)``: :math:`\lambda^2 \, \text{area}(Y) \, (H_X(p_i) - H_Y(v))^2`, the cost of
    placing the part's sample ``P[i]`` at the whole's working vertex ``v`` for the mismatch of
    their smoothed, scale-free mean curvatures (:func:`part_curvature`, ``sy.curvature``), in
    squared distance units; ``weight`` :math:`\lambda`; ``hx`` the part's at ``P``, if computed."""
    if hx is None:
        hx = part_curvature(sx, sy)[np.asarray(P, dtype=np.int64)]
    hy = sy.curvature
    return (float(weight) ** 2 * sy.mesh.area) * (hx[:, None] - hy[None, :]) ** 2


def _search_and_refine(sx, sy, P, dx_pp, W, search: SearchOptions, n_refine: int, n_interior: int,
                       turn: bool = True, more_starts: bool = True, curvature: float = 0.0, hx=None):
    """The initial search in one direction, then one-sided GMDS from its ``n_refine`` best
    starts: the lowest final objective (the weighted stress plus, with ``curvature`` > 0, each
    sample's curvature cost (:func:`curvature_costs`) times its total weight; the coarse
    stages take the same costs as their signatures). When that map is mirrored (orientation agreement at
    most 1/2), GMDS also from the best orientation-preserving starts and from the mirrored map
    composed with Y's reflection (:meth:`ShapeMetric.symmetry`), and a direct map within
    ``ORIENTATION_TOL`` (``FLIP_TOL`` for the composition) of its distortion replaces it.
    ``hx``: the part's smoothed curvature at ``P``, if computed. Returns ``(images, n_iter,
    converged, history, orientation agreement)``."""
    from .orientation import orientation_agreements

    # once: the half-turn rule reads it too
    hx = (part_curvature(sx, sy)[P] if hx is None else hx) if curvature > 0 else None
    unary = curvature_costs(sx, sy, P, curvature, hx) if curvature > 0 else None
    fwd, n_in, complete = _search(sx, sy, P, dx_pp, search, n_interior, unary)
    DY = sy.distances
    oriented = bool(sx.normals[1] and sy.normals[1])
    (nx, _), (ny, _) = sx.normals, sy.normals
    row_w, rows = W.sum(axis=1), np.arange(len(P))

    def bent(img):   # the curvature term of a map given by its vertex images
        return 0.0 if unary is None else float(np.sum(row_w * unary[rows, img]))

    def score(img):
        return float(np.sum(W * (dx_pp - DY[np.ix_(img, img)]) ** 2)) + bent(img)

    def refine(starts):
        fits = []
        for start in starts:
            img, n_iter, converged, history = _one_sided_gmds(sy, dx_pp, W, SurfacePoints.at_vertices(sy.mesh, start),
                                                              search.max_iter, search.tol)
            o = float("nan")
            if oriented:
                pos = img.positions(sy.mesh.vertices, sy.mesh.faces)
                nrm = np.einsum("kc,kcd->kd", img.bary, ny[sy.mesh.faces[img.face]])
                o = float(orientation_agreements(sx.mesh.vertices[P], nx[P], dx_pp, pos[None], nrm[None])[0])
            fits.append((history[-1] + bent(img.vertex(sy.mesh.faces)), img, n_iter, converged, history, o))
        return fits

    starts_all = [complete(img) for img, _ in fwd.extend_plain(polish_all=True)[0]]
    if oriented and more_starts:   # and more orientation-preserving ones, half as many per stage
        starts_all += [complete(img) for img, _ in fwd.extend_preserving(
            _orient(sx, sy, P[:n_in], dx_pp[:n_in, :n_in]), -(-fwd.per_stage // 2))]
    starts = sorted(starts_all, key=score)[:max(1, int(n_refine))]
    fits = refine(starts)
    best = min(fits, key=lambda f: f[0])
    if oriented and not best[5] > 0.5:
        # a mirrored map: GMDS from the best orientation-preserving starts too
        more = [complete(img) for img, _ in
                fwd.extend_preserving(_orient(sx, sy, P[:n_in], dx_pp[:n_in, :n_in]), fwd.per_stage)]
        fits += refine(sorted(more, key=score)[:max(1, int(n_refine))])
        tol = [ORIENTATION_TOL] * len(fits)
        # and from the mirrored map composed with the whole's reflection (:meth:`ShapeMetric.symmetry`)
        sym = sy.symmetry(len(P), 0)
        if sym is not None:
            fits += refine([sym[best[1].vertex(sy.mesh.faces)]])
            tol.append(FLIP_TOL)
        direct = [f for f, t in zip(fits, tol) if f[5] > 0.5 and f[0] <= (1.0 + t) ** 2 * best[0]]
        if direct:
            best = min(direct, key=lambda f: f[0])
    if oriented and best[5] > 0.5 and turn:
        best = _prefer_curvature(sx, sy, P, starts_all, score, refine, best, hx, dx_pp)
    logger.debug("partial fits: %s", [(f[0], f[5]) for f in fits])
    return best[1], best[2], best[3], best[4], best[5]


def part_curvature(sx: ShapeMetric, sy: ShapeMetric) -> np.ndarray:
    """The smoothed mean curvature of the part ``sx`` in the whole's units: smoothed for the same
    time and scaled by the same sqrt(area) as ``sy.curvature`` (:func:`gromov.curvature.mean_curvature`
    measures each shape in its own area)."""
    from .curvature import CURVATURE_SCALE, mean_curvature

    ratio = sy.mesh.area / sx.mesh.area
    return mean_curvature(sx.mesh, sx.normals[0], scale=CURVATURE_SCALE * ratio) * np.sqrt(ratio)


def _prefer_curvature(sx, sy, P, starts, score, refine, best, hx=None, dx_pp=None):
    """A direct map against its half turn (:func:`gromov.gh._prefer_curvature` for one side):
    among the clearly direct starts (agreement above 1/2 + ``DIRECT_MARGIN``) within
    ``TURN_TOL`` of the best start's distortion, the one whose images keep the curvature best;
    GMDS from it, kept when still clearly direct, within ``TURN_TOL`` of the map's distortion
    and better by ``TURN_MARGIN`` in curvature mismatch (the median over the part's samples)."""
    hx = part_curvature(sx, sy)[P] if hx is None else hx
    hy, faces = sy.curvature, sy.mesh.faces

    def mismatch(images):
        return float(np.median(np.abs(hx - hy[images])))

    m_best = mismatch(best[1].vertex(faces))
    s0 = min(score(img) for img in starts)
    dx_pp = sx.distances[np.ix_(P, P)] if dx_pp is None else dx_pp
    agree = _orient(sx, sy, P, dx_pp)(np.stack(starts))
    near = [img for img, a in zip(starts, agree) if a > 0.5 + DIRECT_MARGIN and score(img) <= (1 + TURN_TOL) ** 2 * s0]
    logger.debug("partial: curvature mismatch %.3g, %d direct starts near (agreements %s, scores %s of %.3g)",
                 m_best, len(near), np.round(agree, 2), [round(score(i) / s0, 2) for i in starts], s0)
    if not near:
        return best
    cand = min(near, key=mismatch)
    logger.debug("partial: the best of them %.3g", mismatch(cand))
    if not mismatch(cand) < (1.0 - TURN_MARGIN) * m_best:
        return best
    alt = refine([cand])[0]
    if (alt[5] > 0.5 + DIRECT_MARGIN and alt[0] <= (1 + TURN_TOL) ** 2 * best[0]
            and mismatch(alt[1].vertex(faces)) < (1.0 - TURN_MARGIN) * m_best):
        logger.debug("partial: a half turn replaced (curvature mismatch %.3g -> %.3g)", m_best,
                     mismatch(alt[1].vertex(faces)))
        return alt
    return best


def _search(sx, sy, P, dx_pp, search: SearchOptions, n_interior: int, unary=None):
    """The initial search of :func:`gromov.match` in one direction (X's samples into Y) on the
    interior samples (weight at least 1/2; P lists them first): ``(search, their number, a
    function completing a start)`` -- the other samples placed where their distances to those
    fit best (:func:`gromov.search.anchored_images`). ``unary`` (samples x Y's vertices, the
    curvature costs) replaces the distance signatures of the signature-guided stages (a part
    does not share the whole's distance distributions), from every candidate rather than the
    ``SIGNATURE_STARTS`` whose distance signatures match best."""
    n_in = max(int(n_interior), min(len(P), max(c for c, _ in search.coarse_stages)))
    head = np.ascontiguousarray(dx_pp[:n_in, :n_in])
    cand = _candidates(sx.descriptors[P[0]], sy, search.n_starts)
    stages = search.coarse_stages
    if search.search_vertices is not None:
        st, dom = [(c, None) for c, _ in stages], sy.subset(search.search_vertices)
    else:
        st, dom = [(c, None if k is None else sy.subset(k)) for c, k in stages], None
    sig = None
    if unary is not None:
        sig = unary[:max(c for c, _ in stages)]
    elif search.signature_weight > 0:
        c = max(c for c, _ in stages)
        sig = search.signature_weight * signature_mismatch(sx, sy, P[:c])
    # with the curvature costs every candidate gets the signed run: the candidates are ordered by
    # the distance signatures, which say little of where a part's first sample lies
    fwd = _Search(head, sy.distances, cand, st, search.n_extend, dom, search.extend_keep, sig,
                  len(cand) if unary is not None else SIGNATURE_STARTS)
    DY = sy.distances

    def complete(img):
        img = np.asarray(img, dtype=np.int64)
        if n_in < len(P):
            img = np.concatenate([img, anchored_images(DY, img, dx_pp[n_in:, :n_in])])
        return img

    return fwd, n_in, complete


def _placed(sx, sy, P, img: SurfacePoints, wp: np.ndarray, k: int, ax_all: np.ndarray | None = None) -> np.ndarray:
    """Working vertex of Y for every working vertex of X, placed from the samples and their
    images (:func:`gromov.dense.local_anchored_map`, or :func:`gromov.dense.anchored_map` with ``k = 0``),
    the samples in the boundary band left out; ``ax_all``: X's distances to all samples
    ``(n, len(P))``, if not the metric's own (:func:`bridged_distances`)."""
    from .dense import anchored_map, landmark_distances

    keep = wp >= 0.5 if (wp >= 0.5).sum() >= 3 else np.ones(len(P), dtype=bool)
    ax = landmark_distances(sx, P[keep]) if ax_all is None else ax_all[:, keep]
    ay = landmark_distances(sy, SurfacePoints(img.face[keep], img.bary[keep]))
    return local_anchored_map(ax, ay, k) if k else anchored_map(ax, ay)


def _covered_back(sx, sy, T, covered_w, covered):
    """The dense map back from Y's covered input vertices to X: the input vertex of X at the
    working vertex whose image is nearest (Y's metric); -1 / NaN outside the region."""
    from .dense import DenseMap
    from .dense import _at_vertices as faces_at

    near = sy.working.source_nearest   # each input vertex's nearest working vertex
    want = covered_w.copy()
    want[near[covered]] = True
    cov = np.flatnonzero(want)
    u = np.full(sy.mesh.n_vertices, -1, dtype=np.int64)
    if len(cov):
        u[cov] = np.argmin(sy.distances[np.ix_(cov, T)], axis=1)
    uu = u[near]
    ok = covered & (uu >= 0)
    n = sy.input.n_vertices
    face, bary, vertex = np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan), np.full(n, -1, dtype=np.int64)
    v = sx.working.to_source(uu[ok])
    face[ok], bary[ok] = faces_at(sx.input, v)
    vertex[ok] = sx.input.input_ids[v]
    return DenseMap(*(sy.input.per_file_vertex(a, fill=f) for a, f in ((face, -1), (bary, np.nan), (vertex, -1))))


def _back_images(sx, sy, Q, T, inside, q_images: SurfacePoints | None = None):
    """``(face, bary, vertex)`` on X's input of Y's samples ``inside`` the covered region:
    ``q_images`` (on X's working mesh) where given, else the working vertex of X whose image
    is nearest (Y's metric); -1 / NaN outside it."""
    n = len(Q)
    face, bary, vertex = np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan), np.full(n, -1, dtype=np.int64)
    if inside.any():
        if q_images is None:
            near = np.argmin(sy.distances[np.ix_(Q[inside], T)], axis=1)
            f, bb, v = sx.locate(SurfacePoints.at_vertices(sx.mesh, near))
        else:
            f, bb, v = sx.locate(SurfacePoints(q_images.face[inside], q_images.bary[inside]))
        face[inside], bary[inside], vertex[inside] = f, bb, v
    return face, bary, vertex


def whole_shape(mesh: Mesh) -> bool:
    r"""Whether a "part" is a whole shape: closed, or with only holes the mesh does not resolve
    (every boundary loop shorter than :math:`2\pi` ``HOLE_RADIUS`` mean edge lengths, a hole at
    most about one edge in radius, the covered region's own reach around an image). A closed surface is no
    proper part of a connected one, so nothing of it is missing."""
    loops = mesh.boundary_loops
    if not len(loops):
        return True
    V, limit = mesh.vertices, 2.0 * np.pi * HOLE_RADIUS * mesh.mean_edge_length
    return all(np.linalg.norm(V[loop] - V[np.roll(loop, 1)], axis=1).sum() < limit for loop in loops)


def _as_whole(sx, sy, n_samples, seed, search, dense, n_local, metric, t0) -> MatchResult:
    """A whole shape matched with ``partial=True``: the correspondence and distance of
    :func:`gromov.match` (two-sided, :func:`gromov.gh.two_sided_fit`), with the partial
    result's covered region and dense map."""
    from .gh import pair_residuals, two_sided_fit

    P, Q, gm, fit = two_sided_fit(sx, sy, n_samples, seed, search=search)
    residual, r = pair_residuals(*gm.blocks(fit.img_p, fit.img_q))
    wp = np.ones(len(P))
    T = _placed(sx, sy, P, fit.img_p, wp, n_local)
    return _result(sx, sy, P, Q, fit.img_p, wp, T, fit.img_q, residual, norm_value(r, 2.0), r, dense, metric,
                   t0, n_iter=int(fit.n_iter), converged=bool(fit.converged), history=np.asarray(fit.history),
                   orientation=fit.orientation, diameter=max(sx.diameter, sy.diameter))
