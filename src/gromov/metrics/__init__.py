"""Intrinsic (geodesic, diffusion) and extrinsic (euclidean) metrics behind one interface.

>>> from gromov.shapes import icosphere
>>> from gromov.metrics import metric_solver
>>> s = metric_solver(icosphere(3), "diffusion")       # per-shape work done once
>>> s.from_sources([0, 5]).shape, s.pairwise().shape
((2, 642), (642, 642))
"""

from __future__ import annotations

from ._base import MetricSolver, check_sources
from .diffusion import (
    DIFFUSION_KERNELS,
    GraphDiffusionSolver,
    HeatDiffusionSolver,
    BiharmonicSolver,
    affinity,
    brute_force_diffusion_distance,
    cotan_laplacian,
    diffusion_operator,
)
from .euclidean import EuclideanSolver
from .geodesic import GEODESIC_METHODS, GeodesicSolver

__all__ = [
    "METRICS", "MetricSolver", "metric_solver", "distance_matrix", "check_sources",
    "GeodesicSolver", "GraphDiffusionSolver", "HeatDiffusionSolver", "BiharmonicSolver", "EuclideanSolver",
    "GEODESIC_METHODS", "DIFFUSION_KERNELS", "affinity", "diffusion_operator",
    "brute_force_diffusion_distance", "cotan_laplacian",
]

METRICS = ("geodesic", "diffusion", "euclidean")


def metric_solver(shape, metric: str = "diffusion", **options) -> MetricSolver:
    """Build the solver of ``metric`` on ``shape`` (a Mesh or PointCloud).

    Parameters
    ----------
    shape : Mesh or PointCloud
    metric : {"geodesic", "diffusion", "euclidean"}
    **options
        Passed to the solver. ``geodesic``: ``method`` ("fmm", "heat", "exact",
        "dijkstra"), ``k``. ``diffusion``: ``kernel`` ("connectivity" -- the paper's --,
        "gaussian", "heat" for the resolution-independent Laplace-Beltrami heat kernel, or
        "biharmonic" for the heat-kernel distance integrated over all times),
        then ``m``, ``density_normalize``, ``sigma``, ``k`` (graph kernels) or ``tau``,
        ``laplacian`` (heat kernel), and ``rtol``.

    Returns
    -------
    MetricSolver
    """
    if metric == "geodesic":
        return GeodesicSolver(shape, **options)
    if metric == "diffusion":
        kernel = options.pop("kernel", "heat")
        if kernel == "heat":
            return HeatDiffusionSolver(shape, **options)
        if kernel == "biharmonic":
            return BiharmonicSolver(shape, **options)
        if kernel not in DIFFUSION_KERNELS:
            raise ValueError(f"diffusion kernel must be one of {DIFFUSION_KERNELS}, got {kernel!r}")
        return GraphDiffusionSolver(shape, kernel=kernel, **options)
    if metric == "euclidean":
        if options:
            raise TypeError(f"the euclidean metric takes no options, got {sorted(options)}")
        return EuclideanSolver(shape)
    raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")


def distance_matrix(shape, metric: str = "diffusion", **options):
    """Dense ``(n, n)`` distance matrix of ``metric`` on all vertices of ``shape``."""
    return metric_solver(shape, metric, **options).pairwise()
