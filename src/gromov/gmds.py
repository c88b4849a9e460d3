r"""Generalized multidimensional scaling (GMDS) and the symmetric Gromov-Hausdorff distortion.

GMDS (Bronstein, Bronstein & Kimmel, PNAS 103(5), 2006; SIAM J. Sci. Comput. 28(5), 2006)
embeds samples of one surface into another: samples ``P = {p_1..p_M}`` of X with distances
``d_X`` are mapped to points ``q'_i`` anywhere on Y's working mesh (face + barycentric
coordinates) minimising the distortion

.. math:: \sigma(Q') = \sum_{i<j} w_{ij}\,\big(d_X(p_i, p_j) - d_Y(q'_i, q'_j)\big)^2 .

The symmetric version of Bronstein et al. 2010, §4, uses the two-sided correspondence
:math:`C = (P \times Q') \cup (Q \times P')` (``P'`` on X are images of Y's samples ``Q``) and
compares the full block matrices

.. math::
   \mathrm{dis}(C) = \Big\| \begin{pmatrix} D_X(P,P) & D_X(P,P') \\ D_X(P',P) & D_X(P',P') \end{pmatrix}
   - \begin{pmatrix} D_Y(Q',Q') & D_Y(Q',Q) \\ D_Y(Q,Q') & D_Y(Q,Q) \end{pmatrix} \Big\| ,

including the cross terms. Both embeddings are optimised alternately (block coordinate
descent: with ``P'`` fixed, the ``Q'`` sub-problem is an ordinary weighted GMDS whose targets
include ``d_X(p_i, p'_k)``, and vice versa), so each sweep lowers the L2 distortion.
The Gromov-Hausdorff estimate is :math:`\hat d_{GH} = \tfrac12 \min_C \mathrm{dis}(C)`.

Norms: ``"l2"`` (root mean square over the ordered pairs), ``"p:VALUE"`` by iteratively
reweighted least squares (weights :math:`|r|^{p-2}`), and ``"linf"`` (the maximum) by IRLS
with a growing exponent.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ._gmds_kernel import face_neighbours, pair_distances, sweep
from .errors import MetricError
from .mesh import Mesh

__all__ = ["SurfaceDistance", "SurfacePoints", "parse_norm", "norm_value", "trimmed_rms", "TRIM_KEEP",
           "log_ratio_residuals", "sample_trimmed_rms", "SymmetricGMDS"]

logger = logging.getLogger(__name__)


def parse_norm(norm) -> float:
    """``"l2"`` -> 2, ``"linf"`` -> inf, ``"p:1.5"`` or a number -> that exponent (>= 1)."""
    if isinstance(norm, (int, float)) and not isinstance(norm, bool):
        p = float(norm)
    elif isinstance(norm, str):
        s = norm.strip().lower()
        if s in ("l2", "2"):
            p = 2.0
        elif s in ("linf", "inf", "max"):
            p = np.inf
        elif s.startswith("p:") or s.startswith("l"):
            try:
                p = float(s[2:] if s.startswith("p:") else s[1:])
            except ValueError:
                raise ValueError(f"norm must be 'l2', 'linf' or 'p:VALUE', got {norm!r}") from None
        else:
            raise ValueError(f"norm must be 'l2', 'linf' or 'p:VALUE', got {norm!r}")
    else:
        raise TypeError(f"norm must be a string or a number, got {type(norm).__name__}")
    if not p >= 1:
        raise ValueError(f"the norm's exponent must be >= 1, got {p}")
    return p


def norm_value(r: np.ndarray, p: float) -> float:
    """``(mean |r|^p)^(1/p)`` over the entries of ``r`` (the maximum for ``p = inf``)."""
    r = np.abs(np.asarray(r, dtype=float))
    if r.size == 0:
        return 0.0
    if np.isinf(p):
        return float(r.max())
    return float(np.mean(r**p) ** (1.0 / p))


TRIM_KEEP = 0.8
"""Fraction of the pairs the trimmed distortion keeps (:func:`trimmed_rms`).

Chosen on the synthetic set and TOSCA classes the paper's experiments do not use (horse,
centaur, wolf, michael): the best diffusion ranking of those tried on both sets, EER with welds
0.0% (synthetic) and 0.6% (held-out) against 4.7% and 1.1% for the RMS
(``.venv/bin/python benchmarks/studies/recognition_statistics.py --set synthetic|heldout``; see
docs/design/recognition.md)."""


def trimmed_rms(r: np.ndarray, keep: float = TRIM_KEEP) -> float:
    r"""Root mean square of the best-fitting fraction ``keep`` of the residuals.

    .. math:: \sigma_h(r) = \Big(\frac1h \sum_{k=1}^{h} r_{(k)}^2\Big)^{1/2},
              \qquad |r_{(1)}| \le |r_{(2)}| \le \dots,\quad h = \lceil \mathit{keep}\cdot n \rceil ,

    the objective of least trimmed squares (Rousseeuw, J. Am. Stat. Assoc. 79, 1984). As a
    distortion of a correspondence it ignores the ``1 - keep`` pairs whose distances fit worst:
    a local change of topology (a weld, a handle) alters the distances of the pairs near it
    most, which the trimmed distortion can leave out, while two different shapes disagree on
    most pairs -- in the spirit of partial similarity (Bronstein, Bronstein, Bruckstein &
    Kimmel, IJCV 84, 2009), at a fixed fraction of the pairs. (With the heat-kernel diffusion
    distance a weld moves whole rows -- every pair of a sample near it -- and all distances a
    little: :func:`sample_trimmed_rms` and ``benchmarks/studies/weld_rows.py``.) ``keep = 1`` is the
    RMS (:func:`norm_value` with p = 2).
    """
    if not 0.0 < keep <= 1.0:
        raise ValueError(f"keep must be in (0, 1], got {keep}")
    r2 = np.square(np.asarray(r, dtype=float).ravel())
    if r2.size == 0:
        return 0.0
    h = max(1, int(np.ceil(keep * r2.size - 1e-9)))
    if h < r2.size:
        r2 = np.partition(r2, h - 1)[:h]
    return float(np.sqrt(np.mean(r2)))



def sample_trimmed_rms(e: np.ndarray, keep: float) -> float:
    r"""RMS residual over the pairs of the best-fitting fraction ``keep`` of the *samples*.

    With ``e`` the square residual matrix of a correspondence (e.g.
    :attr:`gromov.MatchResult.pair_distortion`; its diagonal is ignored), each sample's own
    RMS residual :math:`\rho_a = (\frac{1}{n-1}\sum_{b \ne a} e_{ab}^2)^{1/2}` ranks the
    samples; with :math:`S` the :math:`h = \lceil keep \cdot n \rceil` samples of smallest
    :math:`\rho_a` (at least 2; ties by index),

    .. math:: \sigma(e) = \Big(\frac{1}{h(h-1)} \sum_{a \ne b \in S} e_{ab}^2\Big)^{1/2}.

    Least trimmed squares (Rousseeuw 1984) over samples instead of pairs: it sets aside
    whole rows, which is how a weld moves the heat-kernel diffusion distance (between far
    points :math:`d_t^2 \approx k_{2t}(x,x) + k_{2t}(y,y)`, and a weld changes the return
    probability of the points near it). ``keep = 1`` is the RMS of the off-diagonal entries.
    Not used by :func:`gromov.match` or recognition; measured in ``benchmarks/``
    (docs/design/perturbations.md, "What a weld does to the diffusion metric").
    """
    e = np.asarray(e, dtype=float)
    if e.ndim != 2 or e.shape[0] != e.shape[1]:
        raise ValueError(f"e must be a square residual matrix, got shape {e.shape}")
    if not 0.0 < keep <= 1.0:
        raise ValueError(f"keep must be in (0, 1], got {keep}")
    n = len(e)
    if n < 2:
        return 0.0
    off = ~np.eye(n, dtype=bool)
    rows = np.sqrt((np.where(off, e, 0.0) ** 2).sum(axis=1) / (n - 1))
    h = min(n, max(2, int(np.ceil(keep * n - 1e-9))))
    idx = np.sort(np.argsort(rows, kind="stable")[:h])
    sub = e[np.ix_(idx, idx)][~np.eye(h, dtype=bool)]
    return float(np.sqrt(np.mean(sub**2)))


def log_ratio_residuals(dx: np.ndarray, dy: np.ndarray, floor: float = 0.0) -> np.ndarray:
    r"""Multiplicative residuals of a correspondence: the off-diagonal entries of
    :math:`\log\big((d_X + \epsilon) / (d_Y + \epsilon)\big)`, with :math:`\epsilon` = ``floor``.

    ``dx`` and ``dy`` are the square matrices of distances between corresponding points
    (e.g. the blocks of :meth:`SymmetricGMDS.blocks`). Where :math:`d_X - d_Y` measures the
    *additive* distortion (its largest value, :math:`\operatorname{dis} C`, bounds the
    Gromov-Hausdorff distance: :math:`d_{GH} \le \frac12 \operatorname{dis} C`), the log
    ratio measures the *multiplicative* one: for a bijection :math:`f`, its largest absolute
    value over all pairs is :math:`\max(\log \operatorname{dil} f, \log \operatorname{dil}
    f^{-1})`, at least half of the quantity :math:`\log \operatorname{dil} f + \log
    \operatorname{dil} f^{-1}` that Gromov's Lipschitz distance between metric spaces
    minimises (Gromov, *Metric Structures for Riemannian and Non-Riemannian Spaces*, 1999,
    §3.A; Burago, Burago & Ivanov, *A Course in Metric Geometry*, 2001, §7.2). A pair of
    points one unit apart that should be two apart counts as much as one ten units apart that
    should be twenty. ``floor`` (>= 0, in the distances' units) keeps the ratio finite where
    two points coincide.
    """
    dx, dy = np.asarray(dx, dtype=float), np.asarray(dy, dtype=float)
    if dx.ndim != 2 or dx.shape[0] != dx.shape[1] or dx.shape != dy.shape:
        raise ValueError(f"dx and dy must be square matrices of one shape, got {dx.shape} and {dy.shape}")
    if not (np.isfinite(floor) and floor >= 0):
        raise ValueError(f"floor must be a finite number >= 0, got {floor!r}")
    off = ~np.eye(len(dx), dtype=bool)
    a, b = dx[off] + floor, dy[off] + floor
    if np.any(a <= 0) or np.any(b <= 0):
        raise ValueError("a distance between two different points is zero: give a floor > 0")
    return np.log(a / b)


@dataclass(frozen=True, eq=False)
class SurfacePoints:
    """Points on a working mesh: ``face`` (k,) and ``bary`` (k, 3) barycentric coordinates."""

    face: np.ndarray
    bary: np.ndarray

    def vertex(self, faces: np.ndarray) -> np.ndarray:
        """The corner of each point's face with the largest barycentric weight."""
        return faces[self.face, np.argmax(self.bary, axis=1)]

    def positions(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        return np.einsum("kc,kcd->kd", self.bary, vertices[faces[self.face]])

    @classmethod
    def at_vertices(cls, mesh: Mesh, vertices) -> "SurfacePoints":
        """Points exactly at the given vertices (each in one of its faces)."""
        v = np.asarray(vertices, dtype=np.int64)
        indptr, fids = mesh.vertex_faces
        if np.any(indptr[v + 1] == indptr[v]):
            raise MetricError("a vertex with no face cannot carry a surface point")
        face = fids[indptr[v]]
        corner = np.argmax(mesh.faces[face] == v[:, None], axis=1)
        return cls(face.copy(), np.eye(3)[corner])


class SurfaceDistance:
    """What GMDS needs of one surface: its working mesh, vertex distances and face adjacency.

    Parameters
    ----------
    mesh : Mesh
        The working mesh.
    distances : ndarray, shape (n, n)
        Vertex distance matrix of the chosen metric (finite).
    """

    def __init__(self, mesh: Mesh, distances: np.ndarray):
        d = np.asarray(distances, dtype=np.float64)
        if d.shape != (mesh.n_vertices, mesh.n_vertices):
            raise ValueError(f"distances must be ({mesh.n_vertices}, {mesh.n_vertices}), got {d.shape}")
        top = float(d.max())  # inf or NaN anywhere makes the maximum non-finite
        if not np.isfinite(top):
            raise MetricError("GMDS needs finite distances, got inf or NaN (a mesh with several "
                              "connected components has inf between them: --metric diffusion "
                              "measures across them, or keep the largest, Mesh.largest_component())")
        if float(d.min()) < 0.0:
            raise MetricError(f"distances must be non-negative, got {float(d.min())!r}")
        self.mesh = mesh
        self.distances = np.ascontiguousarray(d)   # squared where the kernels read it
        self.max_distance = top
        self.faces = np.ascontiguousarray(mesh.faces)
        self.neighbours = face_neighbours(mesh.faces)

    def between(self, pts: SurfacePoints, fixed: np.ndarray) -> np.ndarray:
        """Interpolated distances ``(k, k + l)`` from points to [points, fixed vertices]."""
        return pair_distances(pts.face, pts.bary, np.asarray(fixed, np.int64), self.distances, self.faces, True)

    def block(self, vertices: np.ndarray) -> np.ndarray:
        """Distances ``(k, k)`` between the given vertices."""
        return self.distances[np.ix_(vertices, vertices)]


class EmbeddedDistance:
    """:class:`SurfaceDistance`'s interpolated distances, for a metric given by an embedding.

    Distances are Euclidean distances between rows of ``embedding`` (a spectral diffusion
    map), computed only on the vertices a query touches -- the corners of the points' faces
    and the fixed vertices -- so that no dense ``(n, n)`` matrix is kept. The interpolant is
    :class:`SurfaceDistance`'s (squared distances interpolated barycentrically), so both give
    the same values for the same metric. Enough to measure a correspondence
    (:meth:`SymmetricGMDS.blocks`), not to optimise one.

    Parameters
    ----------
    mesh : Mesh or PointCloud
        A point cloud: only :meth:`block` (distances between its points), no interpolation.
    embedding : ndarray, shape (n, K)
    """

    def __init__(self, mesh: Mesh, embedding: np.ndarray):
        psi = np.asarray(embedding, dtype=np.float64)
        if psi.ndim != 2 or len(psi) != mesh.n_vertices:
            raise ValueError(f"embedding must have {mesh.n_vertices} rows, got shape {psi.shape}")
        self.mesh, self.embedding = mesh, psi
        # a point cloud has no faces: :meth:`block` only (distances between its points)
        self.faces = np.ascontiguousarray(mesh.faces) if isinstance(mesh, Mesh) else None

    def _squared(self, vertices: np.ndarray) -> np.ndarray:
        """Squared distances between the given vertices, from the Gram matrix (one BLAS
        product, as the dense metric is made)."""
        e = self.embedding[vertices]
        norms = np.einsum("ij,ij->i", e, e)
        sq = np.maximum(norms[:, None] + norms[None, :] - 2.0 * (e @ e.T), 0.0)
        np.fill_diagonal(sq, 0.0)
        return sq

    def block(self, vertices: np.ndarray) -> np.ndarray:
        return np.sqrt(self._squared(np.asarray(vertices, dtype=np.int64)))

    def between(self, pts: SurfacePoints, fixed: np.ndarray) -> np.ndarray:
        if self.faces is None:
            raise TypeError("a point cloud has no faces to interpolate distances on")
        fixed = np.asarray(fixed, np.int64)
        corners = self.faces[pts.face]
        used, local = np.unique(np.concatenate([corners.ravel(), fixed]), return_inverse=True)
        sq = self._squared(used)
        local_faces = np.ascontiguousarray(local[: corners.size].reshape(corners.shape))
        return pair_distances(np.arange(len(corners), dtype=np.int64), pts.bary,
                              np.ascontiguousarray(local[corners.size:]), sq, local_faces, False)


class SymmetricGMDS:
    """Alternating optimisation of the two-sided correspondence ``C = (P x Q') u (Q x P')``.

    Parameters
    ----------
    X, Y : SurfaceDistance
    P, Q : ndarray of int
        Sample vertices on X and on Y (``M`` and ``K`` of them).
    p : float
        Norm exponent (2, a value >= 1, or ``inf``).
    max_iter : int, default 100
        Sweeps (each moves every point of both embeddings once) per IRLS round.
    tol : float, default 1e-6
        Stop when a sweep lowers the weighted distortion by less than ``tol`` relatively.
    n_newton : int, default 3
        Newton steps per point and sweep.
    irls_rounds : int, default 6
        Reweighted rounds for a norm other than L2.
    radius : float, optional
        Only the pairs of samples at most this far apart (on their own shape) are weighed in the
        (P, P) and (Q, Q) blocks; the cross blocks weigh every pair.
    """

    def __init__(self, X: SurfaceDistance, Y: SurfaceDistance, P, Q, *, p: float = 2.0,
                 max_iter: int = 100, tol: float = 1e-6, n_newton: int = 3,
                 irls_rounds: int = 6, radius: float | None = None):
        self.X, self.Y = X, Y
        self.P = np.asarray(P, dtype=np.int64)
        self.Q = np.asarray(Q, dtype=np.int64)
        self.p = float(p)
        self.max_iter, self.tol, self.n_newton = int(max_iter), float(tol), int(n_newton)
        self.irls_rounds = int(irls_rounds)
        self.radius = radius
        self.history: list[float] = []
        self._dx_pp = X.block(self.P)
        self._dy_qq = Y.block(self.Q)
        self._recent: list = []  # (points, ex, ey) of the last few interpolations

    # ------------------------------------------------------------------ blocks
    def _between(self, img_p: SurfacePoints, img_q: SurfacePoints):
        """``(ex, ey)``: interpolated distances P' to [P', P] on X and Q' to [Q', Q] on Y.

        The last few results are kept, keyed by copies of the points, so that scoring, solving
        and reporting the same correspondence interpolate it once.
        """
        for key, ex, ey in self._recent:
            if all(np.array_equal(a, b) for a, b in zip(key, (img_p.face, img_p.bary, img_q.face, img_q.bary))):
                return ex, ey
        ex = self.X.between(img_q, self.P)   # (K, K + M): P' to [P', P]
        ey = self.Y.between(img_p, self.Q)   # (M, M + K): Q' to [Q', Q]
        self._remember(img_p, img_q, ex, ey)
        return ex, ey

    def _remember(self, img_p, img_q, ex, ey):
        key = (img_p.face.copy(), img_p.bary.copy(), img_q.face.copy(), img_q.bary.copy())
        self._recent = [(key, ex, ey)] + self._recent[:3]

    def _assemble(self, ex: np.ndarray, ey: np.ndarray):
        M, K = len(self.P), len(self.Q)
        dx = np.empty((M + K, M + K))
        dy = np.empty_like(dx)
        dx[:M, :M], dx[M:, M:] = self._dx_pp, 0.5 * (ex[:, :K] + ex[:, :K].T)
        dx[M:, :M] = ex[:, K:]
        dx[:M, M:] = ex[:, K:].T
        dy[:M, :M], dy[M:, M:] = 0.5 * (ey[:, :M] + ey[:, :M].T), self._dy_qq
        dy[:M, M:] = ey[:, M:]
        dy[M:, :M] = ey[:, M:].T
        return dx, dy

    def blocks(self, img_p: SurfacePoints, img_q: SurfacePoints):
        """Block distance matrices ``(M+K, M+K)`` of the two-sided correspondence on X and on Y;
        their difference is the residual D_X(C) - D_Y(C)."""
        return self._assemble(*self._between(img_p, img_q))

    def distortion(self, img_p: SurfacePoints, img_q: SurfacePoints, p: float | None = None) -> float:
        """dis(C) in norm ``p`` (default: the solver's), over ordered pairs a != b."""
        dx, dy = self.blocks(img_p, img_q)
        r = (dx - dy)[~np.eye(len(dx), dtype=bool)]
        return norm_value(r, self.p if p is None else p)

    def _base_weights(self):
        M, K = len(self.P), len(self.Q)
        w = np.ones((M + K, M + K))
        if self.radius is not None:
            # partial matching: only pairs closer than radius (in the fixed sample metric)
            wx = (self._dx_pp <= self.radius).astype(float)
            wy = (self._dy_qq <= self.radius).astype(float)
            w[:M, :M], w[M:, M:] = wx, wy
        np.fill_diagonal(w, 0.0)
        return w

    # ------------------------------------------------------------------ optimisation
    def _weighted(self, ex, ey, w):
        dx, dy = self._assemble(ex, ey)
        return float(np.sum(w * (dx - dy) ** 2))

    def _l2_solve(self, img_p: SurfacePoints, img_q: SurfacePoints, w: np.ndarray):
        M, K = len(self.P), len(self.Q)
        X, Y = self.X, self.Y
        eps = 1e-9 * max(X.max_distance, Y.max_distance)
        ex, ey = self._between(img_p, img_q)
        pf, pb = img_p.face.copy(), img_p.bary.copy()
        qf, qb = img_q.face.copy(), img_q.bary.copy()
        cur = self._weighted(ex, ey, w)
        self.history.append(cur)
        wy = np.ascontiguousarray(np.hstack([w[:M, :M], w[:M, M:]]))
        wx = np.ascontiguousarray(np.hstack([w[M:, M:], w[M:, :M]]))
        delta_y = np.empty((M, M + K))
        delta_y[:, :M] = self._dx_pp
        delta_x = np.empty((K, K + M))
        delta_x[:, :K] = self._dy_qq
        n_iter = 0
        converged = False
        for n_iter in range(1, self.max_iter + 1):
            # Q' on Y: targets to [Q', Q] are d_X(P, P) and d_X(P, P'); ex is that of the current P'
            delta_y[:, M:] = ex[:, K:].T
            sweep(pf, pb, self.Q, delta_y, wy, Y.distances, Y.faces, Y.neighbours, self.n_newton, eps)
            # P' on X: targets to [P', P] are d_Y(Q, Q) and d_Y(Q, Q')
            ey = Y.between(SurfacePoints(pf, pb), self.Q)  # (M, M + K)
            delta_x[:, K:] = ey[:, M:].T
            sweep(qf, qb, self.P, delta_x, wx, X.distances, X.faces, X.neighbours, self.n_newton, eps)
            ex = X.between(SurfacePoints(qf, qb), self.P)  # (K, K + M)
            new = self._weighted(ex, ey, w)
            self.history.append(new)
            if cur - new <= self.tol * max(cur, 1e-300):
                converged = True
                cur = new
                break
            cur = new
        img_p, img_q = SurfacePoints(pf, pb), SurfacePoints(qf, qb)
        self._remember(img_p, img_q, ex, ey)
        return img_p, img_q, n_iter, converged

    def solve(self, img_p: SurfacePoints, img_q: SurfacePoints):
        """Optimise from the given initial images; returns ``(img_p, img_q, n_iter, converged)``."""
        w0 = self._base_weights()
        if self.p == 2.0:
            return self._l2_solve(img_p, img_q, w0)
        # IRLS: weights |r|^(p-2); for L-infinity the exponent grows. IRLS does not lower the
        # target norm monotonically, so keep the best correspondence seen in that norm.
        exps = ([4.0, 6.0, 8.0, 12.0, 16.0, 24.0][: self.irls_rounds] if np.isinf(self.p)
                else [self.p] * self.irls_rounds)
        img_p, img_q, total, conv = self._l2_solve(img_p, img_q, w0)
        best = (self.distortion(img_p, img_q), img_p, img_q)
        for e in exps:
            dx, dy = self.blocks(img_p, img_q)
            r = np.abs(dx - dy)
            scale = max(float((r * (w0 > 0)).max()), 1e-300)
            w = w0 * np.maximum(r / scale, 1e-3) ** (e - 2.0)
            img_p, img_q, n, conv = self._l2_solve(img_p, img_q, w)
            total += n
            value = self.distortion(img_p, img_q)
            if value < best[0]:
                best = (value, img_p, img_q)
        return best[1], best[2], total, conv
