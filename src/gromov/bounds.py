r"""A certified interval for the Gromov-Hausdorff distance between two finite metric spaces.

For finite metric spaces :math:`(P, d_X)` and :math:`(Q, d_Y)` (the farthest point samples of
two shapes with their intrinsic distances),

.. math:: d_{GH}(P, Q) = \tfrac12 \inf_R \operatorname{dis} R, \qquad
          \operatorname{dis} R = \max_{(a, b), (a', b') \in R} |d_X(a, a') - d_Y(b, b')|,

over the correspondences :math:`R \subset P \times Q` (Burago, Burago & Ivanov, *A Course in
Metric Geometry*, 2001, Thm. 7.3.25).

**Upper bound.** Any correspondence R gives :math:`d_{GH} \le \tfrac12 \operatorname{dis} R`;
:func:`sample_gh_interval` takes the one a match found, snapped to the samples.

**Lower bound.** For :math:`(a, b) \in R` every distance from a is within
:math:`\operatorname{dis} R` of some distance from b and vice versa, so the Hausdorff distance
on the real line between the sets :math:`d_X(a, P)` and :math:`d_Y(b, Q)` is at most
:math:`\operatorname{dis} R`. Since R pairs every point of each space,

.. math:: d_{GH}(P, Q) \ge \tfrac12 \max\Big(\max_{a} \min_{b} h(a, b),\ \max_{b} \min_{a} h(a, b)\Big),
          \qquad h(a, b) = d_H\big(d_X(a, P),\ d_Y(b, Q)\big),

the bound of the local distance sets (Mémoli, *Gromov-Wasserstein distances and the metric
approach to object matching*, Found. Comput. Math. 11, 2011, §6, the Hausdorff form of its
third lower bound). It implies the eccentricity bound (:math:`|\max A - \max B| \le d_H(A, B)`)
and :math:`\tfrac12 |\operatorname{diam} P - \operatorname{diam} Q|`. It needs no
correspondence: it holds whatever the search found.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["local_hausdorff", "gh_lower_bound", "correspondence_distortion", "sample_gh_interval"]

#: The lower bound is shrunk by this relative amount, so that rounding in the subtractions
#: cannot lift it above the exact value.
ROUNDING = 1e-12


@njit(cache=True, nogil=True)
def _directed(a, b):  # pragma: no cover - compiled
    """:math:`\\max_{x \\in a} \\min_{y \\in b} |x - y|` of sorted 1-D arrays, by one merge:
    each value's nearest in ``b`` is its predecessor or successor there."""
    h = 0.0
    q = 0
    for p in range(a.shape[0]):
        while q + 1 < b.shape[0] and b[q + 1] <= a[p]:
            q += 1
        d = abs(a[p] - b[q])
        if q + 1 < b.shape[0]:
            d = min(d, abs(b[q + 1] - a[p]))
        h = max(h, d)
    return h


@njit(cache=True, nogil=True)
def _hausdorff_rows(A, B, out):  # pragma: no cover - compiled
    """``out[i, j]``: the Hausdorff distance between the sorted rows ``A[i]`` and ``B[j]``."""
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            out[i, j] = max(_directed(A[i], B[j]), _directed(B[j], A[i]))


def local_hausdorff(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """``(m, n)``: the Hausdorff distance between the sets of distances from each point of P
    (rows of ``dx``) and from each point of Q (rows of ``dy``), :math:`h(a, b)`."""
    A = np.sort(np.asarray(dx, dtype=np.float64), axis=1)
    B = np.sort(np.asarray(dy, dtype=np.float64), axis=1)
    out = np.empty((len(A), len(B)))
    _hausdorff_rows(A, B, out)
    return out


def gh_lower_bound(dx: np.ndarray, dy: np.ndarray) -> float:
    r"""A lower bound of :math:`d_{GH}` between the finite metric spaces of the distance
    matrices ``dx (m, m)`` and ``dy (n, n)``: :math:`\tfrac12 \max(\max_a \min_b h,
    \max_b \min_a h)` (module docstring)."""
    h = local_hausdorff(dx, dy)
    value = 0.5 * max(h.min(axis=1).max(), h.min(axis=0).max())
    return float(value * (1.0 - ROUNDING))


def correspondence_distortion(dx: np.ndarray, dy: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    r""":math:`\operatorname{dis} R` of the correspondence :math:`R = \{(a_k, b_k)\}` (indices
    into ``dx`` and ``dy``)."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    return float(np.abs(dx[np.ix_(a, a)] - dy[np.ix_(b, b)]).max())


def sample_gh_interval(dx: np.ndarray, dy: np.ndarray, p_to_q: np.ndarray, q_to_p: np.ndarray) -> tuple[float, float]:
    r"""``(lower, upper)`` around :math:`d_{GH}(P, Q)`, certified.

    Parameters
    ----------
    dx : ndarray (m, m)
        Distances between the samples P of X.
    dy : ndarray (n, n)
        Distances between the samples Q of Y.
    p_to_q : ndarray (m,) of int
        A sample of Q for each sample of P (e.g. the one nearest to its image).
    q_to_p : ndarray (n,) of int
        A sample of P for each sample of Q.

    Returns
    -------
    (float, float)
        :func:`gh_lower_bound` and half the distortion of the correspondence
        :math:`\{(p, p\_to\_q[p])\} \cup \{(q\_to\_p[q], q)\}`.
    """
    dx = np.asarray(dx, dtype=np.float64)
    dy = np.asarray(dy, dtype=np.float64)
    m, n = len(dx), len(dy)
    p_to_q = np.asarray(p_to_q, dtype=np.int64)
    q_to_p = np.asarray(q_to_p, dtype=np.int64)
    if p_to_q.shape != (m,) or q_to_p.shape != (n,):
        raise ValueError(f"p_to_q must be ({m},) and q_to_p ({n},), got {p_to_q.shape} and {q_to_p.shape}")
    a = np.concatenate([np.arange(m), q_to_p])
    b = np.concatenate([p_to_q, np.arange(n)])
    upper = 0.5 * correspondence_distortion(dx, dy, a, b)
    return gh_lower_bound(dx, dy), upper
