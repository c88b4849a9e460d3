"""Closest point on a part of a triangle mesh, used to map points between a mesh and its
working mesh (compiled kernels)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ._arrays import readonly

__all__ = ["closest_point_barycentric", "project_among"]


@njit(cache=True, inline="always")
def _segment_t(p, a, b):
    """Parameter in [0, 1] of the point of segment ab closest to p, and its squared distance."""
    d = 0.0
    t = 0.0
    for k in range(3):
        d += (b[k] - a[k]) ** 2
        t += (p[k] - a[k]) * (b[k] - a[k])
    t = min(max(t / d, 0.0), 1.0) if d > 0.0 else 0.0
    e = 0.0
    for k in range(3):
        e += (a[k] + t * (b[k] - a[k]) - p[k]) ** 2
    return t, e


@njit(cache=True)
def _closest_on_edges(p, a, b, c):
    """The closest of the three edges' closest points, as barycentric coordinates: the
    closest point of a degenerate (zero-area) triangle, which is a segment or a point."""
    t, e = _segment_t(p, a, b)
    u, v, w = 1.0 - t, t, 0.0
    t, e2 = _segment_t(p, b, c)
    if e2 < e:
        e, u, v, w = e2, 0.0, 1.0 - t, t
    t, e2 = _segment_t(p, c, a)
    if e2 < e:
        u, v, w = t, 0.0, 1.0 - t
    return u, v, w


@njit(cache=True, inline="always")
def closest_point_barycentric(p, a, b, c):
    """Barycentric coordinates ``(u, v, w)`` of the point of triangle abc closest to p.

    Region classification of Ericson, *Real-Time Collision Detection* (2005), §5.1.5.
    A degenerate triangle (zero area: two corners coincide, or all three on a line) is the
    segment or point it spans: the closest point of its three edges is taken.
    """
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    n0, n1, n2 = ab1 * ac2 - ab2 * ac1, ab2 * ac0 - ab0 * ac2, ab0 * ac1 - ab1 * ac0
    scale = (ab0 * ab0 + ab1 * ab1 + ab2 * ab2) * (ac0 * ac0 + ac1 * ac1 + ac2 * ac2)
    if n0 * n0 + n1 * n1 + n2 * n2 <= 1e-24 * scale:
        return _closest_on_edges(p, a, b, c)
    ap0, ap1, ap2 = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    bp0, bp1, bp2 = p[0] - b[0], p[1] - b[1], p[2] - b[2]
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        den = d1 - d3
        v = d1 / den if den != 0.0 else 0.0
        return 1.0 - v, v, 0.0
    cp0, cp1, cp2 = p[0] - c[0], p[1] - c[1], p[2] - c[2]
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        den = d2 - d6
        w = d2 / den if den != 0.0 else 0.0
        return 1.0 - w, 0.0, w
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        den = (d4 - d3) + (d5 - d6)
        w = (d4 - d3) / den if den != 0.0 else 0.0
        return 0.0, 1.0 - w, w
    den = va + vb + vc
    if den == 0.0:
        return 1.0, 0.0, 0.0
    v = vb / den
    w = vc / den
    return 1.0 - v - w, v, w


@njit(cache=True)
def _project_among(points, V, F, vf_ptr, vf_ids, cand_ptr, cand_ids):
    """Per point i, the closest point among the faces incident to the vertices
    ``cand_ids[cand_ptr[i]:cand_ptr[i + 1]]``; serial (cheap, and safe in forked workers)."""
    n = points.shape[0]
    face = np.empty(n, np.int64)
    bary = np.empty((n, 3))
    dist = np.empty(n)
    for i in range(n):
        p = points[i]
        best = np.inf
        bf = -1
        bu = bv = bw = 0.0
        for k in range(cand_ptr[i], cand_ptr[i + 1]):
            vtx = cand_ids[k]
            for j in range(vf_ptr[vtx], vf_ptr[vtx + 1]):
                f = vf_ids[j]
                a, b, c = V[F[f, 0]], V[F[f, 1]], V[F[f, 2]]
                u, v, w = closest_point_barycentric(p, a, b, c)
                d = 0.0
                for t in range(3):
                    d += (u * a[t] + v * b[t] + w * c[t] - p[t]) ** 2
                if d < best:
                    best, bf, bu, bv, bw = d, f, u, v, w
        face[i] = bf
        bary[i, 0], bary[i, 1], bary[i, 2] = bu, bv, bw
        dist[i] = np.sqrt(best)
    return face, bary, dist


def project_among(points: np.ndarray, mesh, cand_ptr: np.ndarray, cand_ids: np.ndarray):
    """Project each point onto the part of ``mesh`` it belongs to: the closest point among the
    faces incident to its candidate vertices (CSR: point i's are
    ``cand_ids[cand_ptr[i]:cand_ptr[i + 1]]``).

    Returns ``(face, bary, dist)``: ``(p,)`` face index, ``(p, 3)`` barycentric coordinates
    (non-negative, summing to one) and ``(p,)`` Euclidean distance from each point to the
    surface point ``bary @ vertices[faces[face]]``. Ties (a point closest to an edge or a
    vertex) go to the first face found; the surface point is the same.

    The candidates say *where on the surface* a point may go, so that a point is never put on
    another sheet that happens to pass closer in space (a hand resting on a thigh): the
    globally closest point of a working mesh is not where an input vertex of the hand
    belongs. :func:`gromov.resolution.simplify` gives each input vertex the working vertex it
    was collapsed into and that vertex's neighbours.

    Raises
    ------
    ValueError
        ``points`` is not ``(p, 3)`` or holds NaN or infinite coordinates; the candidate
        arrays do not fit (``cand_ptr`` of length p + 1, non-decreasing, ids of vertices with
        at least one face for every point).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (p, 3), got {points.shape}")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{int(bad.sum())} points have NaN or infinite coordinates, first "
                         f"point {i}: {points[i].tolist()}")
    ptr = np.ascontiguousarray(cand_ptr, dtype=np.int64)
    ids = np.ascontiguousarray(cand_ids, dtype=np.int64)
    if ptr.shape != (len(points) + 1,) or ptr[0] != 0 or (np.diff(ptr) < 0).any() or ptr[-1] != len(ids):
        raise ValueError(f"cand_ptr must be a non-decreasing (p + 1,) array from 0 to "
                         f"len(cand_ids) = {len(ids)}, got shape {ptr.shape}")
    if len(ids) and (ids.min() < 0 or ids.max() >= mesh.n_vertices):
        raise ValueError(f"candidate vertex ids must be in 0..{mesh.n_vertices - 1}")
    vf_ptr, vf_ids = mesh.vertex_faces
    face, bary, dist = _project_among(*(readonly(a) for a in (
        points, np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int64), vf_ptr, vf_ids, ptr, ids)))
    if len(face) and face.min() < 0:
        i = int(np.argmin(face))
        raise ValueError(f"point {i} has no candidate vertex with a face")
    return face, bary, dist
