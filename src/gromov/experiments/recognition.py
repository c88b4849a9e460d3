"""Recognition measures: ROC curves, the equal error rate and MDS maps of shape distances.

Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework with
diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010),
§5, judge a shape distance by how well it separates shapes of the same class from shapes of
different classes: every pair of shapes is a recognition trial, accepted as "same" when its
distance is at most a threshold ``t``. The false acceptance rate ``FAR(t)`` and the false
rejection rate ``FRR(t)`` trace the ROC curve (their Figs. 6-7); the equal error rate
(EER), where ``FAR = FRR``, sums it up in one number (their Table 1). The distance matrices
are also shown as two-dimensional classical MDS maps (their Figs. 4-5), where a good distance
draws tight, separated clusters of classes.

- :func:`roc` and :func:`equal_error_rate` compute the exact ROC curve and the EER;
  :func:`errors_at` says which classes the errors at a threshold come from;
- :func:`local_scaling` divides each distance by the two shapes' local scales (distance to
  their k-th nearest neighbour in the set): a set-level normalisation, not the paper's;
  :func:`local_roc` is the ROC of the locally scaled distances;
- :func:`diffusion_rerank` re-ranks by a diffusion on the set's nearest-neighbour graph
  (another set-level rule); :func:`diffusion_roc` is its ROC;
- :func:`mds_map` embeds a distance matrix in the plane (classical, Torgerson MDS);
- :func:`plot_roc` and :func:`plot_mds` draw them to PNG files (needs ``gromov[plot]``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._atomic import atomic_path

__all__ = ["ROC", "roc", "equal_error_rate", "errors_at", "local_scaling", "local_roc", "LOCAL_SCALING_K",
           "diffusion_rerank", "diffusion_roc", "DIFFUSION_RERANK_K", "DIFFUSION_RERANK_STEPS",
           "smallest_class", "mds_map", "plot_roc", "plot_mds"]

logger = logging.getLogger(__name__)

#: The neighbour whose distance is a shape's local scale in :func:`local_scaling`. Chosen on the
#: validation sets -- synthetic, stretched synthetic, close people, held-out TOSCA classes -- by
#: the geometric mean of the diffusion rankings' margins: 2.095 at k = 4, against 1.608 as ranked
#: and 1.979 / 2.018 / 1.753 at k = 2 / 3 / 5 (``.venv/bin/python benchmarks/studies/probe_local_scaling.py``;
#: docs/design/recognition.md).
#: In those sets the smallest class of Experiment 1 has 5 shapes: k = 4 is that less one, and
#: k >= 5 (scales from other classes) was worse. Keep k below your smallest class.
from .._defaults import LOCAL_SCALING_K  # noqa: E402

#: :func:`diffusion_rerank`'s nearest neighbours and steps. Chosen on TOSCA (80 shapes) and the
#: watertight collection (200) together, among k = 5, 8, 10, 15 and t = 1, 2, 3, by the lowest
#: J = mean(1 - nearest neighbour, 1 - first tier, EER) of the combined ranking: 0.1438 at
#: k = 8, t = 3 (k = 10: 0.1464; as ranked: 0.1855; local scaling k = 4: 0.1716)
#: (``.venv/bin/python benchmarks/studies/recognition_rerank.py --cache CACHE``;
#: docs/design/recognition.md, "What the collection adds").
from .._defaults import DIFFUSION_RERANK_K, DIFFUSION_RERANK_STEPS  # noqa: E402

#: Above this many shapes, :func:`mds_map` uses an iterative eigensolver (seeded).
_DENSE_MAX = 1000


@dataclass(frozen=True, eq=False)
class ROC:
    """Exact ROC curve of a distance matrix as a same-class detector.

    Attributes
    ----------
    thresholds : ndarray of float64, shape (k,)
        ``-inf``, every distinct pair distance in increasing order, then ``+inf``.
    far : ndarray of float64, shape (k,)
        False acceptance rate at each threshold: the fraction of negative (different-class)
        pairs with distance ``<= t``. Non-decreasing, from 0 to 1.
    frr : ndarray of float64, shape (k,)
        False rejection rate at each threshold: the fraction of positive (same-class) pairs
        with distance ``> t``. Non-increasing, from 1 to 0.
    eer : float
        Equal error rate: where the polyline through the points ``(far[i], frr[i])`` crosses
        the diagonal ``FAR = FRR`` (see :func:`roc`).
    eer_threshold : float
        The smallest threshold at which ``FAR(t) >= FRR(t)``.
    n_positive, n_negative : int
        Numbers of positive and negative pairs the rates are fractions of.

    All arrays are read-only.
    """

    thresholds: np.ndarray
    far: np.ndarray
    frr: np.ndarray
    eer: float
    eer_threshold: float
    n_positive: int
    n_negative: int


def _check_distances(distances, name: str = "distances", *, rtol: float = 1e-8) -> np.ndarray:
    """Coerce to a square, finite, symmetric float64 matrix or raise ``ValueError``."""
    d = np.asarray(distances, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise ValueError(f"{name} must be a square (n, n) matrix, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        bad = int(np.count_nonzero(~np.isfinite(d)))
        raise ValueError(f"{name} must be finite, got {bad} NaN or infinite entries")
    scale = max(1.0, float(np.abs(d).max(initial=0.0)))
    asym = float(np.abs(d - d.T).max(initial=0.0))
    if asym > rtol * scale:
        raise ValueError(
            f"{name} must be symmetric, got max |D - D^T| = {asym:.3g} "
            f"(tolerance {rtol * scale:.3g}); symmetrise it first, e.g. max(D, D^T)")
    return d


def _check_labels(labels, n: int) -> np.ndarray:
    lab = np.asarray(labels)
    if lab.ndim != 1 or lab.shape[0] != n:
        raise ValueError(f"labels must be a 1-D array of length n = {n}, got shape {lab.shape}")
    return lab


def roc(distances, labels, *, mask=None, pairs: str = "upper") -> ROC:
    """Exact ROC curve and equal error rate of a shape distance matrix.

    Every pair of shapes ``(i, j)`` is a trial; it is *positive* when
    ``labels[i] == labels[j]`` and is *accepted* at threshold ``t`` when ``D[i, j] <= t``:

    .. math::

        \\mathrm{FAR}(t) = \\frac{|\\{(i,j) \\in N : D_{ij} \\le t\\}|}{|N|}, \\qquad
        \\mathrm{FRR}(t) = \\frac{|\\{(i,j) \\in P : D_{ij} > t\\}|}{|P|},

    with ``P`` and ``N`` the positive and negative pairs (Bronstein et al., IJCV 2010, §5).
    Both rates are step functions that change only at pair distances, so evaluating them at
    every distinct distance (plus ``-inf`` and ``+inf``) gives the curve exactly.

    **Equal error rate.** Let ``(a_i, r_i) = (FAR(t_i), FRR(t_i))`` at the thresholds
    ``t_0 < t_1 < ...``; ``g_i = a_i - r_i`` is non-decreasing from -1 to 1. With ``k`` the
    first index where ``g_k >= 0``, the EER is where the segment from ``(a_{k-1}, r_{k-1})``
    to ``(a_k, r_k)`` crosses the diagonal:

    .. math::

        \\lambda = \\frac{-g_{k-1}}{g_k - g_{k-1}}, \\qquad
        \\mathrm{EER} = a_{k-1} + \\lambda (a_k - a_{k-1}) = r_{k-1} + \\lambda (r_k - r_{k-1}),

    which is ``a_k = r_k`` when ``g_k = 0``. When one step moves only one rate (no positive
    pair ties a negative one) this equals ``min_t max(FAR(t), FRR(t))``; on ties it is the
    error of a threshold that accepts the tied pairs at random, so a constant matrix, which
    cannot tell pairs apart, scores 0.5 rather than 1. The EER is invariant under any
    strictly increasing transformation of the distances.

    Parameters
    ----------
    distances : array_like, shape (n, n)
        Symmetric (up to ``1e-8`` relative to ``max(1, max|D|)``), finite distances. The
        diagonal is never used.
    labels : array_like, shape (n,)
        Class of each shape (any values comparable with ``==``).
    mask : array_like of bool, shape (n, n), optional
        Only pairs with ``mask[i, j]`` true are trials, e.g. pairs involving a perturbed shape.
        Default: all pairs.
    pairs : {"upper", "all"}, default "upper"
        ``"upper"``: the unordered pairs ``i < j``, each counted once. ``"all"``: the ordered
        pairs ``i != j``, for an asymmetric ``mask`` (e.g. queries in rows against a gallery
        in columns); with a symmetric mask it gives the same curve as ``"upper"``.

    Returns
    -------
    ROC

    Raises
    ------
    ValueError
        If ``distances`` is not square, finite and symmetric, ``labels`` is not of length n,
        ``mask`` has the wrong shape or type, ``pairs`` is unknown, or the chosen pairs lack
        a positive or a negative pair.
    """
    d = _check_distances(distances)
    n = d.shape[0]
    lab = _check_labels(labels, n)
    if pairs == "upper":
        sel = np.triu(np.ones((n, n), dtype=bool), k=1)
    elif pairs == "all":
        sel = ~np.eye(n, dtype=bool)
    else:
        raise ValueError(f"pairs must be 'upper' or 'all', got {pairs!r}")
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != (n, n) or m.dtype != bool:
            raise ValueError(
                f"mask must be a boolean (n, n) = ({n}, {n}) array, "
                f"got shape {m.shape} and dtype {m.dtype}")
        sel &= m
    same = lab[:, None] == lab[None, :]
    pos = np.sort(d[sel & same])
    neg = np.sort(d[sel & ~same])
    if pos.size == 0 or neg.size == 0:
        raise ValueError(
            f"need at least one positive (same-label) and one negative pair, got "
            f"{pos.size} positive and {neg.size} negative pairs among the selected ones")
    inner = np.unique(np.concatenate([pos, neg]))
    n_pos_acc = np.searchsorted(pos, inner, side="right")
    n_neg_acc = np.searchsorted(neg, inner, side="right")
    thresholds = np.concatenate([[-np.inf], inner, [np.inf]])
    far = np.concatenate([[0.0], n_neg_acc / neg.size, [1.0]])
    frr = np.concatenate([[1.0], (pos.size - n_pos_acc) / pos.size, [0.0]])
    g = far - frr
    k = int(np.argmax(g >= 0))  # g[-1] == 1 so a crossing exists; g[0] == -1 so k >= 1
    if g[k] == 0:
        eer = float(far[k])
    else:
        lam = -g[k - 1] / (g[k] - g[k - 1])
        eer = float(far[k - 1] + lam * (far[k] - far[k - 1]))
    for a in (thresholds, far, frr):
        a.setflags(write=False)
    return ROC(thresholds, far, frr, eer, float(thresholds[k]), int(pos.size), int(neg.size))


def equal_error_rate(distances, labels, *, mask=None, pairs: str = "upper") -> float:
    """Equal error rate of a distance matrix: ``roc(distances, labels, ...).eer``.

    See :func:`roc` for the definition, the parameters and the errors raised.
    """
    return roc(distances, labels, mask=mask, pairs=pairs).eer


def errors_at(distances, labels, threshold: float, *, mask=None) -> dict:
    """Where the errors of a threshold come from: false acceptances by pair of classes and
    false rejections by class.

    At threshold ``t`` (e.g. :attr:`ROC.eer_threshold`) a pair of different classes ``a, b``
    with ``D[i, j] <= t`` is a false acceptance and a pair of the same class with
    ``D[i, j] > t`` a false rejection (the trials of :func:`roc`, unordered pairs). Their
    counts per class pair and per class tell, for instance, whether an equal error rate
    comes from one pair of similar classes.

    Parameters
    ----------
    distances, labels, mask
        As in :func:`roc`.
    threshold : float

    Returns
    -------
    dict
        ``threshold``; ``false_accept``: ``{"a / b": [errors, pairs]}`` over the class pairs
        with at least one error, classes in order of first appearance, most errors first;
        ``false_reject``: ``{"a": [errors, pairs]}`` likewise; ``far`` and ``frr``: the
        rates at ``threshold``.
    """
    d = _check_distances(distances)
    n = d.shape[0]
    lab = _check_labels(labels, n)
    t = float(threshold)
    sel = np.triu(np.ones((n, n), dtype=bool), k=1)
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != (n, n) or m.dtype != bool:
            raise ValueError(f"mask must be a boolean (n, n) = ({n}, {n}) array, "
                             f"got shape {m.shape} and dtype {m.dtype}")
        sel &= m
    _, first = np.unique(lab, return_index=True)
    order = {c: k for k, c in enumerate(lab[np.sort(first)].tolist())}
    fa: dict = {}
    fr: dict = {}
    n_fa = n_fr = n_neg = n_pos = 0
    labs = lab.tolist()
    for i, j in zip(*np.nonzero(sel)):
        a, b = sorted((labs[i], labs[j]), key=order.__getitem__)
        if a == b:
            n_pos += 1
            e = fr.setdefault(str(a), [0, 0])
            wrong = bool(d[i, j] > t)
            n_fr += wrong
        else:
            n_neg += 1
            e = fa.setdefault(f"{a} / {b}", [0, 0])
            wrong = bool(d[i, j] <= t)
            n_fa += wrong
        e[0] += int(wrong)
        e[1] += 1

    def worst_first(table):
        items = [(k, v) for k, v in table.items() if v[0] > 0]
        return dict(sorted(items, key=lambda kv: -kv[1][0]))   # stable: class order on ties

    return {"threshold": t, "false_accept": worst_first(fa), "false_reject": worst_first(fr),
            "far": float(n_fa / n_neg) if n_neg else None,
            "frr": float(n_fr / n_pos) if n_pos else None}


def local_scaling(distances, k: int = LOCAL_SCALING_K) -> np.ndarray:
    """Distances divided by the local scales of the two shapes: a set-level normalisation.

    Each shape ``i`` of the set gets a local scale ``sigma_i``, its distance to its ``k``-th
    nearest other shape, and every distance is divided by the geometric mean of the two
    scales:

    .. math::

        D'_{ij} = \\frac{D_{ij}}{\\sqrt{\\sigma_i \\sigma_j}}, \\qquad
        \\sigma_i = \\text{the } k\\text{-th smallest of } \\{D_{il} : l \\ne i\\},

    the local scaling of Zelnik-Manor & Perona, "Self-tuning spectral clustering", NIPS 17
    (2004), §2 (their affinity is ``exp(-D'^2)``, a decreasing function of ``D'``). Each
    distance is measured in the units of the two shapes' neighbourhoods: a shape with
    topological noise, which lies farther from its own class than the clean shapes do (welds:
    1.26-1.35 times, in the rankings of ``gromov reproduce``; docs/design/recognition.md),
    gets a larger scale, so one global threshold serves noisy and clean shapes alike. A row
    inflated ``c`` times comes out inflated ``sqrt(c)`` times where the other shapes' scales
    do not involve it.

    Unlike ``D``, ``D'_{ij}`` depends on the other shapes of the set (it is transductive; no
    labels are used): an equal error rate of ``D'`` is a property of the set, not of the pair
    distance alone, and is reported beside, never instead of, the EER of ``D``
    (``gromov reproduce``: ``eer_local``). A shape's nearest neighbour may change, since each
    candidate's own scale counts.

    Parameters
    ----------
    distances : array_like, shape (n, n)
        Symmetric, finite, non-negative distances (as for :func:`roc`); the diagonal is
        ignored.
    k : int, default LOCAL_SCALING_K (4)
        Which nearest neighbour sets the scale, ``1 <= k <= n - 1``. For recognition keep it
        below the size of the smallest class, so that a shape's scale is set by shapes of its
        own class (:func:`local_roc` warns otherwise).

    Returns
    -------
    ndarray of float64, shape (n, n)
        Symmetric, zero diagonal. A scale of 0 (``k`` other shapes at distance 0) is replaced
        by the smallest positive distance of the matrix; an all-zero matrix stays zero.

    Raises
    ------
    ValueError
        If ``distances`` is not square, finite, symmetric and non-negative, or ``k`` is not an
        integer in ``[1, n - 1]``.
    """
    d = _check_distances(distances)
    n = d.shape[0]
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= n - 1:
        raise ValueError(f"k must be an integer in [1, n - 1] = [1, {n - 1}], got {k!r}")
    off = ~np.eye(n, dtype=bool)
    if np.any(d[off] < 0):
        raise ValueError(f"distances must be non-negative, got minimum {d[off].min():.3g}")
    positive = d[off & (d > 0)]
    if positive.size == 0:
        return np.zeros_like(d)
    others = np.where(off, d, np.inf)
    sigma = np.partition(others, int(k) - 1, axis=1)[:, int(k) - 1]
    sigma = np.maximum(sigma, positive.min())
    out = d / np.sqrt(np.outer(sigma, sigma))
    np.fill_diagonal(out, 0.0)
    return out


def diffusion_rerank(distances, k: int = DIFFUSION_RERANK_K, steps: int = DIFFUSION_RERANK_STEPS, *,
                     scale_k: int = LOCAL_SCALING_K) -> np.ndarray:
    r"""Distances re-ranked by a diffusion on the set's nearest-neighbour graph: a set-level rule.

    The affinities of the locally scaled distances :math:`D'` (:func:`local_scaling`, neighbour
    ``scale_k``), kept on each shape's ``k`` nearest and itself and normalised by row, are a
    random walk :math:`P`; ``steps`` steps of the diffusion :math:`A \leftarrow P A P^\top`
    from :math:`A = P` spread each shape's affinity to the shapes its neighbours are close to,
    and the result is ranked as a distance:

    .. math::

        W_{ij} = e^{-D'^2_{ij}}, \qquad
        P_{ij} = \frac{W_{ij}\,[j \in N_k(i) \cup \{i\}]}{\sum_l W_{il}\,[l \in N_k(i) \cup \{i\}]},
        \qquad A_1 = P,\; A_{t+1} = P A_t P^\top,

        D''_{ij} = \max A^s - A^s_{ij}, \qquad A^s = \tfrac12 (A_T + A_T^\top),

    the diffusion process of Donoser & Bischof, "Diffusion processes for retrieval revisited",
    CVPR 2013 (their affinity with the locally scaled kernel of Zelnik-Manor & Perona 2004, the
    kNN sparsification, and the update :math:`P A P^\top`). Two shapes of one class that are not
    close to each other but share close neighbours come closer; a class's shapes form a
    cluster that the walk stays in. Like :func:`local_scaling` it reads the other shapes of the
    set (transductive; no labels): an EER of ``D''`` is reported beside, never instead of, the
    EER of ``D``, and a shape's nearest neighbour may change. It costs ``steps`` products of
    n x n matrices.

    Parameters
    ----------
    distances : array_like, shape (n, n)
        Symmetric, finite, non-negative distances (as for :func:`roc`); the diagonal is
        ignored.
    k : int, default DIFFUSION_RERANK_K (8)
        Each shape's nearest kept in the walk, ``1 <= k <= n - 1``.
    steps : int, default DIFFUSION_RERANK_STEPS (3)
        The walk's steps ``T``, at least 1 (1: the walk's own affinities).
    scale_k : int, default LOCAL_SCALING_K (4)
        The neighbour of :func:`local_scaling` in the affinity, ``1 <= scale_k <= n - 1``.

    Returns
    -------
    ndarray of float64, shape (n, n)
        Symmetric, non-negative, zero diagonal.

    Raises
    ------
    ValueError
        If ``distances`` is not square, finite, symmetric and non-negative, or ``k``, ``steps``
        or ``scale_k`` are out of range.
    """
    d = _check_distances(distances)
    n = d.shape[0]
    for name, v, top in (("k", k, n - 1), ("scale_k", scale_k, n - 1), ("steps", steps, None)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1 or (top is not None and v > top):
            span = f"an integer in [1, n - 1] = [1, {n - 1}]" if top is not None else "a positive integer"
            raise ValueError(f"{name} must be {span}, got {v!r}")
    W = np.exp(-local_scaling(d, int(scale_k)) ** 2)
    np.fill_diagonal(W, 1.0)
    nearest = np.argsort(-W, axis=1, kind="stable")[:, :int(k) + 1]   # itself first (W_ii = 1)
    rows = np.arange(n)[:, None]
    P = np.zeros_like(W)
    P[rows, nearest] = W[rows, nearest]
    P /= P.sum(axis=1, keepdims=True)
    A = P
    for _ in range(int(steps) - 1):
        A = P @ A @ P.T
    A = 0.5 * (A + A.T)
    out = A.max() - A
    np.fill_diagonal(out, 0.0)
    return out


def diffusion_roc(distances, labels, k: int = DIFFUSION_RERANK_K, steps: int = DIFFUSION_RERANK_STEPS, *,
                  warn: bool = True) -> tuple[ROC, np.ndarray, int]:
    """ROC of the distances re-ranked by :func:`diffusion_rerank`, ``k`` and its ``scale_k``
    (:data:`LOCAL_SCALING_K`) capped at ``n - 1``.

    Parameters
    ----------
    distances, labels
        As in :func:`roc` (the labels only score; the re-ranking does not read them).
    k : int, default DIFFUSION_RERANK_K (8)
    steps : int, default DIFFUSION_RERANK_STEPS (3)
    warn : bool, default True
        Warn (:class:`gromov.errors.GromovWarning`) when the ``k`` used is not below the size
        of the smallest class: a shape's walk may then step into other classes from its
        first step (on TOSCA, smallest class 3, k = 8 still ranks well: EER 1.6%; on ten of
        its shapes in classes of two, 20%).

    Returns
    -------
    (ROC, ndarray, int)
        The curve of ``D''``, ``D''`` itself and the ``k`` used.
    """
    d, lab, used = _set_level_arguments(distances, labels, k, warn and (
        "diffusion re-ranking", "a shape's walk may reach other classes"))
    reranked = diffusion_rerank(d, used, steps, scale_k=min(LOCAL_SCALING_K, len(d) - 1))
    return roc(reranked, lab), reranked, used


def _set_level_arguments(distances, labels, k, warning):
    """``(D, labels, k used)`` of a set-level ROC, ``k`` capped at ``n - 1``; with ``warning``
    ``(rule, what goes wrong)``, a :class:`gromov.errors.GromovWarning` where that ``k`` is not
    below the smallest class."""
    d = _check_distances(distances)
    n = d.shape[0]
    lab = _check_labels(labels, n)
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k must be a positive integer, got {k!r}")
    used = min(int(k), n - 1)
    if warning and used >= smallest_class(lab):
        import warnings

        from ..errors import GromovWarning

        rule, what = warning
        warnings.warn(f"{rule} with k = {used} is not below the smallest class "
                      f"({smallest_class(lab)} shapes): {what}", GromovWarning, stacklevel=3)
    return d, lab, used


def smallest_class(labels) -> int:
    """The number of shapes in the smallest class of ``labels``."""
    return int(np.unique(np.asarray(labels), return_counts=True)[1].min())


def local_roc(distances, labels, k: int = LOCAL_SCALING_K, *, warn: bool = True
              ) -> tuple[ROC, np.ndarray, int]:
    """ROC of the locally scaled distances (:func:`local_scaling`), ``k`` capped at ``n - 1``.

    Parameters
    ----------
    distances, labels
        As in :func:`roc`.
    k : int, default LOCAL_SCALING_K (4)
        The neighbour that sets each shape's scale; ``min(k, n - 1)`` is used.
    warn : bool, default True
        Warn (:class:`gromov.errors.GromovWarning`) when the ``k`` used is not below the size
        of the smallest class: a shape of that class then takes its scale from another class.
        The labels are used for this count only, never in ``D'``.

    Returns
    -------
    (ROC, ndarray, int)
        The curve of ``D'``, ``D'`` itself and the ``k`` used.
    """
    d, lab, used = _set_level_arguments(distances, labels, k, warn and (
        "local scaling", "a shape's scale may come from another class"))
    scaled = local_scaling(d, used)
    return roc(scaled, lab), scaled, used


def mds_map(distances, dim: int = 2, *, seed: int = 0) -> np.ndarray:
    """Classical (Torgerson) multidimensional scaling of a distance matrix.

    With ``J = I - 11^T / n`` the centring matrix, the Gram matrix of the centred
    configuration is

    .. math::

        B = -\\tfrac12 J (D \\circ D) J, \\qquad X = V_d \\Lambda_d^{1/2},

    where ``Λ_d, V_d`` are the ``dim`` largest eigenvalues of ``B`` and their eigenvectors
    (Torgerson 1952; Borg & Groenen, *Modern Multidimensional Scaling*, 2005, ch. 12). When
    ``D`` holds Euclidean distances of points in ``R^dim`` the embedding reproduces them
    exactly, up to a rigid motion. Negative eigenvalues (non-Euclidean ``D``) give zero
    columns. Bronstein et al. (IJCV 2010, Figs. 4-5) show shape distances this way.

    The result is centred, its axes are the principal axes in decreasing order of variance,
    and each axis's sign makes its largest-magnitude coordinate positive (the first such one
    on ties), so equal inputs give equal maps.

    Parameters
    ----------
    distances : array_like, shape (n, n)
        Symmetric, finite distances.
    dim : int, default 2
        Embedding dimension, ``1 <= dim <= n``.
    seed : int, default 0
        Seeds the starting vector of the iterative eigensolver used above 1000 shapes
        (below, a dense eigendecomposition is used and ``seed`` has no effect).

    Returns
    -------
    ndarray of float64, shape (n, dim)

    Raises
    ------
    ValueError
        If ``distances`` is not square, finite and symmetric, or ``dim`` is out of range.
    """
    d = _check_distances(distances)
    n = d.shape[0]
    if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or not 1 <= dim <= n:
        raise ValueError(f"dim must be an integer in [1, n = {n}], got {dim!r}")
    d2 = d * d
    b = -0.5 * (d2 - d2.mean(axis=0)[None, :] - d2.mean(axis=1)[:, None] + d2.mean())
    b = 0.5 * (b + b.T)
    if n <= _DENSE_MAX or dim >= n - 1:
        w, v = np.linalg.eigh(b)
        w, v = w[::-1][:dim], v[:, ::-1][:, :dim]
    else:
        from scipy.sparse.linalg import eigsh

        v0 = np.random.default_rng(seed).standard_normal(n)
        w, v = eigsh(b, k=dim, which="LA", v0=v0)
        order = np.argsort(w)[::-1]
        w, v = w[order], v[:, order]
    if np.any(w < 0):
        logger.debug("mds_map: %d of the top %d eigenvalues are negative; zeroed",
                     int(np.count_nonzero(w < 0)), dim)
    x = v * np.sqrt(np.clip(w, 0.0, None))[None, :]
    big = np.argmax(np.abs(x), axis=0)
    sign = np.where(x[big, np.arange(dim)] < 0, -1.0, 1.0)
    return x * sign[None, :]


def _figure(figsize, dpi):
    """A matplotlib Figure on its own Agg canvas.

    Pyplot is never imported, so no global backend is chosen or changed (the effect of
    ``matplotlib.use("Agg")`` without the side effect on the caller's process).
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "plotting needs matplotlib: pip install 'gromov[plot]'") from exc
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def plot_roc(roc_or_dict, path, *, title: str | None = None,
             figsize: tuple[float, float] = (5.0, 4.0), dpi: int = 100) -> Path:
    """Draw ROC curves (FRR against FAR) with their EER points to a PNG file.

    Parameters
    ----------
    roc_or_dict : ROC or mapping of str to ROC
        One curve, or several named ones (e.g. ``{"geodesic": ..., "diffusion": ...}``,
        as in Bronstein et al., IJCV 2010, Figs. 6-7); the legend gives each name and EER.
    path : str or Path
        Output PNG file; its parent folder must exist.
    title : str, optional
    figsize : (float, float), default (5, 4)
        Size in inches; the image is ``figsize * dpi`` pixels.
    dpi : int, default 100

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If the mapping is empty.
    TypeError
        If a curve is not a :class:`ROC`.
    """
    curves = dict(roc_or_dict) if isinstance(roc_or_dict, Mapping) else {"": roc_or_dict}
    if not curves:
        raise ValueError("roc_or_dict must hold at least one ROC, got an empty mapping")
    for name, c in curves.items():
        if not isinstance(c, ROC):
            raise TypeError(f"ROC curve {name!r} must be a ROC, got {type(c).__name__}")
    fig = _figure(figsize, dpi)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], color="0.7", lw=0.8, ls="--")
    for name, c in curves.items():
        label = f"{name} (EER {c.eer:.1%})" if name else f"EER {c.eer:.1%}"
        (line,) = ax.plot(c.far, c.frr, lw=1.5, label=label)
        ax.plot([c.eer], [c.eer], "o", color=line.get_color())
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("false acceptance rate")
    ax.set_ylabel("false rejection rate")
    ax.set_aspect("equal")
    ax.legend(loc="upper right")
    if title:
        ax.set_title(title)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return path


def plot_mds(coords, labels, path, *, marked=None, marked_label: str = "marked",
             title: str | None = None, names=None,
             figsize: tuple[float, float] = (5.0, 5.0), dpi: int = 100) -> Path:
    """Draw a two-dimensional MDS map of shapes, one colour per class, to a PNG file.

    As in Bronstein et al. (IJCV 2010, Figs. 4-5): each shape is a point, classes are
    coloured (``tab10``, or ``tab20`` above ten classes, in order of first appearance) and
    ``marked`` shapes (e.g. those with topological noise) are drawn as crosses instead of
    discs.

    Parameters
    ----------
    coords : array_like, shape (n, 2)
        E.g. ``mds_map(D, 2)``.
    labels : array_like, shape (n,)
        Class of each shape.
    path : str or Path
        Output PNG file; its parent folder must exist.
    marked : array_like of bool, shape (n,), optional
        Shapes drawn as crosses.
    marked_label : str, default "marked"
        Legend entry of the crosses, e.g. ``"topological noise"``.
    title : str, optional
    names : sequence of str, shape (n,), optional
        Written beside each point (e.g. file names).
    figsize : (float, float), default (5, 5)
        Size in inches; the image is ``figsize * dpi`` pixels.
    dpi : int, default 100

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``coords`` is not finite of shape (n, 2), or ``labels``, ``marked`` or ``names``
        is not of length n (``marked`` boolean).
    """
    x = np.asarray(coords, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 2:
        raise ValueError(f"coords must have shape (n, 2), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("coords must be finite, got NaN or infinite entries")
    n = x.shape[0]
    lab = _check_labels(labels, n)
    if marked is None:
        mk = np.zeros(n, dtype=bool)
    else:
        mk = np.asarray(marked)
        if mk.shape != (n,) or mk.dtype != bool:
            raise ValueError(f"marked must be a boolean array of shape ({n},), "
                             f"got shape {mk.shape} and dtype {mk.dtype}")
    if names is not None:
        names = [str(a) for a in names]
        if len(names) != n:
            raise ValueError(f"names must have length n = {n}, got {len(names)}")
    _, first = np.unique(lab, return_index=True)
    classes = lab[np.sort(first)]
    fig = _figure(figsize, dpi)
    from matplotlib import colormaps

    cmap = colormaps["tab10" if len(classes) <= 10 else "tab20"]
    ax = fig.add_subplot()
    for c, cls in enumerate(classes):
        colour = cmap(c % cmap.N)
        this = lab == cls
        ax.scatter(x[this & ~mk, 0], x[this & ~mk, 1], s=30, color=colour, marker="o",
                   label=str(cls))
        if np.any(this & mk):
            ax.scatter(x[this & mk, 0], x[this & mk, 1], s=40, color=colour, marker="x")
    if np.any(mk):
        ax.scatter([], [], s=40, color="0.3", marker="x", label=marked_label)
    for k, name in enumerate(names or ()):
        ax.annotate(name, x[k], xytext=(3, 3), textcoords="offset points", fontsize="x-small")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return path
