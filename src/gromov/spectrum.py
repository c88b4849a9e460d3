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

**The heat kernel signature's distortion** along a correspondence is another of its factors:
the heat kernel signature (Sun, Ovsjanikov & Guibas, "A concise and provably informative
multi-scale signature based on heat diffusion", SGP 2009) of each working vertex,

.. math:: h_t(x) = \log\big(A\, k_t(x, x)\big) = \log\Big(A \sum_i e^{-\lambda_i t}\,
          \phi_i(x)^2\Big), \quad t = \tau A,\ \tau \in \texttt{SIGNATURE\_TAUS},

unchanged by an isometry and by scaling, is compared at each sample and at its image
(:func:`signature_distortion`). The distances compare each sample with the others; the
signature compares each sample with its own image.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SIGNATURE_EIGENPAIRS", "SIGNATURE_KEEP", "SIGNATURE_TAUS", "SIGNATURE_WEIGHT", "SPECTRUM_K",
           "SPECTRUM_WEIGHT", "combined", "heat_signature", "shape_dna", "signature_distance",
           "signature_distortion", "spectral_distances", "spectrum"]

#: Eigenvalues in a shape's signature (Reuter et al. 2006 compare the first 50 or so).
SPECTRUM_K = 50
#: Weight w of the spectral distance S in the combined ranking S^w G^(1 - w), G the trimmed
#: distortion (docs/design/recognition.md, "Across collections").
SPECTRUM_WEIGHT = 0.35
#: Eigenpairs of the working mesh's Laplacian in its heat kernel signature.
SIGNATURE_EIGENPAIRS = 150
#: The signature's diffusion times over the area, t = tau A: the 4th to 9th of 12 spaced
#: geometrically from 0.001 to 0.3 (docs/design/recognition.md, "The signature's distortion").
SIGNATURE_TAUS = np.geomspace(0.001, 0.3, 12)[3:9]
#: The fraction of the sample pairs, best-fitting first, whose signature differences count.
SIGNATURE_KEEP = 0.8
#: Weight v of the signature's distortion H in the combined ranking C^(1 - v) H^v.
SIGNATURE_WEIGHT = 0.5


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


def _eigenpairs(shape, k: int, what: str):
    """``(eigenvalues >= 0, eigenvectors, area)``: the ``k`` (plus one per component) lowest
    eigenpairs of a shape's working cotangent Laplacian with lumped masses (a point cloud's
    robust Laplacian), by :func:`gromov._eigen.shift_invert_eigsh`, as the heat metric and the
    dense maps compute theirs."""
    from ._eigen import shift_invert_eigsh
    from .metrics.diffusion import POINT_CLOUD_NEIGHBORS, _laplacian

    mesh = shape.mesh
    _, L, M, area = _laplacian(mesh, "cotan", what, POINT_CLOUD_NEIGHBORS)
    n = mesh.n_vertices
    want = min(n - 2, k + int(getattr(mesh, "n_components", 1)))
    if want < 1:
        raise ValueError(f"{what} needs at least 3 working vertices, got {n}")
    lam, phi = shift_invert_eigsh(L, M, want, sigma=-1e-2 / max(area, 1e-300))
    return np.maximum(lam, 0.0), phi, area


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
        lam, _, area = _eigenpairs(shape, k, "a spectral signature")
        cache[k] = shape_dna(lam, area, k)
    return cache[k]


def heat_signature(shape) -> np.ndarray:
    r"""``(n, len(SIGNATURE_TAUS))``: the heat kernel signature :math:`\log(A\,k_t(x, x))`,
    :math:`t = \tau A`, of each working vertex of a prepared shape, from
    ``SIGNATURE_EIGENPAIRS`` eigenpairs of its working mesh's cotangent Laplacian (a point
    cloud's robust Laplacian); computed once per shape (module docstring; Sun, Ovsjanikov &
    Guibas, SGP 2009). Read-only."""
    cache = shape.__dict__.setdefault("_spectrum", {})
    if "heat" not in cache:
        lam, phi, area = _eigenpairs(shape, SIGNATURE_EIGENPAIRS, "a heat kernel signature")
        k = (phi**2) @ np.exp(-np.outer(lam, SIGNATURE_TAUS * area))
        h = np.log(area * np.maximum(k, 1e-300))
        h.flags.writeable = False
        cache["heat"] = h
    return cache["heat"]


def signature_distortion(x_side: np.ndarray, y_side: np.ndarray, keep: float = SIGNATURE_KEEP) -> float:
    r"""How far a correspondence is from keeping the heat kernel signature.

    .. math:: H = \Big(\frac1h \sum_{k=1}^{h} r_{(k)}^2\Big)^{1/2}, \qquad
              r_i = \Big(\frac{1}{|T|}\sum_{t \in T} \big(h^X_t(x_i) - h^Y_t(y_i)\big)^2\Big)^{1/2},

    over the sample pairs :math:`(x_i, y_i)` of a two-sided correspondence (X's samples with
    their images, Y's samples' images with them), :math:`r_{(1)} \le r_{(2)} \le \dots`,
    :math:`h = \lceil \mathit{keep}\, n \rceil`: the trimmed RMS
    (:func:`gromov.gmds.trimmed_rms`) of each pair's RMS difference over the times.

    Parameters
    ----------
    x_side, y_side : ndarray (n, T)
        The signatures at the two ends of each sample pair (row i: X's point, Y's point).
    keep : float, default SIGNATURE_KEEP (0.8)
    """
    from .gmds import trimmed_rms

    a, b = np.asarray(x_side, dtype=np.float64), np.asarray(y_side, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or not len(a):
        raise ValueError(f"x_side and y_side must be two (n, T) arrays of one shape, got {a.shape} and {b.shape}")
    return float(trimmed_rms(np.sqrt(np.mean((a - b) ** 2, axis=1)), keep))


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


def combined(spectral: np.ndarray, trimmed: np.ndarray, weight: float = SPECTRUM_WEIGHT,
             signature: np.ndarray | None = None, signature_weight: float = SIGNATURE_WEIGHT) -> np.ndarray:
    r"""The combined ranking :math:`(S^w\, G^{1-w})^{1-v}\, H^v` of the spectral distances S,
    the trimmed distortions G and the signature's distortions H (:func:`signature_distortion`),
    pair by pair; without ``signature``, :math:`S^w\, G^{1-w}`. A weighted geometric mean: a
    pair's value needs nothing of the rest of the collection, and the units of S, G and H only
    scale every value alike. NaN where G or H is (a pair not matched)."""
    for name, w in (("weight", weight), ("signature_weight", signature_weight)):
        if not 0.0 <= w <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {w}")
    S, G = np.asarray(spectral, dtype=np.float64), np.asarray(trimmed, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.power(np.maximum(S, 0.0), weight) * np.power(np.maximum(G, 0.0), 1.0 - weight) \
            + np.where(np.isnan(G), np.nan, 0.0)
        if signature is not None:
            H = np.asarray(signature, dtype=np.float64)
            out = np.power(out, 1.0 - signature_weight) * np.power(np.maximum(H, 0.0), signature_weight) \
                + np.where(np.isnan(H), np.nan, 0.0)
    return out
