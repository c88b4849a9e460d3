r"""Compiled inner loop of GMDS: move surface points one at a time to reduce the distortion.

A surface point is ``(face t, barycentric u)`` on a working mesh whose vertex distance
matrix ``D`` is known. Distances between surface points are interpolated bilinearly in the
squared distances (Bronstein, Bronstein & Kimmel, SIAM J. Sci. Comput. 28(5), 2006, §3.2
discuss such interpolants):

.. math:: d^2\big((t, u), (t', u')\big) = u^T \, D^2[F_t, F_{t'}] \, u',

which is exact at vertices, continuous across edges (on an edge only the edge's two vertices
carry weight), and for a fixed other point is *linear* in ``u``: ``d^2 = u . a``. With the
others fixed, point ``i`` minimises

.. math:: f_i(u) = \sum_j w_{ij} \big(\delta_{ij} - \sqrt{u \cdot a_j}\big)^2 ,

whose gradient and Hessian are :math:`\sum_j w_{ij}(1 - \delta_{ij}/s_j)\,a_j` and
:math:`\sum_j w_{ij}\,\delta_{ij}/(2 s_j^3)\,a_j a_j^T` (positive semi-definite), with
:math:`s_j = \sqrt{u\cdot a_j}`. We take damped Newton steps in the plane
``sum(u) = 1``, cross an edge into the neighbouring face when the step leaves the triangle,
stop at boundary edges, and accept a move only if it lowers :math:`f_i` -- so a sweep over
the points never increases the total distortion (block coordinate descent).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["face_neighbours", "sweep", "pair_distances"]


def face_neighbours(faces: np.ndarray) -> np.ndarray:
    """``(m, 3)``: the face across the edge opposite local vertex k of each face (-1: boundary or non-manifold)."""
    f = np.asarray(faces, dtype=np.int64)
    m = len(f)
    # edge opposite corner k is (k+1, k+2)
    a = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    b = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    owner = np.tile(np.arange(m), 3)
    corner = np.repeat(np.arange(3), m)
    order = np.lexsort((hi, lo))
    lo, hi, owner, corner = lo[order], hi[order], owner[order], corner[order]
    nb = -np.ones((m, 3), np.int64)
    same = (lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1])
    # exactly two faces on an edge: pair them (an edge with 3+ faces is left as a wall)
    starts = np.flatnonzero(same)
    for s in starts:
        if (s > 0 and same[s - 1]) or (s + 1 < len(same) and same[s + 1]):
            continue
        nb[owner[s], corner[s]] = owner[s + 1]
        nb[owner[s + 1], corner[s + 1]] = owner[s]
    return nb


@njit(cache=True)
def _build_a(D2, F, t, vt, vu, fixed, A):
    """Rows of A: a_j such that d^2(point in face t with bary u, j) = u . a_j."""
    r0, r1, r2 = F[t, 0], F[t, 1], F[t, 2]
    nv = vt.shape[0]
    for j in range(nv):
        tj = vt[j]
        for r in range(3):
            rr = F[t, r]
            acc = 0.0
            for c in range(3):
                acc += D2[rr, F[tj, c]] * vu[j, c]
            A[j, r] = acc
    for k in range(fixed.shape[0]):
        v = fixed[k]
        A[nv + k, 0] = D2[r0, v]
        A[nv + k, 1] = D2[r1, v]
        A[nv + k, 2] = D2[r2, v]


@njit(cache=True)
def _objective(u, A, delta, w, skip):
    f = 0.0
    for j in range(A.shape[0]):
        if j == skip or w[j] == 0.0:
            continue
        s2 = u[0] * A[j, 0] + u[1] * A[j, 1] + u[2] * A[j, 2]
        s = np.sqrt(s2) if s2 > 0.0 else 0.0
        r = delta[j] - s
        f += w[j] * r * r
    return f


@njit(cache=True)
def _grad_hess(u, A, delta, w, skip, eps):
    g = np.zeros(3)
    H = np.zeros((3, 3))
    for j in range(A.shape[0]):
        if j == skip or w[j] == 0.0:
            continue
        s2 = u[0] * A[j, 0] + u[1] * A[j, 1] + u[2] * A[j, 2]
        s = np.sqrt(max(s2, eps * eps))
        c = w[j] * (1.0 - delta[j] / s)
        h = w[j] * delta[j] / (2.0 * s * s * s)
        for r in range(3):
            g[r] += c * A[j, r]
            for q in range(3):
                H[r, q] += h * A[j, r] * A[j, q]
    return g, H


@njit(cache=True)
def _move_point(i, vt, vu, fixed, delta, w, D2, F, FN, A, n_newton, eps):
    """Damped Newton steps of point i; returns the decrease of f_i (>= 0)."""
    skip = i
    t = vt[i]
    u = vu[i].copy()
    _build_a(D2, F, t, vt, vu, fixed, A)
    f0 = _objective(u, A, delta, w, skip)
    f = f0
    for _ in range(n_newton):
        g, H = _grad_hess(u, A, delta, w, skip, eps)
        # reduced coordinates: u = u0 + E z, E = [[-1, -1], [1, 0], [0, 1]]
        g0 = g[1] - g[0]
        g1 = g[2] - g[0]
        h00 = H[0, 0] - 2 * H[0, 1] + H[1, 1]
        h11 = H[0, 0] - 2 * H[0, 2] + H[2, 2]
        h01 = H[0, 0] - H[0, 1] - H[0, 2] + H[1, 2]
        lam = 1e-9 * (abs(h00) + abs(h11)) + 1e-300
        det = (h00 + lam) * (h11 + lam) - h01 * h01
        if det > 0.0 and h00 + lam > 0.0:
            z0 = -((h11 + lam) * g0 - h01 * g1) / det
            z1 = -(-h01 * g0 + (h00 + lam) * g1) / det
        else:
            z0, z1 = -g0, -g1
        if g0 * z0 + g1 * z1 >= 0.0:  # not a descent direction: gradient step
            z0, z1 = -g0, -g1
        d = np.array([-z0 - z1, z0, z1])
        if abs(d[0]) + abs(d[1]) + abs(d[2]) < 1e-14:
            break
        step = 1.0
        moved = False
        for _ls in range(30):
            # largest fraction of the step that stays in the triangle
            tau = step
            hit = -1
            for r in range(3):
                if d[r] < 0.0 and u[r] + tau * d[r] < 0.0:
                    tau_r = -u[r] / d[r]
                    if tau_r < tau:
                        tau = tau_r
                        hit = r
            cand = u + tau * d
            for r in range(3):
                if cand[r] < 0.0:
                    cand[r] = 0.0
            ssum = cand[0] + cand[1] + cand[2]
            cand /= ssum
            fc = _objective(cand, A, delta, w, skip)
            if fc < f:
                u = cand
                f = fc
                moved = True
                if hit >= 0:
                    # on the edge opposite corner `hit`: continue in the neighbouring face
                    nb = FN[t, hit]
                    if nb >= 0:
                        a, b = F[t, (hit + 1) % 3], F[t, (hit + 2) % 3]
                        ua, ub = u[(hit + 1) % 3], u[(hit + 2) % 3]
                        nu = np.zeros(3)
                        for r in range(3):
                            if F[nb, r] == a:
                                nu[r] = ua
                            elif F[nb, r] == b:
                                nu[r] = ub
                        t = nb
                        u = nu
                        vt[i] = t
                        _build_a(D2, F, t, vt, vu, fixed, A)
                        f = _objective(u, A, delta, w, skip)
                break
            step *= 0.5
            if step < 1e-10:
                break
        vu[i] = u
        vt[i] = t
        if not moved:
            break
    vt[i] = t
    vu[i] = u
    return f0 - f


@njit(cache=True)
def sweep(vt, vu, fixed, delta, w, D2, F, FN, n_newton, eps):
    """One Gauss-Seidel pass over the moving points; returns the total decrease.

    Parameters
    ----------
    vt, vu : (k,), (k, 3) faces and barycentric coordinates of the moving points (updated in place)
    fixed : (l,) vertex ids of fixed points on the same surface
    delta : (k, k + l) target distances of each moving point to [moving, fixed] points
    w : (k, k + l) weights (0 drops a pair)
    D2 : (n, n) squared vertex distances of the surface
    F, FN : faces and face neighbours of the surface
    """
    k = vt.shape[0]
    A = np.empty((k + fixed.shape[0], 3))
    total = 0.0
    for i in range(k):
        total += _move_point(i, vt, vu, fixed, delta[i], w[i], D2, F, FN, A, n_newton, eps)
    return total


@njit(cache=True)
def pair_distances(vt, vu, fixed, D2, F):
    """Interpolated distances ``(k, k + l)`` from the moving points to [moving, fixed] points."""
    k = vt.shape[0]
    A = np.empty((k + fixed.shape[0], 3))
    out = np.empty((k, k + fixed.shape[0]))
    for i in range(k):
        _build_a(D2, F, vt[i], vt, vu, fixed, A)
        for j in range(A.shape[0]):
            s2 = vu[i, 0] * A[j, 0] + vu[i, 1] * A[j, 1] + vu[i, 2] * A[j, 2]
            out[i, j] = np.sqrt(s2) if s2 > 0.0 else 0.0
        out[i, i] = 0.0
    return out


@njit(cache=True)
def greedy_place(dx, DY, start, m):
    """Extend images ``start`` (c,) to the first ``m`` samples: each next sample goes to the
    vertex of Y whose distances to the placed images best match ``dx`` (least squares)."""
    n = DY.shape[0]
    img = np.empty(m, np.int64)
    c = start.shape[0]
    img[:c] = start
    cost = np.zeros(n)
    for i in range(c, m):
        cost[:] = 0.0
        for j in range(i):
            col = img[j]
            t = dx[i, j]
            for v in range(n):
                r = DY[col, v] - t  # DY is symmetric: read rows
                cost[v] += r * r
        img[i] = np.argmin(cost)
    return img


@njit(cache=True)
def _descent_moves(dx, DY, img, C, max_sweeps):
    n = DY.shape[0]
    m = img.shape[0]
    for _ in range(max_sweeps):
        moved = 0
        for i in range(m):
            row = C[i]
            v = np.argmin(row)
            old = img[i]
            if row[v] < row[old] * (1.0 - 1e-12):
                img[i] = v
                moved += 1
                # every other image's cost changes through the moved one
                for k in range(m):
                    if k == i:
                        continue
                    t = dx[k, i]
                    for u in range(n):
                        a = t - DY[v, u]
                        b = t - DY[old, u]
                        C[k, u] += a * a - b * b
        if moved == 0:
            break
    return img


def discrete_descent(dx, DY, img, max_sweeps):
    """Gauss-Seidel over images: move each to the vertex of Y (any vertex) minimising
    ``C[i, v] = sum_{j != i} (dx[i, j] - DY[v, img[j]])^2``; never increases the one-sided
    distortion. ``C`` is formed once with a matrix product and then updated per move."""
    img = np.array(img, dtype=np.int64)
    dx = np.ascontiguousarray(dx, dtype=np.float64)
    rows = DY[img]                                  # (m, n): DY[img_j, v] (DY symmetric)
    sq = rows * rows
    C = (dx * dx).sum(1)[:, None] - 2.0 * (dx @ rows) + sq.sum(0)[None, :]
    C -= sq                                         # drop j == i (dx[i, i] = 0)
    return _descent_moves(dx, DY, img, C, max_sweeps)
