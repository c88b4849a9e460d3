r"""Retrieval: the shapes of a collection nearest to a query, without matching every pair.

Every pair of shapes is ranked by one number, the *ranked value* of recognition
(:func:`gromov.experiments.gh_matrix`'s ``trimmed``, ``gromov pairwise``): for the two-sided
correspondence C between the farthest point samples P of X and Q of Y that :func:`gromov.match`
finds (``orientation="ignore"``, the shapes in their prepared metric),

.. math:: v(X, Y) = \tfrac12\,\sigma_h\big(\rho(d_X(a, b), d_Y(a', b'))\big)_{(a,a'),(b,b') \in C,\ a \ne b},

:math:`\sigma_h` the RMS of the best-fitting ``TRIM_KEEP`` = 80% of the residuals
(:func:`gromov.gmds.trimmed_rms`), :math:`\rho(s, t) = \log\frac{s+\epsilon}{t+\epsilon}` with
:math:`\epsilon = 0.01 \max(\operatorname{diam} X, \operatorname{diam} Y)` (``rank_residual="log"``)
or :math:`(s - t)/\max(\operatorname{diam} X, \operatorname{diam} Y)` (``"difference"``), the
distances those of the heat kernel at ``rank_tau_scale`` times the diffusion time
(:func:`gromov.gh.ranking_value`). With ``rank_by="gh"`` the ranked value is the relative GH
estimate, ``½ (mean |r|^p)^{1/p} / max diam`` of the differences r in the match's metric.

**Which lower bounds hold.** The per-shape lower bounds on the Gromov-Hausdorff distance of the
literature -- ``½|diam X − diam Y|``, half the Hausdorff distance between the eccentricity
sets, the eccentricity and distance-distribution bounds (Mémoli, Found. Comput. Math. 11, 2011,
§6; Mémoli & Sapiro, Found. Comput. Math. 5, 2005), the bottleneck distance of persistence
diagrams (Chazal et al., Comput. Graph. Forum 28, 2009) -- bound
:math:`d_{GH} \le \tfrac12 \operatorname{dis} R` for every correspondence R, the *largest*
distortion. The ranked value is a trimmed (or power) *mean* of the residuals, which can be far
below their maximum: a shape X that is Y with a long thin tail has ``diam X ≫ diam Y``, yet the
tail's samples take part in fewer than 20% of the pairs, which the trimmed RMS sets aside, so
``v(X, Y)`` can be 0 while ``½|diam X − diam Y|`` is large (``tests/test_retrieval.py``). None of
those bounds is a lower bound of the ranked value, and none is used as one here.

What does hold is a bound pair by pair. On X, the block of C between the samples P themselves
holds their fixed distances :math:`d_X(p_a, p_b)`, which :math:`d_Y(f(p_a), f(p_b))` is compared
with, f the images of P on Y. Whatever the images, that distance lies in
:math:`[0, \operatorname{diam} Y]` (it interpolates squared vertex distances with barycentric
weights, a convex combination, :class:`gromov.gmds.SurfaceDistance`), so

.. math:: |\rho_{ab}| \ge \ell_{ab} = \max\big(0,\ \rho(d_X(p_a, p_b), \operatorname{diam} Y)\big),

and the same on Q with the roles swapped; the other residuals are bounded below by 0. The
trimmed RMS (the mean of the h smallest squares) and the power means are non-decreasing in
each residual's magnitude, so

.. math:: v(X, Y) \ge B(X, Y) = \tfrac12\,\sigma_h(\ell),

which needs only each shape's sample distances and diameter in the ranking metric: the
per-shape invariant :class:`ShapeBound`, computed once per shape. B is symmetric in X and Y.
Pruning with it is exact (``prune="bound"``): :func:`nearest` and :func:`knn_pairs` return the
neighbours brute force returns. It is also the best bound the ranges alone give (the images
can realise any distance in range, pair by pair), and it is weak for the trimmed ranking: the
samples' own pairs are a quarter of all pairs and the trimmed RMS sets a fifth aside, so B > 0
only where about four fifths of one shape's sample distances exceed the other's diameter --
shapes of very different size in the ranking metric (raw heat distances scale as one over
length), e.g. a sphere against strips 60 times longer. On the validation sets (held-out TOSCA
classes; stretched synthetic set) it is 0 for every pair; for the GH estimate, an RMS without
trimming, it is positive for every pair and exact pruning skips 0-34% of the matches.

**A heuristic beside it.** ``prune="profile"`` (the default) also skips a pair when ``slack``
times its *profile gap* -- the same summary of the residuals between the two shapes' sorted
sample distances, matched quantile to quantile (the distance-distribution comparison of
Mémoli 2011, §6, summarised as the ranking is) -- exceeds the k-th value found. It is not a
lower bound (it is 0.24-3.2 times the ranked value on the validation sets), so the neighbours
need not be brute force's: with ``slack`` = 0.3 recall@1, 3 and 5 is 1.0 on both validation
sets, with 44-81% of a search's matches skipped and 21-80% of the pairs of every shape's k
nearest (:data:`PROFILE_SLACK`, docs/guide/retrieval.md).

**Values found before.** Where the values of ``(Q, M)`` and ``(M, C)`` are known -- M a shape
matched with the query Q, and the pair ``(M, C)`` recorded in the store between two shapes of
the collection, or matched earlier by :func:`knn_pairs` -- a metric would give
:math:`v(Q, C) \ge |v(Q, M) - v(M, C)|` (the pivot pruning of metric-space search). The ranked
value is not a metric (each value is the distortion of the correspondence one match finds; on
TOSCA 4.5% of triples break the triangle inequality, by up to 1.46 times), so ``prune="profile"``
uses ``triangle_slack`` (:data:`TRIANGLE_SLACK`, 0.7) times the largest such difference as a
second estimate beside the profile gap, chosen on the validation sets as the slack was.
"""

from __future__ import annotations

import heapq
import logging
import numbers
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ._defaults import DEFAULT_RESOLUTION, PROFILE_SLACK, RANK_RESIDUAL, RANK_TAU_SCALE, TRIANGLE_SLACK
from .gh import RANK_LOG_FLOOR, _match, _upgrade_options, check_rank_residual, check_rank_tau_scale
from .gmds import EmbeddedDistance, norm_value, parse_norm, trimmed_rms
from .shape_metric import ShapeMetric

if TYPE_CHECKING:
    from .partial import PartialMatrix

__all__ = ["BOUND_NAME", "SPECTRUM_NAME", "PROFILE_SLACK", "PRUNE_MODES", "TRIANGLE_SLACK", "KnnPairs",
           "NearestResult", "Neighbor", "ShapeBound", "knn_pairs", "nearest", "nearest_wholes", "pair_bound",
           "profile_gap", "shape_bound"]

logger = logging.getLogger(__name__)

#: How candidates are skipped: by the lower bound only (exact), or also by the profile gap.
PRUNE_MODES = ("bound", "profile", "none")
#: ``prune="profile"`` skips a pair when this times its profile gap exceeds the k-th value found.
#: Chosen on the validation sets: the largest profile gap over ranked value of any pair is 3.17
#: (held-out TOSCA classes and gorillas, 190 pairs) and 2.28 (stretched synthetic set, 120
#: pairs); 0.3, the largest multiple of 0.05 below 1 / 3.17, keeps slack times the gap below
#: every ranked value there, and recall@1, 3, 5 is 1.0 on both, with 44-81% of a search's
#: matches skipped; from 0.45 on recall@5 drops (``.venv/bin/python benchmarks/bench_retrieval.py
#: --set heldout|synthetic``; docs/guide/retrieval.md). Re-exported from ``gromov._defaults``.

#: ``prune="profile"`` also skips a pair when this times its triangle estimate (the largest
#: ``|v(a, m) - v(m, b)|`` over the shapes m whose values with both are known) exceeds the k-th
#: value found. Chosen on the validation sets (held-out TOSCA classes and gorillas; stretched
#: synthetic set): recall@1, 3 and 5 is 1.0 for every search and every shape's k nearest up to
#: 0.8, and 0.96 (held-out, every shape's 5 nearest) at 0.9; 0.7 is one step of 0.1 below
#: (``.venv/bin/python benchmarks/bench_retrieval.py --set heldout|synthetic``;
#: docs/guide/retrieval.md). Re-exported from ``gromov._defaults``.

#: Name (with the samples and seed appended) of the invariants kept beside a store entry.
BOUND_NAME = "retrieval-bound-1"
#: Relative margin that keeps the bound below the ranked value whatever the rounding.
_MARGIN = 1e-9
_RANK_BY = ("trimmed", "gh")
#: What :func:`nearest` can rank by: also the combined distance (:func:`gromov.spectrum.combined`).
_NEAREST_RANK_BY = ("trimmed", "gh", "combined")
#: Name (with the length appended) of the spectral signature kept beside a store entry.
SPECTRUM_NAME = "spectrum-1"
#: Name (with the eigenpairs appended) of the heat kernel signature kept beside a store entry
#: (:func:`gromov.spectrum.heat_signature`; read by the combined ranking).
HEAT_SIGNATURE_NAME = "heat-signature-1"


@dataclass(frozen=True, eq=False)
class ShapeBound:
    """What the lower bound needs of one shape (:func:`shape_bound`), computed once per shape.

    Attributes
    ----------
    distances : ndarray (M (M - 1) / 2,)
        Distances between the shape's M farthest point samples in the ranking metric (the heat
        distance at ``rank_tau_scale`` times the diffusion time, else the match's), ascending.
    diameter : float
        The largest distance between working vertices in that metric.
    gh_distances : ndarray (M (M - 1) / 2,)
        The same distances in the match's metric, ascending (``rank_by="gh"``).
    gh_diameter : float
        The diameter in the match's metric.
    n_samples : int
    ranked_apart : bool
        Whether the ranking metric is not the match's (the heat kernel with ``rank_tau_scale``):
        a pair is ranked in it only when both shapes have it, as :func:`gromov.match` does.
    """

    distances: np.ndarray
    diameter: float
    gh_distances: np.ndarray
    gh_diameter: float
    n_samples: int
    ranked_apart: bool

    def arrays(self) -> dict:
        """The attributes as named arrays (what a shape store keeps)."""
        return {"distances": self.distances, "diameter": np.float64(self.diameter),
                "gh_distances": self.gh_distances, "gh_diameter": np.float64(self.gh_diameter),
                "n_samples": np.int64(self.n_samples), "ranked_apart": np.bool_(self.ranked_apart)}

    @classmethod
    def from_arrays(cls, a: dict) -> ShapeBound:
        """The inverse of :meth:`arrays`."""
        return cls(np.asarray(a["distances"], dtype=np.float64), float(a["diameter"]),
                   np.asarray(a["gh_distances"], dtype=np.float64), float(a["gh_diameter"]),
                   int(a["n_samples"]), bool(a["ranked_apart"]))


def _condensed(d: np.ndarray) -> np.ndarray:
    return np.sort(d[np.triu_indices(len(d), 1)])


def shape_bound(shape: ShapeMetric, n_samples: int = 100, seed: int = 0,
                rank_tau_scale: float | None = RANK_TAU_SCALE) -> ShapeBound:
    """The invariants of one prepared shape that :func:`pair_bound` and :func:`profile_gap` read.

    Parameters
    ----------
    shape : ShapeMetric
        In the metric the pairs are matched in (recognition's: ``as_prepared``).
    n_samples, seed : int
        The farthest point samples :func:`gromov.match` takes (``shape.samples(n_samples, seed)``).
    rank_tau_scale : float or None, default RANK_TAU_SCALE
        As in :func:`gromov.experiments.gh_matrix`.

    Returns
    -------
    ShapeBound
    """
    if not isinstance(shape, ShapeMetric):
        raise TypeError(f"shape must be a prepared gromov.ShapeMetric, got {type(shape).__name__}")
    n_samples = int(n_samples)
    if not 3 <= n_samples <= shape.mesh.n_vertices:
        raise ValueError(f"n_samples must be between 3 and the {shape.mesh.n_vertices} working vertices, "
                         f"got {n_samples}")
    P = shape.samples(n_samples, seed)
    gh = _condensed(shape.distances[np.ix_(P, P)])
    ranking = None if rank_tau_scale is None else shape.ranking_surface(check_rank_tau_scale(rank_tau_scale))
    if ranking is None:
        return ShapeBound(gh, shape.diameter, gh, shape.diameter, n_samples, False)
    surface, diameter = ranking
    if not isinstance(surface, EmbeddedDistance):   # pragma: no cover - every ranking metric is embedded
        raise TypeError(f"unexpected ranking metric {type(surface).__name__}")
    return ShapeBound(_condensed(surface.block(P)), diameter, gh, shape.diameter, n_samples, True)


def _summary(values: np.ndarray, n_pairs: int, rank_by: str, p: float) -> float:
    """½ the ranking's summary of ``values`` padded with zeros to ``n_pairs`` residuals."""
    r = np.zeros(n_pairs)
    r[:len(values)] = values
    return 0.5 * (trimmed_rms(r) if rank_by == "trimmed" else norm_value(r, p))


def _metric(b: ShapeBound, c: ShapeBound, rank_by: str):
    """Sample distances and diameters of the two shapes in the metric the pair is ranked in."""
    if rank_by == "trimmed" and b.ranked_apart and c.ranked_apart:
        return b.distances, b.diameter, c.distances, c.diameter
    return b.gh_distances, b.gh_diameter, c.gh_distances, c.gh_diameter


def _checked(rank_by: str, rank_residual: str, norm) -> float:
    if rank_by not in _RANK_BY:
        raise ValueError(f"rank_by must be one of {_RANK_BY}, got {rank_by!r}")
    check_rank_residual(rank_residual)
    return parse_norm(norm)


def pair_bound(x: ShapeBound, y: ShapeBound, *, rank_by: str = "trimmed", rank_residual: str = RANK_RESIDUAL,
               norm="l2") -> float:
    r"""A lower bound on the ranked value of the pair ``(X, Y)``, from per-shape invariants only.

    :math:`B = \tfrac12 \sigma(\ell)` (module docstring): :math:`\ell` is
    :math:`\rho(d_X(p_a, p_b), \operatorname{diam} Y)` where positive on the pairs of X's samples,
    the same with X and Y swapped on Y's, 0 elsewhere, summarised as the ranking summarises
    the residuals (``rank_by="trimmed"``: :func:`gromov.gh.ranking_value` with ``rank_residual``;
    ``"gh"``: the relative GH estimate in ``norm``). Symmetric in X and Y; never above the value
    :func:`gromov.experiments.gh_matrix` ranks the pair by, whatever correspondence it finds.
    """
    p = _checked(rank_by, rank_residual, norm)
    if x.n_samples != y.n_samples:
        raise ValueError(f"the two shapes' invariants have {x.n_samples} and {y.n_samples} samples")
    dx, diam_x, dy, diam_y = _metric(x, y, rank_by)
    diam = max(diam_x, diam_y)
    if not diam > 0:
        return 0.0
    log = rank_by == "trimmed" and rank_residual == "log"
    eps = RANK_LOG_FLOOR * diam

    def exceed(d, top):   # the positive lower bounds of one shape's sample pairs
        top = top * (1.0 + _MARGIN)
        a = d[np.searchsorted(d, top, side="right"):]
        return np.log((a + eps) / (top + eps)) if log else (a - top) / diam

    lx, ly = exceed(dx, diam_y), exceed(dy, diam_x)
    m = 2 * x.n_samples   # the correspondence's points on each side: P and the images of Q
    pos = np.concatenate([lx, lx, ly, ly])   # ordered pairs: each unordered one twice
    return _summary(pos, m * (m - 1), rank_by, p) * (1.0 - _MARGIN)


def profile_gap(x: ShapeBound, y: ShapeBound, *, rank_by: str = "trimmed", rank_residual: str = RANK_RESIDUAL,
                norm="l2") -> float:
    """The ranking's summary of the residuals between the two shapes' sorted sample distances,
    matched quantile to quantile: a cheap estimate of the ranked value (the distance-distribution
    comparison of Mémoli, Found. Comput. Math. 2011, §6), **not** a lower bound of it."""
    p = _checked(rank_by, rank_residual, norm)
    dx, diam_x, dy, diam_y = _metric(x, y, rank_by)
    if len(dx) != len(dy):
        raise ValueError(f"the two shapes' invariants have {len(dx)} and {len(dy)} sample pairs")
    diam = max(diam_x, diam_y)
    if not diam > 0:
        return 0.0
    if rank_by == "trimmed" and rank_residual == "log":
        eps = RANK_LOG_FLOOR * diam
        r = np.log((dx + eps) / (dy + eps))
    else:
        r = (dx - dy) / diam
    return _summary(r, len(r), rank_by, p)


# ----------------------------------------------------------------------------- the search
def _check_k(k) -> int:
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, numbers.Integral) or k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    return int(k)


def _check_prune(prune: str, slack: float, triangle_slack: float | None = None) -> _Triangle | None:
    """Check the pruning options; the triangle estimates to use (``prune="profile"`` with a
    positive ``triangle_slack``), else None."""
    if prune not in PRUNE_MODES:
        raise ValueError(f"prune must be one of {PRUNE_MODES}, got {prune!r}")
    if not (isinstance(slack, numbers.Real) and 0.0 < slack < np.inf):
        raise ValueError(f"slack must be a positive number, got {slack!r}")
    if triangle_slack is not None and not (isinstance(triangle_slack, numbers.Real)
                                           and 0.0 <= triangle_slack < np.inf):
        raise ValueError(f"triangle_slack must be a number >= 0 or None, got {triangle_slack!r}")
    return _Triangle(triangle_slack) if prune == "profile" and triangle_slack else None


class _Rows:
    """The k smallest ``(value, other)`` found so far in each row."""

    def __init__(self, n: int, k: int):
        self.k = k
        self.best: list[list] = [[] for _ in range(n)]

    def add(self, row: int, value: float, other: int) -> None:
        b = self.best[row]
        b.append((np.inf if np.isnan(value) else value, other))   # NaN: last
        b.sort()
        del b[self.k:]

    def threshold(self, row: int) -> float:
        """The k-th smallest value in ``row`` (inf while fewer than k are known)."""
        b = self.best[row]
        return b[-1][0] if len(b) == self.k else np.inf


class _Triangle:
    r"""Triangle estimates of ranked values from the values found so far.

    When the values of the pairs ``(a, m)`` and ``(m, b)`` are known, the ranked value of
    ``(a, b)`` is estimated from below by :math:`|v(a, m) - v(m, b)|`, the largest such
    difference over every ``m`` known with both, times ``slack``. For a metric this is a lower
    bound (the triangle inequality; the pivot pruning of metric-space search, e.g. Micó, Oncina
    & Vidal, Pattern Recognit. Lett. 15, 1994). The Gromov-Hausdorff distance is a metric, but
    the ranked value is the distortion of the correspondence one match finds: on TOSCA 4.5% of
    triples break the inequality, by up to 1.46 times, so this is a heuristic, as the profile
    gap is (:data:`TRIANGLE_SLACK`). Nodes are any hashable, ordered labels.
    """

    def __init__(self, slack: float):
        self.slack = float(slack)
        self.known: dict = {}   # node -> {node: value}
        self.est: dict = {}     # (a, b), a < b -> the largest difference found

    def add(self, a, b, value: float, *, estimates: bool = True) -> None:
        """Record the value of the pair ``(a, b)`` and raise the estimates it takes part in
        (``estimates=False``: only record it, as a pivot for pairs added later -- a search
        needs no estimates between two candidates)."""
        value = float(value)
        if not np.isfinite(value) or b in self.known.get(a, {}):
            return
        ka, kb = self.known.setdefault(a, {}), self.known.setdefault(b, {})
        if estimates:
            for m, w in kb.items():   # a - b - m
                if m != a:
                    self._raise(a, m, abs(value - w))
            for m, w in ka.items():   # b - a - m
                if m != b:
                    self._raise(b, m, abs(value - w))
        ka[b] = kb[a] = value

    def _raise(self, a, b, t: float) -> None:
        key = (a, b) if a < b else (b, a)
        if t > self.est.get(key, 0.0):
            self.est[key] = t

    def estimate(self, a, b) -> float:
        """``slack`` times the largest known difference for the pair ``(a, b)`` (0 if none)."""
        return self.slack * self.est.get((a, b) if a < b else (b, a), 0.0)


def _schedule(pairs, rows_of, key, tie, k: int, n_rows: int, run, *, known: dict, force=frozenset(),
              batch: int = 1, triangle: _Triangle | None = None, nodes=None):
    """Match the pairs that can enter a row's k nearest, cheapest ``key`` first.

    A pair is skipped when its key exceeds the k-th value found so far in every row it
    belongs to (``rows_of(pair)``); ``run(list of pairs)`` returns their values; ``known``:
    values of pairs found before. With ``triangle``, a pair's key is the larger of ``key`` and
    its triangle estimate from the values found (``nodes(pair)``: its two nodes there), and
    the pairs are taken in the order of their current keys (a raised key sends a pair back
    into the queue). Keys only grow and thresholds only fall, so a skipped pair stays
    skippable. Returns ``(values, rows, n_run, n_skipped)``.
    """
    rows = _Rows(n_rows, k)
    values = {}

    def record(pair, value):
        values[pair] = value
        for row, other in rows_of(pair):
            rows.add(row, value, other)
        if triangle is not None:
            triangle.add(*nodes(pair), value)

    for pair in pairs:
        if pair in known:
            record(pair, known[pair])
    key = np.asarray(key, dtype=float)
    tie = np.asarray(tie, dtype=float)
    # NaN keys last (as a sort puts them), but never skipped by them
    queue = [(k_ if k_ == k_ else np.inf, t_ if t_ == t_ else np.inf, i)
             for i, (k_, t_) in enumerate(zip(key.tolist(), tie.tolist()))]
    heapq.heapify(queue)
    n_run = n_skipped = 0
    while queue:
        take = []
        while queue and len(take) < batch:
            queued, t_, idx = heapq.heappop(queue)
            pair = pairs[idx]
            if pair in values:
                continue
            current = key[idx]
            if triangle is not None:
                current = max(current, triangle.estimate(*nodes(pair)))
                if current > queued:
                    heapq.heappush(queue, (current, t_, idx))
                    continue
            if pair not in force and all(current > rows.threshold(r) for r, _ in rows_of(pair)):
                n_skipped += 1
                continue
            take.append(pair)
        if take:
            for pair, value in zip(take, run(take)):
                record(pair, float(value))
            n_run += len(take)
    return values, rows, n_run, n_skipped


def _keys(bounds, gaps, prune: str, slack: float) -> np.ndarray:
    if prune == "none":
        return np.full(len(bounds), -np.inf)
    b = np.asarray(bounds, dtype=float)
    return np.maximum(b, slack * np.asarray(gaps, dtype=float)) if prune == "profile" else b


@dataclass(frozen=True)
class Neighbor:
    """One of the nearest shapes: its position among the candidates, its name (the file, where
    known) and the ranked value of the pair (query, it)."""

    index: int
    name: str
    distance: float


@dataclass(frozen=True, eq=False)
class NearestResult:
    """The outcome of :func:`nearest`.

    Attributes
    ----------
    neighbors : list of Neighbor
        The k nearest candidates, nearest first (ties by position).
    full_matches : int
        Pairs (query, candidate) matched in full.
    skipped : int
        Candidates not matched: their lower bound (or, ``prune="profile"``, their profile gap
        times ``slack`` or their triangle estimate times ``triangle_slack``) exceeded the k-th
        value found.
    bounds, gaps : ndarray (m,)
        Each candidate's lower bound (:func:`pair_bound`) and profile gap (:func:`profile_gap`);
        NaN in a two-stage search (``candidates``) and with ``rank_by="combined"``, which compute neither.
    values : dict
        ``{candidate index: ranked value}`` of the candidates matched.
    exact : bool
        Whether only the lower bound pruned (the neighbours are brute force's).
    rank_by : str
    known_pairs : int
        Values between candidates known for the triangle estimates or the neighbour descent
        (recorded in the store, or given in ``known``); 0 when neither is used.
    partial : PartialMatrix or None
        :func:`nearest_wholes`: the query matched as a part into every candidate (one row), with
        the covered fractions and area ratios.
    """

    neighbors: list
    full_matches: int
    skipped: int
    bounds: np.ndarray
    gaps: np.ndarray
    values: dict = field(default_factory=dict)
    exact: bool = True
    rank_by: str = "trimmed"
    known_pairs: int = 0
    partial: PartialMatrix | None = None

    def to_dict(self) -> dict:
        """The JSON of ``gromov search --json``: ``neighbors`` (``file``, ``distance``, nearest
        first), ``full_matches``, ``skipped``, ``exact``, ``ranked_by`` and ``known_pairs``;
        with ``partial`` each neighbour's ``partial_distance``, ``relative_distance``,
        ``ranking_distance``, ``covered_fraction`` and ``area_ratio`` too (its ``distance`` is
        the ranked score)."""
        neighbors = [{"file": n.name, "distance": n.distance} for n in self.neighbors]
        if self.partial is not None:
            m = self.partial
            for x, n in zip(neighbors, self.neighbors):
                x.update(partial_distance=float(m.distance[0, n.index]),
                         relative_distance=float(m.relative_distance[0, n.index]),
                         ranking_distance=float(m.ranking_distance[0, n.index]),
                         covered_fraction=float(m.covered_fraction[0, n.index]),
                         area_ratio=float(m.area_ratio[0, n.index]))
        return {"neighbors": neighbors, "full_matches": self.full_matches, "skipped": self.skipped,
                "exact": self.exact, "ranked_by": self.rank_by, "known_pairs": self.known_pairs,
                **({} if self.partial is None else {"partial": True})}


def _ranked(result, rank_by: str) -> float:
    return float(result.ranking_distance if rank_by == "trimmed" else result.relative_distance)


def _combined_value(spectral: float, result, rank_by: str, weight) -> float:
    """A matched candidate's ranked value: ``rank_by``'s, or with ``weight`` (the combined
    ranking) :func:`gromov.spectrum.combined` of the spectral distance, it and the result's
    signature distortion."""
    v = _ranked(result, rank_by)
    if weight is None:
        return v
    from .spectrum import combined

    return float(combined(spectral, v, weight, signature=result.signature_distortion))


def _options(n_samples, seed, rank_tau_scale, rank_residual, match_options, caller) -> dict:
    match_options = _upgrade_options(match_options, caller, stacklevel=4)
    match_options.pop("orientation", None)   # the GH estimate: the lowest distortion found
    return dict(n_samples=n_samples, seed=seed, rank_tau_scale=rank_tau_scale, rank_residual=rank_residual,
                orientation="ignore", as_prepared=True, **match_options)


def nearest(query, shapes, k: int = 5, metric: str = "diffusion", *, n_samples: int = 100, seed: int = 0,
            resolution: int | None = DEFAULT_RESOLUTION, metric_options: dict | None = None,
            rank_by: str = "trimmed", rank_tau_scale: float | None = RANK_TAU_SCALE,
            rank_residual: str = RANK_RESIDUAL, prune: str = "profile", slack: float = PROFILE_SLACK,
            triangle_slack: float | None = TRIANGLE_SLACK, known: dict | None = None,
            candidates: int | None = None, progress: bool = False, **match_options) -> NearestResult:
    """The ``k`` shapes nearest to ``query``, ranked as :func:`gromov.experiments.gh_matrix` ranks.

    Each candidate's lower bound on its ranked value (:func:`pair_bound`) and profile gap
    (:func:`profile_gap`) come from per-shape invariants (:func:`shape_bound`); candidates are
    matched in order of the larger of the bound and ``slack`` times the gap, and those for
    which it exceeds the k-th value found are not matched at all. The bound is a true lower
    bound: with ``prune="bound"`` the result is brute force's. It is rarely above zero for the
    trimmed ranking (shapes of very different size only), which the profile gap, not a bound,
    prunes by default (recall 1.0 on the validation sets, module docstring).

    Parameters
    ----------
    query : path, Mesh, PointCloud or ShapeMetric
    shapes : ShapeStore, path of a store folder, or sequence of shapes
        A store (:mod:`gromov.store`): its entries computed with these options
        (:meth:`ShapeStore.shape_options <gromov.store.ShapeStore.shape_options>`), the
        invariants kept beside each entry (computed once); an entry of the query's own file is
        left out. A sequence: paths, meshes or prepared ``ShapeMetric`` objects.
    k : int, default 5
        Neighbours returned (all candidates when there are fewer).
    metric, n_samples, seed, resolution, metric_options
        As in :func:`gromov.experiments.gh_matrix` (recognition's metric: raw heat units).
    rank_by : {"trimmed", "gh", "combined"}, default "trimmed"
        The trimmed distortion (``PairwiseGH.trimmed``), the relative GH estimate, or the
        trimmed distortion, the spectral distance and the signature distortion together
        (``PairwiseGH.combined``, :func:`gromov.spectrum.combined`). The signature distortion
        has no lower bound from per-shape invariants, so the combined ranking prunes nothing:
        every candidate is matched, in order of spectral distance, unless ``candidates``
        limits them.
    rank_tau_scale, rank_residual
        As in :func:`gromov.experiments.gh_matrix`.
    prune : {"profile", "bound", "none"}, default "profile"
        Skip candidates also by ``slack`` times the profile gap (:func:`profile_gap`; not
        exact), by the lower bound only (exact), or match every candidate.
    slack : float, default PROFILE_SLACK (0.3)
        With ``prune="profile"``.
    triangle_slack : float or None, default TRIANGLE_SLACK (0.7)
        With ``prune="profile"``: skip a candidate also when this times its triangle estimate
        exceeds the k-th value found -- the largest ``|v(query, m) - v(m, candidate)|`` over
        the candidates m matched so far whose value with it is known (the pairs recorded in the
        store between candidates, e.g. by ``gromov pairwise`` or ``gh_matrix(k=...)``, or
        ``known``). Not exact (module docstring); 0 or None: not used.
    known : dict, optional
        ``{(i, j): ranked value}`` of pairs of candidates (positions in ``shapes``) found
        before, for the triangle estimates or, with ``candidates``, the neighbour descent (in
        the ranking ``rank_by``); with a store, its recorded pairs with these options are read
        as well. The query's own recorded pairs are never read: it is matched.
    candidates : int, optional
        A two-stage search: the ``candidates`` shapes nearest to the query by spectral
        distance (:func:`gromov.spectrum.spectrum`, kept beside each store entry) are matched,
        all of them; then, where values between the shapes are known (recorded in the store,
        e.g. by ``gromov pairwise --candidates C -k K``, or given in ``known``), rounds of a
        neighbour descent: each shape among the m = ceil(1.5 k) nearest of one of the query's
        m nearest found is matched, until a round adds none (``DESCENT`` of
        :mod:`gromov.experiments.pairwise`; docs/design/recognition.md). ``prune`` and the
        triangle estimates are not used. Not exact.
    progress : bool, default False
        A progress bar (tqdm) on stderr.
    **match_options
        Passed to :func:`gromov.match` (``norm``, ``search``...).

    Returns
    -------
    NearestResult

    Examples
    --------
    >>> r = nearest("cat2.off.gz", "tosca.store", k=3)         # doctest: +SKIP
    >>> [(n.name, n.distance) for n in r.neighbors], r.skipped  # doctest: +SKIP
    """
    k = _check_k(k)
    if rank_by not in _NEAREST_RANK_BY:
        raise ValueError(f"rank_by must be one of {_NEAREST_RANK_BY}, got {rank_by!r}")
    combine = rank_by == "combined"
    rank_by = "trimmed" if combine else rank_by   # what is matched and bounded
    n_first = None if candidates is None else _check_k(candidates)
    _checked(rank_by, rank_residual, match_options.get("norm", "l2"))
    triangle = _check_prune(prune, slack, triangle_slack)
    if combine or n_first is not None:
        triangle = None   # recorded values are not the combined ones; a two-stage search matches them all
    rank_tau_scale = check_rank_tau_scale(rank_tau_scale)
    options = _options(n_samples, seed, rank_tau_scale, rank_residual, match_options, "nearest")
    if combine:
        options["signature"] = True
    shape_args = {"resolution": resolution, "metric_options": metric_options}
    candidates, query_shape, recorded = _candidates(query, shapes, metric, shape_args, n_samples, seed,
                                                    rank_tau_scale, signature=combine)
    if not candidates:
        raise ValueError("no shapes to search: the collection is empty (or holds only the query)")
    known = {(int(i), int(j)): v for (i, j), v in (known or {}).items()}
    bad = [ij for ij in known if not (0 <= min(ij) and max(ij) < len(candidates)) or ij[0] == ij[1]]
    if bad:
        raise ValueError(f"known needs pairs of two candidates (positions below {len(candidates)}), got {bad[0]}")
    if n_first is not None:   # no bound, profile or triangle estimate: none is read or computed
        from .spectrum import SPECTRUM_WEIGHT

        return _two_stage(query_shape, candidates, k, n_first, _spectral_to(query_shape, candidates),
                          SPECTRUM_WEIGHT if combine else None, rank_by, known,
                          recorded(options) if recorded is not None else {}, metric, options, progress)
    if triangle is not None:   # the candidates' known pairs, pivots for the query (node -1)
        at = 2 if rank_by == "trimmed" else 1
        for (i, j), v in (recorded(options) if recorded is not None else {}).items():
            triangle.add(i, j, v[at], estimates=False)
        for (i, j), v in known.items():
            triangle.add(i, j, v, estimates=False)
    n_known = 0 if triangle is None else sum(len(v) for v in triangle.known.values()) // 2
    from tqdm import tqdm

    spectral = weight = None
    if combine:   # no lower bound (the signature distortion has none): all matched, nearest S first
        from .spectrum import SPECTRUM_WEIGHT

        spectral = _spectral_to(query_shape, candidates)
        weight = SPECTRUM_WEIGHT
        bounds = gaps = np.full(len(candidates), np.nan)
        keys, ties = np.zeros(len(candidates)), spectral
    else:
        qb = shape_bound(query_shape, n_samples, seed, rank_tau_scale)
        kw = {"rank_by": rank_by, "rank_residual": rank_residual, "norm": match_options.get("norm", "l2")}
        cbs = [c.bound() for c in candidates]
        bounds = np.array([pair_bound(qb, b, **kw) for b in cbs])
        gaps = np.array([profile_gap(qb, b, **kw) for b in cbs])
        keys, ties = _keys(bounds, gaps, prune, slack), gaps
    todo = np.arange(len(candidates))
    bar = tqdm(total=len(todo), desc="nearest", disable=not progress, leave=False)

    def run(pairs):
        out = []
        for (_, j) in pairs:
            r = _match(query_shape, candidates[j].shape(), metric, **options)
            out.append(_combined_value(None if spectral is None else spectral[j], r, rank_by, weight))
            bar.update(1)
        return out

    pairs = [(0, int(j)) for j in todo]
    try:
        values, rows, n_run, n_skipped = _schedule(pairs, lambda ij: [(0, ij[1])], keys[todo],
                                                   ties[todo], min(k, len(candidates)), 1, run, known={},
                                                   triangle=triangle, nodes=lambda ij: (-1, ij[1]))
    finally:
        bar.close()
    neighbors = [Neighbor(j, candidates[j].name, v) for v, j in rows.best[0]]
    return NearestResult(neighbors, n_run, n_skipped, bounds, gaps, {j: v for (_, j), v in values.items()},
                         combine or prune == "bound" or prune == "none", "combined" if combine else rank_by,
                         n_known)


def _spectral_to(query_shape, candidates) -> np.ndarray:
    """The spectral distance (:func:`gromov.spectrum.signature_distance`) from the query to each
    candidate."""
    from .spectrum import signature_distance, spectrum

    return signature_distance(spectrum(query_shape), np.array([c.spectrum() for c in candidates]))


def _two_stage(query_shape, candidates, k, n_first, spectral, weight, rank_by, known, recorded, metric, options,
               progress) -> NearestResult:
    """:func:`nearest` with ``candidates``: the ``n_first`` nearest by ``spectral`` matched, then
    rounds of :func:`_descent_candidates` over the values between candidates that are known
    (``known``, or ``recorded`` in the store) until a round adds none. ``weight``: the combined
    ranking's spectral weight (None: ``rank_by`` alone)."""
    from tqdm import tqdm

    from .experiments.pairwise import DESCENT
    from .spectrum import signature_distance

    n = len(candidates)

    def spectral_between(i, j):
        sig = {a: candidates[a].spectrum() for a in np.unique(np.r_[i, j]).tolist()}
        return np.array([signature_distance(sig[a], sig[b]) for a, b in zip(i.tolist(), j.tolist())])

    between = _known_matrix(n, known, recorded, rank_by, weight, spectral_between)
    m = min(int(np.ceil(DESCENT * k)), n - 1)
    graph = None if between is None else _nearest_lists(between, m)
    values = {}
    todo = np.argsort(spectral, kind="stable")[:n_first]
    with tqdm(total=len(todo), desc="nearest", disable=not progress, leave=False) as bar:
        while len(todo):
            for j in todo.tolist():
                r = _match(query_shape, candidates[j].shape(), metric, **options)
                values[j] = _combined_value(spectral[j], r, rank_by, weight)
                bar.update(1)
            todo = np.empty(0, np.int64) if graph is None else _descent_candidates(values, graph, m)
            bar.total += len(todo)
            bar.refresh()
    order = sorted((v, j) for j, v in values.items())[:k]
    n_known = 0 if between is None else int(np.isfinite(between[np.triu_indices(n, 1)]).sum())
    return NearestResult([Neighbor(j, candidates[j].name, v) for v, j in order], len(values), n - len(values),
                         np.full(n, np.nan), np.full(n, np.nan), values, False,
                         "combined" if weight is not None else rank_by, n_known)


def _known_matrix(n: int, known: dict, recorded: dict, rank_by: str, weight, spectral_between):
    """``(n, n)`` ranked values between candidates, NaN where unknown (None when none is):
    ``known`` as given (already in the ranking), ``recorded`` pairs ``(distance, relative,
    ranking, signature)`` read in it (``weight``: combined with ``spectral_between(i, j)``, the
    spectral distances of those pairs, and their signature distortions: NaN, unknown, where a
    pair was recorded without one)."""
    if not known and not recorded:
        return None
    R = np.full((n, n), np.nan)
    if recorded:
        ij = np.array(list(recorded), dtype=np.int64)
        i, j = ij[:, 0], ij[:, 1]
        v = np.array([val[1 if rank_by == "gh" else 2] for val in recorded.values()], dtype=np.float64)
        if weight is not None:
            from .spectrum import combined

            h = np.array([val[3] for val in recorded.values()], dtype=np.float64)
            v = combined(spectral_between(i, j), v, weight, signature=h)
        R[i, j] = R[j, i] = v
    for (i, j), v in known.items():
        R[i, j] = R[j, i] = v
    return R


def _nearest_lists(R: np.ndarray, m: int) -> list[np.ndarray]:
    """Each candidate's ``m`` nearest others by ``R`` (its known values only; fewer where it
    has fewer), ties by position."""
    near = np.argsort(np.where(np.isnan(R), np.inf, R), axis=1, kind="stable")[:, :m]
    known = np.isfinite(np.take_along_axis(R, near, axis=1))
    return [row[ok] for row, ok in zip(near, known)]


def _descent_candidates(values: dict, graph: list, m: int) -> np.ndarray:
    """A round of the neighbour descent for one query (Dong, Moses & Li, WWW 2011, with the
    collection's neighbour lists fixed): the candidates among the ``m`` nearest (``graph``) of
    the query's ``m`` nearest found (``values``: candidate -> ranked value) that are not matched
    yet, sorted."""
    near = [j for _, j in sorted((v, j) for j, v in values.items())[:m]]
    reach = np.unique(np.concatenate([graph[j] for j in near])) if near else np.empty(0, np.int64)
    return reach[~np.isin(reach, list(values))].astype(np.int64)


def nearest_wholes(query, shapes, k: int = 5, metric: str | None = None, *, n_samples: int = 100, seed: int = 0,
                   resolution: int | None = DEFAULT_RESOLUTION, metric_options: dict | None = None,
                   progress: bool = False, **match_options) -> NearestResult:
    """The ``k`` shapes that ``query`` fits into best as a part (``gromov search --partial``).

    The query is matched as the part into every shape of the collection
    (:func:`gromov.partial.partial_matrix`, one row) and the shapes are ranked by the partial
    ranking distance per share of the shape covered (:attr:`gromov.partial.PartialMatrix.score`,
    each neighbour's ``distance``). Every shape is matched: the lower bounds and profile gaps of
    :func:`nearest` bound a two-sided distortion and prune nothing here. Read each neighbour's
    area ratio (``partial`` of the result) beside it: a small part fits almost anywhere.

    Parameters
    ----------
    query : path, Mesh or ShapeMetric
        The part (a triangle mesh).
    shapes : ShapeStore, path of a store folder, or sequence of shapes
        The wholes. A store: each stored file once (its entry of the partial match's metric,
        options and ``resolution`` used as it is, else the input mesh of any of its entries,
        its metric computed), read one at a time; an entry of the query's own file is left
        out. Point clouds are not matched (counted in ``skipped``).
    k : int, default 5
    metric : str, optional
        Default :data:`gromov.partial.PARTIAL_METRIC`.
    n_samples, seed, resolution, metric_options, **match_options
        As :func:`gromov.partial.match_partial`.
    progress : bool, default False
        A progress bar (tqdm) on stderr.

    Returns
    -------
    NearestResult
        ``rank_by="partial"``, ``exact`` True, NaN bounds and gaps, ``partial`` the
        :class:`~gromov.partial.PartialMatrix` (one row, a column per shape matched).
    """
    from .partial import PARTIAL_METRIC, partial_matrix
    from .store import ShapeStore

    k = _check_k(k)
    metric = PARTIAL_METRIC if metric is None else metric
    if isinstance(shapes, ShapeStore) or (isinstance(shapes, (str, os.PathLike)) and os.path.isdir(shapes)):
        names, wholes = _store_wholes(query, shapes, metric, resolution, metric_options)
    elif isinstance(shapes, (str, os.PathLike)):
        from .store import StoreError

        raise StoreError(f"shapes: {os.fspath(shapes)} is not a shape store folder")
    else:
        wholes = list(shapes)
        names = [os.fspath(s) if isinstance(s, (str, os.PathLike)) else f"shape {i}" for i, s in enumerate(wholes)]
    if not wholes:
        raise ValueError("no shapes to search: the collection is empty (or holds only the query)")
    m = partial_matrix([query], wholes, metric, n_samples=n_samples, seed=seed, resolution=resolution,
                       metric_options=metric_options, names=names, progress=progress, **match_options)
    d = m.score[0]
    order = [j for j in np.argsort(np.where(np.isnan(d), np.inf, d), kind="stable") if not np.isnan(d[j])][:k]
    neighbors = [Neighbor(int(j), names[j], float(d[j])) for j in order]
    nan, matched = np.full(len(wholes), np.nan), ~np.isnan(d)
    return NearestResult(neighbors, int(matched.sum()), int((~matched).sum()), nan, nan.copy(),
                         {int(j): float(d[j]) for j in np.flatnonzero(matched)}, True, "partial", 0, m)


def _opened_store(store):
    """``store`` as a :class:`~gromov.store.ShapeStore`: one given, or the folder of one."""
    from .store import ShapeStore, StoreError, as_store

    if isinstance(store, ShapeStore):
        return store
    if not os.path.isfile(os.path.join(os.fspath(store), "catalogue.sqlite")):
        raise StoreError(f"{os.fspath(store)} is not a shape store (no catalogue.sqlite): "
                         "gromov index FILES --store DIR makes one")
    return as_store(store)


def _store_wholes(query, store, metric, resolution, metric_options) -> tuple[list, list]:
    """``(names, wholes)`` of :func:`nearest_wholes` from a store: a function per stored file
    (the query's own left out) returning its ShapeMetric (an entry in the partial match's
    options and this version), else its input mesh (the file, where the entry cannot be read)."""
    from . import __version__
    from .metrics.diffusion import correspondence_options
    from .store import ShapeStore, StoreError, _read_npz, _shape_from_arrays, file_sha256

    store = _opened_store(store)
    own = None
    if isinstance(query, (str, os.PathLike)):
        if not os.path.isfile(query):
            raise FileNotFoundError(f"no such file: {os.fspath(query)}")
        own = file_sha256(query)
    options = ShapeStore.shape_options(metric, resolution=resolution,
                                       metric_options=correspondence_options(metric, metric_options))
    by_file: dict = {}
    for e in store.entries():   # each file once: an entry in these options first, then this version's
        if e.content_hash == own:
            continue
        rank = (e.options != options, e.version != __version__)
        if e.content_hash not in by_file or rank < by_file[e.content_hash][0]:
            by_file[e.content_hash] = (rank, e)
    names, wholes = [], []
    for rank, e in by_file.values():
        def load(e=e, exact=rank == (False, False)):
            data, reason = store._read(e.file, e.checksum)
            if reason is None:
                try:
                    s = _shape_from_arrays(_read_npz(data))
                    return s if exact else s.input
                except Exception as exc:   # noqa: BLE001 - an unreadable entry: its file, where still there
                    reason = f"cannot be read ({type(exc).__name__}: {exc})"
            if e.path is None or not os.path.isfile(e.path):
                raise StoreError(f"{e.path or e.key}: stored entry {e.file} {reason}, and its file is gone")
            return store._load(e.path) if store._load is not None else e.path

        names.append(e.path or e.key)
        wholes.append(load)
    return names, wholes


# ----------------------------------------------------------------------------- candidates
class _Candidate:
    """A shape to search: its invariants (possibly kept in a store) and, when it is matched,
    its prepared shape (read from the store only then, and let go after)."""

    def __init__(self, name: str, bound, shape, spectrum=None):
        self.name, self._bound, self._shape = name, bound, shape
        self._spectrum = spectrum if spectrum is not None else (lambda: _spectrum_of(self.shape()))

    def bound(self) -> ShapeBound:
        if callable(self._bound):
            self._bound = self._bound()
        return self._bound

    def spectrum(self) -> np.ndarray:
        if callable(self._spectrum):
            self._spectrum = self._spectrum()
        return self._spectrum

    def shape(self) -> ShapeMetric:
        return self._shape() if callable(self._shape) else self._shape


def _candidates(query, shapes, metric, shape_args, n_samples, seed, rank_tau_scale, signature=False):
    """``(candidates, prepared query, recorded)`` from a store or a sequence of shapes;
    ``recorded(match options)``: the store's recorded pairs between candidates, ``{(i, j):
    (distance, relative, ranking, signature)}`` by candidate position (None without a store).
    ``signature``: a store entry's heat kernel signature is read from beside it, or computed
    and kept there, when it is matched."""
    from .store import ShapeStore

    if isinstance(shapes, ShapeStore) or (isinstance(shapes, (str, os.PathLike)) and os.path.isdir(shapes)):
        return _store_candidates(query, shapes, metric, shape_args, n_samples, seed, rank_tau_scale, signature)
    if isinstance(shapes, (str, os.PathLike)):
        from .store import StoreError

        raise StoreError(f"shapes: {os.fspath(shapes)} is not a shape store folder")
    items = list(shapes)
    prepared = [_prepared(s, metric, shape_args) for s in items]
    q = _prepared(query, metric, shape_args)
    names = [os.fspath(s) if isinstance(s, (str, os.PathLike)) else f"shape {i}" for i, s in enumerate(items)]
    return ([_Candidate(n, (lambda s=s: shape_bound(s, n_samples, seed, rank_tau_scale)), s)
             for n, s in zip(names, prepared)], q, None)


def _spectrum_of(shape) -> np.ndarray:
    from .spectrum import spectrum

    return spectrum(shape)


def _prepared(s, metric, shape_args) -> ShapeMetric:
    if isinstance(s, ShapeMetric):
        if s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        return s
    return ShapeMetric(s, metric, **shape_args)


def _store_candidates(query, store, metric, shape_args, n_samples, seed, rank_tau_scale, signature=False):
    """The store's entries with these options (the query's own entry left out), their
    invariants read from the store or computed from the entry and kept there."""
    from . import __version__
    from .store import ShapeStore, StoreError, file_sha256

    store = _opened_store(store)
    tau = rank_tau_scale
    options = ShapeStore.shape_options(metric, rank_tau_scale=tau, **shape_args)
    entries = [e for e in store.entries() if e.options == options and e.version == __version__]
    if not entries:
        n = len(store.entries())
        raise StoreError(f"the store {store.root} has no shapes computed with these options and this gromov "
                         f"version ({n} entr{'y' if n == 1 else 'ies'} with others): gromov index FILES "
                         "--store DIR with the same options adds them")
    query_key = q = None
    if isinstance(query, ShapeMetric):
        query_key = store.key_of(query)
        q = _prepared(query, metric, shape_args)
    elif isinstance(query, (str, os.PathLike)):
        if not os.path.isfile(query):
            raise FileNotFoundError(f"no such file: {os.fspath(query)}")
        query_key = ShapeStore.entry_key(file_sha256(query), options)
    by_key = {e.key: e for e in entries}
    if q is None and query_key in by_key:
        q = _entry_shape(store, by_key[query_key], shape_args, tau)
    elif q is None:   # read as the store reads its files
        q = _prepared(store._load(os.fspath(query)) if store._load is not None and query_key is not None
                      else query, metric, shape_args)
    name = f"{BOUND_NAME}:n_samples={int(n_samples)}:seed={int(seed)}"

    def bound_of(e):
        def bound():
            try:
                return shape_bound(_entry_shape(store, e, shape_args, tau), n_samples, seed, tau)
            except ValueError as exc:   # e.g. fewer working vertices than samples: say which shape
                raise ValueError(f"{e.path or e.key}: {exc}") from None
        return lambda: _kept_extra(store, e.key, name, ShapeBound.from_arrays, bound, ShapeBound.arrays)

    kept = [e for e in entries if e.key != query_key]
    from .spectrum import SPECTRUM_K

    spectrum_name = f"{SPECTRUM_NAME}:k={SPECTRUM_K}"

    def spectrum_of(e):
        return lambda: _kept_extra(store, e.key, spectrum_name, lambda got: np.asarray(got["dna"], dtype=np.float64),
                                   lambda: _spectrum_of(_entry_shape(store, e, shape_args, tau)),
                                   lambda dna: {"dna": dna})

    def recorded(options):
        from .store import match_options_key

        rest = {k: v for k, v in options.items() if k not in ("n_samples", "seed", "orientation", "as_prepared")}
        at = {e.key: i for i, e in enumerate(kept)}
        found = store.pair_values_among(at, match_options_key(options["n_samples"], options["seed"], rest))
        return {(at[x], at[y]): v for (x, y), v in found.items()}

    def shape_of(e):
        def load():
            s = _entry_shape(store, e, shape_args, tau)
            if signature:
                _kept_heat_signature(store, e.key, s)
            return s
        return load

    if signature and query_key in by_key:
        _kept_heat_signature(store, query_key, q)
    return ([_Candidate(e.path or e.key, bound_of(e), shape_of(e), spectrum_of(e)) for e in kept], q, recorded)


def heat_signature_name() -> str:
    """The name a store entry's heat kernel signature is kept under: its eigenpairs and times,
    so that a signature of other settings is never read back."""
    from .spectrum import SIGNATURE_EIGENPAIRS, SIGNATURE_TAUS

    return f"{HEAT_SIGNATURE_NAME}:k={SIGNATURE_EIGENPAIRS}:tau={','.join(f'{t:.6g}' for t in SIGNATURE_TAUS)}"


def _kept_extra(store, key: str, name: str, read, compute, arrays):
    """What is kept beside the entry ``key`` under ``name``, read back by ``read(arrays)``, or
    (nothing kept, or kept otherwise: ``read`` raises KeyError, ValueError or TypeError)
    ``compute()``, kept there as ``arrays(value)``."""
    got = store.extra(key, name)
    if got is not None:
        try:
            return read(got)
        except (KeyError, ValueError, TypeError):   # written otherwise: computed again
            pass
    value = compute()
    store.put_extra(key, name, arrays(value))
    return value


def _kept_heat_signature(store, key: str, s: ShapeMetric) -> None:
    """The heat kernel signature of the entry ``key`` (:func:`gromov.spectrum.heat_signature`)
    read from beside it into the prepared shape ``s``, or computed and kept there."""
    from .spectrum import SIGNATURE_TAUS, heat_signature

    def read(got):
        h = np.array(got["h"], dtype=np.float64)
        if h.shape != (s.mesh.n_vertices, len(SIGNATURE_TAUS)):
            raise ValueError(f"a heat signature of shape {h.shape}")
        h.flags.writeable = False
        s.__dict__.setdefault("_spectrum", {})["heat"] = h
        return h

    _kept_extra(store, key, heat_signature_name(), read, lambda: heat_signature(s), lambda h: {"h": h})


def _entry_shape(store, entry, shape_args, rank_tau_scale) -> ShapeMetric:
    """The ShapeMetric of a store entry, read by its key (checked against its checksum); an
    entry that cannot be read is computed again from its file where that is still there."""
    from .store import StoreError, _read_npz, _shape_from_arrays

    data, reason = store._read(entry.file, entry.checksum)
    if reason is None:
        try:
            s = _shape_from_arrays(_read_npz(data))
            store._keys[s] = entry.key
            return s
        except Exception as exc:   # noqa: BLE001 - any unreadable entry is computed again
            reason = f"cannot be read ({type(exc).__name__}: {exc})"
    if entry.path is None or not os.path.isfile(entry.path):
        raise StoreError(f"{entry.path or entry.key}: stored entry {entry.file} {reason}, and its file is gone")
    opts = entry.options
    return store.shape(entry.path, opts["metric"], resolution=opts["resolution"],
                       metric_options=shape_args.get("metric_options"), rank_tau_scale=rank_tau_scale)


# ----------------------------------------------------------------------------- all shapes
@dataclass(frozen=True, eq=False)
class KnnPairs:
    """The outcome of :func:`knn_pairs`.

    Attributes
    ----------
    results : dict
        ``{(i, j): what run returned for the pair}`` (``i < j``) of every pair matched or given
        in ``known``.
    neighbors : ndarray (n, k) int
        Each shape's k nearest others, nearest first (ties by index).
    distances : ndarray (n, k)
        Their ranked values.
    full_matches, skipped : int
        Pairs matched now, and pairs not matched (neither known nor needed).
    bounds : ndarray (n, n)
        The lower bound of every pair (:func:`pair_bound`), 0 on the diagonal.
    """

    results: dict
    neighbors: np.ndarray
    distances: np.ndarray
    full_matches: int
    skipped: int
    bounds: np.ndarray


def knn_pairs(shapes, k: int, run, *, n_samples: int = 100, seed: int = 0,
              rank_tau_scale: float | None = RANK_TAU_SCALE, rank_residual: str = RANK_RESIDUAL,
              rank_by: str = "trimmed", norm="l2", known: dict | None = None, force=(), batch: int = 1,
              prune: str = "profile", slack: float = PROFILE_SLACK,
              triangle_slack: float | None = TRIANGLE_SLACK) -> KnnPairs:
    """Each shape's ``k`` nearest others, matching only the pairs that can be among them.

    The scheduler behind :func:`gromov.experiments.gh_matrix`'s ``k``: the unordered pairs are
    taken in order of their lower bound (:func:`pair_bound`) or, with ``prune="profile"``, of the
    larger of it and ``slack`` times the profile gap (ties by the gap), and a pair is skipped
    when that exceeds the k-th value found so far for both of its shapes. With
    ``prune="bound"`` every shape's k nearest are brute force's.

    Parameters
    ----------
    shapes : list of ShapeMetric
        Prepared shapes (:func:`gromov.experiments.pairwise.prepare`).
    k : int
        Neighbours per shape (capped at ``n - 1``).
    run : callable
        ``run(list of (i, j)) -> list``, one entry per pair, indexable as gh_matrix's worker
        results ``(distance, relative, trimmed, ...)``: the pair's ranked value is entry 2
        (``rank_by="trimmed"``) or 1 (``"gh"``). Called with up to ``batch`` pairs at a time.
    n_samples, seed, rank_tau_scale, rank_residual, rank_by, norm
        As the pairs are matched and ranked.
    known : dict, optional
        ``{(i, j): the same tuples}`` of pairs found before: not run again.
    force : iterable of (int, int)
        Pairs run whatever their bound (gh_matrix's ``keep``).
    batch : int, default 1
        Pairs handed to ``run`` at once (e.g. the worker processes; a pair in a batch may turn
        out not to have been needed, never the other way).
    prune, slack
        As in :func:`nearest`.
    triangle_slack : float or None, default TRIANGLE_SLACK (0.7)
        With ``prune="profile"``: a pair is also skipped when this times its triangle estimate,
        the largest ``|v(i, m) - v(m, j)|`` over the shapes m whose values with both are known
        (given in ``known`` or matched so far), exceeds the k-th value of both shapes (not
        exact); 0 or None: not used.

    Returns
    -------
    KnnPairs
    """
    shapes = list(shapes)
    n = len(shapes)
    if n < 2:
        raise ValueError(f"need at least two shapes, got {n}")
    k = min(_check_k(k), n - 1)
    _checked(rank_by, rank_residual, norm)
    triangle = _check_prune(prune, slack, triangle_slack)
    if int(batch) < 1:
        raise ValueError(f"batch must be >= 1, got {batch}")
    inv = [shape_bound(s, n_samples, seed, rank_tau_scale) for s in shapes]
    kw = {"rank_by": rank_by, "rank_residual": rank_residual, "norm": norm}
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    bounds = np.array([pair_bound(inv[i], inv[j], **kw) for i, j in pairs])
    gaps = np.array([profile_gap(inv[i], inv[j], **kw) for i, j in pairs])
    at = 2 if rank_by == "trimmed" else 1
    results = {(int(i), int(j)): v for (i, j), v in (known or {}).items()}

    def run_values(take):
        out = run(take)
        for ij, r in zip(take, out):
            results[ij] = r
        return [r[at] for r in out]

    force = frozenset((int(i), int(j)) for i, j in force)
    _, rows, n_run, n_skipped = _schedule(
        pairs, lambda ij: [(ij[0], ij[1]), (ij[1], ij[0])], _keys(bounds, gaps, prune, slack), gaps, k, n,
        run_values, known={ij: r[at] for ij, r in results.items()}, force=force, batch=int(batch),
        triangle=triangle, nodes=lambda ij: ij)
    nbr = np.full((n, k), -1, dtype=np.int64)
    dist = np.full((n, k), np.nan)
    for i in range(n):
        for c, (v, j) in enumerate(rows.best[i]):
            nbr[i, c], dist[i, c] = j, v
    B = np.zeros((n, n))
    iu = np.triu_indices(n, 1)
    B[iu] = bounds
    B.T[iu] = bounds
    return KnnPairs(results, nbr, dist, n_run, n_skipped, B)
