"""Topology-safe replay of an edge-collapse sequence (compiled kernel).

The quadric simplifier proposes an order of half-edge collapses ``(keep, remove)``. Replaying
it, we apply a collapse only when it is a legal edge contraction of the current mesh:

- ``keep`` and ``remove`` share an edge with one or two incident faces (manifold edge);
- both are manifold vertices: the faces around each form one fan, closed (interior) or open
  (boundary) -- a vertex where two holes touch (a bow-tie) is never moved;
- the *link condition* holds (Dey, Edelsbrunner, Guha & Nekhayev, "Topology preserving edge
  contraction", Publ. Inst. Math. 1999), with the boundary coned off to a dummy vertex: the
  common neighbours of the two vertices are exactly the opposite vertices of the faces on
  that edge; an interior edge never joins two boundary vertices (that would pinch the
  boundary); no common neighbour ``x`` has both ``x keep`` and ``x remove`` on the boundary
  (the collapse would delete a triangle hanging by its edges and leave ``x`` in no face); and
  no two faces ``keep c d``, ``remove c d`` close a tetrahedron over the edge (it would become
  two copies of one triangle). So the contraction is a homeomorphism and the Euler
  characteristic, components and boundary loops are kept;
- since the kept vertex stays at its own input position, no face around ``remove`` flips,
  becomes degenerate, or (optionally) becomes a sliver when ``remove`` moves onto ``keep``.

Collapses that fail are skipped; later ones that involve the same vertices remain valid
because a skipped collapse leaves both vertices alive.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._arrays import readonly

__all__ = ["replay_collapses"]


@njit(cache=True)
def _remove_face(vf, vcount, v, f):
    c = vcount[v]
    for k in range(c):
        if vf[v, k] == f:
            vf[v, k] = vf[v, c - 1]
            vf[v, c - 1] = -1
            vcount[v] = c - 1
            return


@njit(cache=True)
def _normal(p, q, r):
    a0, a1, a2 = q[0] - p[0], q[1] - p[1], q[2] - p[2]
    b0, b1, b2 = r[0] - p[0], r[1] - p[1], r[2] - p[2]
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def _sum_sq_edges(p, q, r):
    s = 0.0
    for k in range(3):
        s += (p[k] - q[k]) ** 2 + (q[k] - r[k]) ** 2 + (r[k] - p[k]) ** 2
    return s + 1e-300


@njit(cache=True)
def _link(F, vf, vcount, v, deg, nb, stamp, tick):
    """The link of vertex ``v``: ``deg[w]`` (added to, for each neighbour ``w``) is the number
    of faces of ``v`` that contain ``w`` (1: ``vw`` is a boundary edge); ``nb[:k]`` lists the
    ``k`` neighbours. Returns ``(k, manifold)``: manifold when the link is one cycle (interior
    vertex) or one path (boundary vertex) -- not two fans touching at ``v`` (a bow-tie), nor a
    non-manifold edge at ``v``."""
    k = 0
    m = vcount[v]
    for i in range(m):
        f = vf[v, i]
        for j in range(3):
            w = F[f, j]
            if w != v:
                if deg[w] == 0:
                    nb[k] = w
                    k += 1
                deg[w] += 1
    if k == 0:
        return 0, False
    for i in range(k):
        if deg[nb[i]] > 2:
            return k, False
    if k > m + 1:   # more than one path: several fans
        return k, False
    # one path or one cycle: every neighbour is reached from the first along link edges
    stamp[nb[0]] = tick
    reached = 1
    grown = True
    while grown:
        grown = False
        for i in range(m):
            f = vf[v, i]
            x, y = -1, -1
            for j in range(3):
                w = F[f, j]
                if w != v:
                    if x < 0:
                        x = w
                    else:
                        y = w
            if (stamp[x] == tick) != (stamp[y] == tick):
                stamp[x] = tick
                stamp[y] = tick
                reached += 1
                grown = True
    return k, reached == k


@njit(cache=True)
def _has_face(F, vf, vcount, v, x, y):
    for i in range(vcount[v]):
        f = vf[v, i]
        hx, hy = False, False
        for j in range(3):
            hx = hx or F[f, j] == x
            hy = hy or F[f, j] == y
        if hx and hy:
            return True
    return False


@njit(cache=True)
def _link_condition(a, b, F, vf, vcount, stamp, tick, shared, ns, dega, degb, nba, nbb):
    """Dey et al.'s link condition for edge ``(a, b)`` (``ns`` faces on it) of a surface with
    boundary, the boundary coned off to a dummy vertex: both ends have manifold links;
    ``Lk(a) & Lk(b) == Lk(ab)`` on vertices (the common neighbours are the ``ns`` opposite
    vertices, and the dummy vertex is common -- both ends on the boundary -- only when ``ab`` is
    a boundary edge); and on edges (no common neighbour ``x`` with ``ax`` and ``bx`` both
    boundary edges, and no faces ``acd`` and ``bcd`` over the two opposite vertices)."""
    ka, man_a = _link(F, vf, vcount, a, dega, nba, stamp, tick)
    kb, man_b = _link(F, vf, vcount, b, degb, nbb, stamp, tick + 1)
    ok = man_a and man_b
    if ok and ns == 2 and ka != vcount[a] and kb != vcount[b]:
        ok = False   # an interior edge joining two boundary vertices would pinch the boundary
    if ok:
        common = 0
        for i in range(ka):
            x = nba[i]
            if x != b and degb[x] > 0:
                common += 1
                if dega[x] == 1 and degb[x] == 1:
                    ok = False
        if common != ns:
            ok = False
    for i in range(ka):
        dega[nba[i]] = 0
    for i in range(kb):
        degb[nbb[i]] = 0
    if ok and ns == 2:
        c, d = np.int64(-1), np.int64(-1)   # int64, not literals: one compilation of _has_face
        for s in range(2):
            f = shared[s]
            for j in range(3):
                w = F[f, j]
                if w != a and w != b:
                    if s == 0:
                        c = w
                    else:
                        d = w
        if _has_face(F, vf, vcount, a, c, d) and _has_face(F, vf, vcount, b, c, d):
            ok = False
    return ok


@njit(cache=True)
def _try_collapse(a, b, V, F, vf, vcount, face_alive, stamp, tick, shared, width, min_cos, min_quality,
                  dega, degb, nba, nbb):
    """Contract edge (a, b) into a if that is legal (see module docstring); True if done."""
    if vcount[a] + vcount[b] > width:
        return False
    # faces on edge (a, b) and their opposite vertices
    ns = np.int64(0)   # int64, not a literal: one compilation of _link_condition
    for k in range(vcount[b]):
        f = vf[b, k]
        if F[f, 0] == a or F[f, 1] == a or F[f, 2] == a:
            shared[ns] = f
            ns += 1
    if ns == 0 or ns > 2:
        return False
    if not _link_condition(a, b, F, vf, vcount, stamp, tick, shared, ns, dega, degb, nba, nbb):
        return False
    # no flipped or degenerate face when b moves onto a
    ok = True
    for k in range(vcount[b]):
        f = vf[b, k]
        is_shared = False
        for s in range(ns):
            if shared[s] == f:
                is_shared = True
        if is_shared:
            continue
        p = [F[f, 0], F[f, 1], F[f, 2]]
        n0 = _normal(V[p[0]], V[p[1]], V[p[2]])
        for j in range(3):
            if p[j] == b:
                p[j] = a
        n1 = _normal(V[p[0]], V[p[1]], V[p[2]])
        l0 = np.sqrt(n0[0] ** 2 + n0[1] ** 2 + n0[2] ** 2)
        l1 = np.sqrt(n1[0] ** 2 + n1[1] ** 2 + n1[2] ** 2)
        if l1 <= 1e-12 * (l0 + 1e-300) or (n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2]) < min_cos * l0 * l1:
            ok = False
            break
        # shape quality 2*sqrt(3)*|n| / sum of squared edges (1 for an equilateral triangle)
        q1 = 2.0 * np.sqrt(3.0) * l1 / _sum_sq_edges(V[p[0]], V[p[1]], V[p[2]])
        if q1 < min_quality:
            ok = False
            break
    if not ok:
        return False
    # apply
    for s in range(ns):
        f = shared[s]
        face_alive[f] = False
        for j in range(3):
            _remove_face(vf, vcount, F[f, j], f)
    for k in range(vcount[b]):
        f = vf[b, k]
        for j in range(3):
            if F[f, j] == b:
                F[f, j] = a
        vf[a, vcount[a]] = f
        vcount[a] += 1
    vcount[b] = 0
    return True


@njit(cache=True)
def _replay(V, F, collapses, cap, min_cos, min_quality):
    n, m = V.shape[0], F.shape[0]
    F = F.copy()
    vcount = np.zeros(n, np.int64)
    for f in range(m):
        for j in range(3):
            vcount[F[f, j]] += 1
    width = max(cap, vcount.max() * 4)
    vf = -np.ones((n, width), np.int64)
    fill = np.zeros(n, np.int64)
    for f in range(m):
        for j in range(3):
            v = F[f, j]
            vf[v, fill[v]] = f
            fill[v] += 1
    face_alive = np.ones(m, np.bool_)
    alive = np.ones(n, np.bool_)
    applied = np.zeros(collapses.shape[0], np.bool_)
    stamp = np.zeros(n, np.int64)
    tick = 0
    shared = np.empty(width, np.int64)
    dega = np.zeros(n, np.int64)
    degb = np.zeros(n, np.int64)
    nba = np.empty(2 * width, np.int64)
    nbb = np.empty(2 * width, np.int64)
    alias = np.arange(n)
    for c in range(collapses.shape[0]):
        a, b = collapses[c, 0], collapses[c, 1]
        while alias[a] != a:
            a = alias[a]
        while alias[b] != b:
            b = alias[b]
        if a == b:
            continue
        tick += 4
        if _try_collapse(a, b, V, F, vf, vcount, face_alive, stamp, tick, shared, width, min_cos, min_quality,
                         dega, degb, nba, nbb):
            alive[b] = False
            alias[b] = a
            applied[c] = True
        else:
            # the simplifier would have put the merged vertex between the two: try keeping b
            tick += 4
            if _try_collapse(b, a, V, F, vf, vcount, face_alive, stamp, tick, shared, width, min_cos,
                             min_quality, dega, degb, nba, nbb):
                alive[a] = False
                alias[a] = b
                applied[c] = True
    for v in range(n):  # each vertex to the vertex it was merged into, chains followed
        r = v
        while alias[r] != r:
            r = alias[r]
        alias[v] = r
    return alive, F[face_alive], applied, alias


def replay_collapses(vertices: np.ndarray, faces: np.ndarray, collapses: np.ndarray, *,
                     min_cos: float = 0.0, min_quality: float = 0.0):
    """Apply the legal collapses of ``collapses`` (rows ``(keep, remove)``) to a mesh.

    Parameters
    ----------
    vertices : ndarray, shape (n, 3)
    faces : ndarray, shape (m, 3)
    collapses : ndarray, shape (c, 2)
    min_cos : float, default 0.0
        A face around the removed vertex may turn by at most ``arccos(min_cos)``.
    min_quality : float, default 0.0
        Skip a collapse that would create a face of shape quality
        ``2 sqrt(3) area / sum(edge^2)`` (1 for equilateral) below this.

    Returns
    -------
    alive : ndarray of bool, shape (n,)
        Vertices that remain.
    faces : ndarray, shape (m', 3)
        Remaining faces, in input vertex indices.
    applied : ndarray of bool, shape (c,)
        Which collapses were applied.
    owner : ndarray of int, shape (n,)
        The remaining vertex each vertex was merged into (itself if it remains). A collapse
        may be applied the other way round (keeping ``remove``) when that one is legal and
        the proposed one is not, so ``applied`` alone does not say which.
    """
    # read-only views whatever the caller's arrays: one compilation of _replay
    v = readonly(np.ascontiguousarray(vertices, dtype=np.float64))
    f = readonly(np.ascontiguousarray(faces, dtype=np.int64))
    c = readonly(np.ascontiguousarray(collapses, dtype=np.int64).reshape(-1, 2))
    return _replay(v, f, c, 64, float(min_cos), float(min_quality))
