"""gromov: non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry.

Implements Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework
with diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010).

The pipeline, one module each: ``io`` (load/save) -> ``mesh`` (Mesh, PointCloud) ->
``resolution`` (working meshes) -> ``metrics`` (geodesic, diffusion, euclidean) ->
``sampling`` (farthest points) -> ``gmds`` / ``gh`` (GMDS, the Gromov-Hausdorff distance).
"""

from importlib import import_module as _import_module

from .errors import GromovError, GromovWarning, MeshError, MeshFormatError, MetricError

#: Public name -> the module that defines it. The modules are imported on first use (PEP 562),
#: so that ``import gromov`` and ``gromov --help`` do not wait for numba, scipy.sparse and
#: the compiled kernels.
_LAZY = {
    **dict.fromkeys(("MatchResult", "ShapeMetric", "match"), "gh"),
    **dict.fromkeys(("load", "save"), "io"),
    **dict.fromkeys(("Mesh", "PointCloud", "RepairReport", "fill_holes", "repair"), "mesh"),
    **dict.fromkeys(("EuclideanSolver", "GeodesicSolver", "GraphDiffusionSolver", "HeatDiffusionSolver",
                     "BiharmonicSolver", "MetricSolver", "distance_matrix", "metric_solver"), "metrics"),
    **dict.fromkeys(("WorkingMesh", "simplify", "working_mesh"), "resolution"),
    **dict.fromkeys(("Samples", "farthest_point_sampling"), "sampling"),
}
#: Submodules reachable as attributes without an import statement.
_SUBMODULES = ("perturb", "store", "dense", "evaluate", "experiments", "gmds", "io", "mesh", "metrics",
               "resolution", "sampling", "shapes", "gh")


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(_import_module(f".{_LAZY[name]}", __name__), name)
    elif name in _SUBMODULES:
        value = _import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module 'gromov' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES))


__version__ = "0.2.0"

__all__ = [
    "GromovError", "GromovWarning", "MeshError", "MeshFormatError", "MetricError",
    "load", "save", "Mesh", "PointCloud", "RepairReport", "repair", "fill_holes",
    "MetricSolver", "GeodesicSolver", "GraphDiffusionSolver", "HeatDiffusionSolver", "BiharmonicSolver",
    "EuclideanSolver", "metric_solver", "distance_matrix",
    "WorkingMesh", "simplify", "working_mesh", "Samples", "farthest_point_sampling",
    "ShapeMetric", "MatchResult", "match", "perturb",
    "__version__",
]
