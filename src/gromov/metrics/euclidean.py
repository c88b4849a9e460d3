"""Euclidean (extrinsic) distance: the baseline of the paper's §2.3, not bending-invariant."""

from __future__ import annotations

from scipy.spatial.distance import cdist

from ._base import MetricSolver, check_shape

__all__ = ["EuclideanSolver"]


class EuclideanSolver(MetricSolver):
    """Straight-line distance ``|x - y|`` in R^3 between vertices (extrinsic).

    Parameters
    ----------
    shape : Mesh or PointCloud
    """

    name = "euclidean"
    symmetric_rows = True

    def __init__(self, shape):
        super().__init__(check_shape(shape, metric="euclidean"))

    def _rows(self, sources):
        v = self.shape.vertices
        return cdist(v[sources], v)
