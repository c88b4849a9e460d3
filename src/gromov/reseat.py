r"""Samples placed in the wrong region by GMDS, moved where the other samples say they belong.

GMDS moves each image by local descent, so a group of samples whose images landed on the
wrong part of the target (a leg on another leg, with a weld between them) stays there: each
is held by its neighbours. With every other pair of the two-sided correspondence fixed, the
best place for one image can be searched over every working vertex at once. For the sample
``i`` of X and a vertex ``v`` of Y, the cost is the truncated quadratic (Blake & Zisserman,
*Visual Reconstruction*, MIT Press 1987, ch. 3)

.. math:: c_i(v) = \sum_{b \ne i} \min\big((d_X(x_i, x_b) - d_Y(v, y_b))^2,\ \kappa^2\big),

over the pairs ``(x_b, y_b)`` of the correspondence, with :math:`\kappa` the ``keep``
quantile of the current absolute residuals (:data:`gromov.gmds.TRIM_KEEP`, the trimmed
distortion's fraction; over the residuals that are not exactly 0, so that distances that
agree exactly on most pairs still give a cap). The cap lets the pairs that the wrong region
itself distorts be outvoted by the rest, as least trimmed squares does (Rousseeuw, J. Am.
Stat. Assoc. 79, 1984). An image moves when its best vertex lies farther from it than the samples' covering
radius (farther than any point of the target lies from its nearest sample): a jump to
another sample's cell, not a local step, which GMDS itself makes. The moved correspondence is
then a start for GMDS, and the caller keeps the result only if it lowers the distortion.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit

from .gmds import TRIM_KEEP, SurfaceDistance, SurfacePoints

__all__ = ["covering_radius", "reseat_start"]


@njit(cache=True, nogil=True)
def _capped_rows(rows, cols, skip, cap2, out, v0, v1):
    """``out[v, i] = sum_{b != skip[i]} min((rows[i, b] - cols[v, b])^2, cap2)`` for v0 <= v < v1."""
    m, nb = rows.shape
    for v in range(v0, v1):
        for i in range(m):
            s = 0.0
            for b in range(nb):
                if b != skip[i]:
                    r = rows[i, b] - cols[v, b]
                    r *= r
                    s += min(r, cap2)
            out[v, i] = s


def _capped_costs(rows, cols, skip, cap2):
    """:func:`_capped_rows` over every vertex: blocks of vertices on ``numba.get_num_threads()``
    Python threads running the compiled loop without the GIL (not a ``prange`` loop, which
    numba's OpenMP layer aborts in a forked worker of :mod:`gromov.experiments.pairwise`)."""
    n = cols.shape[0]
    out = np.empty((n, rows.shape[0]))
    threads = min(get_num_threads(), max(1, n // 256))
    if threads > 1:
        from concurrent.futures import ThreadPoolExecutor

        cuts = np.linspace(0, n, threads + 1).astype(np.int64)
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda t: _capped_rows(rows, cols, skip, cap2, out, cuts[t], cuts[t + 1]),
                          range(threads)))
    else:
        _capped_rows(rows, cols, skip, cap2, out, 0, n)
    return out


def covering_radius(S: SurfaceDistance, samples: np.ndarray) -> float:
    """Largest distance from a working vertex to its nearest sample."""
    return float(S.distances[:, np.asarray(samples, dtype=np.int64)].min(axis=1).max())


def _to_every_vertex(S: SurfaceDistance, pts: SurfacePoints) -> np.ndarray:
    """``(n, k)``: interpolated distances from every working vertex to the surface points,
    as GMDS interpolates them (:mod:`gromov._gmds_kernel`)."""
    k = len(pts.face)
    return np.ascontiguousarray(S.between(pts, np.arange(S.mesh.n_vertices))[:, k:].T)


def _best_vertices(S: SurfaceDistance, rows, cols, skip, cap2, current, radius):
    """The best vertex of each row's image, and whether it is a jump beyond ``radius``."""
    cost = _capped_costs(np.ascontiguousarray(rows), cols, np.asarray(skip, dtype=np.int64), cap2)
    best = np.argmin(cost, axis=0)
    jump = (S.distances[best, current] > radius) & (cost[best, np.arange(len(best))]
                                                    < cost[current, np.arange(len(best))])
    return best, jump


def reseat_start(X: SurfaceDistance, Y: SurfaceDistance, P, Q, img_p: SurfacePoints, img_q: SurfacePoints,
                 dx: np.ndarray, dy: np.ndarray, keep: float = TRIM_KEEP):
    """A new start for GMDS with every image that jumps moved, or None if none does.

    Parameters
    ----------
    X, Y : SurfaceDistance
    P, Q : ndarray of int
        The samples (``M`` on X, ``K`` on Y).
    img_p, img_q : SurfacePoints
        Their images (on Y, on X): the correspondence pairs ``(P, img_p)`` then ``(img_q, Q)``.
    dx, dy : ndarray, shape (M + K, M + K)
        The correspondence's distances on X and on Y (:meth:`SymmetricGMDS.blocks`).
    keep : float
        The quantile of the squared residuals at which each is capped.

    Returns
    -------
    (SurfacePoints, SurfacePoints) or None
        The moved images of P and of Q (a moved image sits at its vertex).
    """
    P, Q = np.asarray(P, dtype=np.int64), np.asarray(Q, dtype=np.int64)
    M, K = len(P), len(Q)
    off = ~np.eye(M + K, dtype=bool)
    r2 = np.square(dx - dy)[off]
    r2 = r2[r2 > 0.0]
    if not r2.size:   # distances agree on every pair
        return None
    cap2 = float(np.quantile(r2, keep))
    # distances from every vertex of Y to each pair's point on Y, and the same on X
    to_y = np.hstack([_to_every_vertex(Y, img_p), Y.distances[:, Q]])
    to_x = np.hstack([X.distances[:, P], _to_every_vertex(X, img_q)])
    vp, vq = img_p.vertex(Y.faces), img_q.vertex(X.faces)
    bp, jp = _best_vertices(Y, dx[:M], to_y, np.arange(M), cap2, vp, covering_radius(Y, Q))
    bq, jq = _best_vertices(X, dy[M:], to_x, M + np.arange(K), cap2, vq, covering_radius(X, P))
    if not (jp.any() or jq.any()):
        return None
    return _moved(Y, img_p, bp, jp), _moved(X, img_q, bq, jq)


def _moved(S: SurfaceDistance, pts: SurfacePoints, best: np.ndarray, jump: np.ndarray) -> SurfacePoints:
    at = SurfacePoints.at_vertices(S.mesh, best)
    face, bary = pts.face.copy(), pts.bary.copy()
    face[jump], bary[jump] = at.face[jump], at.bary[jump]
    return SurfacePoints(face, bary)
