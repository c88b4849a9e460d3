"""Defaults that both the library and the command line read.

They live here, in a module that imports nothing, so that ``gromov --help`` builds its parser
without loading numba, scipy or the compiled kernels. Each is documented where it is used
(re-exported there under the same name): :mod:`gromov.gh` (``DEFAULT_RESOLUTION``,
``RANK_TAU_SCALE``, ``RANK_RESIDUAL``), :mod:`gromov.perturb` (``WELD_JOINS``, ``CUT_KINDS``,
``CUT_PATCHES``), :mod:`gromov.io`
(``GZIP_RATIO``, ``GZIP_FLOOR``), :mod:`gromov.metrics` (``DIFFUSION_FILL_HOLES``),
:mod:`gromov.metrics.diffusion` (``HEAT_UNITS``, ``DEFAULT_UNITS``),
:mod:`gromov.experiments.recognition` (``LOCAL_SCALING_K``, ``DIFFUSION_RERANK_K``,
``DIFFUSION_RERANK_STEPS``) and :mod:`gromov.retrieval`
(``PROFILE_SLACK``, ``TRIANGLE_SLACK``).
"""

DEFAULT_RESOLUTION = 3000
RANK_TAU_SCALE = 0.5
RANK_RESIDUAL = "log"
RANK_RESIDUALS = ("difference", "log")
WELD_JOINS = ("tube", "pinch")
CUT_KINDS = ("plane", "holes")
CUT_PATCHES = 5
GZIP_RATIO = 100
GZIP_FLOOR = 16 * 2**20
DIFFUSION_FILL_HOLES = 0.5
HEAT_UNITS = ("normalized", "raw", "length", "area")
DEFAULT_UNITS = "raw"
LOCAL_SCALING_K = 4
DIFFUSION_RERANK_K = 8
DIFFUSION_RERANK_STEPS = 3
PROFILE_SLACK = 0.3
TRIANGLE_SLACK = 0.7
