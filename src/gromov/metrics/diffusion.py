r"""Diffusion distances: averages over all random-walk paths, robust to topology changes.

Two constructions share one spectral machinery.

**Graph diffusion** (:class:`GraphDiffusionSolver`), exactly as Bronstein et al. 2010, §3.
An affinity :math:`k(x, y)` on the vertices -- the *connectivity kernel* (1 between mesh
neighbours, the paper's choice) or the *Gaussian kernel* :math:`\exp(-|x-y|^2/\sigma^2)` on
a k-nearest-neighbour graph -- optionally density-normalised (eq. 9)

.. math:: \tilde k(x, y) = k(x, y) / (v(x) v(y)), \qquad v(x) = \textstyle\sum_y k(x, y),

is turned into the symmetric diffusion operator
:math:`\tilde p(x, y) = k(x, y)/\sqrt{v(x) v(y)}` and the diffusion distance after ``m``
steps is eq. (4):

.. math:: d_m^2(x, y) = \sum_z \big(\tilde p^{(m)}(x, z) - \tilde p^{(m)}(y, z)\big)^2,

with :math:`\tilde p^{(m)}` the m-th matrix power. *Convention*: the paper's spectral
eqs. (7)-(8) write :math:`\lambda^m` where eq. (4) implies :math:`\lambda^{2m}`; we implement
eq. (4), so with :math:`\tilde P = \Phi \Lambda \Phi^T`

.. math:: d_m^2(x, y) = \sum_k \lambda_k^{2m} \big(\phi_k(x) - \phi_k(y)\big)^2 .

**Heat-kernel diffusion** (:class:`HeatDiffusionSolver`). The graph kernel depends on the
mesh resolution (m steps on a fine mesh cover a smaller area than on a coarse one). The
Laplace-Beltrami heat kernel does not: with the generalised eigenproblem
:math:`L\phi_k = \lambda_k M \phi_k` (cotangent or robust Laplacian ``L``, lumped mass ``M``,
:math:`\Phi^T M \Phi = I`) and time :math:`t = \tau \cdot \mathrm{area}`,

.. math:: d_t^2(x, y) = \sum_k e^{-2\lambda_k t} \big(\phi_k(x) - \phi_k(y)\big)^2

(Coifman & Lafon, ACHA 21, 2006; Bronstein et al. 2010, eq. 8), which converges as the
same surface is meshed more finely. Its unit is 1/length.

**Normalised heat-kernel diffusion** (``units="normalized"``). Since
:math:`\sum_k e^{-2\lambda_k t}\phi_k(x)\phi_k(y) = k_{2t}(x, y)`,
:math:`d_t^2(x, y) = k_{2t}(x,x) + k_{2t}(y,y) - 2k_{2t}(x,y)`: the squared :math:`L^2` distance
between the heat distributions :math:`k_t(x,\cdot)` and :math:`k_t(y,\cdot)` released at the
two points. Between points farther apart than the diffusion radius it is
:math:`k_{2t}(x,x) + k_{2t}(y,y)`, the two points' *return probabilities*, which depend on
the surface within about :math:`\sqrt{8t}` of each point -- so a topology change (a weld)
moves every distance from the points near it. Scaling each heat distribution to unit
:math:`L^2` norm first,

.. math:: \bar d_t^2(x, y) = \Big\| \frac{k_t(x,\cdot)}{\|k_t(x,\cdot)\|}
          - \frac{k_t(y,\cdot)}{\|k_t(y,\cdot)\|} \Big\|^2
          = 2 - \frac{2\,k_{2t}(x,y)}{\sqrt{k_{2t}(x,x)\,k_{2t}(y,y)}}

(the chordal distance between the normalised rows of the diffusion map), removes the
return probabilities: far pairs all sit at :math:`\sqrt2`, near pairs are measured by how much
their heat distributions overlap. It is dimensionless, bending-invariant like
:math:`d_t`, and unchanged by scaling the shape (t scales with the area).

**Truncation bound.** Both sums are truncated to the leading eigenpairs. For the graph
operator the eigenvectors are orthonormal, so :math:`\sum_k (\phi_k(x)-\phi_k(y))^2 = 2`
(x != y) and the dropped terms add up to at most :math:`2\,|\lambda_{K+1}|^{2m}`. For the
heat kernel :math:`\Phi\Phi^T = M^{-1}`, so the dropped terms are at most
:math:`e^{-2\lambda_{K+1} t}(1/M_x + 1/M_y)`. Eigenpairs are added until that bound is
below ``rtol`` times the mean squared distance; the bound reached is kept in
``truncation_bound``.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from numba import get_num_threads, njit, prange
from scipy.sparse.linalg import ArpackError, eigsh
from scipy.spatial.distance import cdist

from .._eigen import shift_invert_eigsh
from ..errors import MetricError
from ..mesh import Mesh, PointCloud
from ._base import MetricSolver, check_shape

__all__ = [
    "affinity", "diffusion_operator", "cotan_laplacian", "brute_force_diffusion_distance",
    "GraphDiffusionSolver", "HeatDiffusionSolver", "BiharmonicSolver", "DIFFUSION_KERNELS", "HEAT_UNITS",
    "DEFAULT_TAU", "DEFAULT_UNITS", "CORRESPONDENCE_UNITS", "correspondence_options",
]

logger = logging.getLogger(__name__)

DIFFUSION_KERNELS = ("connectivity", "gaussian", "heat", "biharmonic")
from .._defaults import HEAT_UNITS  # noqa: E402
#: Neighbours of each point in the robust point-cloud Laplacian (``robust_laplacian``'s
#: ``n_neighbors``; its own default is 30). Chosen on held-out TOSCA classes (cls0 -> clsN
#: matched as clouds of their vertices: wolf 1, 2, horse 5, 6, centaur 1, 5, michael 1, 6):
#: mean correspondence error 0.0277 / 0.0211 / 0.0309 with 10 / 20 / 30 neighbours
#: (``benchmarks/bench_point_clouds.py --neighbors 10,20,30``; docs/design/point-clouds.md).
#: Fewer neighbours glue fewer parts that pass close in space (a hand near a thigh).
POINT_CLOUD_NEIGHBORS = 20

#: Default heat-kernel diffusion time relative to the area, per ``units`` (see
#: :class:`HeatDiffusionSolver`).
DEFAULT_TAU = {"normalized": 0.01, "raw": 0.005, "length": 0.005, "area": 0.005}
#: Default ``units`` of :class:`HeatDiffusionSolver`, and of recognition (GH distance
#: matrices: :func:`gromov.experiments.pairwise.gh_matrix`, ``gromov pairwise``,
#: ``gromov reproduce``'s EERs).
from .._defaults import DEFAULT_UNITS  # noqa: E402
#: ``units`` of the heat kernel when the task is a *correspondence* (:func:`gromov.match`,
#: ``gromov match``, :func:`gromov.experiments.pairwise.match_pairs`, ``gromov reproduce``'s
#: d(C, C0) table and TOPKIDS) and the options name neither ``units`` nor ``tau``
#: (:func:`correspondence_options`). Chosen on the validation sets (held-out TOSCA classes and
#: the synthetic set), where each task preferred its own: normalised heat distributions took
#: d(C, C0) with welds from 0.023 to 0.013 (held-out) and 0.078 to 0.009 (synthetic), while the
#: raw distances kept the equal error rates with welds at 0% / 0.7% against 4.4% / 6.0%
#: normalised (docs/design/metrics.md, "Heat units").
CORRESPONDENCE_UNITS = "normalized"
#: Components of at most this many vertices are decomposed densely (no truncation).
DENSE_COMPONENT = 200
#: A connected shape on which ARPACK fails is decomposed densely up to this many vertices
#: (about 10 s at 4,000); above, the failure is reported as a MetricError.
DENSE_FALLBACK = 4000


def correspondence_options(metric: str, options: dict | None) -> dict:
    """The metric options a correspondence uses when the caller gave ``options``.

    With ``metric="diffusion"``, the heat kernel (the default kernel) and neither ``units``
    nor ``tau`` in ``options``: ``units`` = :data:`CORRESPONDENCE_UNITS`, so ``tau`` becomes
    that units' :data:`DEFAULT_TAU`. Otherwise (another metric or kernel, or ``units`` or
    ``tau`` given): ``options`` as they are -- what the caller names is what runs.

    Examples
    --------
    >>> correspondence_options("diffusion", None)
    {'units': 'normalized'}
    >>> correspondence_options("diffusion", {"units": "raw"})
    {'units': 'raw'}
    >>> correspondence_options("geodesic", {})
    {}
    """
    options = dict(options or {})
    if (metric == "diffusion" and options.get("kernel", "heat") == "heat"
            and "units" not in options and "tau" not in options):
        options["units"] = CORRESPONDENCE_UNITS
    return options


# ----------------------------------------------------------------------------- operators
def affinity(shape: PointCloud, kernel: str = "connectivity", *, k: int = 10,
             sigma: float | None = None) -> sp.csr_matrix:
    r"""The affinity matrix :math:`k(x, y)` of Bronstein et al. 2010, §3 (symmetric, zero diagonal).

    Parameters
    ----------
    shape : Mesh or PointCloud
    kernel : {"connectivity", "gaussian"}
        ``"connectivity"``: 1 between mesh neighbours (meshes only; the paper's choice).
        ``"gaussian"``: :math:`\exp(-|x-y|^2/\sigma^2)` between k-nearest neighbours
        (symmetrised: an edge when either point is among the other's k nearest).
    k : int, default 10
        Neighbours of the Gaussian kernel's graph.
    sigma : float, optional
        Gaussian width. Default: the mean length of the k-NN graph's edges (the local
        sampling scale). This is our choice; the paper leaves sigma to the user.
    """
    if kernel == "connectivity":
        if not isinstance(shape, Mesh):
            raise MetricError("the connectivity kernel needs mesh edges; use kernel='gaussian' "
                              "for point clouds")
        a = shape.adjacency.copy()
        a.data[:] = 1.0
        return a
    if kernel == "gaussian":
        g = shape.knn_graph(k)
        if sigma is None:
            sigma = float(g.data.mean())
        if not sigma > 0:
            raise ValueError(f"sigma must be positive, got {sigma}")
        g = g.copy()
        g.data = np.exp(-(g.data / sigma) ** 2)
        return g
    raise ValueError(f"kernel must be 'connectivity' or 'gaussian', got {kernel!r}")


def diffusion_operator(kern: sp.spmatrix, *, density_normalize: bool = False) -> sp.csr_matrix:
    r"""Symmetric diffusion operator :math:`\tilde p = k / \sqrt{v(x) v(y)}`, optionally after eq. (9).

    ``density_normalize=True`` first replaces ``k`` by :math:`k/(v(x)v(y))` (Bronstein et al.
    2010, eq. 9; Coifman & Lafon 2006 with alpha = 1), which removes the influence of the
    sampling density. Isolated vertices (no affinity) get a zero row.
    """
    kern = sp.csr_matrix(kern, dtype=float)
    v = np.asarray(kern.sum(axis=1)).ravel()
    if density_normalize:
        inv = np.divide(1.0, v, out=np.zeros_like(v), where=v > 0)
        kern = sp.diags(inv) @ kern @ sp.diags(inv)
        v = np.asarray(kern.sum(axis=1)).ravel()
    s = np.divide(1.0, np.sqrt(v), out=np.zeros_like(v), where=v > 0)
    p = sp.diags(s) @ kern @ sp.diags(s)
    return sp.csr_matrix(0.5 * (p + p.T))


def brute_force_diffusion_distance(p: sp.spmatrix | np.ndarray, m: int) -> np.ndarray:
    r"""Eq. (4) by definition: :math:`d_m(x,y) = \|\tilde P^m e_x - \tilde P^m e_y\|` (dense; tests only)."""
    pm = np.linalg.matrix_power(np.asarray(p.todense() if sp.issparse(p) else p), m)
    return cdist(pm, pm)


def cotan_laplacian(mesh: Mesh) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    r"""Cotangent stiffness ``L`` (positive semi-definite) and lumped mass ``M`` of a mesh.

    :math:`L_{ij} = -\tfrac12(\cot\alpha_{ij} + \cot\beta_{ij})` for an edge ij with opposite
    angles :math:`\alpha, \beta`, :math:`L_{ii} = -\sum_j L_{ij}` (Pinkall & Polthier 1993);
    ``M`` = diag(vertex areas), a third of each incident triangle.
    """
    v, f = mesh.vertices, mesh.faces
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j, o = f[:, (c + 1) % 3], f[:, (c + 2) % 3], f[:, c]
        e1, e2 = v[i] - v[o], v[j] - v[o]
        cross = np.linalg.norm(np.cross(e1, e2), axis=1)
        cot = np.einsum("ij,ij->i", e1, e2) / np.maximum(cross, 1e-300)
        rows += [i, j]
        cols += [j, i]
        vals += [-0.5 * cot, -0.5 * cot]
    n = mesh.n_vertices
    w = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
    lap = w - sp.diags(np.asarray(w.sum(axis=1)).ravel())
    return sp.csr_matrix(lap), sp.diags(mesh.vertex_areas).tocsr()


# ----------------------------------------------------------------------------- spectral base
class _SpectralDiffusion(MetricSolver):
    """Distances as Euclidean distances in a truncated spectral embedding ``psi`` (n, K)."""

    name = "diffusion"
    symmetric_rows = True

    def __init__(self, shape, rtol: float):
        super().__init__(shape)
        if not 0 < rtol < 1:
            raise ValueError(f"rtol must be in (0, 1), got {rtol}")
        self.rtol = float(rtol)
        self._psi: np.ndarray | None = None
        self.eigenvalues: np.ndarray | None = None
        self.truncation_bound: float = np.nan

    @property
    def embedding(self) -> np.ndarray:
        """Diffusion map ``(n, K)``: distances are Euclidean distances between its rows."""
        if self._psi is None:
            # The eigensolvers make many small BLAS calls: threaded BLAS only adds overhead
            # there and, next to any other busy process, slows them 5-10x (measured on the
            # 3,000-vertex cat: 1.0 s single-threaded vs 5-12 s with two threads under load).
            from threadpoolctl import threadpool_limits

            with threadpool_limits(limits=1, user_api="blas"):
                self._psi = self._spectral()
            self._psi.flags.writeable = False
        return self._psi

    def _spectral(self) -> np.ndarray:
        """The embedding; one connected component at a time on a shape in several, densely
        when ARPACK fails on a connected shape of at most :data:`DENSE_FALLBACK` vertices.

        The operator of a shape in ``c`` components is block-diagonal and its eigenvalue 0
        (Laplacian) or 1 (graph operator) has multiplicity ``c``, which a Krylov eigensolver
        started from one vector resolves slowly or not at all: jointly, the connectivity-kernel
        distances between two spheres came out 0 (the truth: 0.08), the heat distances on 8
        copies of a sphere were off by their whole size, and 200 disjoint tetrahedra stopped
        ARPACK (error 3). The eigenpairs of a block-diagonal operator are those of its blocks.
        """
        n_comp, labels = self._components()
        if n_comp > 1:
            return self._by_components(n_comp, labels)
        return self._connected()

    def _connected(self) -> np.ndarray:
        """The embedding of a connected shape; densely where ARPACK fails on a small one."""
        try:
            return self._compute_embedding()
        except ArpackError as exc:
            if self.n_vertices <= DENSE_FALLBACK:
                logger.info("diffusion: ARPACK failed (%s); dense eigendecomposition", exc)
                return self._dense_embedding()
            raise MetricError(f"diffusion metric: the sparse eigensolver (ARPACK) failed on this "
                              f"{self.n_vertices}-vertex shape ({exc}); a smaller --resolution "
                              f"(at most {DENSE_FALLBACK}) uses a dense eigendecomposition") from None

    def _components(self) -> tuple[int, np.ndarray]:
        """Connected components of the operator's graph (its nonzero pattern)."""
        from scipy.sparse.csgraph import connected_components

        return connected_components(self._operator_pattern(), directed=False)

    def _by_components(self, n_comp: int, labels: np.ndarray) -> np.ndarray:
        """The block-diagonal embedding: each component's eigenpairs on its own rows."""
        logger.debug("diffusion: %d connected components decomposed one at a time", n_comp)
        order = np.argsort(labels, kind="stable")
        bounds = np.searchsorted(labels[order], np.arange(n_comp + 1))
        blocks, lams, dropped = [], [], []
        for c in range(n_comp):
            idx = order[bounds[c]:bounds[c + 1]]
            if len(idx) == 0:
                continue
            sub = self._block(idx)
            psi_c = sub._dense_embedding() if len(idx) <= DENSE_COMPONENT else sub._connected()
            blocks.append((idx, psi_c))
            lams.append(np.asarray(sub.eigenvalues))
            dropped.append(float(sub.truncation_bound))
        psi = np.zeros((self.n_vertices, sum(b.shape[1] for _, b in blocks)))
        col = 0
        for idx, b in blocks:
            psi[idx, col:col + b.shape[1]] = b
            col += b.shape[1]
        return self._assembled(np.concatenate(lams), psi, max(dropped))

    def _operator_pattern(self):
        raise NotImplementedError

    def _block(self, idx: np.ndarray) -> "_SpectralDiffusion":
        raise NotImplementedError

    def _dense_embedding(self) -> np.ndarray:
        raise NotImplementedError

    def _assembled(self, lam: np.ndarray, psi: np.ndarray, bound: float) -> np.ndarray:
        raise NotImplementedError

    @staticmethod
    def _mean_sq(psi: np.ndarray) -> float:
        # mean over ordered pairs of |psi_x - psi_y|^2 = 2 (mean |psi|^2 - |mean psi|^2)
        return float(2.0 * ((psi**2).sum(1).mean() - (psi.mean(0) ** 2).sum()))

    def _rows(self, sources):
        psi = self.embedding
        d2 = cdist(psi[sources], psi, "sqeuclidean")
        return np.sqrt(d2)

    def pairwise(self, *, progress=None, chunk: int = 4096) -> np.ndarray:
        if self._pairwise is None:
            from threadpoolctl import threadpool_limits

            psi = self.embedding
            # one BLAS thread: the product's last bits depend on the threads (2,684 of the 9.1
            # million entries of a TOSCA cat's differ between one and two), and one order makes
            # a shape's distances the same in every process, whatever limit is in force there
            # (0.067 s against 0.058 s with two threads at 3,015 x 252)
            with threadpool_limits(limits=1, user_api="blas"):
                gram = psi @ psi.T
            self._pairwise = _distances_from_gram((psi**2).sum(1), gram)
            if progress is not None:
                progress(self.n_vertices)
        return self._pairwise

    def _compute_embedding(self) -> np.ndarray:
        raise NotImplementedError


def _distances_from_gram(sq: np.ndarray, gram: np.ndarray) -> np.ndarray:
    """Read-only ``sqrt(max(sq_x + sq_y - 2 gram_xy, 0))``, symmetrised, zero diagonal.

    ``gram`` holds inner products of an embedding and ``sq`` its squared norms; a writable,
    C-ordered float64 ``gram`` is overwritten and returned, anything else is copied first.
    One pass over cache-sized tile pairs (:func:`_gram_tiles`) instead of several over the
    whole matrix; the same values as the NumPy expression ``d = sqrt(max(d2, 0)); (d + d.T)
    / 2``. With more than one numba thread the tiles run in parallel; with one (the forked
    workers of :mod:`gromov.experiments.pairwise`) numba's threading layer is not entered.
    """
    own = gram.dtype == np.float64 and gram.flags.c_contiguous and gram.flags.writeable
    g = gram if own else np.array(gram, dtype=np.float64, order="C")
    sq = np.ascontiguousarray(sq, dtype=np.float64)
    nb = -(-len(g) // _TILE)
    if get_num_threads() > 1 and nb > 1:  # one thread (forked workers): no threading layer
        _gram_parallel(sq, g, nb)
    else:
        for bi in range(nb):
            _gram_tiles(sq, g, bi)
    g.flags.writeable = False
    return g


_TILE = 64


@njit(cache=True)
def _gram_tiles(sq, G, bi):
    """Rows of tile ``bi`` of :func:`_distances_from_gram`: tile pairs ``(bi, bj >= bi)``."""
    n = G.shape[0]
    i0 = bi * _TILE
    i1 = min(n, i0 + _TILE)
    for j0 in range(i0, n, _TILE):
        j1 = min(n, j0 + _TILE)
        for i in range(i0, i1):
            si = sq[i]
            for j in range(max(j0, i + 1), j1):
                a = (si + sq[j]) - 2.0 * G[i, j]
                b = (sq[j] + si) - 2.0 * G[j, i]
                d = 0.5 * (np.sqrt(max(a, 0.0)) + np.sqrt(max(b, 0.0)))
                G[i, j] = d
                G[j, i] = d
    for i in range(i0, i1):
        G[i, i] = 0.0


@njit(cache=True, parallel=True)
def _gram_parallel(sq, G, nb):
    for bi in prange(nb):
        _gram_tiles(sq, G, np.int64(bi))   # (prange's index is unsigned: one compilation)


def _eigsh_top(a, k, *, sigma):
    """Eigenpairs of the symmetric ``a`` nearest to ``sigma`` (a graph's diffusion operator, not
    positive definite: SuperLU's shift-invert)."""
    n = a.shape[0]
    v0 = np.full(n, 1.0 / np.sqrt(n))  # deterministic start vector
    return eigsh(a, k=k, sigma=sigma, which="LM", v0=v0)


class GraphDiffusionSolver(_SpectralDiffusion):
    """The paper's diffusion distance (eq. 4) on a graph affinity.

    Parameters
    ----------
    shape : Mesh or PointCloud
    kernel : {"connectivity", "gaussian"}, default "connectivity"
        See :func:`affinity`. Point clouds need ``"gaussian"``.
    m : int, default 50
        Number of diffusion steps (the paper's default).
    density_normalize : bool, default False
        Apply eq. (9) before normalising.
    k : int, default 10
        Neighbours of the Gaussian kernel's graph.
    sigma : float, optional
        Gaussian width (default: mean k-NN distance).
    rtol : float, default 1e-6
        Spectral truncation stops when the bound on the dropped terms of d^2 is below
        ``rtol`` times the mean squared distance.
    dense_below : int, default 1500
        Use a full dense eigendecomposition (no truncation) below this many vertices.
    """

    def __init__(self, shape, *, kernel: str = "connectivity", m: int = 50,
                 density_normalize: bool = False, k: int = 10, sigma: float | None = None,
                 rtol: float = 1e-6, dense_below: int = 1500):
        shape = check_shape(shape, metric="diffusion")
        if kernel == "connectivity" and not isinstance(shape, Mesh):
            kernel = "gaussian"
        super().__init__(shape, rtol)
        if int(m) != m or m < 1:
            raise ValueError(f"m (diffusion steps) must be a positive integer, got {m}")
        self.kernel, self.m, self.density_normalize = kernel, int(m), bool(density_normalize)
        self.operator = diffusion_operator(affinity(shape, kernel, k=k, sigma=sigma),
                                           density_normalize=density_normalize)
        self.dense_below = int(dense_below)

    def _compute_embedding(self):
        p, n, m = self.operator, self.n_vertices, self.m
        if n <= self.dense_below:
            return self._dense()
        start = np.full(n, 1.0 / np.sqrt(n))
        lam_pos, phi_pos = self._end(+1, min(n - 2, 64))
        if lam_pos is None:
            return self._dense()
        scale = self._mean_sq(phi_pos * np.abs(lam_pos) ** m)
        thr = (0.5 * self.rtol * scale) ** (1.0 / (2 * m))  # |lambda| below thr is negligible
        lam_pos, phi_pos = self._end(+1, None, thr=thr, first=(lam_pos, phi_pos))
        if lam_pos is None:
            return self._dense()
        # the negative end of the spectrum counts too: eq. (4) has even powers
        lam_min = float(eigsh(p, k=1, which="SA", v0=start)[0][0])
        lam, phi, dropped = lam_pos, phi_pos, max(float(lam_pos.min()), abs(min(lam_min, 0.0)))
        if -lam_min > thr:
            lam_neg, phi_neg = self._end(-1, None, thr=thr)
            if lam_neg is None:
                return self._dense()
            lam, phi = np.concatenate([lam_pos, lam_neg]), np.hstack([phi_pos, phi_neg])
            dropped = max(float(lam_pos.min()), float(-lam_neg.max()))
        psi = phi * np.abs(lam) ** m * np.sign(lam) ** m
        self.eigenvalues = lam
        self.truncation_bound = 2.0 * dropped ** (2 * m)
        logger.debug("graph diffusion: %d eigenpairs, bound %.3g (mean d^2 %.3g)", len(lam),
                     self.truncation_bound, self._mean_sq(psi))
        return psi

    def _end(self, side: int, k: int | None, *, thr: float = 1.0, first=None):
        """Eigenpairs at one end of the spectrum (side=+1 near 1, -1 near -1) down to |lambda| <= thr.

        The count is extrapolated from Weyl's law (1 - |lambda_k| grows about linearly with k).
        Returns (None, None) when more than a third of the spectrum would be needed.
        """
        n = self.n_vertices
        if first is not None:
            lam, phi = first
        else:
            lam, phi = _eigsh_top(self.operator, min(n - 2, k or 64), sigma=side * (1.0 + 1e-3))
        while True:
            order = np.argsort(-side * lam)
            lam, phi = lam[order], phi[:, order]
            edge = abs(float(lam[-1]))
            if k is not None or edge <= thr:
                return lam[side * lam > 0], phi[:, side * lam > 0]
            want = int(np.ceil(len(lam) * (1.0 - thr) / max(1.0 - edge, 1e-12) * 1.1)) + 8
            if want > n // 3:
                return None, None
            lam, phi = _eigsh_top(self.operator, want, sigma=side * (1.0 + 1e-3))

    def _dense(self):
        lam, phi = np.linalg.eigh(self.operator.toarray())
        self.eigenvalues, self.truncation_bound = lam, 0.0
        return phi * lam**self.m

    _dense_embedding = _dense

    def _operator_pattern(self):
        return self.operator

    def _block(self, idx: np.ndarray) -> "GraphDiffusionSolver":
        # the operator of a disconnected graph is block-diagonal (degrees are per row)
        sub = GraphDiffusionSolver.__new__(GraphDiffusionSolver)
        _SpectralDiffusion.__init__(sub, PointCloud(self.shape.vertices[idx]), self.rtol)
        sub.kernel, sub.m, sub.density_normalize = self.kernel, self.m, self.density_normalize
        sub.dense_below = self.dense_below
        sub.operator = sp.csr_matrix(self.operator[idx][:, idx])
        return sub

    def _assembled(self, lam, psi, bound):
        self.eigenvalues, self.truncation_bound = lam, bound
        return psi

    def __repr__(self) -> str:
        return (f"GraphDiffusionSolver(n_vertices={self.n_vertices}, kernel={self.kernel!r}, "
                f"m={self.m}, density_normalize={self.density_normalize})")


def _unit_scale(units: str, t: float, area: float) -> float:
    r"""The factor that puts the raw heat distance :math:`d_t` in ``units``: the length scale
    :math:`\sqrt{32\pi}\, t` ("length"), :math:`\sqrt{A}` ("area": dimensionless), else 1."""
    if units == "length":
        return float(np.sqrt(32.0 * np.pi) * t)
    if units == "area":
        return float(np.sqrt(area))
    return 1.0


class HeatDiffusionSolver(_SpectralDiffusion):
    r"""Resolution-independent diffusion distance from the Laplace-Beltrami heat kernel.

    Parameters
    ----------
    shape : Mesh or PointCloud
    tau : float, optional
        Diffusion time relative to the area: ``t = tau * area``. Default
        :data:`DEFAULT_TAU` of ``units``: 0.005 for "raw" and "length", which makes the
        diffusion radius (sqrt(4t)) about that of the paper's m = 50 graph steps on a
        3,000-vertex mesh (a random walk's mean squared displacement is ``m h^2`` for edge
        length ``h``), so the two constructions are comparable at that resolution; 0.01 for
        "normalized" (chosen on held-out TOSCA classes, see ``units``).
    laplacian : {"cotan", "robust"}, default "cotan"
        Cotangent Laplacian, or the robust Laplacian of Sharp & Crane (SGP 2020) through
        ``robust-laplacian`` (works on non-manifold meshes and point clouds; point clouds
        always use it).
    neighbors : int, default POINT_CLOUD_NEIGHBORS (20)
        Point clouds only: the neighbours of each point in the robust Laplacian.
    rtol : float, default 1e-6
        See :class:`GraphDiffusionSolver`.
    units : {"normalized", "raw", "length", "area"}, default DEFAULT_UNITS
        ``"normalized"``: :math:`\bar d_t`, the distance between the *normalised* heat
        distributions of the two points (module notes): dimensionless, at most 2, unchanged by
        scaling the shape, and blind to the return probabilities that a topology change
        moves. ``"raw"``: :math:`d_t` as defined above (unit 1/length; scaling a shape by ``s``
        scales it by ``1/s``). ``"length"``: :math:`\sqrt{32\pi}\, t\, d_t`, in the shape's
        units of length. On a plane :math:`d_t^2 = 2 (k_{2t}(x,x) - k_{2t}(x,y))` with
        :math:`k_t = e^{-r^2/4t}/(4\pi t)`, so

        .. math:: \sqrt{32\pi}\, t\, d_t(x, y) = \sqrt{8t}\,\sqrt{1 - e^{-r^2/8t}}
                  \approx r \quad (r \ll \sqrt{8t}):

        the scaled distance equals the geodesic distance below the diffusion radius and
        saturates at :math:`\sqrt{8t}` beyond it; scaling a shape by ``s`` scales it by
        ``s``, as geodesic distances do, so a Gromov-Hausdorff distance sees a shape's size the
        way it does with geodesic distances. (A per-shape constant: it changes distances
        between shapes of different areas, never the distances within one shape relative to
        each other.)
        ``"area"``: :math:`\sqrt{A}\, d_t`, A the shape's area: the raw distance of the shape
        scaled to unit area (the heat kernel of :math:`sX` at time :math:`s^2 t` is
        :math:`k_t / s^2`), so dimensionless and unchanged by scaling the shape, like
        ``"normalized"``, while keeping the return probabilities that ``"normalized"`` divides
        out. For recognition among shapes whose size says nothing of their class.
    """

    def __init__(self, shape, *, tau: float | None = None, laplacian: str = "cotan", rtol: float = 1e-6,
                 units: str = DEFAULT_UNITS, neighbors: int = POINT_CLOUD_NEIGHBORS):
        shape = check_shape(shape, metric="diffusion")
        super().__init__(shape, rtol)
        if units not in HEAT_UNITS:
            raise ValueError(f"units must be one of {HEAT_UNITS}, got {units!r}")
        if tau is None:
            tau = DEFAULT_TAU[units]
        if not tau > 0:
            raise ValueError(f"tau must be positive, got {tau}")
        self.tau = float(tau)
        self.units = units
        self.laplacian, self.stiffness, self.mass, self.area = _laplacian(shape, laplacian, "heat diffusion",
                                                                          neighbors)
        self.neighbors = int(neighbors)
        self.t = self.tau * self.area
        self._basis: tuple[np.ndarray, np.ndarray] | None = None
        self.unit_scale = _unit_scale(units, self.t, self.area)

    def _dense_embedding(self):
        lam, phi = _dense_generalized(self.stiffness, self.mass)
        lam = np.maximum(lam, 0.0)
        self.eigenvalues, self.truncation_bound = lam, 0.0
        return self._scaled(lam, phi * np.exp(-lam * self.t))

    def _operator_pattern(self):
        return self.stiffness

    def _components(self) -> tuple[int, np.ndarray]:
        # a mesh's Laplacian couples the vertices of each connected component (a cotangent
        # weight can be exactly 0, as on a diagonal between two right angles: not the pattern)
        if isinstance(self.shape, Mesh):
            return self.shape.n_components, self.shape.component_labels
        return super()._components()

    def _block(self, idx: np.ndarray) -> "HeatDiffusionSolver":
        # one component at the same diffusion time t (not its own area's): raw distances
        sub = HeatDiffusionSolver.__new__(HeatDiffusionSolver)
        _SpectralDiffusion.__init__(sub, PointCloud(self.shape.vertices[idx]), self.rtol)
        sub.stiffness = sp.csr_matrix(self.stiffness[idx][:, idx])
        sub.mass = sp.csr_matrix(self.mass[idx][:, idx])
        sub.area = float(sub.mass.diagonal().sum())
        sub.t, sub.tau = self.t, self.t / sub.area
        sub.units, sub.unit_scale, sub._basis = "raw", 1.0, None
        sub.laplacian, sub.neighbors = self.laplacian, self.neighbors
        return sub

    def _assembled(self, lam, psi, bound):
        self.eigenvalues, self.truncation_bound = lam, bound * self.unit_scale**2
        return self._scaled(lam, psi)

    def _compute_embedding(self):
        n, t, area = self.n_vertices, self.t, self.area
        max_inv_mass = float((1.0 / self.mass.diagonal()).max())
        sigma = -1e-8 / max(area, 1e-300)
        # First guess of the number of eigenpairs from Weyl's law, lambda_k ~ 4 pi k / area:
        # mean d^2 ~ 2 sum_k exp(-2 lambda_k t) / area ~ 2 / (area (1 - exp(-8 pi tau))), and
        # the terms beyond lambda* = log(2 max(1/M) / (rtol mean d^2)) / (2t) are negligible.
        scale = 2.0 / (area * (1.0 - np.exp(-8.0 * np.pi * self.tau)))
        lam_star = np.log(2.0 * max_inv_mass / (self.rtol * scale)) / (2.0 * t)
        k = int(min(n - 2, max(32, np.ceil(1.15 * lam_star * area / (4.0 * np.pi)) + 8)))
        dense = n < 16   # a few vertices (one triangle): all eigenpairs, no truncation bound
        while True:
            if dense or k > n // 3:
                lam, phi = _dense_generalized(self.stiffness, self.mass)
                lam = np.maximum(lam, 0.0)
                self.eigenvalues, self.truncation_bound = lam, 0.0
                return self._scaled(lam, phi * np.exp(-lam * t))
            lam, phi = shift_invert_eigsh(self.stiffness, self.mass, k, sigma=sigma)
            order = np.argsort(lam)
            lam, phi = np.maximum(lam[order], 0.0), phi[:, order]
            psi = phi * np.exp(-lam * t)
            # the bound with the measured mean d^2 decides
            mean_sq = self._mean_sq(psi)
            if not mean_sq > 0:   # only constant eigenvectors so far: take them all
                dense = True
                continue
            lam_star = np.log(2.0 * max_inv_mass / (self.rtol * mean_sq)) / (2.0 * t)
            if lam[-1] >= lam_star or k >= n - 2:
                break
            k = int(np.ceil(k * lam_star / max(lam[-1], 1e-300) * 1.1)) + 8  # Weyl: lambda_k ~ k
        self.eigenvalues = lam
        self.truncation_bound = float(np.exp(-2.0 * lam[-1] * t) * 2.0 * max_inv_mass) * self.unit_scale**2
        return self._scaled(lam, psi)

    def _scaled(self, lam: np.ndarray, psi: np.ndarray) -> np.ndarray:
        """The embedding from the raw one ``psi = exp(-lambda t) phi`` (a fresh array, changed
        in place): times ``unit_scale``, rows normalised with ``units="normalized"`` -- which
        loses ``psi``, so that ``at_tau`` can start from it, it is then kept (``_basis``)."""
        if self.units == "normalized":
            self._basis = (lam, psi)
            psi = psi.copy()
        else:
            psi *= self.unit_scale
        return self._normalized(psi)

    def at_tau(self, tau: float) -> "HeatDiffusionSolver":
        r"""The same heat distance at diffusion time ``tau`` (relative to the area), from this
        solver's eigenpairs: no new eigendecomposition.

        With :math:`\psi_k = e^{-\lambda_k t}\phi_k` computed, the embedding at
        :math:`t' = \tau' \cdot \mathrm{area}` is :math:`e^{-\lambda_k (t' - t)}\psi_k` over the
        same ``K`` eigenpairs. For ``tau >= self.tau`` the truncation error only shrinks. For a
        smaller ``tau`` the result is the heat distance band-limited to those eigenpairs,
        :math:`d^2 = \sum_{k \le K} e^{-2\lambda_k t'}(\phi_k(x) - \phi_k(y))^2`; its worst-case
        bound (``truncation_bound``, from the largest inverse vertex mass) is then loose, and
        what was measured instead: at ``tau`` = 0.0025 from the eigenpairs of 0.005 on TOSCA
        shapes at 3,000 vertices (david0, cat1) the distances differ from a full
        decomposition at 0.0025 by at most 1.7e-5 / 1.6e-4 of the diameter (median relative
        difference 1e-7 / 1e-6). Used by recognition to measure a correspondence at a finer
        scale than the one it was found at (:data:`gromov.gh.RANK_TAU_SCALE`).
        """
        if not tau > 0:
            raise ValueError(f"tau must be positive, got {tau}")
        lam, psi = self._basis_pairs()
        out = HeatDiffusionSolver.__new__(HeatDiffusionSolver)
        _SpectralDiffusion.__init__(out, self.shape, self.rtol)
        out.tau, out.units, out.laplacian, out.neighbors = float(tau), self.units, self.laplacian, self.neighbors
        out.stiffness, out.mass, out.area = self.stiffness, self.mass, self.area
        out.t = out.tau * out.area
        out.unit_scale = _unit_scale(out.units, out.t, out.area)
        out.eigenvalues = lam
        if self.truncation_bound == 0.0:
            out.truncation_bound = 0.0
        else:
            max_inv_mass = float((1.0 / self.mass.diagonal()).max())
            out.truncation_bound = float(np.exp(-2.0 * lam[-1] * out.t) * 2.0 * max_inv_mass) * out.unit_scale**2
        # exp(lambda (t - t')) overflows for the top eigenpairs of a small shape (all of them
        # computed) at a finer time; their psi = exp(-lambda t) phi has underflowed to 0 there,
        # and the true exp(-lambda t') phi is below exp(-700 t' / (t - t')): negligible unless
        # t' is a small fraction of t. Capped, they stay 0 instead of 0 * inf = NaN.
        psi_out = out._scaled(lam, psi * np.exp(np.minimum(-lam * (out.t - self.t), 700.0)))
        psi_out.flags.writeable = False
        out._psi = psi_out
        return out

    def _basis_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lambda, psi)``: the eigenvalues and the raw embedding ``exp(-lambda t) phi`` (the
        embedding itself, divided by ``unit_scale``, unless its rows were normalised)."""
        psi = self.embedding  # computed once
        if self._basis is not None:
            return self._basis
        return self.eigenvalues, psi / self.unit_scale

    def _normalized(self, psi: np.ndarray) -> np.ndarray:
        """Rows scaled to unit norm with ``units="normalized"`` (in place), else ``psi``.

        The truncation bound ``b`` on the squared distances becomes one on the normalised
        ones: each row's squared norm :math:`k_{2t}(x,x)` is off by at most ``b / 2`` (half a
        squared distance to a far point), so :math:`\bar d^2` moves by at most about
        ``2 b / min_x |psi_x|^2``."""
        if self.units != "normalized":
            return psi
        norms = np.linalg.norm(psi, axis=1)
        low = float(norms.min())
        if not low > 0:
            raise MetricError("a vertex has no heat at any kept eigenpair: cannot normalise its row "
                              "(raw heat distances need no normalisation: --units raw; units='raw')")
        psi /= norms[:, None]
        self.truncation_bound = float(2.0 * self.truncation_bound / low**2)
        return psi

    def __repr__(self) -> str:
        cloud = "" if isinstance(self.shape, Mesh) else f", neighbors={self.neighbors}"
        return (f"HeatDiffusionSolver(n_vertices={self.n_vertices}, tau={self.tau}, "
                f"laplacian={self.laplacian!r}, units={self.units!r}{cloud})")


def _point_cloud_laplacian(rl, v: np.ndarray, neighbors: int = POINT_CLOUD_NEIGHBORS):
    """``robust_laplacian.point_cloud_laplacian`` of the points ``v``, made independent of where
    the cloud lies and of the order of its points.

    The library's operator depends on both (local triangulations of nearly co-circular
    neighbours, neighbour ties): measured on 1,800 random points of a bumpy torus (its default
    30 neighbours), the heat
    distances (raw) moved by up to 4.2% of the diameter (median 0.18%) when the cloud was
    shifted by 1 (about its radius) and by up to 1.0% when its points were reordered (rotated:
    0.3%). So the points are given to it centred on their centroid and sorted by their distance
    from it (a canonical order for any placement of the same cloud), and the operator is put
    back in the given order. A rotation can still move distances a little (up to 0.3% of the
    diameter there): no canonical orientation is imposed.
    """
    c = v - v.mean(axis=0)
    order = np.argsort(np.einsum("ij,ij->i", c, c), kind="stable")
    if len(v) < 4:
        raise MetricError(f"a point cloud needs at least 4 points for its Laplacian, got {len(v)}")
    # a cloud of no more points than that: every other point is a neighbour
    lap, m = rl.point_cloud_laplacian(np.ascontiguousarray(c[order]), n_neighbors=min(int(neighbors), len(v) - 1))
    back = np.empty_like(order)
    back[order] = np.arange(len(order))
    return sp.csr_matrix(lap)[back][:, back], sp.csr_matrix(m)[back][:, back]


def _laplacian(shape, laplacian: str, what: str, neighbors: int = POINT_CLOUD_NEIGHBORS):
    """``(name, stiffness L, lumped mass M, area)`` of a mesh or point cloud (``neighbors``:
    :data:`POINT_CLOUD_NEIGHBORS`)."""
    if laplacian not in ("cotan", "robust"):
        raise ValueError(f"laplacian must be 'cotan' or 'robust', got {laplacian!r}")
    if isinstance(neighbors, (bool, np.bool_)) or not isinstance(neighbors, (int, np.integer)) or neighbors < 3:
        raise ValueError(f"neighbors must be an integer >= 3, got {neighbors!r} (the number of "
                         f"neighbours of a point: --neighbors)")
    laplacian = laplacian if isinstance(shape, Mesh) else "robust"
    if laplacian == "cotan":
        stiffness, mass = cotan_laplacian(shape)
        area = shape.area
    else:
        import robust_laplacian as rl

        v = np.array(shape.vertices)
        if not isinstance(shape, Mesh):
            _check_spread(v, what)
        try:
            if isinstance(shape, Mesh):
                lap, m = rl.mesh_laplacian(v, np.array(shape.faces))
            else:
                lap, m = _point_cloud_laplacian(rl, v, neighbors)
        except (RuntimeError, ValueError) as exc:   # geometry-central's checks (GC_SAFETY_ASSERT)
            raise MetricError(f"{what}: the robust Laplacian (robust-laplacian) cannot be built on this "
                              f"{'mesh' if isinstance(shape, Mesh) else 'point cloud'} ({exc}); the "
                              "geodesic metric (--metric geodesic) or the Gaussian kernel (--kernel "
                              "gaussian) need no Laplacian") from None
        stiffness, mass = sp.csr_matrix(lap), sp.csr_matrix(m)
        area = float(mass.diagonal().sum())
    if not (np.all(mass.diagonal() > 0) and np.isfinite(area)):
        zero = np.flatnonzero(~(mass.diagonal() > 0))
        which = (f"{len(zero)} of its {mass.shape[0]} vertices (first: vertex {zero[0]}) are in no "
                 "triangle of positive area" if len(zero) else "its area is not finite")
        raise MetricError(f"{what} needs positive vertex areas, and {which}: a mesh built from arrays "
                          "is made valid by gromov.repair(mesh), which drops such vertices and keeps "
                          "their file numbering")
    return laplacian, stiffness, mass, float(area)


def _check_spread(points: np.ndarray, what: str) -> None:
    """Refuse a point cloud whose points lie on one line (or at one place): no surface to
    diffuse on, and the robust point-cloud Laplacian stops on it (geometry-central:
    "unreferenced vertex")."""
    c = points - points.mean(axis=0)
    s = np.linalg.svd(c, compute_uv=False)
    if s[0] == 0.0 or s[1] <= 1e-9 * s[0]:
        where = "at one place" if s[0] == 0.0 else "on a line"
        raise MetricError(f"{what}: the {len(points)} points lie {where}, with no surface to diffuse "
                          "heat on; the geodesic metric (--metric geodesic) or the Gaussian kernel "
                          "(--kernel gaussian) work on such a cloud")


class BiharmonicSolver(MetricSolver):
    r"""Biharmonic distance: the heat-kernel diffusion distance integrated over all times.

    With the generalised eigenpairs :math:`L\phi_k = \lambda_k M \phi_k` of the heat kernel
    above (Lipman, Rustamov & Funkhouser, "Biharmonic distance", ACM TOG 29(3), 2010),

    .. math:: d_B^2(x, y) = \sum_{k \ge 1} \frac{(\phi_k(x) - \phi_k(y))^2}{\lambda_k^2}
              = 4 \int_0^\infty t \, d_t^2(x, y) \, dt ,

    since :math:`\int_0^\infty t e^{-2\lambda t} dt = 1/(4\lambda^2)`: a multi-scale
    diffusion distance with no time to choose. It is bending-invariant (intrinsic, through
    ``L`` and ``M``), has the units of length (scaling a shape by ``s`` scales it by ``s``),
    and is smooth and globally informative (far pairs are not saturated, unlike
    :math:`d_t` at small ``t``).

    **Computation** (exact, no truncation): :math:`G = \Phi' \Lambda'^{-2} \Phi'^T` (the
    non-constant eigenpairs) is, up to an added constant that cancels in
    :math:`d_B^2 = G_{xx} + G_{yy} - 2 G_{xy}`, the inverse of the positive definite
    :math:`H = L M^{-1} L + \alpha^2 M 1 1^T M / A` (``A`` the area; the rank-one term gives
    the constant eigenvector the eigenvalue :math:`\alpha^2`, :math:`\alpha = 4\pi/A`,
    Weyl's estimate of :math:`\lambda_1`). One dense Cholesky factorisation and inverse,
    :math:`O(n^3)`: 0.7 s at 3,000 vertices with two idle cores, 1.9 s on one. Each
    connected component is solved on its own; distances between components are ``inf`` (the
    matcher refuses such shapes, as for geodesic distances).

    Parameters
    ----------
    shape : Mesh or PointCloud
    laplacian : {"cotan", "robust"}, default "cotan"
        As in :class:`HeatDiffusionSolver` (point clouds always use the robust Laplacian).
    neighbors : int, default POINT_CLOUD_NEIGHBORS (20)
        As in :class:`HeatDiffusionSolver`.
    """

    name = "diffusion"
    symmetric_rows = True

    def __init__(self, shape, *, laplacian: str = "cotan", neighbors: int = POINT_CLOUD_NEIGHBORS):
        shape = check_shape(shape, metric="diffusion")
        super().__init__(shape)
        self.laplacian, self.stiffness, self.mass, self.area = _laplacian(shape, laplacian,
                                                                          "biharmonic distance", neighbors)
        self.neighbors = int(neighbors)

    def _components(self):
        if isinstance(self.shape, Mesh):
            return self.shape.n_components, self.shape.component_labels
        from scipy.sparse.csgraph import connected_components

        return connected_components(abs(self.stiffness) > 0, directed=False)

    def pairwise(self, *, progress=None, chunk: int = 256) -> np.ndarray:
        if self._pairwise is None:
            n = self.n_vertices
            n_comp, labels = self._components()
            if n_comp == 1:
                d = _distances_from_gram(*self._gram(np.arange(n)))
            else:
                d = np.full((n, n), np.inf)
                for c in range(n_comp):
                    idx = np.flatnonzero(labels == c)
                    d[np.ix_(idx, idx)] = (_distances_from_gram(*self._gram(idx)) if len(idx) > 1
                                           else 0.0)
                d.flags.writeable = False
            self._pairwise = d
            if progress is not None:
                progress(n)
        return self._pairwise

    def _gram(self, idx: np.ndarray):
        """``(diag G, G)`` with ``G = H^{-1}`` on one connected component (see the class notes)."""
        from scipy.linalg import lapack

        lap = self.stiffness[idx][:, idx]
        mc = self.mass.diagonal()[idx]
        area = float(mc.sum())
        alpha = 4.0 * np.pi / area
        h = (lap @ sp.diags(1.0 / mc) @ lap).toarray()
        h += (alpha**2 / area) * np.outer(mc, mc)
        # h is symmetric: its transpose is the Fortran-ordered array LAPACK factorises in place.
        # Dense LAPACK uses the BLAS threads it is given (pair workers run single-threaded).
        cho, info = lapack.dpotrf(h.T, lower=0, overwrite_a=1)
        if info != 0:
            raise MetricError(f"biharmonic distance: the operator is not positive definite "
                              f"(LAPACK dpotrf info={info})")
        g, info = lapack.dpotri(cho, lower=0, overwrite_c=1)
        if info != 0:
            raise MetricError(f"biharmonic distance: inverting the factor failed (LAPACK dpotri info={info})")
        g = np.triu(g)  # dpotri fills the upper triangle
        g += np.triu(g, 1).T
        return np.diag(g).copy(), g

    def _rows(self, sources):
        return np.array(self.pairwise()[sources])

    def __repr__(self) -> str:
        cloud = "" if isinstance(self.shape, Mesh) else f", neighbors={self.neighbors}"
        return f"BiharmonicSolver(n_vertices={self.n_vertices}, laplacian={self.laplacian!r}{cloud})"


def _dense_generalized(stiffness, mass):
    from scipy.linalg import eigh

    return eigh(stiffness.toarray(), mass.toarray())
