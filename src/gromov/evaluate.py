"""Correspondence quality against ground truth, aware of intrinsic symmetries.

Bodies have a left/right intrinsic symmetry: the Gromov-Hausdorff distance has two
near-equal minima, the true map and its mirror. Both are fine for the distance; for
correspondence, :func:`correspondence_error` measures both readings and says which branch
the match found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gh import MatchResult, ShapeMetric

__all__ = ["CorrespondenceError", "correspondence_error", "image_errors"]


@dataclass(frozen=True, eq=False)
class CorrespondenceError:
    """Errors of the images of X's samples on Y, divided by Y's diameter in the error metric.

    Attributes
    ----------
    errors : ndarray (M,)
        Per sample, distance between the image and the ground-truth image.
    mean : float
    mirrored_errors : ndarray (M,) or None
        The same against the mirrored ground truth (when a symmetry is given).
    mirrored_mean : float or None
    branch : str
        ``"direct"`` or ``"mirrored"``: which reading fits the match better
        (``"direct"`` when no symmetry is given).
    """

    errors: np.ndarray
    mean: float
    mirrored_errors: np.ndarray | None
    mirrored_mean: float | None
    branch: str

    @property
    def best(self) -> float:
        """The mean error of the better branch."""
        return self.mean if self.mirrored_mean is None else min(self.mean, self.mirrored_mean)


def image_errors(samples, images, target: ShapeMetric, truth=None, *, name: str = "") -> np.ndarray:
    """Distance in ``target``'s metric from each image to its ground-truth image, / diameter.

    ``samples`` are input ids of the source shape, ``images`` input ids of ``target``;
    ``truth[i]`` is the target input vertex matching source input vertex ``i`` (default: the
    identity). Distances are taken between the nearest working vertices.
    """
    prefix = f"{name}: " if name else ""
    src = np.asarray(samples, dtype=np.int64)
    img = np.asarray(images, dtype=np.int64)
    if src.ndim != 1 or img.shape != src.shape:
        raise ValueError(f"{prefix}samples and images must be 1-D of equal length, "
                         f"got shapes {src.shape} and {img.shape}")
    if truth is None:
        gt = src
    else:
        truth = np.asarray(truth, dtype=np.int64)
        if src.size and (src.min() < 0 or src.max() >= len(truth)):
            raise ValueError(f"{prefix}ground truth has {len(truth)} entries, "
                             f"but a sample has input id {int(src.max())}")
        gt = truth[src]

    def near(ids):
        return target.working.from_source(target.input.from_input_ids(ids))

    return target.distances[near(img), near(gt)] / target.diameter


def correspondence_error(result: MatchResult, y: ShapeMetric, truth=None,
                         symmetry=None) -> CorrespondenceError:
    """Error of ``result``'s X -> Y images against a ground-truth map.

    Parameters
    ----------
    result : MatchResult
    y : ShapeMetric
        Y with the metric in which errors are measured (usually geodesic); distances are taken
        between the working vertices nearest to the image and to the ground-truth vertex.
    truth : array_like of int, optional
        ``truth[i]`` is the input vertex of Y matching input vertex ``i`` of X. Default: the
        identity (same vertex numbering, as within a TOSCA class).
    symmetry : array_like of int, optional
        ``symmetry[j]`` is the mirror of Y's input vertex ``j`` (0-based; e.g. from TOPKIDS
        ``*_sym.txt`` or a reflection of a symmetric reference pose).

    Returns
    -------
    CorrespondenceError
    """
    e = image_errors(result.x_samples, result.x_to_y_vertex, y, truth)
    if symmetry is None:
        return CorrespondenceError(e, float(e.mean()), None, None, "direct")
    symmetry = np.asarray(symmetry, dtype=np.int64)
    mirrored_truth = symmetry if truth is None else symmetry[np.asarray(truth, dtype=np.int64)]
    em = image_errors(result.x_samples, result.x_to_y_vertex, y, mirrored_truth)
    branch = "direct" if e.mean() <= em.mean() else "mirrored"
    return CorrespondenceError(e, float(e.mean()), em, float(em.mean()), branch)
