r"""A per-shape spectral signature: the first stage of recognition in collections.

**Shape-DNA** (Reuter, Wolter & Peinecke, "Laplace-Beltrami spectra as 'Shape-DNA' of surfaces
and solids", Computer-Aided Design 38, 2006): the first ``k`` non-zero eigenvalues of the
Laplace-Beltrami operator, :math:`L\phi = \lambda M \phi`, times the area A (unchanged by scaling
the shape, their §4) and over Weyl's asymptote :math:`\lambda_i \approx 4\pi i / A`:

.. math:: \operatorname{DNA}_i = \frac{\lambda_i A}{4 \pi i}, \quad i = 1..k,

compared between shapes by the Euclidean distance. It is an isometry invariant that costs one
sparse eigendecomposition per shape (here of the working mesh's cotangent Laplacian with lumped
masses) and nothing per pair, so it ranks a collection's candidates before GMDS matches the
few that matter (:func:`gromov.experiments.gh_matrix`'s ``candidates``), and it is one factor of
the ``combined`` ranking (:attr:`gromov.experiments.PairwiseGH.combined`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["SPECTRUM_K", "SPECTRUM_WEIGHT", "combined", "shape_dna", "signature_distance", "spectral_distances",
           "spectrum"]

#: Eigenvalues in a shape's signature (Reuter et al. 2006 compare the first 50 or so).
SPECTRUM_K = 50
#: Weight w of the spectral distance S in the combined ranking S^w G^(1 - w), G the trimmed
#: distortion (docs/design/recognition.md, "Across collections").
SPECTRUM_WEIGHT = 0.35


def shape_dna(eigenvalues: np.ndarray, area: float, k: int = SPECTRUM_K) -> np.ndarray:
    r"""``(k,)``: :math:`\lambda_i A / (4\pi i)` of the ascending ``eigenvalues`` past the zero
    ones (one per connected component), padded with NaN where fewer than ``k`` are given."""
    lam = np.sort(np.asarray(eigenvalues, dtype=np.float64))
    if not area > 0:
        raise ValueError(f"area must be positive, got {area}")
    lam = lam[np.count_nonzero(lam * area < 1e-6):][:k]
    out = np.full(int(k), np.nan)
    out[:len(lam)] = lam * area / (4.0 * np.pi * np.arange(1, len(lam) + 1))
    return out


def spectrum(shape, k: int = SPECTRUM_K) -> np.ndarray:
    """The Shape-DNA of a prepared shape's working mesh (computed once per shape and ``k``).

    Parameters
    ----------
    shape : gromov.ShapeMetric
        Its working mesh's cotangent Laplacian is decomposed (whatever the metric, so that a
        shape read from a store and one computed now give the same signature); a point
        cloud's robust Laplacian (Sharp & Crane, SGP 2020).
    k : int, default SPECTRUM_K (50)

    Returns
    -------
    ndarray (k,)
    """
    k = int(k)
    if k < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    cache = shape.__dict__.setdefault("_spectrum", {})
    if k not in cache:
        from .dense import _shift_invert_eigsh
        from .metrics.diffusion import POINT_CLOUD_NEIGHBORS, _laplacian

        mesh = shape.mesh
        _, L, M, area = _laplacian(mesh, "cotan", "a spectral signature", POINT_CLOUD_NEIGHBORS)
        n = mesh.n_vertices
        comps = int(getattr(mesh, "n_components", 1))
        want = min(n - 2, k + comps)
        if want < 1:
            raise ValueError(f"a spectral signature needs at least 3 working vertices, got {n}")
        lam, _ = _shift_invert_eigsh(L, M, want, sigma=-1e-2 / max(area, 1e-300))   # as the dense maps
        cache[k] = shape_dna(np.maximum(lam, 0.0), area, k)
    return cache[k]


def signature_distance(a: np.ndarray, b) -> np.ndarray | float:
    """Euclidean distance between the signature ``a`` and ``b`` (one signature, or one per row),
    over the entries both have (a tiny shape has fewer eigenvalues)."""
    a, B = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    ok = np.isfinite(a) & np.isfinite(B)
    d = np.sqrt(np.where(ok, (B - a) ** 2, 0.0).sum(-1))
    return float(d) if d.ndim == 0 else d


def spectral_distances(shapes, k: int = SPECTRUM_K) -> np.ndarray:
    """``(n, n)`` :func:`signature_distance` between the shapes' :func:`spectrum`."""
    X = np.array([spectrum(s, k) for s in shapes])
    D = np.array([signature_distance(x, X) for x in X]).reshape(len(X), len(X))
    return 0.5 * (D + D.T)


def combined(spectral: np.ndarray, trimmed: np.ndarray, weight: float = SPECTRUM_WEIGHT) -> np.ndarray:
    r"""The combined ranking :math:`S^w\, G^{1-w}` of the spectral distances S and the trimmed
    distortions G, pair by pair (a weighted geometric mean: a pair's value needs nothing of the
    rest of the collection, and the units of S and G only scale every value alike). NaN where G
    is (a pair not matched)."""
    if not 0.0 <= weight <= 1.0:
        raise ValueError(f"weight must be in [0, 1], got {weight}")
    S, G = np.asarray(spectral, dtype=np.float64), np.asarray(trimmed, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.power(np.maximum(S, 0.0), weight) * np.power(np.maximum(G, 0.0), 1.0 - weight) \
            + np.where(np.isnan(G), np.nan, 0.0)
