"""gromov: non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry.

Implements Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework
with diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010).

The pipeline, one module each: ``io`` (load/save) -> ``mesh`` (Mesh, PointCloud) ->
``resolution`` (working meshes) -> ``metrics`` (geodesic, diffusion, euclidean) ->
``sampling`` (farthest points) -> ``gmds`` (GMDS) -> ``shape_metric`` (a shape prepared for
matching) -> ``search`` (GMDS's initial search) -> ``gh`` (the Gromov-Hausdorff distance,
``match``, whose outcome is a ``match_result.MatchResult``).
"""

from importlib import import_module as _import_module
from typing import TYPE_CHECKING

from ._numba import set_up_cache as _set_up_numba_cache
from ._version import __version__
from .errors import GromovError, GromovWarning, MeshError, MeshFormatError, MetricError

_set_up_numba_cache()   # before any module that compiles kernels loads numba (they load lazily, below)

#: Public name -> the module that defines it. The modules are imported on first use (PEP 562),
#: so that ``import gromov`` and ``gromov --help`` do not wait for numba, scipy.sparse and
#: the compiled kernels.
_LAZY = {
    "ShapeMetric": "shape_metric",
    "MatchResult": "match_result",
    "match": "gh",
    **dict.fromkeys(("load", "save"), "io"),
    **dict.fromkeys(("Mesh", "PointCloud", "RepairReport", "fill_holes", "repair"), "mesh"),
    **dict.fromkeys(("EuclideanSolver", "GeodesicSolver", "GraphDiffusionSolver", "HeatDiffusionSolver",
                     "BiharmonicSolver", "MetricSolver", "distance_matrix", "metric_solver"), "metrics"),
    **dict.fromkeys(("WorkingMesh", "simplify", "working_mesh"), "resolution"),
    **dict.fromkeys(("Samples", "farthest_point_sampling"), "sampling"),
    "SearchOptions": "search",
}
#: Submodules reachable as attributes without an import statement.
_SUBMODULES = ("perturb", "store", "search", "dense", "evaluate", "experiments", "gmds", "io", "mesh", "metrics",
               "resolution", "sampling", "shapes", "gh", "shape_metric", "match_result")


if TYPE_CHECKING:   # what the lazy table serves, for type checkers and documentation tools
    from . import perturb, store
    from .gh import match
    from .io import load, save
    from .match_result import MatchResult
    from .mesh import Mesh, PointCloud, RepairReport, fill_holes, repair
    from .metrics import (BiharmonicSolver, EuclideanSolver, GeodesicSolver, GraphDiffusionSolver,
                          HeatDiffusionSolver, MetricSolver, distance_matrix, metric_solver)
    from .resolution import WorkingMesh, simplify, working_mesh
    from .sampling import Samples, farthest_point_sampling
    from .search import SearchOptions
    from .shape_metric import ShapeMetric


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


__all__ = [
    "GromovError", "GromovWarning", "MeshError", "MeshFormatError", "MetricError",
    "load", "save", "Mesh", "PointCloud", "RepairReport", "repair", "fill_holes",
    "MetricSolver", "GeodesicSolver", "GraphDiffusionSolver", "HeatDiffusionSolver", "BiharmonicSolver",
    "EuclideanSolver", "metric_solver", "distance_matrix",
    "WorkingMesh", "simplify", "working_mesh", "Samples", "farthest_point_sampling",
    "ShapeMetric", "MatchResult", "match", "SearchOptions", "perturb", "store",
    "__version__",
]
