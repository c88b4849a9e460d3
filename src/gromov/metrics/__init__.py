"""Intrinsic (geodesic, diffusion) and extrinsic (euclidean) metrics behind one interface.

>>> from gromov.shapes import icosphere
>>> from gromov.metrics import metric_solver
>>> s = metric_solver(icosphere(3), "diffusion")       # per-shape work done once
>>> s.from_sources([0, 5]).shape, s.pairwise().shape
((2, 642), (642, 642))
"""

from __future__ import annotations

import inspect
import numbers

import numpy as np

from ..mesh import Mesh, component_areas, fill_holes
from ._base import MetricSolver, RestrictedSolver, check_sources
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
from ._fmm import subdivide
from .geodesic import GEODESIC_METHODS, GeodesicSolver

__all__ = [
    "METRICS", "MetricSolver", "RestrictedSolver", "metric_solver", "DIFFUSION_FILL_HOLES",
    "distance_matrix", "check_sources",
    "GeodesicSolver", "GraphDiffusionSolver", "HeatDiffusionSolver", "BiharmonicSolver", "EuclideanSolver",
    "GEODESIC_METHODS", "DIFFUSION_KERNELS", "affinity", "diffusion_operator",
    "brute_force_diffusion_distance", "cotan_laplacian", "subdivide",
]

METRICS = ("geodesic", "diffusion", "euclidean")

#: Default ``fill_holes`` of the diffusion metric: boundary loops shorter than this times
#: the square root of the mesh's area are closed before the metric is computed.
from .._defaults import DIFFUSION_FILL_HOLES  # noqa: E402


def metric_solver(shape, metric: str = "diffusion", **options) -> MetricSolver:
    """Build the solver of ``metric`` on ``shape`` (a Mesh or PointCloud).

    Parameters
    ----------
    shape : Mesh or PointCloud
    metric : {"diffusion", "geodesic", "euclidean"}, default "diffusion"
    **options
        Passed to the solver. ``geodesic``: ``method`` ("fmm", "heat", "exact",
        "dijkstra"), ``k``, ``refine`` (fast marching on a subdivided copy, more accurate). ``diffusion``: ``kernel`` ("connectivity" -- the paper's --,
        "gaussian", "heat" for the resolution-independent Laplace-Beltrami heat kernel, or
        "biharmonic" for the heat-kernel distance integrated over all times),
        then ``m``, ``density_normalize``, ``sigma``, ``k`` (graph kernels) or ``tau``,
        ``laplacian``, ``units`` (heat kernel), and ``rtol``.
        Every metric on a mesh also takes ``fill_holes`` (float or None): boundary loops
        shorter than ``fill_holes * sqrt(A)``, ``A`` the area of the connected component that
        the loop bounds (:func:`gromov.mesh.component_areas`), are closed by a fan of triangles
        (:func:`gromov.mesh.fill_holes`) and the metric is computed on the closed surface,
        reported on the original vertices (:class:`RestrictedSolver`). Default
        :data:`DIFFUSION_FILL_HOLES` (0.5) for ``diffusion``, None (off) for the others.
        Small holes are insulating boundaries for heat: they raise every diffusion distance
        from near them, and the matcher then prefers wrong maps. On held-out TOSCA classes
        (horse, centaur, wolf, michael; ``benchmarks/bench_heldout.py``) filling took the
        heat-kernel metric's ground-truth distortion with 10 / 20 holes from 0.042 / 0.063
        to 0.012 / 0.012 (clean shapes: 0.010) and the matches' d(C, C0) from 0.078 / 0.159
        to 0.048 / 0.041; loops of 0.5 sqrt(area) or longer (open ends of a
        scan, partial shapes) stay open. The geodesic metric barely notices small holes and
        is left as it is by default.

    Returns
    -------
    MetricSolver
    """
    fill = options.pop("fill_holes", DIFFUSION_FILL_HOLES if metric == "diffusion" else None)
    if fill is not None:
        if isinstance(fill, (bool, np.bool_)) or not isinstance(fill, numbers.Real) or not 0 < fill < np.inf:
            raise ValueError(f"fill_holes must be a positive number or None (None: leave holes "
                             f"open), got {fill!r}")
        fill = float(fill)
        if metric in METRICS and isinstance(shape, Mesh) and shape.boundary_edges.size:
            # per component: a loop is small or not relative to the piece of surface it bounds
            closed, n_filled = fill_holes(shape, fill * np.sqrt(np.maximum(component_areas(shape), 1e-300)))
            if n_filled:
                return RestrictedSolver(shape, metric_solver(closed, metric, fill_holes=None, **options))
    if metric == "geodesic":
        return _solver(GeodesicSolver, shape, "the geodesic metric", options)
    if metric == "diffusion":
        kernel = options.pop("kernel", "heat")
        if kernel == "heat":
            return _solver(HeatDiffusionSolver, shape, "the diffusion metric's heat kernel", options)
        if kernel == "biharmonic":
            return _solver(BiharmonicSolver, shape, "the biharmonic distance", options)
        if kernel not in DIFFUSION_KERNELS:
            raise ValueError(f"diffusion kernel must be one of {DIFFUSION_KERNELS}, got {kernel!r}")
        return _solver(GraphDiffusionSolver, shape, f"the diffusion metric's {kernel} kernel",
                       {"kernel": kernel, **options})
    if metric == "euclidean":
        if options:
            raise TypeError(f"the euclidean metric takes no options, got {sorted(options)}")
        return EuclideanSolver(shape)
    raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")


def _solver(cls, shape, what: str, options: dict) -> MetricSolver:
    """``cls(shape, **options)``, an option it does not take named in the error."""
    takes = list(inspect.signature(cls).parameters)[1:]
    unknown = sorted(set(options) - set(takes) - {"kernel"})
    if unknown:
        raise TypeError(f"{what} takes no option {', '.join(map(repr, unknown))}; its options: "
                        f"{', '.join(t for t in takes if t != 'kernel')}")
    return cls(shape, **options)


def distance_matrix(shape, metric: str = "diffusion", **options):
    """Dense ``(n, n)`` distance matrix of ``metric`` on all vertices of ``shape``."""
    return metric_solver(shape, metric, **options).pairwise()
