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
from numba import get_num_threads, njit

from ._arrays import readonly

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
    pad = np.r_[False, same, False]
    s = np.flatnonzero(same & ~pad[:-2] & ~pad[2:])
    nb[owner[s], corner[s]] = owner[s + 1]
    nb[owner[s + 1], corner[s + 1]] = owner[s]
    return nb


@njit(cache=True)
def _build_a(D, F, t, vt, vu, fixed, A):
    """Rows of A: a_j such that d^2(point in face t with bary u, j) = u . a_j (``D``: vertex
    distances, squared as they are read)."""
    r0, r1, r2 = F[t, 0], F[t, 1], F[t, 2]
    nv = vt.shape[0]
    for j in range(nv):
        tj = vt[j]
        for r in range(3):
            rr = F[t, r]
            acc = 0.0
            for c in range(3):
                d = D[rr, F[tj, c]]
                acc += (d * d) * vu[j, c]
            A[j, r] = acc
    for k in range(fixed.shape[0]):
        v = fixed[k]
        d0, d1, d2 = D[r0, v], D[r1, v], D[r2, v]
        A[nv + k, 0] = d0 * d0
        A[nv + k, 1] = d1 * d1
        A[nv + k, 2] = d2 * d2


@njit(cache=True)
def _objective(u0, u1, u2, A, delta, w, skip):
    f = 0.0
    for j in range(A.shape[0]):
        if j == skip or w[j] == 0.0:
            continue
        s2 = u0 * A[j, 0] + u1 * A[j, 1] + u2 * A[j, 2]
        s = np.sqrt(s2) if s2 > 0.0 else 0.0
        r = delta[j] - s
        f += w[j] * r * r
    return f


@njit(cache=True)
def _grad_hess(u0, u1, u2, A, delta, w, skip, eps):
    """Gradient ``g`` and the upper triangle of the Hessian ``H`` (all the reduced step uses)."""
    g0 = g1 = g2 = 0.0
    h00 = h01 = h02 = h11 = h12 = h22 = 0.0
    for j in range(A.shape[0]):
        if j == skip or w[j] == 0.0:
            continue
        a0, a1, a2 = A[j, 0], A[j, 1], A[j, 2]
        s2 = u0 * a0 + u1 * a1 + u2 * a2
        s = np.sqrt(max(s2, eps * eps))
        c = w[j] * (1.0 - delta[j] / s)
        h = w[j] * delta[j] / (2.0 * s * s * s)
        g0 += c * a0
        g1 += c * a1
        g2 += c * a2
        h00 += h * a0 * a0
        h01 += h * a0 * a1
        h02 += h * a0 * a2
        h11 += h * a1 * a1
        h12 += h * a1 * a2
        h22 += h * a2 * a2
    return g0, g1, g2, h00, h01, h02, h11, h12, h22


@njit(cache=True)
def _move_point(i, vt, vu, fixed, delta, w, D, F, FN, A, n_newton, eps):
    """Damped Newton steps of point i; returns the decrease of f_i (>= 0)."""
    skip = i
    t = vt[i]
    u0, u1, u2 = vu[i, 0], vu[i, 1], vu[i, 2]
    _build_a(D, F, t, vt, vu, fixed, A)
    f0 = _objective(u0, u1, u2, A, delta, w, skip)
    f = f0
    for _ in range(n_newton):
        g0_, g1_, g2_, H00, H01, H02, H11, H12, H22 = _grad_hess(u0, u1, u2, A, delta, w, skip, eps)
        # reduced coordinates: u = u0 + E z, E = [[-1, -1], [1, 0], [0, 1]]
        g0 = g1_ - g0_
        g1 = g2_ - g0_
        h00 = H00 - 2 * H01 + H11
        h11 = H00 - 2 * H02 + H22
        h01 = H00 - H01 - H02 + H12
        lam = 1e-9 * (abs(h00) + abs(h11)) + 1e-300
        det = (h00 + lam) * (h11 + lam) - h01 * h01
        if det > 0.0 and h00 + lam > 0.0:
            z0 = -((h11 + lam) * g0 - h01 * g1) / det
            z1 = -(-h01 * g0 + (h00 + lam) * g1) / det
        else:
            z0, z1 = -g0, -g1
        if g0 * z0 + g1 * z1 >= 0.0:  # not a descent direction: gradient step
            z0, z1 = -g0, -g1
        d0, d1, d2 = -z0 - z1, z0, z1
        if abs(d0) + abs(d1) + abs(d2) < 1e-14:
            break
        step = 1.0
        moved = False
        for _ls in range(30):
            # largest fraction of the step that stays in the triangle
            tau = step
            hit = -1
            if d0 < 0.0 and u0 + tau * d0 < 0.0:
                tau_r = -u0 / d0
                if tau_r < tau:
                    tau = tau_r
                    hit = 0
            if d1 < 0.0 and u1 + tau * d1 < 0.0:
                tau_r = -u1 / d1
                if tau_r < tau:
                    tau = tau_r
                    hit = 1
            if d2 < 0.0 and u2 + tau * d2 < 0.0:
                tau_r = -u2 / d2
                if tau_r < tau:
                    tau = tau_r
                    hit = 2
            c0 = max(u0 + tau * d0, 0.0)
            c1 = max(u1 + tau * d1, 0.0)
            c2 = max(u2 + tau * d2, 0.0)
            ssum = c0 + c1 + c2
            c0 /= ssum
            c1 /= ssum
            c2 /= ssum
            fc = _objective(c0, c1, c2, A, delta, w, skip)
            if fc < f:
                u0, u1, u2 = c0, c1, c2
                f = fc
                moved = True
                if hit >= 0:
                    # on the edge opposite corner `hit`: continue in the neighbouring face
                    nb = FN[t, hit]
                    if nb >= 0:
                        ka, kb = (hit + 1) % 3, (hit + 2) % 3
                        a, b = F[t, ka], F[t, kb]
                        ua = u0 if ka == 0 else (u1 if ka == 1 else u2)
                        ub = u0 if kb == 0 else (u1 if kb == 1 else u2)
                        n0 = ua if F[nb, 0] == a else (ub if F[nb, 0] == b else 0.0)
                        n1 = ua if F[nb, 1] == a else (ub if F[nb, 1] == b else 0.0)
                        n2 = ua if F[nb, 2] == a else (ub if F[nb, 2] == b else 0.0)
                        t = nb
                        u0, u1, u2 = n0, n1, n2
                        vt[i] = t
                        _build_a(D, F, t, vt, vu, fixed, A)
                        f = _objective(u0, u1, u2, A, delta, w, skip)
                break
            step *= 0.5
            if step < 1e-10:
                break
        vu[i, 0], vu[i, 1], vu[i, 2] = u0, u1, u2
        vt[i] = t
        if not moved:
            break
    vt[i] = t
    vu[i, 0], vu[i, 1], vu[i, 2] = u0, u1, u2
    return f0 - f


@njit(cache=True)
def sweep(vt, vu, fixed, delta, w, D, F, FN, n_newton, eps):
    """One Gauss-Seidel pass over the moving points; returns the total decrease.

    Parameters
    ----------
    vt, vu : (k,), (k, 3) faces and barycentric coordinates of the moving points (updated in place)
    fixed : (l,) vertex ids of fixed points on the same surface
    delta : (k, k + l) target distances of each moving point to [moving, fixed] points
    w : (k, k + l) weights (0 drops a pair)
    D : (n, n) vertex distances of the surface (squared as they are read: no second (n, n)
        matrix is kept)
    F, FN : faces and face neighbours of the surface
    """
    k = vt.shape[0]
    A = np.empty((k + fixed.shape[0], 3))
    total = 0.0
    for i in range(k):
        total += _move_point(i, vt, vu, fixed, delta[i], w[i], D, F, FN, A, n_newton, eps)
    return total


@njit(cache=True)
def pair_distances(vt, vu, fixed, D, F, square):
    """Interpolated distances ``(k, k + l)`` from the moving points to [moving, fixed] points.

    ``D``: vertex distances, squared as they are read when ``square`` (else squared
    distances; a flag, not a default, so that both callers share one compilation). Row i first
    forms ``u_i^T D2[F_{t_i}, :]`` (three contiguous rows of ``D``, read in order), then reads it
    at the others' corners: the same interpolant as
    :func:`_build_a` with far fewer scattered reads of the large matrix.
    """
    k = vt.shape[0]
    n = D.shape[0]
    nf = fixed.shape[0]
    out = np.empty((k, k + nf))
    rowv = np.empty(n)
    for i in range(k):
        t = vt[i]
        a0, a1, a2 = D[F[t, 0]], D[F[t, 1]], D[F[t, 2]]
        u0, u1, u2 = vu[i, 0], vu[i, 1], vu[i, 2]
        if square:
            for v in range(n):
                rowv[v] = u0 * (a0[v] * a0[v]) + u1 * (a1[v] * a1[v]) + u2 * (a2[v] * a2[v])
        else:
            for v in range(n):
                rowv[v] = u0 * a0[v] + u1 * a1[v] + u2 * a2[v]
        for j in range(k):
            tj = vt[j]
            s2 = vu[j, 0] * rowv[F[tj, 0]] + vu[j, 1] * rowv[F[tj, 1]] + vu[j, 2] * rowv[F[tj, 2]]
            out[i, j] = np.sqrt(s2) if s2 > 0.0 else 0.0
        for q in range(nf):
            s2 = rowv[fixed[q]]
            out[i, k + q] = np.sqrt(s2) if s2 > 0.0 else 0.0
        out[i, i] = 0.0
    return out


_NO_COST = np.zeros((0, 0))  # no per-image costs


@njit(cache=True)
def _argmin(x):
    """``np.argmin`` (first index of the minimum) for finite ``x``, about twice as fast: the
    minimum is taken over eight independent lanes, then its first position is looked up."""
    n = x.shape[0]
    n8 = n - n % 8
    m0 = m1 = m2 = m3 = m4 = m5 = m6 = m7 = np.inf
    for u in range(0, n8, 8):
        a0, a1, a2, a3 = x[u], x[u + 1], x[u + 2], x[u + 3]
        a4, a5, a6, a7 = x[u + 4], x[u + 5], x[u + 6], x[u + 7]
        m0 = a0 if a0 < m0 else m0
        m1 = a1 if a1 < m1 else m1
        m2 = a2 if a2 < m2 else m2
        m3 = a3 if a3 < m3 else m3
        m4 = a4 if a4 < m4 else m4
        m5 = a5 if a5 < m5 else m5
        m6 = a6 if a6 < m6 else m6
        m7 = a7 if a7 < m7 else m7
    m = min(min(min(m0, m1), min(m2, m3)), min(min(m4, m5), min(m6, m7)))
    for u in range(n8, n):
        if x[u] < m:
            m = x[u]
    for u in range(n):
        if x[u] == m:
            return u
    return 0


@njit(cache=True)
def _sq_dist_sum(dx, DY, img):
    """``sum_ij (dx[i, j] - DY[img_i, img_j])^2``: the one-sided distortion times ``m^2``."""
    m = img.shape[0]
    f = 0.0
    for i in range(m):
        for j in range(m):
            r = dx[i, j] - DY[img[i], img[j]]
            f += r * r
    return f


@njit(cache=True)
def _place(dx, DY, img, c, R, C, block, U):
    """Greedy placement of samples ``c..m-1`` given ``img[:c]``; leaves in ``C[k]`` the cost
    ``sum_{j<k} (dx[k, j] - DY[img_j, :])^2`` that placed sample k (for all k) and in ``R[k]``
    the row ``DY[img_k]``.

    Blocked: for the rows of a block the part over samples placed before the block is one
    matrix product ``dx[block, :b] @ R[:b]`` (expanded square), the rest is summed directly.
    ``U`` ``(m', n)``: per-image costs of the first ``m'`` samples, added to their rows
    (``(0, 0)``: none); they stay in ``C`` through the descent, which updates rows by differences.
    """
    m = dx.shape[0]
    n = DY.shape[0]
    S = np.zeros(n)  # sum_{j < b} R[j]^2
    for b in range(0, m, block):
        e = min(b + block, m)
        if b > 0:
            G = np.dot(np.ascontiguousarray(dx[b:e, :b]), R[:b])
        for k in range(b, e):
            row = C[k]
            if b > 0:
                a = 0.0
                for j in range(b):
                    a += dx[k, j] * dx[k, j]
                g = G[k - b]
                for u in range(n):
                    row[u] = a - 2.0 * g[u] + S[u]
            else:
                row[:] = 0.0
            for j in range(b, k):
                t = dx[k, j]
                rj = R[j]
                for u in range(n):
                    d = t - rj[u]
                    row[u] += d * d
            if U.shape[0] > k:  # a per-image cost of sample k (its signature's mismatch)
                uk = U[k]
                for u in range(n):
                    row[u] += uk[u]
            if k >= c:
                img[k] = _argmin(row)
            rk, dyk = R[k], DY[img[k]]
            for u in range(n):   # (an element loop: a slice assignment compiles a shape check)
                rk[u] = dyk[u]
        for k in range(b, e):
            rk = R[k]
            for u in range(n):
                S[u] += rk[u] * rk[u]


@njit(cache=True)
def _complete(dx, R, C, block):
    """Add ``sum_{j>k} (dx[k, j] - R[j])^2`` to each ``C[k]`` (blocked like :func:`_place`)."""
    m = dx.shape[0]
    n = R.shape[1]
    S = np.zeros(n)  # sum_{j >= e} R[j]^2
    for e in range(m, 0, -block):
        b = max(e - block, 0)
        if e < m:
            G = np.dot(np.ascontiguousarray(dx[b:e, e:]), R[e:])
        for k in range(b, e):
            row = C[k]
            if e < m:
                a = 0.0
                for j in range(e, m):
                    a += dx[k, j] * dx[k, j]
                g = G[k - b]
                for u in range(n):
                    row[u] += a - 2.0 * g[u] + S[u]
            for j in range(k + 1, e):
                t = dx[k, j]
                rj = R[j]
                for u in range(n):
                    d = t - rj[u]
                    row[u] += d * d
        for k in range(b, e):
            rk = R[k]
            for u in range(n):
                S[u] += rk[u] * rk[u]


@njit(cache=True)
def _flush(dx, DY, C, pend, dD, v_new, v_old, tot, r):
    """Apply ``r`` pending moves to every row of ``C`` in one pass (see :func:`_descend`)."""
    m, n = C.shape
    coef = np.empty(r)
    for k in range(m):
        ck = C[k]
        for u in range(n):
            ck[u] += tot[u]
        for s in range(r):
            if pend[s] == k:  # row k leaves out its own image: take back that move's dS
                coef[s] = 0.0
                a, b = DY[v_new[s]], DY[v_old[s]]
                for u in range(n):
                    ck[u] -= a[u] * a[u] - b[u] * b[u]
            else:
                coef[s] = -2.0 * dx[k, pend[s]]
        for s in range(r):
            cs = coef[s]
            if cs != 0.0:
                ds = dD[s]
                for u in range(n):
                    ck[u] += cs * ds[u]
    tot[:] = 0.0


@njit(cache=True)
def _descend_steps(dx, DY, img, C, max_sweeps, state, pend, v_new, v_old, dD, tot, buf, limit):
    """Gauss-Seidel over images on the cost table ``C``, resumable (see :func:`_descend`).

    ``state`` = (sweep, next sample, moves this sweep, pending moves, work since the last
    pass). Returns True when the pending moves are due to be applied to ``C`` (the caller
    applies them, sets ``state[3:5] = 0`` and calls again), False when the descent is over.
    """
    m = img.shape[0]
    n = DY.shape[0]
    cap = pend.shape[0]
    sw, i, moved, r, work = state[0], state[1], state[2], state[3], state[4]
    while sw < max_sweeps:
        while i < m:
            if r == 0:
                row = C[i]
            else:
                ci = C[i]
                for u in range(n):
                    buf[u] = ci[u] + tot[u]
                for s in range(r):
                    if pend[s] == i:  # row i leaves out its own image: take back that move's dS
                        a, b = DY[v_new[s]], DY[v_old[s]]
                        for u in range(n):
                            buf[u] -= a[u] * a[u] - b[u] * b[u]
                    else:
                        t = -2.0 * dx[i, pend[s]]
                        dd = dD[s]
                        for u in range(n):
                            buf[u] += t * dd[u]
                row = buf
                work += r
            v = _argmin(row)
            old = img[i]
            if row[v] < row[old] - 1e-12 * abs(row[old]):
                img[i] = v
                moved += 1
                a, b = DY[v], DY[old]
                for u in range(n):
                    dD[r, u] = a[u] - b[u]
                    tot[u] += a[u] * a[u] - b[u] * b[u]
                pend[r] = i
                v_new[r] = v
                v_old[r] = old
                r += 1
            i += 1
            if r > 0 and (r == cap or work >= limit):
                state[0], state[1], state[2], state[3], state[4] = sw, i, moved, r, work
                return True
        if moved == 0:
            break
        sw += 1
        i = 0
        moved = 0
    state[0], state[1], state[2], state[3], state[4] = max_sweeps, m, 0, r, work
    return False


@njit(cache=True)
def _take_back_own(C, DY, pend, v_new, v_old, r):
    """Row k of ``C`` leaves out image k: undo the ``dS`` a pass added for k's own moves."""
    n = C.shape[1]
    for s in range(r):
        ck = C[pend[s]]
        a, b = DY[v_new[s]], DY[v_old[s]]
        for u in range(n):
            ck[u] -= a[u] * a[u] - b[u] * b[u]


def _work_arrays(cap, n):
    return (np.zeros(5, np.int64), np.empty(cap, np.int64), np.empty(cap, np.int64),
            np.empty(cap, np.int64), np.empty((cap + 1, n)), np.zeros(n), np.empty(n))


@njit(cache=True)
def _descend(dx, DY, img, C, max_sweeps, cap, ratio):
    """Gauss-Seidel over images on the cost table ``C`` (see :func:`place_and_descend`).

    A move of image i from ``old`` to ``v`` changes every other row k of ``C`` by
    ``dS - 2 dx[k, i] dD`` with ``dS = DY[v]^2 - DY[old]^2`` and ``dD = DY[v] - DY[old]``.
    Moves are kept pending (their ``dD`` rows, small enough to stay in cache) and added to a
    row only when it is read; they are applied to all of ``C`` in one pass once the rows
    read since the last pass, times the moves pending, reach ``ratio`` times the rows of
    ``C``, or ``cap`` moves are pending. This reads and writes ``C`` (too large for the
    cache) a few times per sweep instead of once per move.
    """
    n = DY.shape[0]
    state = np.zeros(5, np.int64)
    pend = np.empty(cap, np.int64)
    v_new = np.empty(cap, np.int64)
    v_old = np.empty(cap, np.int64)
    dD = np.empty((cap + 1, n))
    tot = np.zeros(n)  # sum of the pending dS
    buf = np.empty(n)
    limit = ratio * img.shape[0]
    while _descend_steps(dx, DY, img, C, max_sweeps, state, pend, v_new, v_old, dD, tot, buf, limit):
        _flush(dx, DY, C, pend, dD, v_new, v_old, tot, state[3])
        state[3] = 0
        state[4] = 0
    return img


def descend_blas(dx, DY, img, C, max_sweeps, *, cap=32, ratio=2.0):
    """:func:`_descend` with the passes over ``C`` as one BLAS product each (``C`` C-ordered).

    A pass adds ``[-2 dx[:, pend], 1] @ [dD; tot]`` to ``C`` (``dgemm`` with ``beta = 1``,
    in place on ``C.T``), then takes back each moved image's ``dS`` from its own row.
    """
    from scipy.linalg.blas import dgemm

    m = len(img)
    state, pend, v_new, v_old, dD, tot, buf = _work_arrays(cap, DY.shape[0])
    coef = np.empty((m, cap + 1))
    Ct = C.T  # Fortran-ordered view: dgemm updates it in place
    while _descend_steps(dx, DY, img, C, max_sweeps, state, pend, v_new, v_old, dD, tot, buf, ratio * m):
        r = int(state[3])
        I = pend[:r]
        dD[r] = tot
        coef[:, :r] = dx[:, I]
        coef[:, :r] *= -2.0
        coef[I, np.arange(r)] = 0.0  # row k leaves out its own image
        coef[:, r] = 1.0
        out = dgemm(1.0, dD[: r + 1].T, coef[:, : r + 1].T, 1.0, Ct, overwrite_c=True)
        if not np.shares_memory(out, C):  # pragma: no cover - dgemm copied instead of updating
            C[...] = out.T
        _take_back_own(C, DY, pend, v_new, v_old, r)
        tot[:] = 0.0
        state[3] = 0
        state[4] = 0
    return img


def place_and_descend(dx, DY, start, max_sweeps, R, C, U=None, *, block=16, cap=32, ratio=2.0):
    """:func:`_place_and_descend`; ``U`` (optional, ``(m', n)``): per-image costs of the first
    ``m'`` samples, added to their placement and descent costs and to the cost returned."""
    U = _NO_COST if U is None else np.ascontiguousarray(U, dtype=np.float64)
    return _place_and_descend(dx, DY, np.asarray(start, dtype=np.int64), max_sweeps, R, C, U, block, cap, ratio)


@njit(cache=True)
def _place_and_descend(dx, DY, start, max_sweeps, R, C, U, block, cap, ratio):
    """Greedy placement of all samples from images ``start`` of the first ones, then discrete
    descent; returns ``(images, sum_ij (dx[i, j] - DY[img_i, img_j])^2)``.

    Placement: sample k goes to the vertex v of Y minimising ``sum_{j<k} (dx[k, j] - DY[v, img_j])^2``.
    Descent: Gauss-Seidel over images, each moving to the vertex of Y (any vertex) minimising
    ``C[i, v] = sum_{j != i} (dx[i, j] - DY[v, img_j])^2``; it never increases the one-sided
    distortion. ``DY`` must be symmetric (rows are read for columns). ``R`` and ``C`` are
    ``(m, n)`` work arrays (overwritten), so that repeated calls reuse their memory.
    """
    m = dx.shape[0]
    img = np.empty(m, np.int64)
    c = start.shape[0]
    for i in range(c):   # (an element loop: a slice assignment compiles a shape check)
        img[i] = start[i]
    _place(dx, DY, img, c, R, C, block, U)
    if max_sweeps > 0:
        _complete(dx, R, C, block)
        img = _descend(dx, DY, img, C, max_sweeps, cap, ratio)
    f = _sq_dist_sum(dx, DY, img)
    for k in range(min(U.shape[0], m)):
        f += U[k, img[k]]
    return img, f


@njit(cache=True, nogil=True)
def gather_block(A, idx):
    """``A[idx][:, idx]`` in one pass (a row's entries gathered while it is in cache): the
    initial search's distances on a vertex subset, made for every pair of shapes."""
    n = idx.shape[0]
    out = np.empty((n, n), A.dtype)
    for a in range(n):
        row = A[idx[a]]
        for b in range(n):
            out[a, b] = row[idx[b]]
    return out


#: Interleaved slices of the candidates per thread in :func:`coarse_starts`.
CHUNKS_PER_THREAD = 4


def coarse_starts(dx, DY, candidates, max_sweeps, U=None):
    """:func:`place_and_descend` from each candidate image of the first sample:
    images ``(s, m)`` and their summed squared distortions ``(s,)`` (plus their per-image costs
    ``U``, if given).

    The candidates are independent: with more than one numba thread
    (``numba.get_num_threads()``) they are split into ``CHUNKS_PER_THREAD`` interleaved
    slices per thread, handed out to that many Python threads running the compiled kernel
    without the GIL as they come free, with the same results as one after the other.
    Threads rather than a ``prange`` loop: the parallel kernel took most of the
    first run's compilation (45 of 69 s of a first ``gromov.match``), and it is never entered
    in a forked worker of :mod:`gromov.experiments.pairwise`, which numba's OpenMP layer
    aborts.
    """
    candidates = np.asarray(candidates, dtype=np.int64)
    DY = readonly(DY)   # one compilation, whether a shape's matrix or a slice of it
    s = len(candidates)
    imgs = np.empty((s, dx.shape[0]), np.int64)
    costs = np.empty(s)
    U = _NO_COST if U is None else np.ascontiguousarray(U, dtype=np.float64)
    threads = min(get_num_threads(), s)
    if threads > 1:
        from concurrent.futures import ThreadPoolExecutor

        # CHUNKS_PER_THREAD interleaved slices per thread, handed out as threads come free:
        # the candidates' costs differ, and one task per candidate made the hand-outs, not the
        # work, most of the time on small shapes
        tasks = min(s, CHUNKS_PER_THREAD * threads)

        def part(q):   # candidates q, q + tasks, q + 2 tasks, ...
            _coarse_chunk(dx, DY, candidates, max_sweeps, imgs, costs, q, tasks, U)

        with ThreadPoolExecutor(threads) as pool:
            for _ in pool.map(part, range(tasks)):
                pass
    else:
        _coarse_chunk(dx, DY, candidates, max_sweeps, imgs, costs, 0, 1, U)
    return imgs, costs


@njit(cache=True, nogil=True)
def _coarse_chunk(dx, DY, candidates, max_sweeps, imgs, costs, first, step, U):
    """Candidates ``first, first + step, ...`` of :func:`coarse_starts`, into ``imgs, costs``."""
    m = dx.shape[0]
    n = DY.shape[0]
    R = np.empty((m, n))
    C = np.empty((m, n))
    start = np.empty(1, np.int64)
    for q in range(first, candidates.shape[0], step):
        start[0] = candidates[q]
        # typed int64, not as literals: one compilation of the kernels below for all callers
        img, f = _place_and_descend(dx, DY, start, max_sweeps, R, C, U, np.int64(16), np.int64(32), 2.0)
        for i in range(m):
            imgs[q, i] = img[i]
        costs[q] = f


def place_and_descend_blas(dx, DY, start, max_sweeps, R, C, *, block=16, cap=32, ratio=2.0):
    """:func:`place_and_descend` with the descent's passes over ``C`` done by BLAS
    (:func:`descend_blas`): for many samples, where those passes are most of the work."""
    m = dx.shape[0]
    img = np.empty(m, np.int64)
    img[: len(start)] = start
    _place(dx, DY, img, len(start), R, C, block, _NO_COST)
    if max_sweeps > 0:
        _complete(dx, R, C, block)
        img = descend_blas(dx, DY, img, C, max_sweeps, cap=cap, ratio=ratio)
    return img, _sq_dist_sum(dx, DY, img)


@njit(cache=True)
def spaced_in_order(order, D, radius, k):
    """Up to ``k`` vertices taken greedily in ``order``, each farther than ``radius`` from
    every one taken before it (``D[v, w] > radius``; ``D`` symmetric): the first-sample
    candidates of the initial search (:func:`gromov.search._candidates`)."""
    n = order.shape[0]
    free = np.ones(D.shape[0], np.bool_)   # per vertex: farther than radius from all taken
    out = np.empty(k, np.int64)
    taken = 0
    i = 0
    while taken < k:
        while i < n and not free[order[i]]:
            i += 1
        if i == n:
            break
        v = order[i]
        out[taken] = v
        taken += 1
        row = D[v]
        for w in range(D.shape[0]):
            if not row[w] > radius:
                free[w] = False
    return out[:taken]
