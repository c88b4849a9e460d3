"""Topological noise -- welds (self-contacts glued together) and holes -- and parts (cuts).

Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework with
diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010),
§5 and Fig. 2, test matching under *topological noise*: the same shape with parts glued
where they touch in space (a hand on a thigh, the two legs, a tail against the body) and
with holes punched in the surface. Geodesic distances change drastically under both --
a weld is a shortcut, a hole a detour -- while diffusion distances, which average over
all paths, change little. This module makes such shapes with a known ground truth:

- :func:`weld` glues ``count`` places where two parts of the surface are close in space
  but far apart along the surface (real self-contacts of the kind that SHREC'16
  "Topological KIDS" shapes have merged into handles);
- :func:`holes` removes ``count`` geodesic disks.

:func:`cut` makes a *part* instead, as SHREC'16 Partial Matching of Deformable Shapes did: one
side of a plane, or the surface outside large patches, holding a stated fraction of the area.

All three return a :class:`Perturbation` whose ``vertex_map`` gives, for every output vertex,
its vertex in the input mesh, and whose output ``mesh.input_ids`` equal
``input.input_ids[vertex_map]`` (the file ids survive). Output vertices keep their input
coordinates exactly, so Euclidean distances between surviving vertices are unchanged.

Distances used to *choose* sites (geodesic separation, hole disks, the diameter) are
shortest paths along mesh edges (Dijkstra), which overestimate surface distances by a few
percent; that is enough to pick sites and keeps this module independent of the fast
marching backend.
"""

from __future__ import annotations

import logging
import numbers
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.sparse.csgraph import dijkstra

from .mesh import Mesh
from .metrics._fmm import _FROZEN, _UNSEEN, _pop, _sift_up

__all__ = ["Perturbation", "weld", "holes", "cut", "WELD_JOINS", "WELD_RESOLUTION", "CUT_KINDS",
           "CUT_PATCHES"]

logger = logging.getLogger(__name__)

from ._defaults import CUT_KINDS, CUT_PATCHES, WELD_JOINS  # noqa: E402
#: :func:`weld` searches its sites on a copy of at most this many vertices: the candidate
#: pairs of a 28k-vertex TOSCA cat at 5 edge lengths take minutes and gigabytes on the mesh
#: itself, about a second on the copy (docs/design/perturbations.md).
WELD_RESOLUTION = 3000
#: :func:`weld`'s default radius: this many mean edge lengths, grown by the factor up to
#: ``WELD_RADIUS_TRIES`` times while too few sites are found.
WELD_RADIUS_EDGES, WELD_RADIUS_GROWTH, WELD_RADIUS_TRIES = 5.0, 1.5, 4


@dataclass(frozen=True, eq=False)
class Perturbation:
    """A mesh with topological noise, or a part of it, and the ground truth back to the input.

    Attributes
    ----------
    mesh : Mesh
        The perturbed mesh. ``mesh.input_ids == input.input_ids[vertex_map]``.
    vertex_map : ndarray of int64, shape (n_out,)
        Index in the input mesh of each output vertex (ground-truth correspondence).
        Output vertex ``i`` has exactly the coordinates of input vertex ``vertex_map[i]``.
    kind : str
        ``"weld"``, ``"holes"`` or ``"cut"`` (its own kind, plane or holes, in ``params``).
    euler_before, euler_after : int
        Euler characteristic ``V - E + F`` of the input and of the output.
    boundary_loops_before, boundary_loops_after : int
        Number of boundary loops of the input and of the output.
    sites : ndarray of int64
        Where the noise was put, as vertex indices of the *input* mesh (like
        ``vertex_map``; the file ids are ``input.input_ids[sites]``).
        ``weld``: ``(K, 2)`` welded vertex pairs ``(u, v)``; ``holes``: ``(K,)`` hole centres;
        ``cut``: the patches' centres ``(K,)``, or ``(0,)`` for a plane.
    params : dict
        The parameters used, defaults resolved (``count``, ``radius``, ``seed``, ...), and
        derived quantities: for welds ``diameter`` (edge-graph), ``min_geodesic``,
        ``n_candidates`` and ``gaps`` (Euclidean length of each weld); for holes
        ``min_separation`` and ``dropped_vertices`` (slivers cut off and dropped); for a cut
        ``kept`` (the part's fraction of the area) and the plane or the patches (:func:`cut`).
    """

    mesh: Mesh
    vertex_map: np.ndarray
    kind: str
    euler_before: int
    euler_after: int
    boundary_loops_before: int
    boundary_loops_after: int
    sites: np.ndarray
    params: dict

    def __repr__(self) -> str:
        return (f"Perturbation(kind={self.kind!r}, sites={len(self.sites)}, "
                f"n_vertices={self.mesh.n_vertices}, euler={self.euler_before}->{self.euler_after}, "
                f"boundary_loops={self.boundary_loops_before}->{self.boundary_loops_after})")


# ---------------------------------------------------------------------------- validation
def _check_mesh(mesh) -> Mesh:
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh must be a gromov.Mesh, got {type(mesh).__name__}")
    return mesh


def _check_count(count) -> int:
    if isinstance(count, (bool, np.bool_)) or not isinstance(count, numbers.Integral) or count < 1:
        raise ValueError(f"count must be a positive integer, got {count!r}")
    return int(count)


def _check_positive(value, name: str, *, minimum: float = 0.0, strict: bool = True) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    x = float(value)
    ok = (x > minimum if strict else x >= minimum) and np.isfinite(x)
    if not ok:
        rel = ">" if strict else ">="
        raise ValueError(f"{name} must be a finite number {rel} {minimum:g}, got {value!r}")
    return x


# ---------------------------------------------------------------------------- helpers
def _diameter(mesh: Mesh) -> float:
    """Graph-geodesic diameter estimate of the largest component (double sweep).

    Dijkstra from a vertex, then again from the farthest vertex found; the largest finite
    distance of the second sweep. A lower bound of the edge-graph diameter, exact on most
    shapes (always within a factor 2).
    """
    ref = mesh.referenced
    labels = mesh.component_labels
    sizes = np.bincount(labels[ref], minlength=mesh.n_components)
    start = int(np.flatnonzero(ref & (labels == int(np.argmax(sizes))))[0])
    d = dijkstra(mesh.adjacency, directed=False, indices=start)
    d[~np.isfinite(d)] = -1.0
    far = int(np.argmax(d))
    d = dijkstra(mesh.adjacency, directed=False, indices=far)
    return float(d[np.isfinite(d)].max())


def _edge_keys(faces: np.ndarray, n: int) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    return e[:, 0] * n + e[:, 1]


def _boundary_valence(faces: np.ndarray, n: int) -> np.ndarray:
    """Number of boundary edges (one incident face) at each vertex."""
    if len(faces) == 0:
        return np.zeros(n, np.int64)
    keys, counts = np.unique(_edge_keys(faces, n), return_counts=True)
    b = keys[counts == 1]
    return np.bincount(np.concatenate([b // n, b % n]), minlength=n)


def _rng(seed) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def _seed_param(seed):
    """The seed as recorded in ``params`` (``None`` for a Generator, whose state is not kept)."""
    return None if isinstance(seed, np.random.Generator) else seed


def _result(mesh: Mesh, out: Mesh, keep_ids: np.ndarray, kind: str, sites, params) -> Perturbation:
    return Perturbation(
        mesh=out, vertex_map=np.asarray(keep_ids, dtype=np.int64), kind=kind,
        euler_before=mesh.euler_characteristic, euler_after=out.euler_characteristic,
        boundary_loops_before=len(mesh.boundary_loops), boundary_loops_after=len(out.boundary_loops),
        sites=np.asarray(sites, dtype=np.int64), params=params)


# ---------------------------------------------------------------------------- weld
def _star_cycle(mesh: Mesh, u: int) -> np.ndarray | None:
    """Link of ``u`` as a cycle in the orientation of its faces, or None when ``u`` has no disk star.

    Face ``(u, a, b)`` (rotated so ``u`` comes first) contributes the link edge ``a -> b``;
    an interior vertex with a consistently oriented disk neighbourhood has a single cycle.
    """
    indptr, fids = mesh.vertex_faces
    star = mesh.faces[fids[indptr[u]:indptr[u + 1]]]
    if len(star) < 3:
        return None
    pos = np.argmax(star == u, axis=1)
    a = star[np.arange(len(star)), (pos + 1) % 3]
    b = star[np.arange(len(star)), (pos + 2) % 3]
    if len(np.unique(a)) != len(a) or len(np.unique(b)) != len(b) or set(a.tolist()) != set(b.tolist()):
        return None
    nxt = dict(zip(a.tolist(), b.tolist()))
    cyc = [int(a[0])]
    while len(cyc) <= len(a):
        w = nxt[cyc[-1]]
        if w == cyc[0]:
            break
        cyc.append(w)
    if len(cyc) != len(a):
        return None
    return np.asarray(cyc, dtype=np.int64)


@njit(cache=True)
def _farther_than(indptr, indices, weights, sources, targets, thresholds, start, far):
    """``far[i] = d(sources[k], targets[i]) > thresholds[i]`` for ``i`` in
    ``start[k]:start[k + 1]`` (the pairs of source ``k``), ``d`` the shortest path along the
    weighted graph ``(indptr, indices, weights)`` (CSR, symmetric).

    One Dijkstra per source (the fast marching's heap with decrease-key), stopped once the
    smallest tentative distance exceeds the largest threshold of the pairs whose target is not
    settled yet (those are then farther than their thresholds); a distance is the same sum of
    edge weights as :func:`scipy.sparse.csgraph.dijkstra`'s.
    """
    n = indptr.shape[0] - 1
    dist = np.full(n, np.inf)
    pos = np.full(n, _UNSEEN, np.int64)   # heap slot, _UNSEEN or _FROZEN (settled)
    hk = np.empty(n)
    hv = np.empty(n, np.int64)
    touched = np.empty(n, np.int64)
    wanted = np.zeros(n, np.bool_)      # targets of the current source
    for k in range(sources.shape[0]):
        lo, hi = start[k], start[k + 1]
        for i in range(lo, hi):
            wanted[targets[i]] = True
        by = lo + np.argsort(-thresholds[lo:hi])   # the pairs by decreasing threshold
        first = 0                       # (in by) the largest threshold not settled yet
        m = hi - lo
        s = sources[k]
        dist[s] = 0.0
        _sift_up(hk, hv, pos, 0, 0.0, s)
        size = 1
        nt = 1
        touched[0] = s
        while size > 0 and first < m:
            u = hv[0]
            du = hk[0]
            if du > thresholds[by[first]]:
                break
            size = _pop(hk, hv, pos, size)
            if wanted[u]:
                while first < m and pos[targets[by[first]]] == _FROZEN:
                    first += 1
            for e in range(indptr[u], indptr[u + 1]):
                v = indices[e]
                dv = du + weights[e]
                if pos[v] == _FROZEN or not dv < dist[v]:
                    continue
                dist[v] = dv
                if pos[v] == _UNSEEN:
                    touched[nt] = v
                    nt += 1
                    _sift_up(hk, hv, pos, size, dv, v)
                    size += 1
                else:
                    _sift_up(hk, hv, pos, pos[v], dv, v)
        for i in range(lo, hi):
            t = targets[i]
            far[i] = not (pos[t] == _FROZEN and dist[t] <= thresholds[i])
            wanted[t] = False
        for q in range(nt):
            dist[touched[q]] = np.inf
            pos[touched[q]] = _UNSEEN


def _far_pairs(mesh: Mesh, pairs: np.ndarray, threshold: np.ndarray) -> np.ndarray:
    """Mask of pairs whose edge-graph distance exceeds their ``threshold``.

    One bounded Dijkstra per distinct first vertex (:func:`_farther_than`), stopped at the
    largest threshold of its partners not reached yet.
    """
    far = np.zeros(len(pairs), bool)
    if len(pairs) == 0:
        return far
    order = np.argsort(pairs[:, 0], kind="stable")
    first = pairs[order, 0]
    sources, start = np.unique(first, return_index=True)
    start = np.append(start, len(first)).astype(np.int64)
    A = mesh.adjacency
    out = np.empty(len(pairs), np.bool_)
    _farther_than(A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data.astype(np.float64),
                  sources.astype(np.int64), np.ascontiguousarray(pairs[order, 1], dtype=np.int64),
                  np.ascontiguousarray(threshold[order], dtype=np.float64), start, out)
    far[order] = out
    return far


def _bridge(p: np.ndarray, q: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Triangulate the band between the link cycles ``p`` (of u) and ``q`` (of v): a tube.

    ``p`` is u's link in its star's orientation and ``q`` v's link reversed; each band
    triangle then uses a link edge opposite to the face that keeps it, so an oriented mesh
    stays oriented (for two facing sheets both cycles turn the same way around the axis
    ``u -> v``). The band's first edge joins the closest pair of link vertices; from there
    the cycles are zipped by normalised arc length -- every step adds the triangle whose
    new corner comes first along its cycle -- which interleaves them evenly even when
    the rings differ in size.
    """
    d = np.linalg.norm(X[p][:, None] - X[q][None], axis=-1)
    i0, j0 = np.unravel_index(int(np.argmin(d)), d.shape)
    p, q = np.roll(p, -int(i0)), np.roll(q, -int(j0))

    def arc(c):
        seg = np.linalg.norm(X[np.roll(c, -1)] - X[c], axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        return s / s[-1]

    sp, sq = arc(p), arc(q)
    n_p, n_q = len(p), len(q)
    tris = []
    i = j = 0
    while i < n_p or j < n_q:
        if j == n_q or (i < n_p and sp[i + 1] <= sq[j + 1]):
            tris.append((p[i], p[(i + 1) % n_p], q[j % n_q]))
            i += 1
        else:
            tris.append((q[(j + 1) % n_q], q[j], p[i % n_p]))
            j += 1
    return np.asarray(tris, dtype=np.int64)


def weld(mesh: Mesh, count: int, *, radius: float | None = None, seed=0,
         min_geodesic_ratio: float = 4.0, min_geodesic_fraction: float = 0.1,
         separation: float | None = None, join: str = "tube",
         resolution: int | None = WELD_RESOLUTION) -> Perturbation:
    """Glue the surface to itself at ``count`` places where two parts nearly touch.

    Point-wise topology changes of Bronstein et al. (IJCV 2010, §5, Fig. 2): where two
    parts of the shape come close in space (legs side by side, an ear against the head)
    they are welded together, so the geodesic distance across the contact collapses from
    "around the body" to the width of the gap.

    **Candidates.** Vertex pairs ``(u, v)`` with

    .. math::

        \\|x_u - x_v\\| \\le r, \\qquad
        d_G(u, v) > \\max\\big(\\rho\\,\\|x_u - x_v\\|,\\; \\phi\\,\\mathrm{diam}\\big),

    ``r = radius``, ``rho = min_geodesic_ratio``, ``phi = min_geodesic_fraction`` and
    ``d_G`` the shortest path along edges (pairs on different components qualify, their
    ``d_G`` is infinite). Both vertices must be interior with an oriented disk star, and at
    least four edges apart, so that their two 1-rings are disjoint and not adjacent.

    **Sites.** Candidates are drawn in a random order (from ``seed``); one becomes a site
    when both its vertices are at least ``separation`` (edge-graph distance) from the
    vertices welded so far and the 1-rings of different sites do not touch.

    **Gluing** (``join``):

    ``"tube"`` (default)
        Remove ``u``, ``v`` and their 1-ring faces, and connect the two link polygons by a
        band of triangles: a short tube (a *handle*), like the merged self-contacts of
        SHREC'16 "Topological KIDS". The mesh stays edge- and vertex-manifold and oriented
        as it was. Each weld lowers the Euler characteristic by 2 (the genus of a connected
        surface grows by 1; welding two components instead joins them); boundary loops are
        unchanged. The geodesic distance between the two 1-rings becomes the Euclidean
        distance between them (the band's first edge joins their closest vertices), about
        ``||x_u - x_v||``.
    ``"pinch"``
        Identify ``v`` with ``u`` (``v`` is replaced by ``u`` in all faces; the faces
        around ``v`` stretch to ``x_u``). ``d_G(u, v)`` becomes exactly 0, and ``u``
        becomes a non-manifold (pinch) vertex joining two disks. Each weld lowers the Euler
        characteristic by 1; boundary loops are unchanged. Non-manifold vertices can trouble
        methods that assume a manifold (the heat method, some FMM codes).

    Parameters
    ----------
    mesh : Mesh
    count : int
        Number of welds, ``>= 1``.
    radius : float, optional
        Euclidean search radius ``r``. Default: :data:`WELD_RADIUS_EDGES` (5) mean edge
        lengths of the mesh the sites are searched on -- surfaces that touch at its
        resolution -- grown :data:`WELD_RADIUS_GROWTH` (1.5) times at a time, up to
        :data:`WELD_RADIUS_TRIES` (4) times, until ``count`` sites are found (``params``
        records the radius used).
    seed : int, Generator or None, default 0
        Order in which candidates are drawn.
    min_geodesic_ratio : float, default 4.0
        ``rho >= 1``: the surface path must be this many times longer than the gap.
    min_geodesic_fraction : float, default 0.1
        ``phi``: and longer than this fraction of the (edge-graph) geodesic diameter.
    separation : float, optional
        Minimum edge-graph distance between the vertices of different sites. Default
        ``radius / 2``.
    join : {"tube", "pinch"}, default "tube"
    resolution : int or None, default WELD_RESOLUTION
        On a mesh of more vertices, the sites are searched on a copy simplified to this many
        vertices (:func:`gromov.resolution.simplify`, which keeps a subset of the vertices:
        each site is a pair of the mesh's own vertices), and glued on the mesh itself. The
        distances that choose the sites (``radius``, ``separation``, the geodesic test) are
        then measured on that copy. ``None``: search the mesh itself.

    Returns
    -------
    Perturbation
        ``kind="weld"``, ``sites`` ``(count, 2)``: the welded pairs ``(u, v)`` (input
        indices). With ``"tube"`` both ``u`` and ``v`` are removed (they are not in
        ``vertex_map``); with ``"pinch"`` ``v`` is removed and ``u`` kept.

    Raises
    ------
    ValueError
        When fewer than ``count`` separated sites exist (the message says how many were
        found), or for an invalid parameter.
    TypeError
        When ``mesh`` is not a :class:`~gromov.Mesh`.

    Examples
    --------
    >>> p = weld(mesh, 4, seed=0)                                   # doctest: +SKIP
    >>> p.euler_after == p.euler_before - 2 * 4                     # doctest: +SKIP
    True
    """
    mesh = _check_mesh(mesh)
    count = _check_count(count)
    if join not in WELD_JOINS:
        raise ValueError(f"join must be one of {WELD_JOINS}, got {join!r}")
    given = None if radius is None else _check_positive(radius, "radius")
    ratio = _check_positive(min_geodesic_ratio, "min_geodesic_ratio", minimum=1.0, strict=False)
    frac = _check_positive(min_geodesic_fraction, "min_geodesic_fraction", strict=False)
    sep_given = None if separation is None else _check_positive(separation, "separation", strict=False)
    if resolution is not None:
        resolution = _check_count(resolution)

    search, ids = mesh, np.arange(mesh.n_vertices)
    if resolution is not None and mesh.n_vertices > resolution:
        from .resolution import simplify

        work = simplify(mesh, resolution)
        search, ids = work.mesh, work.vertex_ids
    edge = search.mean_edge_length
    radii = ([given] if given is not None else
             [WELD_RADIUS_EDGES * edge * WELD_RADIUS_GROWTH ** i for i in range(WELD_RADIUS_TRIES + 1)])
    diam = _diameter(search)
    g_min = frac * diam

    # a site needs both ends interior with a disk star, 1-rings disjoint and not adjacent, on
    # the mesh that is glued (checked lazily, only for the pairs drawn)
    A = mesh.adjacency
    cycles: dict[int, np.ndarray | None] = {}

    def cycle(w: int) -> np.ndarray | None:
        if w not in cycles:
            cycles[w] = _star_cycle(mesh, w)
        return cycles[w]

    def usable(u: int, v: int) -> bool:
        u, v = int(ids[u]), int(ids[v])
        cu, cv = cycle(u), cycle(v)
        if cu is None or cv is None:
            return False
        ru, rv = np.append(cu, u), np.append(cv, v)
        return not np.intersect1d(ru, rv).size and A[ru][:, rv].nnz == 0

    rng = _rng(seed)
    for r in radii:
        sep = r / 2 if sep_given is None else sep_given
        sites, n_candidates = _weld_sites(search, count, r, ratio, g_min, sep, rng, usable)
        if len(sites) == count:
            break
    if len(sites) < count:
        tried = f"radius={r:.4g}" if given is not None else (
            f"radius up to {r:.4g} ({r / edge:.3g} mean edge lengths)")
        raise ValueError(
            f"found only {len(sites)} separated weld site(s) for count={count} "
            f"({n_candidates} candidate vertex pairs closer than {tried} in space and farther "
            f"than max({ratio:g} x gap, {g_min:.4g}) along the surface, separation {sep:.4g}); "
            "lower the count, raise the radius, or lower the geodesic ratio or the separation")
    site_arr = ids[np.asarray(sites, dtype=np.int64)]
    out, keep_ids = _glue(mesh, site_arr, [(cycle(u), cycle(v)) for u, v in site_arr], join)
    X = mesh.vertices
    params = {"count": count, "radius": r, "seed": _seed_param(seed),
              "min_geodesic_ratio": ratio, "min_geodesic_fraction": frac, "min_geodesic": g_min,
              "separation": sep, "join": join, "diameter": diam, "n_candidates": int(n_candidates),
              "resolution": resolution, "search_vertices": search.n_vertices,
              "gaps": np.linalg.norm(X[site_arr[:, 0]] - X[site_arr[:, 1]], axis=1)}
    res = _result(mesh, out, keep_ids, "weld", site_arr, params)
    logger.info("weld: %d %s weld(s), Euler characteristic %d -> %d", count, join,
                res.euler_before, res.euler_after)
    return res


def _weld_sites(mesh: Mesh, count: int, r: float, ratio: float, g_min: float, sep: float,
                rng: np.random.Generator, usable) -> tuple[list[tuple[int, int]], int]:
    """Up to ``count`` weld sites of ``mesh`` (:func:`weld`'s candidates and sites) and the
    number of candidate pairs. ``usable(u, v)``: whether a drawn pair can be glued."""
    from scipy.spatial import cKDTree

    X, n = mesh.vertices, mesh.n_vertices
    # 1. close in space, far along the surface
    ref = np.flatnonzero(mesh.referenced)
    pairs = ref[cKDTree(X[ref]).query_pairs(r, output_type="ndarray")]
    pairs.sort(axis=1)
    gap = np.linalg.norm(X[pairs[:, 0]] - X[pairs[:, 1]], axis=1)
    pairs = pairs[_far_pairs(mesh, pairs, np.maximum(ratio * gap, g_min))]
    logger.info("weld: %d candidate pairs (radius %.4g, geodesic > max(%.3g x gap, %.4g))",
                len(pairs), r, ratio, g_min)

    # 2. sites drawn at random among candidates separated from the sites so far
    A = mesh.adjacency
    sites: list[tuple[int, int]] = []
    blocked = np.zeros(n, bool)          # 2-rings of chosen vertices: closed 1-rings would overlap
    d_sites = np.full(n, np.inf)         # edge-graph distance to the nearest welded vertex
    for k in rng.permutation(len(pairs)):
        u, v = int(pairs[k, 0]), int(pairs[k, 1])
        if blocked[u] or blocked[v] or min(d_sites[u], d_sites[v]) < sep or not usable(u, v):
            continue
        sites.append((u, v))
        if len(sites) == count:
            break
        d_sites = np.minimum(d_sites, dijkstra(A, directed=False, indices=[u, v], min_only=True))
        hop = dijkstra(A, directed=False, unweighted=True, indices=[u, v], limit=2, min_only=True)
        blocked |= np.isfinite(hop)
    return sites, len(pairs)


def _glue(mesh: Mesh, site_arr: np.ndarray, rings, join: str) -> tuple[Mesh, np.ndarray]:
    """Weld the pairs ``site_arr`` (K, 2) of ``mesh`` (their link cycles ``rings``): the
    welded mesh and the input index of each of its vertices."""
    X, F, n = mesh.vertices, mesh.faces, mesh.n_vertices
    if join == "tube":
        gone = site_arr.ravel()
        star = np.isin(F, gone).any(axis=1)
        band = [_bridge(cu, cv[::-1], X) for cu, cv in rings]
        new_faces = np.concatenate([F[~star]] + band)
    else:
        gone = site_arr[:, 1]
        remap = np.arange(n)
        remap[site_arr[:, 1]] = site_arr[:, 0]
        new_faces = remap[F]
    keep = mesh.referenced.copy()
    keep[gone] = False
    new_index = np.full(n, -1, dtype=np.int64)
    new_index[keep] = np.arange(int(keep.sum()))
    keep_ids = np.flatnonzero(keep)
    return Mesh(X[keep], new_index[new_faces], input_ids=mesh.input_ids[keep]), keep_ids


# ---------------------------------------------------------------------------- holes
def _clean_removal(faces: np.ndarray, removed: np.ndarray, b0: np.ndarray) -> np.ndarray:
    """Grow ``removed`` until what is left is a clean surface; returns the kept-vertex mask.

    Faces with a removed vertex go; then vertices left without a face go, and so do new
    bow-tie vertices (more boundary edges than they had in the input: two fans touching at
    one vertex), until nothing changes.
    """
    n = len(removed)
    removed = removed.copy()
    while True:
        kept = faces[~removed[faces].any(axis=1)]
        used = np.zeros(n, bool)
        used[kept.ravel()] = True
        bv = _boundary_valence(kept, n)
        grow = ~removed & (~used | ((bv > 2) & (bv > b0)))
        if not grow.any():
            return ~removed
        removed |= grow


def holes(mesh: Mesh, count: int, *, radius: float | None = None, seed=0) -> Perturbation:
    """Punch ``count`` holes: remove geodesic disks of radius ``radius`` at random centres.

    The second kind of topological noise of Bronstein et al. (IJCV 2010, §5, Fig. 2; the
    experiments there use 10 and 20 holes). A hole is the geodesic disk

    .. math:: D(c) = \\{x : d_G(c, x) \\le r\\}

    around a centre ``c``, ``d_G`` the shortest path along edges; its vertices and every
    face touching them are removed. Vertices left with no face, and vertices that would
    become bow-ties (two fans of faces meeting at one vertex), are removed too.

    **Centres** are drawn in a seeded random order and accepted when they are at least
    ``3 r`` (edge-graph distance) from every accepted centre -- so disks stay at least
    ``r`` apart and never merge -- and at least ``2 r`` from the mesh's boundary, and when
    removing the disk changes the topology exactly as a disk should: Euler characteristic
    ``-1``, boundary loops ``+1``, components unchanged. A disk that would cut a thin part
    (wrap around a tail) is rejected; one that would only cut off a sliver of no more
    vertices than the disk itself is accepted with the sliver dropped (logged). On a closed
    mesh the result therefore has ``count`` boundary loops and Euler characteristic
    ``chi - count`` (a sphere: ``2 - count``).

    Parameters
    ----------
    mesh : Mesh
    count : int
        Number of holes, ``>= 1``.
    radius : float, optional
        Geodesic radius ``r`` of each hole. Default ``0.03 * sqrt(mesh.area)``: 4.2 units
        on a TOSCA cat (1.5 mean edges of its 3,000-vertex working mesh). With the faces
        around the disk, a hole then takes about 0.5% of the area at working resolution
        (10 holes about 5%, 20 holes about 9%, on the cat as on a sphere). Holes always
        remove at least their centre.
    seed : int, Generator or None, default 0
        Order in which centres are tried.

    Returns
    -------
    Perturbation
        ``kind="holes"``, ``sites`` ``(count,)``: the centres (input indices; removed).
        Vertices no face uses are dropped as well.

    Raises
    ------
    ValueError
        When fewer than ``count`` holes fit (the message says how many did), or for an
        invalid parameter.
    TypeError
        When ``mesh`` is not a :class:`~gromov.Mesh`.
    """
    mesh = _check_mesh(mesh)
    count = _check_count(count)
    r = 0.03 * np.sqrt(mesh.area) if radius is None else _check_positive(radius, "radius")
    A, F, n = mesh.adjacency, mesh.faces, mesh.n_vertices
    rng = _rng(seed)

    b0 = _boundary_valence(F, n)
    boundary = np.flatnonzero(b0 > 0)
    d_boundary = (dijkstra(A, directed=False, indices=boundary, min_only=True, limit=2 * r)
                  if len(boundary) else np.full(n, np.inf))
    d_centres = np.full(n, np.inf)

    def stats(m: Mesh) -> tuple[int, int, int]:
        comps = len(np.unique(m.component_labels[m.referenced]))
        return m.euler_characteristic, len(m.boundary_loops), comps

    cur = mesh.submesh(mesh.referenced) if not mesh.referenced.all() else mesh
    chi, loops, comps = stats(cur)
    removed = ~mesh.referenced
    centres: list[int] = []
    dropped = 0
    for c in rng.permutation(np.flatnonzero(mesh.referenced)):
        c = int(c)
        if d_centres[c] < 3 * r or d_boundary[c] < 2 * r:
            continue
        d = dijkstra(A, directed=False, indices=c, limit=3 * r)
        disk = d <= r
        keep = _clean_removal(F, removed | disk, b0)
        trial = mesh.submesh(keep)
        extra = 0
        t_labels = trial.component_labels
        n_comp = len(np.unique(t_labels))
        if n_comp > comps:
            # drop the smallest new components if they are slivers (no bigger than the disk)
            sizes = np.bincount(t_labels)
            small = np.argsort(sizes)[: n_comp - comps]
            extra = int(sizes[small].sum())
            if extra > int(disk.sum()):
                continue
            ids = np.flatnonzero(keep)
            keep = keep.copy()
            keep[ids[np.isin(t_labels, small)]] = False
            keep = _clean_removal(F, ~keep, b0)
            trial = mesh.submesh(keep)
        t_chi, t_loops, t_comps = stats(trial)
        if (t_chi, t_loops, t_comps) != (chi - 1, loops + 1, comps):
            continue
        if extra:
            logger.info("holes: dropped %d vertices cut off by the hole at vertex %d", extra, c)
            dropped += extra
        removed = ~keep
        chi, loops = t_chi, t_loops
        d_centres = np.minimum(d_centres, d)
        centres.append(c)
        if len(centres) == count:
            break
    if len(centres) < count:
        raise ValueError(
            f"only {len(centres)} hole(s) of radius {r:.4g} fit for count={count} (centres at least "
            f"{3 * r:.4g} apart and {2 * r:.4g} from the boundary, each removal a clean disk); "
            "lower count or radius")
    keep = ~removed
    out = mesh.submesh(keep)
    params = {"count": count, "radius": r, "seed": _seed_param(seed),
              "min_separation": 3 * r, "dropped_vertices": dropped}
    res = _result(mesh, out, np.flatnonzero(keep), "holes", centres, params)
    logger.info("holes: %d holes of radius %.4g, %d -> %d vertices, boundary loops %d -> %d", count, r,
                mesh.n_vertices, out.n_vertices, res.boundary_loops_before, res.boundary_loops_after)
    return res


# ---------------------------------------------------------------------------- cut
def _check_fraction(value, name: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not 0.0 < value < 1.0:
        raise ValueError(f"{name} must be a fraction of the area strictly between 0 and 1, got {value!r}")
    return float(value)


def _largest_piece(faces: np.ndarray, face_areas: np.ndarray, kept: np.ndarray) -> tuple[float, np.ndarray]:
    """Area of the largest connected piece of the faces whose three vertices are ``kept``
    (pieces joined through a vertex count as one), and its vertex mask."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(kept)
    fk = kept[faces].all(axis=1)
    if not fk.any():
        return 0.0, np.zeros(n, bool)
    f = faces[fk]
    g = coo_matrix((np.ones(2 * len(f)), (np.r_[f[:, 0], f[:, 1]], np.r_[f[:, 1], f[:, 2]])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    area = np.bincount(labels[f[:, 0]], weights=face_areas[fk])
    best = int(np.argmax(area))
    used = np.zeros(n, bool)
    used[f[labels[f[:, 0]] == best].ravel()] = True
    return float(area[best]), used


def _clean_piece(mesh: Mesh, kept: np.ndarray, b0: np.ndarray) -> np.ndarray:
    """The largest piece of ``kept`` as a clean surface: no bow-tie vertex that the input did
    not have, no vertex without a face (:func:`_clean_removal`), one connected component."""
    F, fa = mesh.faces, mesh.face_areas
    while True:
        clean = _clean_removal(F, ~kept, b0)
        _, piece = _largest_piece(F, fa, clean)
        if np.array_equal(piece, kept):
            return piece
        kept = piece


def _threshold_part(mesh: Mesh, field: np.ndarray, keep: float, total: float,
                    iterations: int = 60) -> tuple[float, np.ndarray]:
    """Bisection on ``t`` for the largest piece of ``{field <= t}`` holding ``keep`` of the area.

    That piece's area never decreases with ``t`` (the kept set only grows, its pieces only grow
    or merge), but it jumps where two pieces merge. Returns the threshold whose piece's area is
    nearest ``keep * total``, of the two that bracket it, and that piece (not yet cleaned).
    Vertices where ``field`` is -inf (another component than the holes' centres) are always kept."""
    F, fa = mesh.faces, mesh.face_areas
    ref = mesh.referenced
    finite = field[ref & np.isfinite(field)]
    lo, hi = float(finite.min()) - 1.0, float(finite.max())
    span = hi - lo
    area_hi, piece_hi = _largest_piece(F, fa, ref & (field <= hi))
    area_lo, piece_lo = 0.0, np.zeros(len(field), bool)
    target = keep * total
    for _ in range(iterations):
        if hi - lo <= 1e-12 * span:
            break
        t = 0.5 * (lo + hi)
        area, piece = _largest_piece(F, fa, ref & (field <= t))
        if area >= target:
            hi, area_hi, piece_hi = t, area, piece
        else:
            lo, area_lo, piece_lo = t, area, piece
    if abs(area_lo - target) < abs(area_hi - target):
        return lo, piece_lo
    return hi, piece_hi


def cut(mesh: Mesh, keep: float = 0.6, *, kind: str = "plane", count: int | None = None, seed=0,
        tol: float = 0.02, max_tries: int = 20) -> Perturbation:
    """A part of ``mesh`` holding a stated fraction ``keep`` of its area: a plane cut or large holes.

    The partial shapes of SHREC'16 *Partial Matching of Deformable Shapes* (Cosmo, Rodolà,
    Bronstein, Torsello, Cremers & Sahillioğlu, Eurographics 3DOR 2016): TOSCA shapes with
    *cuts* (one side of a plane) and *holes* (removed patches), the part to be matched against
    a whole shape in another pose. The part is a subset of the input's vertices and faces:

    - ``kind="plane"``: the vertices on one side of a plane, :math:`n \\cdot x \\le t`, with
      ``n`` a uniformly random unit direction (from ``seed``);
    - ``kind="holes"``: the vertices outside ``count`` geodesic disks of a common radius,
      :math:`\\min_k d_G(c_k, x) > r`, with the centres ``c_k`` drawn at random, weighted by
      vertex area (uniform on the surface), and ``d_G`` the shortest path along edges.

    Faces are kept when all three of their vertices are. The offset ``t`` (the radius ``r``) is
    found by bisection so that the part holds ``keep`` of the input's area. Only the **largest
    connected piece** is kept -- a plane across the legs leaves the feet apart, big holes cut
    off a tail -- since a part in pieces has no finite geodesic distances between them; the
    bisection measures that piece's area, which grows with ``t`` but jumps where two pieces
    merge. When the piece nearest the target is further than ``tol`` from it, another direction
    (other centres) is drawn, up to ``max_tries`` times. Bow-tie vertices (two fans of faces
    meeting at one vertex) that the selection makes are removed with their faces, as in
    :func:`holes`. The part is a valid mesh for gromov: every vertex in a face, every face an
    input face (no new zero-area face), one component.

    Parameters
    ----------
    mesh : Mesh
    keep : float, default 0.6
        Fraction of the input's area the part holds, strictly between 0 and 1.
    kind : {"plane", "holes"}, default "plane"
    count : int, optional
        ``kind="holes"``: number of disks, default :data:`CUT_PATCHES` (5). Disks may overlap
        and merge into one hole. Not used by ``"plane"``.
    seed : int, Generator or None, default 0
        The plane's direction (the disks' centres), and those of the further tries.
    tol : float, default 0.02
        Largest accepted difference between the part's area fraction and ``keep``.
    max_tries : int, default 20
        Directions (sets of centres) drawn before giving up.

    Returns
    -------
    Perturbation
        ``kind="cut"``; ``vertex_map`` the input vertex of each part vertex (the ground truth of
        part -> whole), ``sites`` the disk centres (input indices, ``(count,)``) for holes and
        empty for a plane. ``params``: ``kind``, ``keep``, ``kept`` (the part's area over the
        input's), ``tol``, ``seed``, ``tries`` (draws used), ``side_fraction`` (area of the
        whole kept side, all its pieces, over the input's); for a plane ``normal`` and
        ``offset`` (the part is ``vertices @ normal <= offset``), for holes ``count`` and
        ``radius`` (edge-graph).

    Raises
    ------
    ValueError
        For ``keep`` outside (0, 1), an unknown ``kind`` or another invalid parameter, and when
        no draw within ``max_tries`` gives a piece within ``tol`` of ``keep`` (the message says
        the nearest fraction found).
    TypeError
        When ``mesh`` is not a :class:`~gromov.Mesh`.

    Examples
    --------
    >>> p = cut(cat, 0.6, kind="plane", seed=0)                  # doctest: +SKIP
    >>> round(p.params["kept"], 2), p.mesh.n_components           # doctest: +SKIP
    (0.6, 1)
    >>> truth = p.mesh.input_ids    # the input's vertex of each part vertex   # doctest: +SKIP
    """
    mesh = _check_mesh(mesh)
    keep = _check_fraction(keep, "keep")
    if kind not in CUT_KINDS:
        raise ValueError(f"kind must be one of {CUT_KINDS}, got {kind!r}")
    if count is not None and kind != "holes":
        raise ValueError(f"count applies to kind='holes', not to kind={kind!r}")
    count = CUT_PATCHES if count is None else _check_count(count)
    tol = _check_fraction(tol, "tol")
    max_tries = _check_count(max_tries)
    ref = np.flatnonzero(mesh.referenced)
    if kind == "holes" and count > len(ref):
        raise ValueError(f"count={count} exceeds the {len(ref)} vertices of the mesh")
    total = float(mesh.area)
    X, A = mesh.vertices, mesh.adjacency
    b0 = _boundary_valence(mesh.faces, mesh.n_vertices)
    rng = _rng(seed)
    best = None
    for attempt in range(1, max_tries + 1):
        if kind == "plane":
            normal = rng.normal(size=3)
            normal /= np.linalg.norm(normal)
            field = X @ normal
            centres = np.zeros(0, np.int64)
        else:
            w = mesh.vertex_areas[ref]
            centres = np.sort(rng.choice(ref, size=count, replace=False, p=w / w.sum()))
            field = -dijkstra(A, directed=False, indices=centres, min_only=True)
        t, piece = _threshold_part(mesh, field, keep, total)
        part = _clean_piece(mesh, piece, b0)
        kept = float(mesh.face_areas[part[mesh.faces].all(axis=1)].sum()) / total
        if best is None or abs(kept - keep) < abs(best[0] - keep):
            best = (kept, t, part, centres, field, normal if kind == "plane" else None)
        if abs(kept - keep) <= tol:
            break
        logger.info("cut: draw %d keeps %.3f of the area (target %.3f +- %.3f); drawing again",
                    attempt, kept, keep, tol)
    kept, t, part, centres, field, normal = best
    if abs(kept - keep) > tol:
        what = "plane direction" if kind == "plane" else f"set of {count} centres"
        raise ValueError(
            f"no {what} out of max_tries={max_tries} keeps {keep:g} +- {tol:g} of the area in one "
            f"piece (nearest: {kept:.3f}): the shape's largest piece jumps past it where parts "
            "join; raise tol or max_tries, or choose another keep")
    side = mesh.referenced & (field <= t)
    params = {"kind": kind, "keep": keep, "kept": kept, "tol": tol, "seed": _seed_param(seed),
              "tries": attempt, "side_fraction": float(mesh.face_areas[side[mesh.faces].all(axis=1)].sum()) / total}
    if kind == "plane":
        params.update(normal=normal.tolist(), offset=float(t))
    else:
        params.update(count=count, radius=float(-t))
    res = _result(mesh, mesh.submesh(part), np.flatnonzero(part), "cut", centres, params)
    logger.info("cut (%s): %d -> %d vertices, %.3f of the area kept, boundary loops %d -> %d", kind,
                mesh.n_vertices, res.mesh.n_vertices, kept, res.boundary_loops_before, res.boundary_loops_after)
    return res
