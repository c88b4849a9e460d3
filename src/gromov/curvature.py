r"""Smoothed mean curvature: what tells a body's front from its back when distances cannot.

A human body is nearly symmetric left to right, and -- in its intrinsic distances at the scale
a correspondence is found -- nearly symmetric front to back as well: a torso is a flattened
tube, limbs are tubes. Besides the identity, a map between two such bodies then has three
rivals of almost the same distortion: the left/right mirror image, the front/back mirror image
and their composition, a half turn about the long axis that sends left to right *and* front to
back. The orientation (:mod:`gromov.orientation`) rules out the two mirror images; the half turn
keeps the orientation like the identity does. What differs is the surface's bending in space:
a face against the back of a head, a belly against a back, the fronts of the knees against
their hollows. Bending in space (the mean curvature) is not intrinsic, but a pose changes it
only at the joints, where a part bends, and not on the parts between them.

The mean curvature normal is half the Laplace-Beltrami operator applied to the coordinates,
:math:`\Delta x = -2 H n` (Meyer, Desbrun, Schröder & Barr, "Discrete differential-geometry
operators for triangulated 2-manifolds", VisMath 2002), so with the cotangent stiffness ``L``
and the lumped mass ``M``,

.. math:: H_i = \tfrac12 \langle (M^{-1} L x)_i,\ n_i \rangle \sqrt{A},

signed by the outward normal ``n`` (positive where the surface is convex), times the square
root of the area ``A`` so that it does not depend on the shape's size. Raw, it is noisy from
vertex to vertex; it is smoothed by one implicit heat step,

.. math:: (M + t L)\,\bar H = M H, \qquad t = \mathit{scale} \cdot A,

a diffusion over a length of about :math:`\sqrt{t}` (a tenth of :math:`\sqrt{A}` at the default
scale, 0.01).
"""

from __future__ import annotations

import numpy as np

from .mesh import Mesh

__all__ = ["CURVATURE_SCALE", "mean_curvature"]

#: Smoothing of :func:`mean_curvature`, as a fraction of the area (see the module's text and
#: docs/design/initial-search.md, "Half turns").
CURVATURE_SCALE = 0.01


def mean_curvature(mesh: Mesh, normals: np.ndarray, *, scale: float = CURVATURE_SCALE) -> np.ndarray:
    """Signed mean curvature ``(n,)`` of a triangle mesh, smoothed and scale-free (formula above).

    Parameters
    ----------
    mesh : Mesh
    normals : ndarray (n, 3)
        Outward unit vertex normals (:func:`gromov.orientation.outward_normals`).
    scale : float, default CURVATURE_SCALE
        Smoothing time as a fraction of the area; 0 for none.
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    from .metrics.diffusion import cotan_laplacian

    if not scale >= 0:
        raise ValueError(f"scale must be >= 0, got {scale}")
    L, M = cotan_laplacian(mesh)
    m = np.asarray(M.diagonal(), dtype=float)
    area = float(m.sum())
    hn = (L @ np.asarray(mesh.vertices, dtype=float)) / np.maximum(m, 1e-300)[:, None]
    h = 0.5 * np.einsum("ij,ij->i", hn, np.asarray(normals, dtype=float)) * np.sqrt(area)
    h[~np.isfinite(h)] = 0.0
    if scale == 0:
        return h
    eps = 1e-12 * area / max(len(m), 1)   # a vertex without faces keeps its value (0)
    lu = splu(sp.csc_matrix(M + (scale * area) * L + eps * sp.identity(len(m))))
    return lu.solve(m * h)
