"""gromov: non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry.

Implements Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework
with diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010).

The pipeline, one module each: ``io`` (load/save) -> ``mesh`` (Mesh, PointCloud) ->
``resolution`` (working meshes) -> ``metrics`` (geodesic, diffusion, euclidean) ->
``sampling`` (farthest points) -> ``gmds`` / ``gh`` (GMDS, the Gromov-Hausdorff distance).
"""

from importlib import import_module as _import_module
from typing import TYPE_CHECKING

from .errors import GromovError, GromovWarning, MeshError, MeshFormatError, MetricError


def _numba_cache() -> None:
    """Give numba's on-disk cache of compiled kernels a writable folder, before numba loads.

    numba caches beside the sources (``__pycache__``) or, where that is read-only, in the
    user's cache folder; with neither writable (a read-only install and no writable home)
    every ``@njit(cache=True)`` fails with "no locator available". Then, unless the user set
    ``NUMBA_CACHE_DIR``, the cache goes to ``<temp>/gromov-numba-<uid>``; where even that is
    not writable the kernels are compiled but not cached, in each run (a warning says so).
    """
    import os
    import sys
    import tempfile

    if os.environ.get("NUMBA_CACHE_DIR"):
        return

    def writable(folder: str) -> bool:
        try:
            os.makedirs(folder, exist_ok=True)
            tempfile.TemporaryFile(dir=folder).close()
        except OSError:
            return False
        return True

    if writable(os.path.join(os.path.dirname(os.path.abspath(__file__)), "__pycache__")):
        return
    if sys.platform == "darwin":
        user = os.path.expanduser("~/Library/Caches")
    elif sys.platform == "win32":
        user = os.environ.get("LOCALAPPDATA", os.path.expanduser("~"))
    else:
        user = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    if writable(os.path.join(user, "numba")):
        return
    uid = os.getuid() if hasattr(os, "getuid") else 0
    try:
        folder = os.path.join(tempfile.gettempdir(), f"gromov-numba-{uid}")
    except FileNotFoundError:   # no writable temporary folder at all
        folder = None
    if folder is not None and writable(folder):
        os.environ["NUMBA_CACHE_DIR"] = folder
        config = sys.modules.get("numba.core.config")
        if config is not None:   # numba loaded before gromov: it reads the folder per kernel
            config.CACHE_DIR = folder
        return
    import warnings

    import numba

    plain = numba.njit

    def njit(*args, **kwargs):   # the kernels' @njit(cache=True), compiled but not cached
        kwargs.pop("cache", None)
        return plain(*args, **kwargs)

    numba.njit = njit
    warnings.warn("gromov: no writable folder for numba's cache of compiled kernels (the package "
                  "folder, the user's cache folder and the temporary folder are read-only), so they "
                  "are compiled again in each run: set NUMBA_CACHE_DIR to a writable folder",
                  RuntimeWarning, stacklevel=3)


_numba_cache()   # before any module that compiles kernels loads numba (they load lazily, below)

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
    "SearchOptions": "search",
}
#: Submodules reachable as attributes without an import statement.
_SUBMODULES = ("perturb", "store", "search", "dense", "evaluate", "experiments", "gmds", "io", "mesh", "metrics",
               "resolution", "sampling", "shapes", "gh")


if TYPE_CHECKING:   # what the lazy table serves, for type checkers and documentation tools
    from . import perturb, store
    from .gh import MatchResult, ShapeMetric, match
    from .io import load, save
    from .mesh import Mesh, PointCloud, RepairReport, fill_holes, repair
    from .metrics import (BiharmonicSolver, EuclideanSolver, GeodesicSolver, GraphDiffusionSolver,
                          HeatDiffusionSolver, MetricSolver, distance_matrix, metric_solver)
    from .resolution import WorkingMesh, simplify, working_mesh
    from .sampling import Samples, farthest_point_sampling
    from .search import SearchOptions


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
    "ShapeMetric", "MatchResult", "match", "SearchOptions", "perturb", "store",
    "__version__",
]
