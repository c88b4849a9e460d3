"""Closest point on a triangle mesh, used to map points between a mesh and its working mesh.

The search is libigl's axis-aligned bounding-box tree (``igl.AABB``), which is exact; the
barycentric coordinates of the point found are computed here (compiled kernel).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["closest_point_barycentric", "project_points", "surface_tree"]


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


def _bary_impl(points, V, F, face):
    n = points.shape[0]
    bary = np.empty((n, 3))
    for i in prange(n):
        f = face[i]
        u, v, w = closest_point_barycentric(points[i], V[F[f, 0]], V[F[f, 1]], V[F[f, 2]])
        bary[i, 0], bary[i, 1], bary[i, 2] = u, v, w
    return bary


# threaded for many points; serial for a few (cheaper, and safe in forked worker processes,
# where numba's thread pool must not be started again)
_bary = njit(cache=True, parallel=True)(_bary_impl)
_bary_serial = njit(cache=True)(_bary_impl)


def surface_tree(mesh):
    """libigl's bounding-box tree over the faces of ``mesh``, for :func:`project_points`.

    Build it once per mesh when projecting onto the same mesh many times.
    """
    import igl

    tree = igl.AABB()
    tree.init(np.ascontiguousarray(mesh.vertices, dtype=np.float64),
              np.ascontiguousarray(mesh.faces, dtype=np.int64))
    return tree


def project_points(points: np.ndarray, mesh, *, tree=None):
    """Project points onto ``mesh``: the closest point of the surface, exactly.

    Returns ``(face, bary, dist)``: ``(p,)`` face index, ``(p, 3)`` barycentric coordinates
    (non-negative, summing to one) and ``(p,)`` Euclidean distance to the surface point.
    Where several faces are equally close (a point closest to an edge or a vertex) any of
    them may be returned; the surface point is the same. ``tree`` is a
    :func:`surface_tree` of ``mesh`` to reuse (built here when not given).

    Until session 18 this took the nearest point among the faces around the 4 nearest
    vertices, which among long, thin triangles can miss the closest face: on TOSCA poses
    simplified to 3,000 vertices it missed for 0.4-0.9% of the input vertices, by up to
    1.1% of the bounding-box diagonal.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (p, 3), got {points.shape}")
    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    if len(F) == 0:
        raise ValueError("cannot project onto a mesh without faces")
    if tree is None:
        tree = surface_tree(mesh)
    sq, face, _ = tree.squared_distance(V, F, points)
    face = np.asarray(face, dtype=np.int64)
    bary = (_bary_serial if len(points) < 4096 else _bary)(points, V, F, face)
    return face, bary, np.sqrt(np.maximum(sq, 0.0))
