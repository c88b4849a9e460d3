r"""Correspondence quality against ground truth: the measures of Bronstein et al. (IJCV 2010, §5).

:func:`correspondence_distortion` is the paper's :math:`d(C, C_0)`: the distance, in each
shape's own metric, between every computed image and its ground-truth image, averaged over
samples, divided by that shape's diameter, and averaged over the two directions.
:func:`error_curve` is the standard cumulative geodesic error curve of Kim, Lipman &
Funkhouser (SIGGRAPH 2011).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..evaluate import image_errors
from ..match_result import MatchResult
from ..shape_metric import ShapeMetric

__all__ = ["CorrespondenceQuality", "correspondence_distortion", "error_curve"]


@dataclass(frozen=True, eq=False)
class CorrespondenceQuality:
    r"""The paper's :math:`d(C, C_0)` and its two directions.

    Attributes
    ----------
    value : float
        :math:`d(C, C_0) = \tfrac12` (``x_to_y`` + ``y_to_x``).
    x_to_y : float
        Mean of ``errors_x_to_y``.
    y_to_x : float
        Mean of ``errors_y_to_x``.
    errors_x_to_y : ndarray (M,)
        Per sample of X, :math:`d_Y(c(x_i), c_0(x_i)) / \mathrm{diam}\, Y`.
    errors_y_to_x : ndarray (K,)
        Per sample of Y, :math:`d_X(c(y_j), c_0(y_j)) / \mathrm{diam}\, X`.
    """

    value: float
    x_to_y: float
    y_to_x: float
    errors_x_to_y: np.ndarray
    errors_y_to_x: np.ndarray


def _truth(truth, name: str) -> np.ndarray | None:
    if truth is None:
        return None
    t = np.asarray(truth)
    if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"{name} must be a 1-D integer array, got dtype {t.dtype} and shape {t.shape}")
    return t.astype(np.int64)


def correspondence_distortion(result: MatchResult, x: ShapeMetric, y: ShapeMetric,
                              truth_xy=None, truth_yx=None) -> CorrespondenceQuality:
    r"""Distance :math:`d(C, C_0)` between a computed and the ground-truth correspondence.

    .. math::

        d(C, C_0) = \frac12 \left( \frac{1}{M \, \mathrm{diam}\,Y} \sum_i d_Y(c(x_i), c_0(x_i))
                  + \frac{1}{K \, \mathrm{diam}\,X} \sum_j d_X(c(y_j), c_0(y_j)) \right)

    (Bronstein et al., IJCV 2010, §5). Distances are taken in each :class:`ShapeMetric`'s own
    metric between the working vertices nearest to the computed and to the ground-truth image;
    diameters are in that metric too.

    Parameters
    ----------
    result : MatchResult
        Uses ``x_samples``, ``x_to_y_vertex``, ``y_samples``, ``y_to_x_vertex`` (input ids).
    x, y : ShapeMetric
        The two shapes with the metric in which errors are measured.
    truth_xy : array_like of int, optional
        ``truth_xy[i]`` is the input vertex of Y matching input vertex ``i`` of X.
        Default: the identity (same vertex numbering).
    truth_yx : array_like of int, optional
        ``truth_yx[j]`` is the input vertex of X matching input vertex ``j`` of Y.
        Default: the identity.

    Returns
    -------
    CorrespondenceQuality
    """
    if not isinstance(x, ShapeMetric) or not isinstance(y, ShapeMetric):
        raise TypeError(f"x and y must be ShapeMetric, got {type(x).__name__} and {type(y).__name__}")
    txy, tyx = _truth(truth_xy, "truth_xy"), _truth(truth_yx, "truth_yx")
    exy = image_errors(result.x_samples, result.x_to_y_vertex, y, txy, name="X -> Y")
    eyx = image_errors(result.y_samples, result.y_to_x_vertex, x, tyx, name="Y -> X")
    if exy.size == 0 or eyx.size == 0:
        raise ValueError(f"result has no samples in one direction ({exy.size} X -> Y, {eyx.size} Y -> X)")
    mxy, myx = float(exy.mean()), float(eyx.mean())
    return CorrespondenceQuality(0.5 * (mxy + myx), mxy, myx, exy, eyx)


def error_curve(errors, area, thresholds=None) -> tuple[np.ndarray, np.ndarray]:
    r"""Cumulative geodesic error curve (Kim, Lipman & Funkhouser, SIGGRAPH 2011).

    The fraction of points whose geodesic error is at most :math:`e \sqrt{A}` for each
    threshold :math:`e`, where :math:`A` is the surface area of the target shape.

    Parameters
    ----------
    errors : array_like (N,)
        Absolute (not normalised) geodesic errors, finite and non-negative.
    area : float
        Surface area of the shape the errors are measured on; positive.
    thresholds : array_like (T,), optional
        Normalised error thresholds, non-negative. Default ``np.linspace(0, 0.25, 51)``.

    Returns
    -------
    thresholds : ndarray (T,)
    fraction : ndarray (T,)
        ``fraction[t] = mean(errors <= thresholds[t] * sqrt(area))``.
    """
    e = np.asarray(errors, dtype=np.float64)
    if e.ndim != 1 or e.size == 0:
        raise ValueError(f"errors must be a non-empty 1-D array, got shape {e.shape}")
    if not np.all(np.isfinite(e)) or (e < 0).any():
        raise ValueError(f"errors must be finite and non-negative, got min {np.nanmin(e)!r}"
                         f" and {int((~np.isfinite(e)).sum())} non-finite values")
    a = float(area)
    if not np.isfinite(a) or a <= 0:
        raise ValueError(f"area must be positive and finite, got {area!r}")
    t = np.linspace(0.0, 0.25, 51) if thresholds is None else np.asarray(thresholds, dtype=np.float64)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) or (t < 0).any():
        raise ValueError(f"thresholds must be a non-empty 1-D array of finite non-negative values, "
                         f"got {t!r}")
    scale = np.sqrt(a)
    fraction = (e[None, :] <= t[:, None] * scale).mean(axis=1)
    return t, fraction
