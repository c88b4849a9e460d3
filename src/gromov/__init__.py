"""gromov: non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry.

Implements Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework
with diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010).

The pipeline, one module each: ``io`` (load/save) -> ``mesh`` (Mesh, PointCloud) ->
``resolution`` (working meshes) -> ``metrics`` (geodesic, diffusion, euclidean) ->
``sampling`` (farthest points) -> ``gmds`` / ``gh`` (GMDS, the Gromov-Hausdorff distance).
"""

from . import perturb
from .errors import GromovError, GromovWarning, MeshError, MeshFormatError, MetricError
from .gh import MatchResult, ShapeMetric, match
from .io import load, save
from .mesh import Mesh, PointCloud, RepairReport, fill_holes, repair
from .metrics import (
    EuclideanSolver,
    GeodesicSolver,
    GraphDiffusionSolver,
    HeatDiffusionSolver,
    BiharmonicSolver,
    MetricSolver,
    distance_matrix,
    metric_solver,
)
from .resolution import WorkingMesh, simplify, working_mesh
from .sampling import Samples, farthest_point_sampling

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
