r"""The initial search of :func:`gromov.match`: where GMDS starts (Bronstein et al., IJCV 2010, §4).

GMDS descends to a local minimum of the distortion, so the map it ends in is decided by its
start. The search finds that start in three steps, each direction (X to Y, Y to X) on its own:

1. *candidates* (:func:`_candidates`): the working vertices of the target whose signatures
   (:attr:`ShapeMetric.descriptors <gromov.shape_metric.ShapeMetric.descriptors>`) best match the first
   sample's, at least 5% of the diameter apart;
2. *coarse starts* (:class:`_Search`): from every candidate, the first few samples placed
   greedily and polished by discrete descent, once on distances alone and once with the
   signatures' mismatch as a per-image cost (:func:`signature_mismatch`);
3. *extension*: the lowest-cost coarse starts extended to all samples, the other direction
   anchored on each (:func:`anchored_images`), and the two-sided pair of lower distortion kept
   (:func:`initial_pairs`).

Its options are :class:`SearchOptions`; how they were chosen: docs/design/initial-search.md.
The orientation helpers here let :func:`gromov.match` ask for more orientation-preserving (or,
for a shape's own reflection, :func:`_self_reflection`, reversing) starts.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from . import _gmds_kernel as _kernel
from ._arrays import argmin_stable, argsort_stable, readonly
from .gmds import SurfacePoints, SymmetricGMDS
from .orientation import orientation_agreements
from .shape_metric import ShapeMetric, _anchor_rows

__all__ = ["SearchOptions", "greedy_init", "initial_pairs", "anchored_images", "signature_mismatch",
           "search_subsets", "pair_orientation", "pairs_orientation"]

#: Defaults of :class:`SearchOptions`. First-sample candidates, and coarse starts extended to
#: all samples per direction (chosen on held-out TOSCA classes: docs/design/initial-search.md).
DEFAULT_N_STARTS = 128
DEFAULT_N_EXTEND = 8
#: Coarse stages of the initial search: (samples placed, farthest point samples of the target
#: it runs on, None for all working vertices).
DEFAULT_COARSE_STAGES: tuple[tuple[int, int | None], ...] = ((12, None), (20, 1000))
#: Fraction of the samples a coarse start's extension descends on after its first descent
#: (sample-level least trimmed squares; 1, the default, disables it), and how many rounds:
#: see :attr:`SearchOptions.extend_keep`.
EXTEND_KEEP = 1.0
EXTEND_ROUNDS = 3
#: Farthest point samples of the target to which the initial search is restricted (None: all
#: working vertices); the best start is then polished on all of them.
DEFAULT_SEARCH_VERTICES: int | None = None
#: :meth:`ShapeMetric.symmetry <gromov.shape_metric.ShapeMetric.symmetry>` accepts a self-map whose RMS distortion is below this fraction of
#: the diameter.
SYMMETRY_TOL = 0.05
#: ... and repairs it up to this many times where its two halves disagree by more than
#: ``INVOLUTION_TOL`` of the diameter at a sample (a reflection is its own inverse).
INVOLUTION_REPAIRS = 2
INVOLUTION_TOL = 0.05
#: Signature-guided coarse stages (:attr:`SearchOptions.signature_weight`): the weight of the
#: per-image cost, and how many of the candidates (the best-matching signatures first) they
#: start from.
SIGNATURE_WEIGHT = 1.0
SIGNATURE_STARTS = 32


@dataclass(frozen=True)
class SearchOptions:
    r"""How :func:`gromov.match` searches for the correspondence: the initial search's options
    and the GMDS descent's stopping rule.

    The defaults are those chosen on held-out TOSCA classes (docs/design/initial-search.md).

    Parameters
    ----------
    n_starts : int, default 128
        Candidate images of the first sample per direction: the working vertices of the
        target with the closest signatures, at least 5% of the diameter apart.
    n_extend : int, default 8
        Coarse starts per direction extended to all samples, shared out evenly among the
        coarse stages (each stage's lowest-cost first).
    coarse_stages : sequence of (int, int or None), default ((12, None), (20, 1000))
        Each stage ``(c, k)`` places the first ``c`` samples from every candidate, over ``k``
        farthest point samples of the target (None: all its working vertices).
    search_vertices : int or None, default None
        Run the whole search on this many farthest point samples of each target (the stages'
        own ``k`` are then ignored) and polish the best start on all vertices: faster, its
        cost grows with this size. None: as ``coarse_stages`` say.
    extend_keep : float, default 1.0
        Below 1: each extended start then descends on this fraction of its samples, in
        ``EXTEND_ROUNDS`` rounds of sample-level least trimmed squares (samples near a change
        of topology set aside). 1: off.
    signature_weight : float, default 1.0
        Weight :math:`w` of the per-image cost :math:`w\,(c - 1)\,\delta(k, v)^2` (:math:`\delta`:
        the signature mismatch of sample ``k`` and vertex ``v``, :func:`signature_mismatch`)
        in each coarse stage's second run, from the ``SIGNATURE_STARTS`` (32) candidates with
        the best signatures. 0: no second run.
    max_iter : int, default 100
        GMDS sweeps from the chosen start (:class:`gromov.gmds.SymmetricGMDS`).
    tol : float, default 1e-6
        GMDS's relative stopping tolerance on the distortion.

    Examples
    --------
    >>> from gromov import SearchOptions
    >>> fast = SearchOptions(search_vertices=500)
    >>> fast.n_starts, fast.search_vertices
    (128, 500)
    >>> r = gromov.match("cat0.off.gz", "cat1.off.gz", search=fast)    # doctest: +SKIP
    """

    n_starts: int = DEFAULT_N_STARTS
    n_extend: int = DEFAULT_N_EXTEND
    coarse_stages: tuple[tuple[int, int | None], ...] = DEFAULT_COARSE_STAGES
    search_vertices: int | None = DEFAULT_SEARCH_VERTICES
    extend_keep: float = EXTEND_KEEP
    signature_weight: float = SIGNATURE_WEIGHT
    max_iter: int = 100
    tol: float = 1e-6

    def __post_init__(self):
        checked = [("n_starts", self.n_starts, 1), ("n_extend", self.n_extend, 1), ("max_iter", self.max_iter, 0)]
        if self.search_vertices is not None:
            checked.append(("search_vertices", self.search_vertices, 1))
        for name, value, low in checked:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                kind = "a positive integer" if low else "an integer >= 0"
                raise ValueError(f"{name} must be {kind}, got {value!r}")
        if not 0.0 < self.extend_keep <= 1.0:
            raise ValueError(f"extend_keep must be in (0, 1], got {self.extend_keep!r}")
        w = self.signature_weight
        if isinstance(w, bool) or not isinstance(w, numbers.Real) or not (np.isfinite(w) and w >= 0):
            raise ValueError(f"signature_weight must be a finite number >= 0, got {w!r}")
        if isinstance(self.tol, bool) or not isinstance(self.tol, numbers.Real) or not self.tol >= 0:
            raise ValueError(f"tol must be a number >= 0, got {self.tol!r}")
        try:
            stages = tuple((int(c), None if k is None else int(k)) for c, k in self.coarse_stages)
        except (TypeError, ValueError):
            raise ValueError("coarse_stages must be pairs (samples, vertices or None), got "
                             f"{self.coarse_stages!r}") from None
        if not stages or any(c < 1 or (k is not None and k < 1) for c, k in stages):
            raise ValueError(f"coarse_stages must be non-empty pairs of positive sizes, got {stages!r}")
        object.__setattr__(self, "coarse_stages", stages)

    @property
    def subsets(self) -> list[int]:
        """Sizes of the vertex subsets (:meth:`ShapeMetric.subset <gromov.shape_metric.ShapeMetric.subset>`)
        this search runs on, so that they can be computed once per shape
        (:func:`search_subsets`)."""
        return search_subsets(self.coarse_stages, self.search_vertices)


# ----------------------------------------------------------------------------- initialisation
def greedy_init(dx_pp: np.ndarray, DY: np.ndarray, candidates: np.ndarray, *,
                stages=((12, None),), n_extend: int = DEFAULT_N_EXTEND,
                domain: np.ndarray | None = None, all_starts: bool = False,
                extend_keep: float = EXTEND_KEEP):
    """Multi-resolution, multi-start initial images (vertex ids on Y) of samples of X.

    Coarse stage: for every candidate image of the first sample, place the first ``c``
    samples greedily, polish them by discrete descent (each image moves to the best vertex of
    Y) and score their distortion. Each of ``stages``, ``(c, vertices)``, is one such coarse
    stage, over the given vertices of Y (an array, e.g. farthest point samples; the
    candidates are added to it) or over all of them (None). The ``n_extend`` extended starts
    are shared out evenly among the stages, each stage's best first: they are extended to all
    samples (greedy placement, then discrete descent over all vertices of Y) and the one with
    the lowest distortion is returned. ``DY`` must be symmetric.

    ``domain``: vertices of Y to which the whole search is restricted (the stages' own
    vertex sets are then ignored); the candidates are added to it. The best start found there
    is then polished by discrete descent over all vertices of Y. The search's cost is
    proportional to the domain's size.

    Returns the images ``(m,)`` of the best start, or with ``all_starts`` a list of
    ``(images, summed squared distortion)`` of every extended start, in the order they were
    extended (without ``domain`` the best is the first of the lowest cost; with it, each
    start is polished on all vertices, and the best is the one chosen on the domain): for
    studies of the selection. ``extend_keep``: see :class:`SearchOptions`.
    """
    search = _Search(dx_pp, DY, candidates, stages, n_extend, domain, extend_keep)
    every, best = search.extend_plain(polish_all=all_starts)
    return every if all_starts else every[best][0]


def _trimmed_descent(dx, DY, img, keep: float, rounds: int, R, C):
    r"""Sample-level least trimmed squares on discrete images: ``(images, summed squared
    distortion)``.

    Each round ranks the samples by their own squared residual
    :math:`\sum_j (d_X(p_i, p_j) - d_Y(q_i, q_j))^2`, descends (discrete Gauss-Seidel over
    all vertices of Y) on the best-fitting ``ceil(keep m)`` samples alone, then places the
    others greedily given them; it stops after ``rounds`` rounds or when nothing moves. A
    change of topology moves whole rows of the distances (a weld changes a nearby point's
    diffusion distance to every point: docs/design/perturbations.md), so the samples near it
    are set aside instead of pulling the others' images.
    """
    m = len(dx)
    h = max(2, int(np.ceil(keep * m - 1e-9)))
    img = np.asarray(img, dtype=np.int64).copy()
    for _ in range(rounds):
        e = dx - DY[np.ix_(img, img)]
        np.fill_diagonal(e, 0.0)
        order = argsort_stable((e**2).sum(axis=1))
        t, u = np.sort(order[:h]), np.sort(order[h:])
        new_t, _ = _kernel.place_and_descend_blas(np.ascontiguousarray(dx[np.ix_(t, t)]), DY, img[t],
                                                  20, R[:h], C[:h])
        perm = np.concatenate([t, u])
        placed, _ = _kernel.place_and_descend_blas(np.ascontiguousarray(dx[np.ix_(perm, perm)]), DY,
                                                   new_t, 0, R, C)
        new = np.empty(m, np.int64)
        new[perm] = placed
        if np.array_equal(new, img):
            break
        img = new
    return img, float(np.sum((dx - DY[np.ix_(img, img)]) ** 2))


class _Search:
    """One direction of :func:`greedy_init`'s search, kept so that more of its coarse starts
    can be extended later (:meth:`extend_preserving`)."""

    def __init__(self, dx_pp, DY, candidates, stages, n_extend, domain, extend_keep=EXTEND_KEEP,
                 signature_costs=None, signature_starts=SIGNATURE_STARTS):
        self.extend_keep = float(extend_keep)
        self.dx_pp = np.ascontiguousarray(dx_pp, dtype=np.float64)
        candidates = np.asarray(candidates, dtype=np.int64)
        self.DY = DY
        restricted = _on_subset(DY, domain, candidates)
        if restricted is not None:  # the whole search on the domain, then polished on all of Y
            self.dom, work, candidates = restricted
            stages = [(c, None) for c, _ in stages]
        else:
            self.dom, work = None, np.ascontiguousarray(DY, dtype=np.float64)
        self.work = work
        # per stage: (cost, images as a tuple of ids of ``work``), from the lowest cost, costs
        # equal within TIE_RTOL in candidate order (a tie that rounding cannot flip)
        self.coarse = []
        # each stage's vertex subset with the candidates, once for both of its runs
        subsets = [_on_subset(work, vertices, candidates) for _, vertices in stages]
        runs = [(c, s, False) for s, (c, _) in enumerate(stages)]
        if signature_costs is not None:  # each stage again, with the signatures' costs
            if self.dom is not None:
                signature_costs = signature_costs[:, self.dom]
            runs += [(c, s, True) for s, (c, _) in enumerate(stages)]
        for c, stage, signed in runs:
            c = min(int(c), len(self.dx_pp))
            head = np.ascontiguousarray(self.dx_pp[:c, :c])
            sub = subsets[stage]
            U, k = None, len(candidates)
            if signed:  # as if each of a sample's c - 1 distances were off by its mismatch
                U, k = (c - 1) * signature_costs[:c], min(k, int(signature_starts))
            if sub is not None:
                dom, part, cand = sub
                imgs, costs = _kernel.coarse_starts(head, part, cand[:k], 20, None if U is None else U[:, dom])
                imgs = dom[imgs]
            else:
                imgs, costs = _kernel.coarse_starts(head, work, candidates[:k], 20, U)
            imgs = imgs.tolist()
            self.coarse.append([(float(costs[k]), tuple(imgs[k])) for k in argsort_stable(costs)])
        self.per_stage = -(-int(n_extend) // len(self.coarse))  # evenly, rounded up
        self.seen: set = set()
        self._R = self._C = self._plain = self._full = None
        self._polished: dict = {}

    def _extend(self, coarse_imgs, polish: bool):
        """Extend coarse starts to all samples on ``work`` (and polish them on all of Y)."""
        n = len(self.dx_pp)
        if self._R is None:
            self._R, self._C = np.empty((n, len(self.work))), np.empty((n, len(self.work)))
        out = [_kernel.place_and_descend_blas(self.dx_pp, self.work, np.asarray(img, dtype=np.int64),
                                              20, self._R, self._C) for img in coarse_imgs]
        if self.extend_keep < 1.0:
            out = [_trimmed_descent(self.dx_pp, self.work, img, self.extend_keep, EXTEND_ROUNDS,
                                    self._R, self._C) for img, _ in out]
        if self.dom is not None and polish:
            out = [self.polish(img) for img, _ in out]
        return out

    def polish(self, img):
        """``(images on Y, cost)``: discrete descent over all of Y from images on ``work``
        (each start once)."""
        key = tuple(np.asarray(img).tolist())
        if key not in self._polished:
            if self._full is None:  # Y and the work arrays of its size, once
                DY = np.ascontiguousarray(self.DY, dtype=np.float64)
                n = len(self.dx_pp)
                self._full = (DY, np.empty((n, len(DY))), np.empty((n, len(DY))))
            DY, R, C = self._full
            # all images given: no placement, discrete descent over every vertex of Y
            self._polished[key] = _kernel.place_and_descend_blas(self.dx_pp, DY, self.dom[img], 20, R, C)
        return self._polished[key]

    def extend_plain(self, polish_all: bool = True):
        """The ``n_extend`` lowest-cost coarse starts (shared out among the stages), extended:
        ``(list of (images on Y, cost), index of the best)``. Without ``polish_all`` (and with a
        domain) only the best is polished on all of Y and the others stay on the domain."""
        if self._plain is None:  # once
            todo = []
            for scored in self.coarse:
                taken = 0
                for _, img in scored:
                    if img in self.seen:
                        continue
                    self.seen.add(img)
                    todo.append(img)
                    taken += 1
                    if taken >= self.per_stage:
                        break
            self._plain = self._extend(todo, polish=False)
        every = self._plain
        costs = [cost for _, cost in every]
        best = argmin_stable(costs)  # the first of the lowest cost (within TIE_RTOL)
        if self.dom is not None:
            every = ([self.polish(img) for img, _ in every] if polish_all else
                     [self.polish(img) if k == best else (self.dom[img], cost)
                      for k, (img, cost) in enumerate(every)])
        return every, best

    def extend_preserving(self, orient, count: int, reversing: bool = False):
        """Up to ``count`` more starts per stage: its lowest-cost coarse starts not extended
        yet whose orientation agreement ``orient(images on Y) > 1/2`` (``< 1/2`` with
        ``reversing``); extended and polished."""
        todo = []
        for scored in self.coarse:
            rest = [img for _, img in scored if img not in self.seen]
            if not rest:
                continue
            ids = np.asarray(rest, dtype=np.int64)
            agree = orient(ids if self.dom is None else self.dom[ids])
            keep = agree < 0.5 if reversing else agree > 0.5
            chosen = [img for img, k in zip(rest, keep) if k][:count]
            self.seen.update(chosen)
            todo += chosen
        return self._extend(todo, polish=True)


def signature_mismatch(sx: "ShapeMetric", sy: "ShapeMetric", A: np.ndarray) -> np.ndarray:
    """``(len(A), n)``: squared mean absolute difference between the signatures
    (:attr:`ShapeMetric.descriptors <gromov.shape_metric.ShapeMetric.descriptors>`) of the vertices
    ``A`` of ``sx`` and of each working vertex of ``sy``, in squared distance units."""
    sb = sy.descriptors
    sa = sx.descriptors[np.asarray(A, dtype=np.int64)]
    delta = np.empty((len(sa), len(sb)))
    for k, row in enumerate(sa):  # one sample at a time: no (len(A), n, 16) temporary
        delta[k] = np.abs(sb - row).mean(axis=1)
    return delta * delta


def search_subsets(coarse_stages=DEFAULT_COARSE_STAGES, search_vertices: int | None = None) -> list[int]:
    """Sizes of the vertex subsets (:meth:`ShapeMetric.subset <gromov.shape_metric.ShapeMetric.subset>`)
    that :func:`gromov.match` searches on with these options, so that they can be computed
    once per shape."""
    if search_vertices is not None:
        return [int(search_vertices)]
    return [int(k) for _, k in coarse_stages if k is not None]


def _on_subset(DY: np.ndarray, vertices, candidates: np.ndarray):
    """``(dom, DY[dom][:, dom], candidates as positions in dom)`` with ``dom`` the given vertices
    and the candidates, sorted; None when ``vertices`` is None or ``dom`` is all of Y."""
    if vertices is None:
        return None
    dom = np.union1d(np.asarray(vertices, dtype=np.int64), candidates)
    if len(dom) >= len(DY):
        return None
    block = _kernel.gather_block(readonly(np.asarray(DY, dtype=np.float64)), dom)
    return dom, block, np.searchsorted(dom, candidates)


def anchored_images(DX: np.ndarray, P: np.ndarray, DY_rows: np.ndarray) -> np.ndarray:
    """Images on X of points whose distances to the images of ``P`` are ``DY_rows`` (K, M).

    Each point goes to the vertex v of X minimising sum_i (D_X(v, p_i) - d_i)^2: the
    reverse map that is consistent with a given forward map, so that the two halves of the
    two-sided correspondence start on the same branch (e.g. the same left/right choice).
    ``DX`` must be symmetric (its rows ``P`` are read for its columns).
    """
    return _anchored(*_anchor_rows(DX, P), DY_rows)


def _anchored(At: np.ndarray, sq: np.ndarray, DY_rows: np.ndarray) -> np.ndarray:
    """:func:`anchored_images` from :func:`_anchor_rows`."""
    cost = sq[None, :] - 2.0 * (DY_rows @ At)  # + |d|^2, constant per row
    return argmin_stable(cost, axis=1)


def _candidates(signature: np.ndarray, target: "ShapeMetric", k: int) -> np.ndarray:
    """The ``k`` vertices of ``target`` with the closest signatures, at least 5% of the diameter apart."""
    cost = np.abs(target.descriptors - signature).sum(axis=1)
    order = argsort_stable(cost)
    # greedily in that order, each farther than the radius from those chosen before it
    return _kernel.spaced_in_order(order, readonly(target.distances), 0.05 * target.diameter, int(k))


def initial_pairs(sx: "ShapeMetric", sy: "ShapeMetric", P: np.ndarray, Q: np.ndarray, *,
                  n_starts: int = DEFAULT_N_STARTS, n_extend: int = DEFAULT_N_EXTEND,
                  coarse_stages=DEFAULT_COARSE_STAGES, search_vertices: int | None = DEFAULT_SEARCH_VERTICES,
                  all_starts: bool = False, extend_keep: float = EXTEND_KEEP,
                  signature_weight: float = SIGNATURE_WEIGHT) -> list[tuple[np.ndarray, np.ndarray]]:
    """The two-sided starts of :func:`gromov.match`'s GMDS: pairs ``(images of P on Y, images of Q on X)``
    (working vertex ids).

    :func:`greedy_init` from X to Y, with the images of ``Q`` anchored on it
    (:func:`anchored_images`), then the same from Y to X: two pairs, or with ``all_starts`` one
    per extended start of each direction (``n_extend`` forward ones first). The options are
    those of :class:`SearchOptions`.
    """
    options = SearchOptions(n_starts=n_starts, n_extend=n_extend, coarse_stages=coarse_stages,
                            search_vertices=search_vertices, extend_keep=extend_keep,
                            signature_weight=signature_weight)
    return _Starts(sx, sy, P, Q, options).plain(all_starts)


class _Starts:
    """Both directions of :func:`initial_pairs`' search, kept for more starts later."""

    def __init__(self, sx, sy, P, Q, options: SearchOptions):
        n_starts, n_extend, coarse_stages = options.n_starts, options.n_extend, options.coarse_stages
        search_vertices, extend_keep = options.search_vertices, options.extend_keep
        signature_weight = options.signature_weight
        self.sx, self.sy, self.P, self.Q = sx, sy, P, Q
        DX, DY = sx.distances, sy.distances
        self.dx_pp, self.dy_qq = DX[np.ix_(P, P)], DY[np.ix_(Q, Q)]
        cand_y = _candidates(sx.descriptors[P[0]], sy, n_starts)
        cand_x = _candidates(sy.descriptors[Q[0]], sx, n_starts)

        def search(s):  # (stages, domain): the vertex subsets of the initial search on s
            if search_vertices is not None:  # one subset for the whole search
                return [(c, None) for c, _ in coarse_stages], s.subset(search_vertices)
            return [(c, None if k is None else s.subset(k)) for c, k in coarse_stages], None

        (st_y, dom_y), (st_x, dom_x) = search(sy), search(sx)
        sig_y = sig_x = None
        if signature_weight > 0:  # per image of the first samples, on all vertices of the target
            c = max(c for c, _ in coarse_stages)
            sig_y = signature_weight * signature_mismatch(sx, sy, P[:c])
            sig_x = signature_weight * signature_mismatch(sy, sx, Q[:c])
        self.fwd = _Search(self.dx_pp, DY, cand_y, st_y, n_extend, dom_y, extend_keep, sig_y)
        self.bwd = _Search(self.dy_qq, DX, cand_x, st_x, n_extend, dom_x, extend_keep, sig_x)

    def _pairs(self, fwd, bwd):
        DX, DY, P, Q = self.sx.distances, self.sy.distances, self.P, self.Q
        ax, ay = self.sx._anchors(P), self.sy._anchors(Q)   # per shape, for its samples
        return ([(f, _anchored(*ax, DY[np.ix_(Q, f)])) for f in fwd]
                + [(_anchored(*ay, DX[np.ix_(P, b)]), b) for b in bwd])

    def plain(self, all_starts: bool):
        """Pairs of the extended starts: all of them, or each direction's best."""
        fwd, bf = self.fwd.extend_plain(polish_all=all_starts)
        bwd, bb = self.bwd.extend_plain(polish_all=all_starts)
        if not all_starts:
            return self._pairs([fwd[bf][0]], [bwd[bb][0]])
        return self._pairs([i for i, _ in fwd], [i for i, _ in bwd])

    def preserving(self, count: int, reversing: bool = False):
        """Pairs of up to ``count`` more orientation-preserving (or reversing) starts per
        stage and direction."""
        fwd = self.fwd.extend_preserving(_orient(self.sx, self.sy, self.P, self.dx_pp), count, reversing)
        bwd = self.bwd.extend_preserving(_orient(self.sy, self.sx, self.Q, self.dy_qq), count, reversing)
        return self._pairs([i for i, _ in fwd], [i for i, _ in bwd])


def _self_reflection(s: "ShapeMetric", n_samples: int, seed: int) -> np.ndarray | None:
    """:meth:`ShapeMetric.symmetry <gromov.shape_metric.ShapeMetric.symmetry>`: the search from the shape
    to itself among orientation-reversing starts, then GMDS and the involution repairs."""
    if not s.normals[1] or n_samples > s.mesh.n_vertices:
        return None
    P = s.samples(n_samples, seed)
    # a shape against itself has no change of topology to set aside: the plain extension (with
    # the trimmed one the wolf's reflection sent 31% of its vertices astray, not 1.3%), and no
    # signature-guided stages (with them the wolf's reflection again sent 31% of its vertices
    # astray)
    search = _Starts(s, s, P, P, SearchOptions(extend_keep=1.0, signature_weight=0.0))
    pairs = search.plain(all_starts=True) + search.preserving(-(-search.fwd.per_stage // 2) * 2,
                                                                 reversing=True)
    at = [_at_vertices(s, s, a, b) for a, b in pairs]
    flips = pairs_orientation(s, s, P, P, at) < 0.5
    if not flips.any():
        return None
    gm = SymmetricGMDS(s.surface, s.surface, P, P)
    scores = np.array([gm.distortion(a, b, 2.0) for a, b in at])
    img_p, img_q, _, _ = gm.solve(*at[int(np.flatnonzero(flips)[argmin_stable(scores[flips])])])
    D = s.distances
    for _ in range(INVOLUTION_REPAIRS):
        # a reflection is its own inverse: both halves of the self-map must agree. Where
        # they do not (on a quadruped: a leg sent to another leg, a map of lower distortion
        # than the reflection in the diffusion metric), re-anchor those samples on the
        # agreeing ones and descend again from the one-map start
        f, g = img_p.vertex(s.mesh.faces), img_q.vertex(s.mesh.faces)
        ok = D[f, g] < INVOLUTION_TOL * s.diameter
        if ok.all() or ok.sum() < 3:
            break
        f[~ok] = anchored_images(D, f[ok], D[np.ix_(P[~ok], P[ok])])
        img_p, img_q, _, _ = gm.solve(*_at_vertices(s, s, f, f))
    if not (pair_orientation(s, s, P, P, img_p, img_q) < 0.5
            and gm.distortion(img_p, img_q, 2.0) < SYMMETRY_TOL * s.diameter):
        return None
    images = img_p.vertex(s.mesh.faces)
    return anchored_images(D, images, D[:, P])


def _at_vertices(sx, sy, img_p, img_q) -> tuple[SurfacePoints, SurfacePoints]:
    """Vertex images ``(of P on Y, of Q on X)`` as surface points."""
    return SurfacePoints.at_vertices(sy.mesh, img_p), SurfacePoints.at_vertices(sx.mesh, img_q)


def _orient(sa: "ShapeMetric", sb: "ShapeMetric", A: np.ndarray, da: np.ndarray):
    """The orientation agreement of vertex images ``(s, c)`` on ``sb`` of the first ``c`` of
    the samples ``A`` of ``sa`` (``da`` their distances)."""
    (na, _), (nb, _) = sa.normals, sb.normals
    xa, xb = sa.mesh.vertices, sb.mesh.vertices

    def agreement(imgs: np.ndarray) -> np.ndarray:
        imgs = np.asarray(imgs, dtype=np.int64)
        c = imgs.shape[1]
        head = A[:c]
        return orientation_agreements(xa[head], na[head], da[:c, :c], xb[imgs], nb[imgs])

    return agreement


def pair_orientation(sx: "ShapeMetric", sy: "ShapeMetric", P: np.ndarray, Q: np.ndarray,
                     img_p: SurfacePoints, img_q: SurfacePoints) -> float:
    """Orientation agreement of a two-sided correspondence (the mean of its two directions;
    :func:`gromov.orientation.orientation_agreement`); NaN unless both working meshes are
    orientable."""
    return float(pairs_orientation(sx, sy, P, Q, [(img_p, img_q)])[0])


def pairs_orientation(sx: "ShapeMetric", sy: "ShapeMetric", P: np.ndarray, Q: np.ndarray,
                      pairs: list) -> np.ndarray:
    """:func:`pair_orientation` of several correspondences ``(img_p, img_q)`` of the same
    samples at once (the samples' neighbour triangles are found once)."""
    (nx, okx), (ny, oky) = sx.normals, sy.normals
    if not (okx and oky):
        return np.full(len(pairs), np.nan)
    out = []
    for side, (sa, sb, A, nb) in enumerate(((sx, sy, P, ny), (sy, sx, Q, nx))):
        imgs = [pair[side] for pair in pairs]
        pos = np.stack([img.positions(sb.mesh.vertices, sb.mesh.faces) for img in imgs])
        nrm = np.stack([np.einsum("kc,kcd->kd", img.bary, nb[sb.mesh.faces[img.face]]) for img in imgs])
        out.append(orientation_agreements(sa.mesh.vertices[A], sa.normals[0][A], sa.distances[np.ix_(A, A)],
                                          pos, nrm))
    return 0.5 * (out[0] + out[1])

