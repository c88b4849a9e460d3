r"""Dense correspondence: an image on the other shape for every input vertex.

:func:`match` finds a correspondence between farthest-point samples. The dense map places
every other point of X where its distances to the matched samples fit best on Y -- the
paper's interpolation of a point from its distances to anchor points (Bronstein et al., IJCV
2010, §4; Bronstein, Bronstein & Kimmel, PNAS 2006), applied to each working vertex:

.. math::

    T(v) = \arg\min_{w \in Y} \sum_{l \in L} \big(d_Y(w, y_l) - d_X(v, x_l)\big)^2 ,

over the landmark pairs :math:`(x_l, y_l)` of the two-sided sample correspondence (X's
samples with their images, Y's samples with theirs). Two refinements make it precise:

- **a finer scale.** With the heat-kernel diffusion metric the distances are measured at
  :data:`DENSE_TAU_SCALE` times the diffusion time the samples were matched at, from the same
  eigenpairs: the coarse scale finds the right correspondence, the finer one places a point
  between its neighbours more sharply;
- **trimmed landmarks.** A landmark whose distances disagree with the map everywhere (an
  image placed off by the search, or a sample beside a change of topology) is set aside:
  ``DENSE_ROUNDS`` times, the fraction ``DENSE_KEEP`` of the landmarks with the smallest RMS
  residual over all vertices is kept (least trimmed squares over landmarks). With
  ``DENSE_CANDIDATES`` > 0 the trimming is per pair instead (:func:`anchored_map`).

Input vertices are then carried through the working meshes: an input vertex of X lies on a
working face; its three corners' images, weighted by its barycentric coordinates, give a
point that is projected onto Y's input mesh near those images (never onto another sheet that
passes closer in space). By default the map is then refined at the input resolution
(:func:`input_zoomout`): ZoomOut's spectral step on the input meshes' own Laplace-Beltrami
eigenfunctions, each image searched only near where the robust map put it. The measurements
that chose these settings are in ``docs/design/dense.md``.
"""

from __future__ import annotations

import logging
import mmap
import os
from dataclasses import dataclass

import numpy as np

from numba import njit

from ._arrays import one_blas_thread, readonly
from ._eigen import shift_invert_eigsh, spd_solver
from ._project import project_among
from .resolution import gather

__all__ = ["DenseMap", "dense_maps", "anchored_map", "local_anchored_map", "landmark_distances", "zoomout", "input_zoomout",
           "laplace_beltrami_basis", "prolonged_basis", "ring_neighbourhoods", "DENSE_TAU_SCALE", "DENSE_KEEP", "DENSE_ROUNDS",
           "DENSE_REFINE", "DENSE_CANDIDATES", "DENSE_LOCAL", "DENSE_CHOICE", "CHOICE_K", "REFINEMENTS",
           "place_small_pieces", "PIECE_PATCH", "zoomout_energy", "refine_better", "placements_agree",
           "relax_isometric", "DENSE_RELAX", "RELAX_EDGES", "RELAX_CAP", "RELAX_REACH", "RELAX_SWEEPS", "RELAX_MAX_RINGS",
           "isometric_stress", "inverse_map", "consistent_maps", "DENSE_INVERSE", "INVERSE_RINGS",
           "INVERSE_SWEEPS"]

logger = logging.getLogger(__name__)

#: Heat-kernel diffusion time of the dense placement, relative to the match's.
DENSE_TAU_SCALE = 0.5
#: Each vertex placed from this many of its nearest landmarks (:func:`local_anchored_map`); 0,
#: the default: from all of them, trimmed (:func:`anchored_map`). 16 repairs welded shapes and
#: loses on TOPKIDS (docs/design/dense.md, "Placed from the nearest landmarks").
DENSE_LOCAL = 0
#: Beside the default placement, each vertex also placed from this many of its nearest landmarks;
#: both refined on the input meshes up to CHOICE_K eigenfunctions and the one of lower ZoomOut
#: energy refined on (:func:`refine_better`; docs/design/dense.md, "Two placements, one kept").
#: 0: the default placement alone.
DENSE_CHOICE = 16
#: The eigenfunctions up to which both placements are refined and at which their energies compare.
CHOICE_K = 60
#: Where both placements put at least CHOICE_AGREE of the working vertices within CHOICE_RADIUS
#: mean working edges of each other, the default one is refined alone: they are one start.
CHOICE_AGREE, CHOICE_RADIUS = 0.995, 5.0
#: With ``local=0``: the fraction of the landmarks kept, and how many trimming rounds.
DENSE_KEEP = 0.7
DENSE_ROUNDS = 3
#: Candidate images per vertex, re-ranked by their own trimmed residual (:func:`anchored_map`);
#: 0, the default: the landmarks trimmed over all vertices alike. 32 repairs welded shapes and
#: loses on other TOPKIDS pairs (docs/design/dense.md, "The landmarks trimmed per pair").
DENSE_CANDIDATES = 0
#: Refinements of the placed map (:func:`dense_maps`' ``refine``): "input" (:func:`input_zoomout`
#: on the input meshes), "zoomout" (:func:`zoomout` on the working meshes) or None.
REFINEMENTS = ("input", "zoomout", None)
#: The default refinement: "input", the most precise on the pairs measured (docs/design/dense.md).
DENSE_REFINE: str | None = "input"
#: ZoomOut refinement on the working meshes: eigenfunctions from, to, step.
ZOOMOUT_START, ZOOMOUT_END, ZOOMOUT_STEP = 20, 60, 4
#: Refinement on the input meshes: eigenfunctions from, to, step; the rings of the input mesh
#: around the current image that each step searches; the steps with at most INPUT_GLOBAL
#: eigenfunctions search all of Y (docs/design/dense.md).
INPUT_START, INPUT_K, INPUT_STEP, INPUT_RINGS, INPUT_GLOBAL = 20, 180, 4, 2, 32
#: After the refinement on the input meshes, each map made locally isometric
#: (:func:`relax_isometric`); docs/design/dense.md, "Local isometry after the refinement".
DENSE_RELAX = True
#: :func:`relax_isometric`: the neighbourhood's radius in mean edges of the coarser mesh; the cap
#: of a residual in the same unit, the radius itself (a residual beyond it is no slide within the
#: neighbourhood: a weld or a glued contact); the sweeps at most.
RELAX_EDGES = 4
RELAX_CAP = RELAX_EDGES
#: ... and at most this part of the shape: the radius is min(RELAX_EDGES mean edges,
#: RELAX_REACH √area of Y). On a coarse mesh 4 edges reach a large part of the shape (0.11 √area
#: on 1,500 vertices) and a fit over a bent joint moves right images (docs/design/dense.md,
#: "The steps' neighbourhoods").
RELAX_REACH = 0.06
RELAX_SWEEPS = 10
#: ... and at most this many rings of X (the neighbourhoods' memory and time grow with the square
#: of the rings: an X more than twice as fine as Y gets a smaller radius).
RELAX_MAX_RINGS = 8
#: After the local isometry step (and again after the inverse rounds, around the images they
#: changed), each map's image of each vertex moved to the vertex of Y nearest where the rigid
#: motion that best carries its neighbourhood puts it
#: (:func:`align_locally`; docs/design/dense.md, "Local rigid alignment"): the rounds at most
#: (0: none), the rings around the current image searched, and the residual, in mean edges of
#: the coarser mesh, beyond which a neighbour's weight falls in the refit.
DENSE_ALIGN = 3
ALIGN_RINGS = 2
ALIGN_CAP = 1.0
#: After the local isometry step and the local rigid alignment, rounds in which each
#: direction's map is offered the inverse of the other direction's as new starts, kept where
#: they lower the local stress (:func:`consistent_maps`); the maps they change are aligned
#: again (docs/design/dense.md, "Each direction from the other"). 0: none.
DENSE_INVERSE = 1
#: :func:`inverse_map`: a vertex without preimages takes the images of those within this many rings.
INVERSE_RINGS = 2
#: The sweeps of each start's local isometry step in those rounds, at most.
INVERSE_SWEEPS = 3
#: The input meshes' eigenpairs from the working mesh's (:func:`prolonged_basis`): how many
#: working eigenvectors per eigenpair wanted, and the subspace iterations on the input mesh.
BASIS_GUARD, BASIS_ITERATIONS = 1.1, 1


@dataclass(frozen=True, eq=False)
class DenseMap:
    """Images of every input vertex of one shape on the other shape's input mesh.

    Arrays are indexed by the source file's vertex ids: entry ``i`` is the image of vertex
    ``i`` of the file (``-1`` / NaN for a file vertex that loading dropped).

    Attributes
    ----------
    face : ndarray (n,) of int64
        Face of the target's input mesh holding the image; -1 on a point cloud.
    bary : ndarray (n, 3)
        Barycentric coordinates of the image in ``face``; NaN on a point cloud.
    vertex : ndarray (n,) of int64
        Nearest target input vertex (file id): the corner with the largest weight, or on a
        point cloud the image point itself.
    """

    face: np.ndarray
    bary: np.ndarray
    vertex: np.ndarray


def _corners(s, points) -> tuple[np.ndarray, np.ndarray]:
    """``(corners (L, 3), bary (L, 3))`` of landmark points: SurfacePoints on a mesh, or
    vertex ids (a point cloud, or images at vertices)."""
    if hasattr(points, "face"):
        return s.mesh.faces[np.asarray(points.face, dtype=np.int64)], np.asarray(points.bary, dtype=np.float64)
    v = np.asarray(points, dtype=np.int64)
    return np.repeat(v[:, None], 3, axis=1), np.tile([1.0, 0.0, 0.0], (len(v), 1))


def landmark_distances(s, points, tau_scale: float = DENSE_TAU_SCALE) -> np.ndarray:
    r"""``(n, L)``: distance from every working vertex of ``s`` to each landmark point.

    Between a vertex and a point inside a face the squared distances to the face's corners
    are interpolated barycentrically (as :class:`gromov.gmds.SurfaceDistance` does). With the
    heat-kernel diffusion metric the distances are those at ``tau_scale`` times its diffusion
    time (:meth:`gromov.shape_metric.ShapeMetric.ranking_surface`, the same eigenpairs); with any other
    metric, the metric's own.

    Parameters
    ----------
    s : ShapeMetric
    points : SurfacePoints or array of working vertex ids, L of them
    tau_scale : float, default DENSE_TAU_SCALE
    """
    corners, bary = _corners(s, points)
    flat = corners.ravel()
    fine = s.ranking_surface(tau_scale) if tau_scale != 1.0 else None
    if fine is not None:
        psi = fine[0].embedding
        sq = (psi * psi).sum(1)
        d2 = sq[:, None] + sq[flat][None, :] - 2.0 * (psi @ psi[flat].T)
    else:
        d2 = s.distances[:, flat] ** 2
    d2 = np.maximum(d2, 0.0).reshape(len(d2), len(corners), 3)
    return np.sqrt(np.einsum("nlc,lc->nl", d2, bary))


def anchored_map(ax: np.ndarray, ay: np.ndarray, *, keep: float = DENSE_KEEP,
                 rounds: int = DENSE_ROUNDS, candidates: int | None = None) -> np.ndarray:
    r"""Working vertex of Y for each working vertex of X, from distances to paired landmarks.

    With ``candidates`` K > 0, least trimmed squares per pair (Rousseeuw, "Least
    median of squares regression", JASA 79, 1984): among the K vertices w with the smallest
    :math:`\sum_l (a^Y_{wl} - a^X_{vl})^2` over all L landmarks,

    .. math:: T(v) = \arg\min_w \sum_{l \in H(v, w)} (a^Y_{wl} - a^X_{vl})^2 ,

    :math:`H(v, w)` the ``ceil(keep L)`` landmarks with the smallest squared residuals for that
    pair. A weld or a glued contact shortens, on one shape only, the distances from a vertex to
    the landmarks whose paths cross it: for the true pair those are its largest residuals, and
    they are set aside for that pair alone (``docs/design/dense.md``).

    With K = 0 (the default), :math:`T(v) = \arg\min_w \sum_{l \in S} (a^Y_{wl} - a^X_{vl})^2` over one
    landmark subset S for all vertices: all landmarks first, then ``rounds`` times the ``ceil(keep
    L)`` landmarks with the smallest residual :math:`(\frac1n \sum_v (a^Y_{T(v) l} -
    a^X_{vl})^2)^{1/2}`.

    Parameters
    ----------
    ax : ndarray (n_X, L)
        Distances from X's working vertices to X's landmarks.
    ay : ndarray (n_Y, L)
        Distances from Y's working vertices to the paired landmarks on Y.
    keep : float in (0, 1], default DENSE_KEEP
    rounds : int, default DENSE_ROUNDS
        With ``candidates=0`` only.
    candidates : int, optional
        Default: :data:`DENSE_CANDIDATES`, read at each call.

    Returns
    -------
    ndarray (n_X,) of int64
    """
    ax, ay = _landmark_pair(np.asarray(ax), np.asarray(ay))
    if not 0.0 < keep <= 1.0:
        raise ValueError(f"keep must be in (0, 1], got {keep!r}")
    # the costs in single precision: half the time of the products, and the map is the same
    # but for near-ties (docs/design/dense.md)
    ax32, ay32 = ax.astype(np.float32), ay.astype(np.float32)
    L = ax.shape[1]
    h = max(3, int(np.ceil(keep * L - 1e-9)))
    candidates = DENSE_CANDIDATES if candidates is None else candidates
    if candidates < 0:
        raise ValueError(f"candidates must be non-negative, got {candidates!r}")
    if candidates > 0:
        return _trimmed_per_pair(ax32, ay32, min(h, L), int(candidates))
    idx = np.arange(L)
    for r in range(int(rounds) + 1):
        T = np.argmin(_sum_of_squares(ax32[:, idx], ay32[:, idx]), axis=1)
        if r == rounds or h >= L:
            break
        e = ((ay[T] - ax) ** 2).mean(axis=0)
        idx = np.sort(np.argsort(e, kind="stable")[:h])
    return T.astype(np.int64)


def _landmark_pair(ax: np.ndarray, ay: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(ax, ay)`` checked: distances of both shapes' vertices to the same ``L`` landmarks."""
    if ax.ndim != 2 or ay.ndim != 2 or ax.shape[1] != ay.shape[1]:
        raise ValueError(f"ax and ay must be (n_X, L) and (n_Y, L), got {ax.shape} and {ay.shape}")
    return ax, ay


def _sum_of_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    r"""``(n_a, n_b)``: :math:`\lVert b_w - a_v \rVert^2 - \lVert a_v \rVert^2` for every pair of
    rows (the row's own constant left out: the same argmin per row), by one product."""
    cost = a @ b.T
    cost *= -2.0
    cost += (b * b).sum(1)[None, :]
    return cost


def local_anchored_map(ax: np.ndarray, ay: np.ndarray, k: int = 16) -> np.ndarray:
    r"""Working vertex of Y for each working vertex of X from its ``k`` nearest landmarks:

    .. math:: T(v) = \arg\min_w \sum_{l \in N_k(v)} (a^Y_{wl} - a^X_{vl})^2 ,

    :math:`N_k(v)` the ``k`` landmarks nearest to ``v`` on X: a point is placed by the anchors
    around it, as in the interpolation of a point from nearby anchors (Bronstein et al., IJCV
    2010, §4). Over all landmarks (:func:`anchored_map`) the far ones pull every point, and their
    distances are those a weld, a glued contact or a cut changes most.

    Parameters
    ----------
    ax, ay : ndarray (n_X, L), (n_Y, L)
        As :func:`anchored_map`.
    k : int, default 16
        At least 3 and at most L are used.

    Returns
    -------
    ndarray (n_X,) of int64
    """
    ax, ay = _landmark_pair(np.asarray(ax), np.asarray(ay))
    k = int(min(max(k, 3), ax.shape[1]))
    near = np.argpartition(ax, k - 1, axis=1)[:, :k]
    # single precision, as anchored_map: half the time of the products, the same map but for near-ties
    ax32, ay32 = ax.astype(np.float32), ay.astype(np.float32)
    m = np.zeros_like(ax32)
    np.put_along_axis(m, near, 1.0, axis=1)
    cost = m @ (ay32 * ay32).T
    cost -= 2.0 * ((m * ax32) @ ay32.T)
    return np.argmin(cost, axis=1).astype(np.int64)


def _trimmed_per_pair(ax: np.ndarray, ay: np.ndarray, h: int, k: int, chunk: int = 256) -> np.ndarray:
    """:func:`anchored_map` with candidates: the ``k`` best rows of ``ay`` for each row of ``ax``
    by the full sum of squares, then the one with the smallest sum of its ``h`` smallest
    squared residuals."""
    cost = _sum_of_squares(ax, ay)
    k = min(k, len(ay))
    cand = np.argpartition(cost, k - 1, axis=1)[:, :k] if k < len(ay) else np.broadcast_to(
        np.arange(len(ay)), cost.shape)
    T = np.empty(len(ax), dtype=np.int64)
    for s in range(0, len(ax), chunk):
        c = cand[s:s + chunk]
        r = ay[c] - ax[s:s + chunk, None, :]
        r *= r
        if h < r.shape[2]:
            r = np.partition(r, h - 1, axis=2)[:, :, :h]
        T[s:s + chunk] = c[np.arange(len(c)), np.argmin(r.sum(axis=2), axis=1)]
    return T


def _basis(s, k: int):
    """``(phi (n, k), mass (n,))``: the first ``k`` Laplace-Beltrami eigenfunctions of the
    working mesh and its vertex masses, computed once per shape: the heat kernel's own
    eigenpairs where the metric has them (:math:`\\phi = e^{\\lambda t}\\psi`), else the
    cotangent Laplacian's."""
    cached = s._lb_basis
    if cached is not None and cached[0].shape[1] >= k:
        return cached[0][:, :k], cached[1]
    n = s.mesh.n_vertices
    inner = getattr(s.solver, "inner", s.solver)   # through a hole-filling wrapper
    if hasattr(inner, "_basis_pairs") and len(inner.eigenvalues if inner.eigenvalues is not None
                                              else []) >= k:
        lam, psi = inner._basis_pairs()
        phi = psi[:n, :k] * np.exp(lam[:k] * inner.t)
        mass = np.asarray(inner.mass.diagonal())[:n]
    else:
        from scipy.sparse.linalg import eigsh

        from .metrics.diffusion import cotan_laplacian

        L, M = cotan_laplacian(s.mesh)
        lam, phi = eigsh(L, min(k, n - 2), M=M, sigma=-1e-8 / max(s.mesh.area, 1e-300))
        phi = phi[:, np.argsort(lam)]
        mass = np.asarray(M.diagonal())
    s._lb_basis = (np.ascontiguousarray(phi), mass)
    return s._lb_basis[0][:, :k], mass


def zoomout(sx, sy, T: np.ndarray, *, k_start: int = ZOOMOUT_START, k_end: int = ZOOMOUT_END,
            step: int = ZOOMOUT_STEP) -> np.ndarray:
    r"""Spectral upsampling of a vertex map X -> Y (ZoomOut; Melzi et al., SIGGRAPH Asia 2019).

    For k from ``k_start`` to ``k_end``: the functional map
    :math:`C = \Phi_X^\top M_X \Phi_Y[T]` on the first k eigenfunctions (it carries
    coefficients on Y to coefficients on X), then each vertex of X to the vertex of Y whose
    delta function C carries closest to its own,
    :math:`T(v) = \arg\min_w \lVert \Phi_X(v) - \Phi_Y(w) C^\top \rVert`.
    """
    phx, mx = _basis(sx, k_end)
    phy, _ = _basis(sy, k_end)
    k_end = min(k_end, phx.shape[1], phy.shape[1])
    for k in range(min(k_start, k_end), k_end + 1, step):
        C = phx[:, :k].T @ (mx[:, None] * phy[T, :k])
        a = phx[:, :k].astype(np.float32)
        b = (phy[:, :k] @ C.T).astype(np.float32)
        cost = a @ b.T            # nearest row of b: argmin |b|^2 - 2 a.b, by products
        cost *= -2.0
        cost += (b * b).sum(1)[None, :]
        T = np.argmin(cost, axis=1)
    return np.asarray(T, dtype=np.int64)


def laplace_beltrami_basis(mesh, k: int) -> tuple[np.ndarray, np.ndarray]:
    r"""``(phi (n, k), mass (n,))``: the first ``k`` eigenfunctions of the cotangent Laplacian of
    ``mesh`` (:func:`gromov.metrics.diffusion.cotan_laplacian`), :math:`L\phi = \lambda M\phi`,
    M-orthonormal, by increasing eigenvalue, and the lumped vertex masses.

    Shift-invert Lanczos (:func:`gromov._eigen.shift_invert_eigsh`) about
    :math:`\sigma = -10^{-2}/\text{area}`, just below the spectrum (as pyFM does on
    area-normalised meshes), from a fixed start vector: the same eigenpairs on every run.
    Fewer than ``k`` for a mesh of ``k + 2`` vertices or fewer.
    """
    from .metrics.diffusion import cotan_laplacian

    L, M = cotan_laplacian(mesh)
    k = int(min(k, mesh.n_vertices - 2))
    lam, phi = shift_invert_eigsh(L, M, k, sigma=-1e-2 / max(mesh.area, 1e-300))
    return np.ascontiguousarray(phi[:, np.argsort(lam)]), np.asarray(M.diagonal())


def prolonged_basis(working, k: int, *, guard: float = BASIS_GUARD,
                    iterations: int = BASIS_ITERATIONS) -> tuple[np.ndarray, np.ndarray]:
    r"""``(phi (n, k), mass (n,))``: the first ``k`` Laplace-Beltrami eigenpairs of a large mesh,
    approximated from those of its working mesh, as :func:`laplace_beltrami_basis` returns them.

    The :math:`p = \lceil \text{guard}\, k \rceil` first eigenvectors of the working mesh
    (:func:`laplace_beltrami_basis`, cheap on a few thousand vertices) are carried to the
    input mesh by linear interpolation on the working faces, :math:`V = P \Phi_w`; then
    ``iterations`` steps of subspace iteration with the shift-invert operator, each followed by
    M-orthonormalisation,

    .. math:: V \leftarrow (L - \sigma M)^{-1} M V ,

    and Rayleigh-Ritz on the span of V: :math:`(V^\top L V) y = \lambda (V^\top M V) y`,
    :math:`\phi = V y`, the k smallest (Saad, *Numerical Methods for Large Eigenvalue
    Problems*, 2nd ed., SIAM 2011, ch. 5: subspace iteration and the Rayleigh-Ritz
    procedure). Each Ritz value is at least the true eigenvalue of the same rank
    (Courant-Fischer); the eigenfunctions of the working mesh are already close to the input
    mesh's at these frequencies (its mean edge is a few percent of a wavelength of the k-th),
    and one iteration brings the Ritz values within a few percent of the true ones
    (``docs/design/dense.md``, "Cost"). The extra ``p - k`` vectors absorb the error of the
    last wanted ones. Four to six times faster than the Lanczos solve on the input mesh for
    28,000 vertices; it is that solve (:func:`laplace_beltrami_basis`) where the working mesh
    is no smaller than the input mesh, holds too few vertices for ``p`` vectors, or the
    projected problem is singular.

    Parameters
    ----------
    working : gromov.resolution.WorkingMesh
        The working mesh and its map to the input mesh (``working.source``).
    k : int
        Eigenpairs wanted; fewer for a mesh of ``k + 2`` vertices or fewer.
    guard : float, default BASIS_GUARD
    iterations : int, default BASIS_ITERATIONS

    Returns
    -------
    (ndarray (n, k), ndarray (n,))
        On the pieces of the input mesh the working mesh covers
        (:attr:`~gromov.resolution.WorkingMesh.source_kept`), rows in their order.
    """
    import scipy.linalg as sl
    import scipy.sparse as sp

    from .metrics.diffusion import cotan_laplacian

    kept = working.source_kept
    mesh = working.source if kept.all() else working.source.submesh(kept)
    wm = working.mesh
    k = int(min(k, mesh.n_vertices - 2))
    p = int(np.ceil(guard * k))
    if mesh.n_vertices <= wm.n_vertices or p > wm.n_vertices - 2 or k < 1:
        return laplace_beltrami_basis(mesh, k)
    phi_w, _ = laplace_beltrami_basis(wm, p)
    rows = np.repeat(np.arange(mesh.n_vertices), 3)
    P = sp.csr_matrix((working.source_bary[kept].ravel(), (rows, wm.faces[working.source_face[kept]].ravel())),
                      shape=(mesh.n_vertices, wm.n_vertices))
    V = P @ phi_w
    L, M = cotan_laplacian(mesh)
    mass = np.asarray(M.diagonal())     # lumped: M V is a row scaling
    solve, _ = spd_solver(L + (1e-2 / max(mesh.area, 1e-300)) * M)
    try:
        with one_blas_thread():
            for _ in range(int(iterations)):
                V = solve(mass[:, None] * V)
                V /= np.sqrt(np.einsum("ij,ij->j", V, mass[:, None] * V))   # columns of like scale
                R = np.linalg.cholesky(V.T @ (mass[:, None] * V))           # then M-orthonormal
                V = V @ sl.solve_triangular(R, np.eye(len(R)), lower=True).T
            lam, Y = sl.eigh(V.T @ (L @ V), V.T @ (mass[:, None] * V))
    except np.linalg.LinAlgError:   # the carried vectors not independent: the full solve
        return laplace_beltrami_basis(mesh, k)
    return np.ascontiguousarray(V @ Y[:, :k]), mass


def _input_basis(s, k: int, computed=None) -> tuple[np.ndarray, np.ndarray]:
    """The input mesh's eigenpairs (:func:`prolonged_basis` from ``s``'s working mesh, or
    ``computed``, its result), computed once per shape: of the pieces its working mesh covers
    (:attr:`~gromov.resolution.WorkingMesh.source_kept`), with rows and masses 0 on the pieces
    left out."""
    kept = s.working.source_kept
    n = int(kept.sum())
    if _needs_basis(s, k):
        phi, mass = prolonged_basis(s.working, k) if computed is None else computed
        if n == len(kept):
            s._input_basis = (phi, mass)
        else:
            full, m = np.zeros((len(kept), phi.shape[1])), np.zeros(len(kept))
            full[kept], m[kept] = phi, mass
            s._input_basis = (full, m)
    return s._input_basis[0][:, :k], s._input_basis[1]


def _needs_basis(s, k: int) -> bool:
    """Whether ``s`` holds fewer input eigenpairs than ``k`` (or all there are) yet."""
    cached = s._input_basis
    return cached is None or cached[0].shape[1] < min(k, int(s.working.source_kept.sum()) - 2)


#: ``(shape, buffer, alongside)``: the shapes whose input eigenpairs a forked process computes
#: (read there, not pickled), the memory shared with it where it writes them, and what it calls
#: after them (or None).
_FORKED: list = []


def _shared_buffer(s, k: int) -> mmap.mmap:
    """Anonymous memory shared with processes forked after it, room for the eigenpairs of
    :func:`prolonged_basis` on ``s``'s kept input vertices: ``(n, k)`` vectors then ``n``
    masses, in double precision."""
    n = int(s.working.source_kept.sum())
    return mmap.mmap(-1, max(n * (max(min(k, n - 2), 0) + 1), 1) * 8)


def _forked_basis(i: int, k: int):
    """In the forked process: :func:`prolonged_basis` of ``_FORKED[i]``'s shape, written to its
    shared buffer, then its ``alongside()`` on one BLAS thread; ``(number of vectors, what
    alongside returned)``."""
    s, buffer, alongside = _FORKED[i]
    phi, mass = prolonged_basis(s.working, k)
    n, kk = phi.shape
    out = np.frombuffer(buffer, dtype=np.float64)
    out[:n * kk].reshape(n, kk)[:] = phi
    out[n * kk:n * kk + n] = mass
    if alongside is None:
        return kk, None
    with one_blas_thread():
        return kk, alongside()


def _from_buffer(s, buffer: mmap.mmap, kk: int) -> tuple[np.ndarray, np.ndarray]:
    """The eigenpairs :func:`_forked_basis` wrote for ``s``, copied out of the shared buffer."""
    n = int(s.working.source_kept.sum())
    out = np.frombuffer(buffer, dtype=np.float64)
    return out[:n * kk].reshape(n, kk).copy(), out[n * kk:n * kk + n].copy()


def _may_fork() -> bool:
    """Whether a second process may take a core: two cores and two numba threads allowed (a
    worker of :mod:`gromov.experiments.pairwise` runs on one), not a daemonic process, and
    ``fork`` available."""
    import multiprocessing as mp

    from numba import get_num_threads

    return ((os.cpu_count() or 1) >= 2 and get_num_threads() >= 2 and not mp.current_process().daemon
            and "fork" in mp.get_all_start_methods())


def _input_bases(sx, sy, k: int, meanwhile=None, alongside=None):
    """Both shapes' input eigenpairs (:func:`_input_basis`), once per shape, and what
    ``meanwhile()`` and ``alongside()`` return (None for either not given); in one process the
    two are called in that order, before the eigenpairs.

    Where both shapes' are missing and two cores are there, Y's are computed in a forked
    process, which then calls ``alongside()``, while ``meanwhile()`` and X's are computed here,
    each side on one BLAS thread: the shift-invert Lanczos of each holds the GIL (threads would
    take turns), and the two solves are about half the dense maps' time on two 28k-vertex
    meshes; the two calls, one direction's placement each in :func:`dense_maps`, even the two
    sides' work. The child runs the same code on the same data with one BLAS thread, so the
    eigenpairs are those of a sequential run. It writes them to memory the two processes
    share: sent back through a pipe, the 40 MB of a 28k-vertex mesh's took 0.2 s more.
    """
    import multiprocessing as mp

    here = there_result = None
    if sx is not sy and _needs_basis(sx, k) and _needs_basis(sy, k) and _may_fork():
        from concurrent.futures import ProcessPoolExecutor

        global _FORKED
        buffer = _shared_buffer(sy, k)
        _FORKED = [(sy, buffer, alongside)]
        try:
            with ProcessPoolExecutor(1, mp_context=mp.get_context("fork")) as pool:
                there = pool.submit(_forked_basis, 0, k)
                if meanwhile is not None:
                    with one_blas_thread():
                        here = meanwhile()
                _input_basis(sx, k)
                kk, there_result = there.result()
                _input_basis(sy, k, _from_buffer(sy, buffer, kk))
        finally:
            _FORKED = []
            buffer.close()
    else:
        here = meanwhile() if meanwhile is not None else None
        there_result = alongside() if alongside is not None else None
    for s in (sx, sy):
        _input_basis(s, k)
    return here, there_result


def ring_neighbourhoods(mesh, rings: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(indptr, ids)``: the vertices within ``rings`` edges of each vertex, itself
    included, sorted."""
    if rings < 0:
        raise ValueError(f"rings must be non-negative, got {rings!r}")
    adj = mesh.adjacency.tocsr()
    return _rings(adj.indptr.astype(np.int64), adj.indices.astype(np.int64), int(rings))


@njit(cache=True, nogil=True)
def _rings(ptr, ids, rings):
    """:func:`ring_neighbourhoods` of the graph ``(ptr, ids)`` (CSR adjacency), by a
    breadth-first search of ``rings`` levels from each vertex."""
    n = ptr.shape[0] - 1
    seen = np.full(n, -1, np.int64)    # the last vertex whose search reached it
    level = np.empty(n, np.int64)      # that search's vertices, level after level
    out_ptr = np.zeros(n + 1, np.int64)
    out = np.empty(max(4 * n, 1), np.int64)
    for v in range(n):
        seen[v] = v
        level[0] = v
        begin, end = 0, 1
        for _ in range(rings):
            stop = end
            for q in range(begin, stop):
                u = level[q]
                for j in range(ptr[u], ptr[u + 1]):
                    w = ids[j]
                    if seen[w] != v:
                        seen[w] = v
                        level[end] = w
                        end += 1
            if end == stop:
                break
            begin = stop
        start = out_ptr[v]
        if start + end > out.shape[0]:
            grown = np.empty(max(2 * out.shape[0], start + end), np.int64)
            grown[:start] = out[:start]
            out = grown
        if end <= 64:   # insertion sort: no call for a short list
            for q in range(end):
                w = level[q]
                i = start + q
                while i > start and out[i - 1] > w:
                    out[i] = out[i - 1]
                    i -= 1
                out[i] = w
        else:
            out[start:start + end] = np.sort(level[:end])
        out_ptr[v + 1] = start + end
    return out_ptr, out[:out_ptr[n]].copy()


@njit(cache=True, nogil=True, fastmath=True)
def _nearest_in_rings(a, b, T, ptr, ids):
    """For each row v of ``a``, the row c of ``b`` nearest to it (squared Euclidean, over b's
    columns: the first of ``a``'s) among ``ids[ptr[T[v]]:ptr[T[v] + 1]]``; the first of equal
    ones. The sums are taken in the arrays' precision (single for the refinement's: twice the
    lanes, and a quarter less time on 28k vertices)."""
    n = a.shape[0]
    k = b.shape[1]
    out = np.empty(n, np.int64)
    zero = a.dtype.type(0)
    for v in range(n):
        t = T[v]
        best = np.inf
        arg = t
        for j in range(ptr[t], ptr[t + 1]):
            c = ids[j]
            d = zero
            for q in range(k):
                e = a[v, q] - b[c, q]
                d += e * e
            if d < best:
                best = d
                arg = c
        out[v] = arg
    return out


def _nearest_rows(a: np.ndarray, b: np.ndarray, chunk: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """``(index, squared distance)`` of the row of ``b`` nearest to each row of ``a``, by
    products, ``chunk`` rows of ``a`` at a time (``b`` has a few thousand rows: a chunk's
    products stay in cache while they are scaled, shifted and searched)."""
    bb = np.einsum("ij,ij->i", b, b)
    idx, d2 = np.empty(len(a), np.int64), np.empty(len(a), a.dtype)
    for s in range(0, len(a), chunk):
        part = a[s:s + chunk]
        d = part @ b.T
        d *= -2.0
        d += bb[None, :]
        idx[s:s + chunk] = j = np.argmin(d, axis=1)
        d2[s:s + chunk] = d[np.arange(len(part)), j] + np.einsum("ij,ij->i", part, part)
    return idx, d2


def input_zoomout(sx, sy, T: np.ndarray, *, k_start: int = INPUT_START, k_end: int = INPUT_K,
                  step: int = INPUT_STEP, rings: int = INPUT_RINGS, global_k: int = INPUT_GLOBAL,
                  orthogonal: bool = False) -> np.ndarray:
    r"""Refine a vertex map between the *input* meshes of X and Y spectrally.

    ZoomOut (Melzi et al., SIGGRAPH Asia 2019) on the Laplace-Beltrami eigenfunctions
    :math:`\Phi` of each input mesh (:func:`prolonged_basis`), each scaled to be orthonormal
    for the mass over the total area (so that shapes of different sizes compare): for k from ``k_start`` to
    ``k_end`` by ``step``, the functional map of the current map on the first k of them, which
    carries coefficients on Y to coefficients on X,

    .. math:: C = \Phi_X^\top M_X \Phi_Y[T],

    then each vertex of X goes to the vertex of Y whose delta function C carries closest to its
    own (ZoomOut's point-to-point recovery),

    .. math:: T(v) = \arg\min_{w} \lVert \Phi_X(v) - \Phi_Y(w)\, C^\top \rVert .

    Each vertex's image is searched in the ``rings``-ring :math:`N(T(v))` of its current image
    on Y's input mesh: the high frequencies sharpen the map without letting it jump to a
    symmetric part or across a change of topology, at ``O(n k)`` per step. While k is at most
    ``global_k`` the vertices of Y's working mesh, spread over all of Y, are searched too (by
    products), and the nearer of the two is kept: a functional map of so few, smooth
    eigenfunctions is made by the whole of a mostly right map, and it moves a region the robust
    placement put wrong (one hand on the other's place) back to where the rest of the map says
    it belongs; the later local steps then refine it.

    Parameters
    ----------
    sx, sy : ShapeMetric
        Both meshes.
    T : ndarray (n_X,) of int
        Vertex of Y's input mesh (index, not file id) for each vertex of X's input mesh.
    k_start, k_end, step, rings, global_k : int, defaults INPUT_START, INPUT_K, INPUT_STEP,
        INPUT_RINGS, INPUT_GLOBAL
    orthogonal : bool, default False
        Replace each functional map by the closest orthogonal matrix :math:`U V^\top` of its SVD
        (the ICP step of Ovsjanikov et al., "Functional maps", SIGGRAPH 2012, §6.1); measured
        less precise on TOSCA (``docs/design/dense.md``).

    Returns
    -------
    ndarray (n_X,) of int64
    """
    T = _input_map(sx, T)
    a, ma, phy = _input_arrays(sx, sy, k_end)
    k_end = a.shape[1]
    steps = [(k, k) for k in range(min(k_start, k_end), k_end + 1, step)]
    return _zoomout_steps(sx, sy, T, a, ma, phy, steps, rings=rings, global_k=global_k, orthogonal=orthogonal)


def _input_map(sx, T) -> np.ndarray:
    """``T`` checked: one vertex of Y's input mesh per input vertex of X."""
    T = np.asarray(T, dtype=np.int64)
    if T.shape != (sx.input.n_vertices,):
        raise ValueError(f"T must have one vertex of Y per input vertex of X, shape "
                         f"({sx.input.n_vertices},), got {T.shape}")
    return T


def _input_arrays(sx, sy, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(Phi_X, M_X Phi_X, Phi_Y)`` of the input meshes, first ``k`` (at most what both have),
    single precision, as the refinement uses them."""
    phx, mx = _input_basis(sx, k)
    phy, my = _input_basis(sy, k)
    k = min(k, phx.shape[1], phy.shape[1])
    # each basis orthonormal for the mass over the total area (Phi sqrt(A), M / A): the relation
    # Phi_X(v) = Phi_Y(T(v)) C^T holds between shapes of different sizes, and the values are
    # of order 1, so that single precision holds them: half the time of the products, and the
    # maps agree but for near-ties (docs/design/dense.md, "Cost")
    root_x, root_y = np.sqrt(mx.sum()), np.sqrt(my.sum())
    a = (phx[:, :k] * root_x).astype(np.float32)
    ma = (mx[:, None] * phx[:, :k] / root_x).astype(np.float32)
    return a, ma, (phy[:, :k] * root_y).astype(np.float32)


def zoomout_energy(sx, sy, T: np.ndarray, k: int) -> float:
    r"""Mean ZoomOut energy of the input-vertex map ``T`` on the first ``k`` eigenfunctions:

    .. math:: E_k(T) = \frac{1}{n_X} \sum_v \lVert \Phi_X(v) - \Phi_Y(T(v))\, C^\top \rVert^2,
              \quad C = \Phi_X^\top M_X \Phi_Y[T],

    in the bases of :func:`input_zoomout` (orthonormal for the mass over the total area): how far
    the map is from one that a functional map of ``k`` eigenfunctions carries, what ZoomOut's
    steps lower (Melzi et al., SIGGRAPH Asia 2019, §4). A region placed on the wrong part of Y is
    a jump that no such functional map makes.
    """
    return _energy(*_input_arrays(sx, sy, INPUT_K), _input_map(sx, T), k)


def _energy(a, ma, phy, T, k: int) -> float:
    """:func:`zoomout_energy` from the refinement's arrays."""
    k = min(int(k), a.shape[1])
    b = phy[T, :k]
    with one_blas_thread():
        C = ma[:, :k].T @ b
        r = a[:, :k] - b @ C.T
    return float(np.mean(np.einsum("ij,ij->i", r, r, dtype=np.float64)))


def refine_better(sx, sy, starts, *, split: int = CHOICE_K) -> tuple[np.ndarray, int]:
    """Several starts of one map refined, the one ZoomOut explains best kept.

    Each input-vertex map of ``starts`` takes the steps of :func:`input_zoomout` (its defaults)
    up to ``split`` eigenfunctions; the one of lowest :func:`zoomout_energy` there takes the
    rest. One start gives :func:`input_zoomout`'s map.

    Returns
    -------
    (ndarray (n_X,) of int64, int)
        The refined map and the index of the start it came from.
    """
    if not len(starts):
        raise ValueError("refine_better needs at least one start")
    a, ma, phy = _input_arrays(sx, sy, INPUT_K)
    k_end = a.shape[1]
    steps = [(k, k) for k in range(min(INPUT_START, k_end), k_end + 1, INPUT_STEP)]
    early, late = [st for st in steps if st[0] <= split], [st for st in steps if st[0] > split]
    opts = {"rings": INPUT_RINGS, "global_k": INPUT_GLOBAL}
    maps = [_zoomout_steps(sx, sy, _input_map(sx, T), a, ma, phy, early, **opts) for T in starts]
    energies = [_energy(a, ma, phy, T, split) for T in maps]
    best = int(np.argmin(energies))
    logger.debug("dense: ZoomOut energies at k=%d of the starts: %s", split, np.round(energies, 4))
    return _zoomout_steps(sx, sy, maps[best], a, ma, phy, late, **opts), best


def placements_agree(s, t1: np.ndarray, t2: np.ndarray, *, agree: float = CHOICE_AGREE,
                     radius: float = CHOICE_RADIUS) -> bool:
    """Whether two placements (working vertices of ``s``) put at least ``agree`` of the vertices
    within ``radius`` mean working edges of each other."""
    v = s.mesh.vertices
    d = np.linalg.norm(v[np.asarray(t1)] - v[np.asarray(t2)], axis=1)
    return bool(np.mean(d <= radius * s.mesh.mean_edge_length) >= agree)


def _zoomout_steps(sx, sy, T: np.ndarray, a: np.ndarray, ma: np.ndarray, phy: np.ndarray, steps, *,
                  rings: int = INPUT_RINGS, global_k: int = 0, orthogonal: bool = False) -> np.ndarray:
    r"""ZoomOut's steps on the input meshes from the map ``T``, as :func:`input_zoomout` and
    :func:`gromov.partial.partial_zoomout` take them: for each ``(k_X, k_Y)`` of ``steps``,
    :math:`C = (M_X \Phi_X)_{k_X}^\top \Phi_{Y,k_Y}[T]` (``ma``, ``phy``), then each input
    vertex of X to the vertex of Y within ``rings`` rings of its image whose row of
    :math:`\Phi_{Y,k_Y} C^\top` is nearest to its row of :math:`\Phi_{X,k_X}` (``a``); while
    :math:`k_X \le` ``global_k`` Y's working vertices are searched too. The vertices of X on
    pieces left out of its working mesh keep their images."""
    ptr, ids = (readonly(c) for c in _input_rings(sy, rings))
    left_out = ~sx.working.source_kept    # a piece left out of the working mesh keeps its map
    kept_x = np.flatnonzero(~left_out)
    spread = sy.working.vertex_ids        # Y's working vertices, spread over its kept pieces
    T = np.array(T, dtype=np.int64)
    T0 = T[left_out]
    a = readonly(np.ascontiguousarray(a))
    with one_blas_thread():   # products of n x k by k x k: a second thread costs more than it gains
        for kx, ky in steps:
            C = ma[:, :kx].T @ _gather_rows(phy, T, ky)
            if orthogonal:
                u, _, vt = np.linalg.svd(C)
                C = u @ vt
            b = phy[:, :ky] @ C.T
            T = _nearest_in_rings(a, readonly(b), readonly(T), ptr, ids)
            if kx <= global_k:    # or a far vertex of Y's working mesh, where that is nearer
                far, d_far = _nearest_rows(a[kept_x, :kx], b[spread])
                here = ((a[kept_x, :kx] - b[T[kept_x]]) ** 2).sum(axis=1)
                move = d_far < here
                T[kept_x[move]] = spread[far[move]]
            T[left_out] = T0
    return T


@njit(cache=True, nogil=True)
def _gather_rows(src, idx, k):
    """``src[idx, :k]``, contiguous: the first ``k`` columns of the rows ``idx`` (a compiled
    copy, without the GIL; numpy's indexing took three times as long on a cat's 28k rows)."""
    k = min(k, src.shape[1])
    out = np.empty((idx.shape[0], k), src.dtype)
    for i in range(idx.shape[0]):
        r = idx[i]
        for q in range(k):
            out[i, q] = src[r, q]
    return out


def _input_rings(s, rings: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`ring_neighbourhoods` of ``s``'s input mesh, kept on the shape."""
    if s._input_rings is None or s._input_rings[0] != rings:
        s._input_rings = (rings, ring_neighbourhoods(s.input, rings))
    return s._input_rings[1]


def _input_images(sx, sy, T: np.ndarray):
    """``(face, bary, vertex)`` on Y's input mesh of every input vertex of X, from the working
    map ``T``: each input vertex's working face corners' images, weighted by its barycentric
    coordinates, projected onto Y's input near those images. ``vertex`` indexes Y's input
    mesh (not its file ids)."""
    wx, wy = sx.working, sy.working
    if sx.has_faces:
        corners = T[sx.mesh.faces[wx.source_face]]            # (n_in, 3) images of the corners
        w = wx.source_bary
    else:
        corners = np.repeat(T[wx.source_nearest][:, None], 3, axis=1)
        w = np.tile([1.0, 0.0, 0.0], (len(corners), 1))
    if not sy.has_faces:
        best = corners[np.arange(len(corners)), np.argmax(w, axis=1)]
        n = len(best)
        return np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan), wy.to_source(best)
    pos = np.einsum("kc,kcd->kd", w, sy.mesh.vertices[corners])
    own_ptr, own_ids = sy.owned
    # the nearest of the input vertices the three images own (the point lies between them),
    # then the closest point on that vertex's faces
    ptr, ids = gather(own_ptr, own_ids, np.arange(0, corners.size + 1, 3), corners.ravel())
    lens = np.diff(ptr)
    d2 = ((sy.input.vertices[ids] - np.repeat(pos, lens, axis=0)) ** 2).sum(axis=1)
    first = _segment_argmin(d2, ptr)
    near = ids[first]
    face, bary, _ = project_among(pos, sy.input, np.arange(len(near) + 1), near)
    return face, bary, sy.input.faces[face, np.argmax(bary, axis=1)]


def relax_isometric(sx, sy, T: np.ndarray, *, edges: float = RELAX_EDGES, cap: float | None = RELAX_CAP,
                    sweeps: int = RELAX_SWEEPS, reach: float | None = RELAX_REACH) -> np.ndarray:
    r"""An input-vertex map X -> Y made locally isometric, by moves of one edge.

    The stress of GMDS (Bronstein, Bronstein & Kimmel, PNAS 103, 2006) over the pairs of nearby
    vertices only, with the Euclidean distance as their distance (on a smooth surface it is the
    geodesic one to second order in their distance): each sweep moves the image of every input
    vertex v of X, all at once (Jacobi: the result does not depend on the vertex order), to the
    vertex w among its current image and that image's neighbours on Y's input mesh minimising

    .. math:: E_v(w) = \sum_{u \in N(v)} \rho\big(s\,\lVert x_v - x_u \rVert
              - \lVert y_w - y_{T(u)} \rVert\big),
              \qquad s = \sqrt{A_Y / A_X},

    :math:`N(v)` the vertices within r rings of v on X, r the rings that reach the smaller of
    ``edges`` mean edges of the coarser of the two meshes (X's edges scaled by s) and ``reach``
    :math:`\sqrt{A_Y}` (at most :data:`RELAX_MAX_RINGS`); :math:`\rho(e) = e^2`, or
    :math:`\min(e^2, \kappa^2)` with :math:`\kappa` ``cap`` such edges (Blake & Zisserman,
    *Visual Reconstruction*, 1987). A spectral refinement leaves slides of a few edges where its
    eigenfunctions vary slowly (the ends of limbs, docs/design/dense.md); there the map
    stretches one side of a neighbourhood and squeezes the other, which this energy sees.

    Parameters
    ----------
    sx, sy : ShapeMetric or Mesh
        Their input meshes are used (a Mesh is its own).
    T : ndarray (n_X,) of int
        Vertex of Y's input mesh (index) for each vertex of X's input mesh.
    edges : float, default RELAX_EDGES
    cap : float, optional
        Default RELAX_CAP.
    sweeps : int, default RELAX_SWEEPS
        At most; they stop when no image moves.
    reach : float, optional
        Default RELAX_REACH; None: ``edges`` alone.

    Returns
    -------
    ndarray (n_X,) of int64
    """
    nptr, nids, dist, py, cap2, T = _relax_setup(sx, sy, T, edges, cap, reach)
    y = getattr(sy, "input", sy)
    yptr, yids = ring_neighbourhoods(y, 1)
    return _relax(nptr, nids, dist, py, yptr, yids, T, cap2, int(sweeps))


def _relax_setup(sx, sy, T, edges, cap, reach):
    """The arrays :func:`relax_isometric` and :func:`isometric_stress` share, ``T`` checked."""
    x, y = (getattr(s, "input", s) for s in (sx, sy))
    T = np.asarray(T, dtype=np.int64)
    if T.shape != (x.n_vertices,) or (len(T) and not 0 <= T.min() <= T.max() < y.n_vertices):
        raise ValueError(f"T must hold one vertex of Y (0..{y.n_vertices - 1}) per vertex of X, "
                         f"shape ({x.n_vertices},)")
    if not edges > 0:
        raise ValueError(f"edges must be positive, got {edges!r}")
    if cap is not None and not cap > 0:
        raise ValueError(f"cap must be positive or None, got {cap!r}")
    if reach is not None and not reach > 0:
        raise ValueError(f"reach must be positive or None, got {reach!r}")
    scale = np.sqrt(y.area / x.area)
    hx, hy = x.mean_edge_length * scale, y.mean_edge_length
    h = max(hx, hy)
    radius = edges * h if reach is None else min(edges * h, reach * np.sqrt(y.area))
    rings = max(1, min(int(np.ceil(radius / hx - 1e-9)), RELAX_MAX_RINGS))
    nptr, nids, lengths = _relax_neighbourhoods(sx, x, rings)
    cap2 = np.inf if cap is None else float(cap * h) ** 2
    return nptr, nids, lengths * scale, np.ascontiguousarray(y.vertices, dtype=np.float64), cap2, T


def isometric_stress(sx, sy, T: np.ndarray, *, edges: float = RELAX_EDGES,
                     cap: float | None = RELAX_CAP, reach: float | None = RELAX_REACH) -> np.ndarray:
    r"""Each input vertex's term of the local stress that :func:`relax_isometric` lowers,
    :math:`E_v(T(v)) = \sum_{u \in N(v)} \rho(s\,\lVert x_v - x_u \rVert
    - \lVert y_{T(v)} - y_{T(u)} \rVert)`, with the same neighbourhoods, scale and cap.

    Parameters
    ----------
    sx, sy : ShapeMetric or Mesh
        Their input meshes are used.
    T : ndarray (n_X,) of int
        Vertex of Y's input mesh for each vertex of X's input mesh.
    edges, cap, reach : float
        As in :func:`relax_isometric`.

    Returns
    -------
    ndarray (n_X,) of float64
    """
    nptr, nids, dist, py, cap2, T = _relax_setup(sx, sy, T, edges, cap, reach)
    return _stress(nptr, nids, dist, py, T, cap2)


@njit(cache=True, nogil=True)
def _stress(nptr, nids, dist, py, T, cap2):
    n = T.shape[0]
    out = np.zeros(n)
    for v in range(n):
        t = T[v]
        c = 0.0
        for j in range(nptr[v], nptr[v + 1]):
            q = T[nids[j]]
            d = np.sqrt((py[t, 0] - py[q, 0]) ** 2 + (py[t, 1] - py[q, 1]) ** 2 + (py[t, 2] - py[q, 2]) ** 2)
            e = (dist[j] - d) ** 2
            c += e if e < cap2 else cap2
        out[v] = c
    return out


def inverse_map(sx, sy, S: np.ndarray, T: np.ndarray, *, rings: int = INVERSE_RINGS) -> np.ndarray:
    r"""An input-vertex map X -> Y read off a map S: Y -> X.

    Each vertex v of X that S reaches goes to the vertex of Y nearest the centroid of its
    preimages :math:`\{w : S(w) = v\}`; a vertex that S does not reach, to the vertex of Y
    nearest the centroid of its neighbours' (within ``rings`` rings of X, weighted by the
    inverse of their distance to v); one with no such neighbour keeps ``T(v)``.

    Parameters
    ----------
    sx, sy : ShapeMetric or Mesh
        Their input meshes are used.
    S : ndarray (n_Y,) of int
        Vertex of X's input mesh for each vertex of Y's.
    T : ndarray (n_X,) of int
        The map X -> Y it replaces, where S says nothing.

    Returns
    -------
    ndarray (n_X,) of int64
    """
    x, y = (getattr(s, "input", s) for s in (sx, sy))
    S, T = np.asarray(S, dtype=np.int64), np.asarray(T, dtype=np.int64)
    if S.shape != (y.n_vertices,) or (len(S) and not 0 <= S.min() <= S.max() < x.n_vertices):
        raise ValueError(f"S must hold one vertex of X (0..{x.n_vertices - 1}) per vertex of Y, "
                         f"shape ({y.n_vertices},)")
    if T.shape != (x.n_vertices,):
        raise ValueError(f"T must have shape ({x.n_vertices},), got {T.shape}")
    from scipy.spatial import cKDTree

    count = np.bincount(S, minlength=x.n_vertices).astype(np.float64)
    centre = np.stack([np.bincount(S, y.vertices[:, j], x.n_vertices) for j in range(3)], axis=1)
    reached = count > 0
    centre[reached] /= count[reached, None]
    if not reached.all():
        ptr, ids = _input_rings(sx, rings) if hasattr(sx, "_input_rings") else ring_neighbourhoods(x, rings)
        src = np.repeat(np.arange(x.n_vertices), np.diff(ptr))
        use = reached[ids] & ~reached[src]
        w = 1.0 / np.maximum(np.linalg.norm(x.vertices[src[use]] - x.vertices[ids[use]], axis=1), 1e-300)
        total = np.bincount(src[use], w, x.n_vertices)
        filled = ~reached & (total > 0)
        for j in range(3):
            centre[filled, j] = np.bincount(src[use], w * centre[ids[use], j], x.n_vertices)[filled]
        centre[filled] /= total[filled, None]
        reached |= filled
    out = T.copy()
    out[reached] = cKDTree(y.vertices).query(centre[reached])[1]
    return out


def _better_start(sx, sy, T: np.ndarray, S: np.ndarray, sweeps: int, reach=RELAX_REACH) -> np.ndarray:
    """T, or the lowest in local stress of two starts from S's inverse I, each relaxed: I
    itself, and T with I taken where I's vertex has the lower stress (neighbourhoods of
    :func:`relax_isometric` with ``reach``)."""
    inv = inverse_map(sx, sy, S, T)
    here, there = isometric_stress(sx, sy, T, reach=reach), isometric_stress(sx, sy, inv, reach=reach)
    best, low = T, here.sum()
    for start in (inv, np.where(there < here, inv, T)):
        relaxed = relax_isometric(sx, sy, start, sweeps=sweeps, reach=reach)
        e = isometric_stress(sx, sy, relaxed, reach=reach).sum()
        if e < low:
            best, low = relaxed, e
    return best


def consistent_maps(sx, sy, T: np.ndarray, S: np.ndarray, *, rounds: int = 1,
                    sweeps: int = INVERSE_SWEEPS, pool=None) -> tuple[np.ndarray, np.ndarray]:
    """Input-vertex maps T: X -> Y and S: Y -> X, each offered the other's inverse.

    A relaxed map (:func:`relax_isometric`) sits in a local minimum of its stress: a region
    slid by a few edges along a thin part keeps its own distances. The other direction's map
    often has no slide there, and its inverse (:func:`inverse_map`) is a start on the other
    side of that minimum. Each round replaces each map by the lowest in local stress
    (:func:`isometric_stress`, summed) of itself, the other's inverse relaxed, and itself with
    the inverse taken per vertex where that vertex's stress is lower, relaxed; both directions
    from the maps of the round before (so the order of X and Y is not read). The rounds stop
    when neither map changes. The idea of repairing one direction of a map by the other's is
    that of the bijective refinements of Ren et al., "Continuous and orientation-preserving
    correspondences via functional maps", ACM TOG 37(6), 2018.

    Parameters
    ----------
    sx, sy : ShapeMetric or Mesh
    T, S : ndarray of int
        Vertex maps between the input meshes.
    rounds : int, default 1
        At most (:func:`dense_maps` runs :data:`DENSE_INVERSE`).
    sweeps : int, default INVERSE_SWEEPS
        Of each start's :func:`relax_isometric`, at most.
    pool : concurrent.futures.Executor, optional
        Runs the two directions of a round at once.

    Returns
    -------
    (ndarray, ndarray)
    """
    if not (isinstance(rounds, (int, np.integer)) and rounds >= 0):
        raise ValueError(f"rounds must be a non-negative integer, got {rounds!r}")
    for _ in range(int(rounds)):
        if pool is None:
            t, s = _better_start(sx, sy, T, S, sweeps), _better_start(sy, sx, S, T, sweeps)
        else:
            there = pool.submit(_better_start, sy, sx, S, T, sweeps)
            t = _better_start(sx, sy, T, S, sweeps)
            s = there.result()
        if t is T and s is S:
            break
        T, S = t, s
    return T, S


def align_locally(sx, sy, T: np.ndarray, *, rounds: int = DENSE_ALIGN, edges: float = RELAX_EDGES,
                  rings: int = ALIGN_RINGS, cap: float = ALIGN_CAP,
                  since: np.ndarray | None = None, reach: float | None = RELAX_REACH) -> np.ndarray:
    r"""An input-vertex map X -> Y whose images sit where their neighbourhoods put them.

    Each image of a vertex map is off by its rounding to Y's vertices and by slides a local
    stress hardly sees, but over a neighbourhood those errors average out. For each input
    vertex v of X, the motion that best carries its neighbours' points onto their images,

    .. math:: (R_v, c_v) = \arg\min_{R \in O(3),\, c} \sum_{u \in N(v) \setminus \{v\}}
              w_u \lVert R\, s\, x_u + c - y_{T(u)} \rVert^2, \qquad s = \sqrt{A_Y / A_X},

    (orthogonal Procrustes: Schönemann, Psychometrika 31, 1966; :math:`N(v)` the
    neighbourhood of :func:`relax_isometric`), fitted once with unit weights and once more with
    :math:`w_u = \min(1, \kappa / r_u)`, :math:`r_u` the first fit's residual and
    :math:`\kappa` ``cap`` mean edges of the coarser mesh (Huber's weights: a neighbour across a
    weld or a glued contact does not pull); v's new image is the vertex of Y nearest
    :math:`R_v\, s\, x_v + c_v` among those within ``rings`` rings of its image. Every image
    moves at once (no vertex order is read), for ``rounds`` rounds or until none moves; a
    vertex none of whose neighbours' images moved is not fitted again. v's own image is left
    out of its fit, so an isolated wrong image does not hold itself in place. The local
    rigidity is that of as-rigid-as-possible deformation (Sorkine & Alexa, SGP 2007).

    Parameters
    ----------
    sx, sy : ShapeMetric or Mesh
        Their input meshes are used.
    T : ndarray (n_X,) of int
        Vertex of Y's input mesh for each vertex of X's input mesh.
    rounds : int, default DENSE_ALIGN
    edges : float, default RELAX_EDGES
        The neighbourhood's radius, as in :func:`relax_isometric`, with ``reach`` (default
        RELAX_REACH).
    rings : int, default ALIGN_RINGS
    cap : float, default ALIGN_CAP
    since : ndarray (n_X,) of int, optional
        A map this one was aligned from: only the vertices whose neighbourhoods hold an image
        that differs from it are fitted in the first round (the others sat where their
        neighbourhoods put them already).

    Returns
    -------
    ndarray (n_X,) of int64
    """
    if not (isinstance(rounds, (int, np.integer)) and rounds >= 0):
        raise ValueError(f"rounds must be a non-negative integer, got {rounds!r}")
    if not (isinstance(rings, (int, np.integer)) and rings >= 1):
        raise ValueError(f"rings must be a positive integer, got {rings!r}")
    if not cap > 0:
        raise ValueError(f"cap must be positive, got {cap!r}")
    nptr, nids, _, py, cap2, T = _relax_setup(sx, sy, T, edges, cap, reach)   # cap2: (cap edges)^2
    x, y = (getattr(s, "input", s) for s in (sx, sy))
    scale = np.sqrt(y.area / x.area)
    # the rings the input refinement keeps on the shape, where they are these
    kept = hasattr(sy, "_input_rings") and rings == INPUT_RINGS
    yptr, yids = _input_rings(sy, rings) if kept else ring_neighbourhoods(y, rings)
    px = np.ascontiguousarray(x.vertices, dtype=np.float64) * scale
    if since is None:
        changed = np.ones(len(T), dtype=bool)
    else:
        since = np.asarray(since)
        if since.shape != T.shape:
            raise ValueError(f"since must have the shape of T, {T.shape}, got {since.shape}")
        changed = T != since
    return _align(nptr, nids, px, py, yptr, yids, T, float(np.sqrt(cap2)), int(rounds), changed)


@njit(cache=True, nogil=True)
def _orthogonal_factor(H, R):
    """``R = V U^T`` for the singular value decomposition ``H = U S V^T`` of a 3 x 3 matrix (the
    orthogonal matrix nearest ``H^T``): V from the eigenvectors of ``H^T H`` by cyclic Jacobi
    rotations, ``u_i = H v_i / s_i`` for the two largest singular values and the third their
    cross product, signed as ``H v_3`` (a 3 x 3 LAPACK call costs more than the fit)."""
    A = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            A[a, b] = H[0, a] * H[0, b] + H[1, a] * H[1, b] + H[2, a] * H[2, b]
    V = np.eye(3)
    scale = A[0, 0] + A[1, 1] + A[2, 2]
    if not scale > 0:
        R[:] = np.eye(3)
        return
    for _ in range(32):   # cyclic Jacobi (Golub & Van Loan, Matrix Computations, 8.5)
        off = A[0, 1] ** 2 + A[0, 2] ** 2 + A[1, 2] ** 2
        if off <= 1e-32 * scale * scale:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq = A[p, q]
            if apq == 0.0:
                continue
            theta = (A[q, q] - A[p, p]) / (2.0 * apq)
            t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
            c = 1.0 / np.sqrt(t * t + 1.0)
            sn = t * c
            for k in range(3):   # A <- A J, then J^T A
                akp, akq = A[k, p], A[k, q]
                A[k, p], A[k, q] = c * akp - sn * akq, sn * akp + c * akq
            for k in range(3):
                apk, aqk = A[p, k], A[q, k]
                A[p, k], A[q, k] = c * apk - sn * aqk, sn * apk + c * aqk
            for k in range(3):
                vkp, vkq = V[k, p], V[k, q]
                V[k, p], V[k, q] = c * vkp - sn * vkq, sn * vkp + c * vkq
    order = np.argsort(-np.array([A[0, 0], A[1, 1], A[2, 2]]))
    U = np.empty((3, 3))
    Vs = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            Vs[k, i] = V[k, order[i]]
    for i in range(2):
        n = 0.0
        for k in range(3):
            U[k, i] = H[k, 0] * Vs[0, i] + H[k, 1] * Vs[1, i] + H[k, 2] * Vs[2, i]
            n += U[k, i] ** 2
        n = np.sqrt(n)
        if i == 1:   # orthogonal to the first, against rounding
            d = U[0, 1] * U[0, 0] + U[1, 1] * U[1, 0] + U[2, 1] * U[2, 0]
            for k in range(3):
                U[k, 1] -= d * U[k, 0]
            n = np.sqrt(U[0, 1] ** 2 + U[1, 1] ** 2 + U[2, 1] ** 2)
        if not n > 1e-12 * np.sqrt(scale):   # rank below 2: any unit vector orthogonal to the first
            a = 0 if abs(U[0, 0]) < 0.9 else 1
            e = np.zeros(3)
            e[a] = 1.0
            d = e[0] * U[0, 0] + e[1] * U[1, 0] + e[2] * U[2, 0]
            for k in range(3):
                U[k, i] = e[k] - d * U[k, 0]
            n = np.sqrt(U[0, i] ** 2 + U[1, i] ** 2 + U[2, i] ** 2)
        for k in range(3):
            U[k, i] /= n
    U[0, 2] = U[1, 0] * U[2, 1] - U[2, 0] * U[1, 1]
    U[1, 2] = U[2, 0] * U[0, 1] - U[0, 0] * U[2, 1]
    U[2, 2] = U[0, 0] * U[1, 1] - U[1, 0] * U[0, 1]
    h3 = 0.0
    for k in range(3):
        h3 += U[k, 2] * (H[k, 0] * Vs[0, 2] + H[k, 1] * Vs[1, 2] + H[k, 2] * Vs[2, 2])
    if h3 < 0:
        for k in range(3):
            U[k, 2] = -U[k, 2]
    for a in range(3):
        for b in range(3):
            R[a, b] = Vs[a, 0] * U[b, 0] + Vs[a, 1] * U[b, 1] + Vs[a, 2] * U[b, 2]


@njit(cache=True, nogil=True)
def _procrustes(P, Q, W, k, v, out, H, R):
    """The weighted orthogonal Procrustes motion of ``P[:k]`` onto ``Q[:k]``: ``R`` gets its
    rotation, ``out`` the image of ``v``; returns the two centroids (``H``: workspace)."""
    sw = 0.0
    p0 = p1 = p2 = q0 = q1 = q2 = 0.0
    for i in range(k):
        w = W[i]
        sw += w
        p0 += w * P[i, 0]
        p1 += w * P[i, 1]
        p2 += w * P[i, 2]
        q0 += w * Q[i, 0]
        q1 += w * Q[i, 1]
        q2 += w * Q[i, 2]
    p0, p1, p2, q0, q1, q2 = p0 / sw, p1 / sw, p2 / sw, q0 / sw, q1 / sw, q2 / sw
    h00 = h01 = h02 = h10 = h11 = h12 = h20 = h21 = h22 = 0.0
    for i in range(k):
        w = W[i]
        a0, a1, a2 = P[i, 0] - p0, P[i, 1] - p1, P[i, 2] - p2
        b0, b1, b2 = w * (Q[i, 0] - q0), w * (Q[i, 1] - q1), w * (Q[i, 2] - q2)
        h00 += a0 * b0
        h01 += a0 * b1
        h02 += a0 * b2
        h10 += a1 * b0
        h11 += a1 * b1
        h12 += a1 * b2
        h20 += a2 * b0
        h21 += a2 * b1
        h22 += a2 * b2
    H[0, 0], H[0, 1], H[0, 2] = h00, h01, h02
    H[1, 0], H[1, 1], H[1, 2] = h10, h11, h12
    H[2, 0], H[2, 1], H[2, 2] = h20, h21, h22
    _orthogonal_factor(H, R)
    d0, d1, d2 = v[0] - p0, v[1] - p1, v[2] - p2
    out[0] = R[0, 0] * d0 + R[0, 1] * d1 + R[0, 2] * d2 + q0
    out[1] = R[1, 0] * d0 + R[1, 1] * d1 + R[1, 2] * d2 + q1
    out[2] = R[2, 0] * d0 + R[2, 1] * d1 + R[2, 2] * d2 + q2
    return p0, p1, p2, q0, q1, q2


@njit(cache=True, nogil=True)
def _align(nptr, nids, px, py, yptr, yids, T, cap, rounds, changed):
    """The rounds of :func:`align_locally` (``px``: X's points already scaled; ``changed``: the
    images taken as moved before the first round)."""
    n = T.shape[0]
    T, new, moved_last, moved_now, m = _jacobi_arrays(T, nptr)
    moved_last[:] = changed
    P, Q, W = np.empty((m, 3)), np.empty((m, 3)), np.empty(m)
    at, H, R = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    for _ in range(rounds):
        for v in range(n):
            t = T[v]
            new[v] = t
            moved_now[v] = False
            k = 0
            due = False
            for j in range(nptr[v], nptr[v + 1]):
                u = nids[j]
                due = due or moved_last[u]
                if u == v:
                    continue
                for a in range(3):
                    P[k, a] = px[u, a]
                    Q[k, a] = py[T[u], a]
                W[k] = 1.0
                k += 1
            if not due or k < 4:
                continue
            p0, p1, p2, q0, q1, q2 = _procrustes(P, Q, W, k, px[v], at, H, R)
            c2 = cap * cap
            refit = False
            for i in range(k):   # Huber's weights from the first fit's residuals
                a0, a1, a2 = P[i, 0] - p0, P[i, 1] - p1, P[i, 2] - p2
                e0 = R[0, 0] * a0 + R[0, 1] * a1 + R[0, 2] * a2 + q0 - Q[i, 0]
                e1 = R[1, 0] * a0 + R[1, 1] * a1 + R[1, 2] * a2 + q1 - Q[i, 1]
                e2 = R[2, 0] * a0 + R[2, 1] * a1 + R[2, 2] * a2 + q2 - Q[i, 2]
                r2 = e0 * e0 + e1 * e1 + e2 * e2
                if r2 > c2:
                    W[i] = cap / np.sqrt(r2)
                    refit = True
            if refit:   # with every weight 1 the refit is the fit
                _procrustes(P, Q, W, k, px[v], at, H, R)
            best = np.inf
            arg = t
            for jj in range(yptr[t], yptr[t + 1]):
                w = yids[jj]
                d = (py[w, 0] - at[0]) ** 2 + (py[w, 1] - at[1]) ** 2 + (py[w, 2] - at[2]) ** 2
                if d < best or (d == best and w == t):   # a tie keeps the current image
                    best = d
                    arg = w
            new[v] = arg
            moved_now[v] = arg != t
        if _jacobi_step(T, new, moved_last, moved_now) == 0:
            break
    return T


def _relax_neighbourhoods(s, mesh, rings: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(indptr, ids, lengths)``: :func:`ring_neighbourhoods` of ``mesh`` and the distance from
    each vertex to each of its neighbours; kept on ``s`` where it is a ShapeMetric (per shape,
    not per pair: the rings depend on the pair only through the ratio of the edge lengths)."""
    cached = getattr(s, "_relax_rings", None)
    if cached is not None and cached[0] == rings:
        return cached[1]
    nptr, nids = ring_neighbourhoods(mesh, rings)
    out = (nptr, nids, _ring_lengths(nptr, nids, np.ascontiguousarray(mesh.vertices, dtype=np.float64)))
    if hasattr(s, "_relax_rings"):
        s._relax_rings = (rings, out)
    return out


@njit(cache=True, nogil=True)
def _ring_lengths(nptr, nids, v):
    """Euclidean distance from each vertex to each of its neighbours ``nids[nptr[i]:nptr[i+1]]``
    (in a loop without the GIL: the two directions compute theirs at once)."""
    out = np.empty(len(nids))
    for i in range(len(nptr) - 1):
        for j in range(nptr[i], nptr[i + 1]):
            c = nids[j]
            dx, dy, dz = v[i, 0] - v[c, 0], v[i, 1] - v[c, 1], v[i, 2] - v[c, 2]
            out[j] = np.sqrt(dx * dx + dy * dy + dz * dz)
    return out


@njit(cache=True, nogil=True)
def _jacobi_arrays(T, nptr):
    """What the Jacobi sweeps of :func:`_relax` and :func:`_align` start from: a copy of ``T``,
    the next images, who moved in the last sweep (everyone) and in this one, and the largest
    neighbourhood of ``nptr`` (at least 1)."""
    n = T.shape[0]
    m = 1
    for v in range(n):
        m = max(m, nptr[v + 1] - nptr[v])
    return T.copy(), T.copy(), np.ones(n, np.bool_), np.zeros(n, np.bool_), m


@njit(cache=True, nogil=True)
def _jacobi_step(T, new, moved_last, moved_now):
    """The images of a sweep made at once: ``T`` takes ``new``, ``moved_last`` ``moved_now``;
    returns how many moved."""
    moved = 0
    for v in range(T.shape[0]):
        T[v] = new[v]
        moved_last[v] = moved_now[v]
        moved += moved_now[v]
    return moved


@njit(cache=True, nogil=True)
def _relax(nptr, nids, dist, py, yptr, yids, T, cap2, sweeps):
    """Jacobi sweeps of :func:`relax_isometric` (``dist``: the scaled distances on X of the
    pairs ``(v, nids[j])``, ``j`` in ``nptr[v]:nptr[v + 1]``). A vertex none of whose
    neighbourhood's images moved in the last sweep keeps its image without being evaluated:
    it would find the same one. The neighbours' images are gathered once per vertex, and a
    candidate's sum stops once it exceeds the best (its terms are not negative)."""
    n = T.shape[0]
    T, new, moved_last, moved_now, m = _jacobi_arrays(T, nptr)
    bx, by, bz, bd, be = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    for _ in range(sweeps):
        for v in range(n):
            due = False
            for j in range(nptr[v], nptr[v + 1]):   # v itself is in its neighbourhood
                if moved_last[nids[j]]:
                    due = True
                    break
            t = T[v]
            new[v] = t
            moved_now[v] = False
            if not due:
                continue
            k = 0
            for j in range(nptr[v], nptr[v + 1]):
                u = nids[j]
                if u == v:
                    continue
                q = T[u]
                bx[k], by[k], bz[k], bd[k] = py[q, 0], py[q, 1], py[q, 2], dist[j]
                k += 1
            best = np.inf
            arg = t
            for jj in range(yptr[t], yptr[t + 1]):   # t and its neighbours, in index order
                w = yids[jj]
                wx, wy, wz = py[w, 0], py[w, 1], py[w, 2]
                for i in range(k):
                    d = np.sqrt((wx - bx[i]) ** 2 + (wy - by[i]) ** 2 + (wz - bz[i]) ** 2)
                    e = (bd[i] - d) ** 2
                    be[i] = e if e < cap2 else cap2
                c = 0.0
                for i in range(k):
                    c += be[i]
                    if c > best:
                        break
                if c < best or (c == best and w == t):   # a tie keeps the current image
                    best = c
                    arg = w
            new[v] = arg
            moved_now[v] = arg != t
        if _jacobi_step(T, new, moved_last, moved_now) == 0:
            break
    return T


def _at_vertices(mesh, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(face, bary)`` of vertices ``v`` of ``mesh`` as surface points: the first face
    around each, with the unit weight on its corner."""
    indptr, face_ids = mesh.vertex_faces
    face = face_ids[indptr[v]]
    bary = (mesh.faces[face] == v[:, None]).astype(np.float64)
    return face, bary


PIECE_PATCH = 30
"""Vertices of the surface nearest to a left-out piece whose map gives the piece its motion
(:func:`place_small_pieces`)."""


def place_small_pieces(sx, sy, T: np.ndarray, *, patch: int = PIECE_PATCH) -> np.ndarray:
    r"""Images of the vertices on X's small pieces, which the metric leaves out
    (:func:`gromov.resolution.main_pieces`): each piece moves as the surface nearest to it.

    A piece too small to carry its own samples is placed by the rigid motion (with scale) that
    best carries the ``patch`` kept vertices of X nearest to its centroid onto their images,
    :math:`\min_{s, R, t} \sum_i \lVert s R x_i + t - y_{T(i)} \rVert^2` (Umeyama, IEEE PAMI 13,
    1991); each of its vertices, so moved, goes to the nearest vertex of Y's small pieces (an eye
    to an eye) where one lies within the patch's radius or as near as any vertex of Y, else to
    the nearest vertex of Y's input mesh. The rest of ``T`` is returned unchanged.

    Parameters
    ----------
    sx, sy : ShapeMetric
        Both meshes.
    T : ndarray (n_X,) of int
        Vertex of Y's input mesh for each vertex of X's input mesh.
    patch : int, default PIECE_PATCH

    Returns
    -------
    ndarray (n_X,) of int64
    """
    from scipy.spatial import cKDTree

    T = np.array(T, dtype=np.int64)
    kept = sx.working.source_kept
    if kept.all():
        return T
    X, Y = sx.input.vertices, sy.input.vertices
    on = np.flatnonzero(kept)
    near = cKDTree(X[on])
    targets = cKDTree(Y)
    y_out = np.flatnonzero(~sy.working.source_kept)
    y_pieces = cKDTree(Y[y_out]) if len(y_out) else None
    labels = sx.input.component_labels
    out = np.flatnonzero(~kept)
    for piece in np.unique(labels[out]):
        v = out[labels[out] == piece]
        _, nb = near.query(X[v].mean(0), k=min(patch, len(on)))
        a, b = X[on[np.atleast_1d(nb)]], Y[T[on[np.atleast_1d(nb)]]]
        ca, cb = a.mean(0), b.mean(0)
        u, sig, vt = np.linalg.svd((b - cb).T @ (a - ca))
        d = np.ones(3)
        d[2] = np.sign(np.linalg.det(u @ vt)) or 1.0
        R = u @ np.diag(d) @ vt
        var = ((a - ca) ** 2).sum()
        scale = float((sig * d).sum() / var) if var > 0 else 1.0
        moved = scale * (X[v] - ca) @ R.T + cb
        d_all, T[v] = targets.query(moved)
        if y_pieces is not None:   # onto a small piece of Y where one is about as near
            d_piece, j = y_pieces.query(moved)
            reach = max(float(np.sqrt(((b - cb) ** 2).sum(1).mean())), 0.0)
            onto = d_piece <= np.maximum(d_all, reach)
            T[v[onto]] = y_out[j[onto]]
    return T


def _segment_argmin(values: np.ndarray, ptr: np.ndarray) -> np.ndarray:
    """Index into ``values`` of the smallest value of each non-empty segment
    ``values[ptr[i]:ptr[i + 1]]`` (the first of equal ones)."""
    mins = np.minimum.reduceat(values, ptr[:-1])
    hits = np.flatnonzero(values == np.repeat(mins, np.diff(ptr)))
    return hits[np.searchsorted(hits, ptr[:-1])]


def _by_file_id(s, face, bary, vertex) -> DenseMap:
    """The images indexed by ``s``'s input file ids (-1 / NaN where the file has no vertex)."""
    return DenseMap(*(s.input.per_file_vertex(a) for a in (face, bary, vertex)))


def dense_maps(sx, sy, landmarks_x, landmarks_y, *, tau_scale: float = DENSE_TAU_SCALE,
               local: int | None = None, keep: float = DENSE_KEEP, rounds: int = DENSE_ROUNDS,
               refine: str | None = DENSE_REFINE, choice: int | None = None,
               relax: bool | None = None, inverse: int | None = None,
               align: int | None = None) -> tuple[DenseMap, DenseMap]:
    """Dense maps X -> Y and Y -> X from paired landmarks.

    Parameters
    ----------
    sx, sy : ShapeMetric
    landmarks_x, landmarks_y : pairs ``(SurfacePoints or vertex ids, SurfacePoints or vertex
        ids)``
        The two halves of the sample correspondence on each shape, in matching order: on X
        ``(P, images of Q)``, on Y ``(images of P, Q)``.
    tau_scale : float, default DENSE_TAU_SCALE
        :func:`landmark_distances`.
    local : int, optional
        Default: :data:`DENSE_LOCAL`, read at each call. Each working vertex placed from its
        ``local`` nearest landmarks
        (:func:`local_anchored_map`); 0: from all of them, trimmed (:func:`anchored_map` with
        ``keep`` and ``rounds``).
    refine : {"input", "zoomout", None}, default DENSE_REFINE
        Refine each placed map by :func:`input_zoomout` on the input meshes ("input"), or by
        :func:`zoomout` on the working meshes ("zoomout"); meshes only (a point cloud's map is
        the placed one).
    choice : int, optional
        Default: :data:`DENSE_CHOICE`, read at each call. With ``local=0`` and ``refine="input"``,
        each direction is also placed from each vertex's ``choice`` nearest landmarks; where the
        two placements differ (:func:`placements_agree`), both are refined and the one of lower
        ZoomOut energy kept (:func:`refine_better`). 0: the default placement alone.
    relax : bool, optional
        Default: :data:`DENSE_RELAX`, read at each call. With ``refine="input"``, each refined
        map made locally isometric (:func:`relax_isometric`).
    inverse : int, optional
        Default: :data:`DENSE_INVERSE`, read at each call. With ``relax``, the rounds of
        :func:`consistent_maps` (each direction offered the other's inverse), after the
        alignment; 0: none.
    align : int, optional
        Default: :data:`DENSE_ALIGN`, read at each call. With ``refine="input"``, the rounds of
        :func:`align_locally` each map gets after the local isometry step, and again after the
        inverse rounds around the images they changed (``since``); 0: none.

    Returns
    -------
    (DenseMap, DenseMap)
        X -> Y indexed by X's file ids, Y -> X indexed by Y's.
    """
    if refine not in REFINEMENTS:
        raise ValueError(f"refine must be one of {REFINEMENTS}, got {refine!r}")
    local = DENSE_LOCAL if local is None else local
    if not (isinstance(local, (int, np.integer)) and local >= 0):
        raise ValueError(f"local must be a non-negative number of landmarks, got {local!r}")
    choice = DENSE_CHOICE if choice is None else choice
    if not (isinstance(choice, (int, np.integer)) and choice >= 0):
        raise ValueError(f"choice must be a non-negative number of landmarks, got {choice!r}")

    def placed(a, b):   # one direction's robust map on the working meshes
        if local:
            return local_anchored_map(a, b, int(local))
        return anchored_map(a, b, keep=keep, rounds=rounds)

    ax = np.hstack([landmark_distances(sx, p, tau_scale) for p in landmarks_x])
    ay = np.hstack([landmark_distances(sy, p, tau_scale) for p in landmarks_y])
    meshes = sx.has_faces and sy.has_faces
    refine_input = refine == "input" and meshes
    if refine_input:   # per shape, once, before the two directions share them; placed meanwhile
        t_xy, t_yx = _input_bases(sx, sy, INPUT_K, meanwhile=lambda: placed(ax, ay),
                                  alongside=lambda: placed(ay, ax))
        for s in (sx, sy):
            _input_rings(s, INPUT_RINGS)
    else:
        t_xy, t_yx = placed(ax, ay), placed(ay, ax)
    if refine == "zoomout" and meshes:
        t_xy, t_yx = zoomout(sx, sy, t_xy), zoomout(sy, sx, t_yx)

    second = bool(choice) and not local and refine_input
    relax = bool(DENSE_RELAX if relax is None else relax) and refine_input
    inverse = int(DENSE_INVERSE if inverse is None else inverse) if relax else 0
    align = int(DENSE_ALIGN if align is None else align) if refine_input else 0

    def refined(a, b, t, da, db):
        face, bary, vertex = _input_images(a, b, t)
        if refine_input:
            starts = [vertex]
            if second:   # the placement from the nearest landmarks, where it differs
                t2 = local_anchored_map(da, db, int(choice))
                if not placements_agree(b, t, t2):
                    starts.append(_input_images(a, b, t2)[2])
            vertex = refine_better(a, b, starts)[0]   # one start: input_zoomout's map
            if relax:
                vertex = relax_isometric(a, b, vertex, sweeps=RELAX_SWEEPS)
            face, bary = _at_vertices(b.input, vertex)
        return face, bary, vertex

    def finished(a, b, face, bary, vertex, moved):
        if moved:
            face, bary = _at_vertices(b.input, vertex)
        if meshes and not a.working.source_kept.all():   # small pieces move with the surface
            vertex = place_small_pieces(a, b, vertex)
            out = ~a.working.source_kept
            face, bary = face.copy(), bary.copy()
            face[out], bary[out] = _at_vertices(b.input, vertex[out])
        return _by_file_id(a, face, bary, b.input.input_ids[vertex])

    ways = ((sx, sy, t_xy, ax, ay), (sy, sx, t_yx, ay, ax))

    def both(pool=None):
        if pool is None:
            first, second_way = refined(*ways[0]), refined(*ways[1])
        else:
            there = pool.submit(refined, *ways[1])
            first = refined(*ways[0])
            second_way = there.result()
        vx, vy = first[2], second_way[2]

        def aligned(vx, vy, since=(None, None)):
            if pool is None:
                return (align_locally(sx, sy, vx, rounds=align, since=since[0]),
                        align_locally(sy, sx, vy, rounds=align, since=since[1]))
            there = pool.submit(align_locally, sy, sx, vy, rounds=align, since=since[1])
            return align_locally(sx, sy, vx, rounds=align, since=since[0]), there.result()

        if align:
            vx, vy = aligned(vx, vy)
        if inverse:   # each from the other's inverse, then aligned again where that changed it
            cx, cy = consistent_maps(sx, sy, vx, vy, rounds=inverse, sweeps=INVERSE_SWEEPS, pool=pool)
            if align and (cx is not vx or cy is not vy):
                cx, cy = aligned(cx, cy, (vx, vy))
            vx, vy = cx, cy
        return (finished(sx, sy, *first[:2], vx, vx is not first[2]),
                finished(sy, sx, *second_way[:2], vy, vy is not second_way[2]))

    if not refine_input or (os.cpu_count() or 1) < 2:
        return both()
    # the two directions at once, one BLAS thread each: their products and ring searches
    # release the GIL (set here, around both, so that neither thread's own limit undoes it)
    from concurrent.futures import ThreadPoolExecutor

    with one_blas_thread(), ThreadPoolExecutor(2) as pool:
        return both(pool)
