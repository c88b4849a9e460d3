"""Closest point on a triangle mesh (compiled kernel), used to map points onto working meshes."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["closest_point_barycentric", "project_points"]


@njit(cache=True, inline="always")
def closest_point_barycentric(p, a, b, c):
    """Barycentric coordinates ``(u, v, w)`` of the point of triangle abc closest to p.

    Region classification of Ericson, *Real-Time Collision Detection* (2005), §5.1.5.
    Degenerate triangles fall back to the nearest vertex.
    """
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
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


def _project_impl(points, V, F, vf_indptr, vf_ids, candidates):
    n = points.shape[0]
    face = np.empty(n, np.int64)
    bary = np.empty((n, 3))
    dist = np.empty(n)
    for i in prange(n):
        best = np.inf
        bf = -1
        bu = bv = bw = 0.0
        p = points[i]
        for k in range(candidates.shape[1]):
            vtx = candidates[i, k]
            for j in range(vf_indptr[vtx], vf_indptr[vtx + 1]):
                f = vf_ids[j]
                a, b, c = V[F[f, 0]], V[F[f, 1]], V[F[f, 2]]
                u, v, w = closest_point_barycentric(p, a, b, c)
                d = 0.0
                for t in range(3):
                    q = u * a[t] + v * b[t] + w * c[t] - p[t]
                    d += q * q
                if d < best:
                    best, bf, bu, bv, bw = d, f, u, v, w
        face[i] = bf
        bary[i, 0], bary[i, 1], bary[i, 2] = bu, bv, bw
        dist[i] = np.sqrt(best)
    return face, bary, dist


# threaded for many points; serial for a few (cheaper, and safe in forked worker processes,
# where numba's thread pool must not be started again)
_project = njit(cache=True, parallel=True)(_project_impl)
_project_serial = njit(cache=True)(_project_impl)


def project_points(points: np.ndarray, mesh, *, k: int = 4, tree=None):
    """Project points onto ``mesh``: nearest point among faces around the ``k`` nearest vertices.

    Returns ``(face, bary, dist)``: ``(p,)`` face index, ``(p, 3)`` barycentric coordinates
    (non-negative, summing to one) and ``(p,)`` Euclidean distance to the surface point.
    Exact when the closest surface point lies on a face incident to one of the ``k``
    nearest vertices, which holds for points near a reasonably shaped mesh. ``tree`` is a
    ``scipy.spatial.cKDTree`` of ``mesh.vertices`` to reuse (built here when not given).
    """
    from scipy.spatial import cKDTree

    k = min(k, mesh.n_vertices)
    if tree is None:
        tree = cKDTree(mesh.vertices)
    _, cand = tree.query(points, k=k)
    cand = np.asarray(cand, dtype=np.int64).reshape(len(points), k)
    indptr, ids = mesh.vertex_faces
    kernel = _project if len(points) >= 4096 else _project_serial
    return kernel(np.ascontiguousarray(points, dtype=np.float64), mesh.vertices, mesh.faces,
                  indptr, ids, cand)
