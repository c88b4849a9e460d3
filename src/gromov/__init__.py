"""gromov: non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry.

Implements Bronstein, Bronstein, Mahmoudi, Kimmel & Sapiro, "A Gromov-Hausdorff framework
with diffusion geometry for topologically-robust non-rigid shape matching", IJCV 89 (2010).
"""

from .errors import GromovError, GromovWarning, MeshError, MeshFormatError, MetricError
from .mesh import Mesh, PointCloud, RepairReport, repair

__version__ = "0.1.0"

__all__ = [
    "GromovError", "GromovWarning", "MeshError", "MeshFormatError", "MetricError",
    "Mesh", "PointCloud", "RepairReport", "repair", "__version__",
]
