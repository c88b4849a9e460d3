"""Array helpers: read-only views for the compiled kernels, and discrete choices that ties
in floating point cannot flip."""

from __future__ import annotations

import numpy as np


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (``a`` itself when it is read-only already).

    Numba compiles a kernel once per argument type, and the writeable flag is part of an
    array's type: handing a kernel the same arrays always read-only keeps it to one
    compilation (a first ``gromov.match`` compiled the coarse search twice, once for a
    shape's read-only distance matrix and once for a writable slice of it).
    """
    if not a.flags.writeable:
        return a
    v = a.view()
    v.flags.writeable = False
    return v


#: Relative tolerance under which two scores of a discrete choice count as tied: scores within
#: ``TIE_RTOL`` times the largest magnitude among them are equal, and the lowest index wins.
#: Summing the same n terms in another order (another CPU's BLAS kernel, vector width or fused
#: multiply-add) changes a sum by at most about n * 1.1e-16 of the sum of the magnitudes
#: (3.3e-13 for n = 3,000 vertices), so a tie in exact arithmetic stays a tie on every
#: machine. On three TOSCA pairs, 2 of the search's 3,009 minima had a runner-up within it,
#: and no distance or map changed (docs/design/reproduction.md, "What is reproducible").
TIE_RTOL = 1e-9


def _tie_tolerance(w: np.ndarray, rtol: float) -> np.ndarray:
    """``rtol`` times the largest finite magnitude along the last axis (0 where none)."""
    return rtol * np.max(np.abs(w), axis=-1, where=np.isfinite(w), initial=0.0, keepdims=True)


def argmin_stable(values, rtol: float = TIE_RTOL, *, axis: int | None = None):
    r"""Index of the minimum, near-ties broken by the lowest index.

    Among the entries within ``rtol`` times the largest finite magnitude of the minimum,
    :math:`v_i \le \min v + \mathrm{rtol}\,\max_j |v_j|`, the first. With ``rtol=0`` it is
    ``np.argmin``. NaN counts as :math:`+\infty`.

    Parameters
    ----------
    values : array_like
        Scores, lower is better.
    rtol : float, default TIE_RTOL (1e-9)
        Relative tolerance of a tie (:data:`TIE_RTOL`).
    axis : int, optional
        Along this axis, each slice with its own scale (like ``np.argmin``); None: over the
        flattened array.

    Returns
    -------
    int or ndarray of int64

    Examples
    --------
    >>> argmin_stable([3.0, 1.0 + 1e-12, 1.0])
    1
    >>> argmin_stable([3.0, 1.0 + 1e-6, 1.0])
    2
    """
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0:
        raise ValueError("argmin_stable of an empty array")
    w = np.moveaxis(a, axis, -1) if axis is not None else a.reshape(-1)
    lo, hi = w.min(axis=-1, keepdims=True), w.max(axis=-1, keepdims=True)
    if np.isfinite(lo).all() and np.isfinite(hi).all():   # the usual case: two reductions
        tol = rtol * np.maximum(np.abs(lo), np.abs(hi))
    else:
        w = np.where(np.isnan(w), np.inf, w)
        lo, tol = w.min(axis=-1, keepdims=True), _tie_tolerance(w, rtol)
    near = w <= lo + tol
    first = np.argmax(near, axis=-1)
    return int(first) if axis is None else first.astype(np.int64)


def argsort_stable(values, rtol: float = TIE_RTOL) -> np.ndarray:
    r"""Order of ``values`` (1-D) from the lowest, near-ties by index.

    Sorted values whose successive gaps are at most ``rtol`` times the largest finite
    magnitude form a group of ties, kept in index order; groups follow each other by value.
    Without near-ties it is ``np.argsort(values, kind="stable")``. NaN counts as
    :math:`+\infty`.

    Examples
    --------
    >>> argsort_stable([2.0, 1.0 + 1e-12, 1.0, 0.5]).tolist()
    [3, 1, 2, 0]
    """
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"argsort_stable sorts a 1-D array, got shape {a.shape}")
    if a.size == 0:
        return np.zeros(0, dtype=np.int64)
    w = np.where(np.isnan(a), np.inf, a)
    order = np.argsort(w, kind="stable")
    s = w[order]
    with np.errstate(invalid="ignore"):   # inf - inf: NaN, no new group among infinite values
        new = np.diff(s) > _tie_tolerance(w, rtol)[0]
    group = np.concatenate([[0], np.cumsum(new)])
    return order[np.lexsort((order, group))]


_BLAS = None


def one_blas_thread():
    """A context in which BLAS runs on one thread (threadpoolctl).

    The search and GMDS call BLAS on small blocks (rank-32 updates of a 100 x n matrix), where
    handing each call to a second thread costs more than it gains, and much more when the
    other core is busy; on one thread the products also sum in one order, whatever the
    machine's BLAS threads.
    """
    global _BLAS
    if _BLAS is None:
        import scipy.linalg  # noqa: F401  (its BLAS loaded before the libraries are listed)
        from threadpoolctl import ThreadpoolController

        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")
