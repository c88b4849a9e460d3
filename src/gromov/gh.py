r"""The Gromov-Hausdorff distance between two shapes: :func:`match` and :class:`ShapeMetric`.

:math:`\hat d_{GH}(X, Y) = \tfrac12 \min_C \mathrm{dis}(C)` over two-sided correspondences
between farthest-point samples, minimised by symmetric GMDS (:mod:`gromov.gmds`) from a
global initial guess (Bronstein et al., IJCV 2010, §2 and §4). ``solver="gw"`` instead
takes the Gromov-Wasserstein coupling of the two sample distance matrices (POT) and reads a
correspondence off it, so both are judged by the same distortion.
"""

from __future__ import annotations

import logging
import numbers
import os
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import _gmds_kernel as _kernel
from ._project import project_among
from .errors import GromovWarning, MetricError
from .gmds import (EmbeddedDistance, SurfaceDistance, SurfacePoints, SymmetricGMDS, log_ratio_residuals,
                   norm_value, parse_norm, trimmed_rms)
from .mesh import Mesh, as_mesh, as_shape
from .metrics import metric_solver
from .metrics.diffusion import correspondence_options
from .orientation import orientation_agreements, outward_normals
from .resolution import WorkingCloud, WorkingMesh, gather, ring_candidates, working_shape
from .sampling import farthest_point_sampling

__all__ = ["ShapeMetric", "MatchResult", "match"]

logger = logging.getLogger(__name__)

DEFAULT_RESOLUTION = 3000
#: Initial search of :func:`match`: first-sample candidates, and coarse starts extended to all
#: samples per direction (chosen on held-out TOSCA classes: docs/design/initial-search.md).
DEFAULT_N_STARTS = 128
DEFAULT_N_EXTEND = 8
#: Coarse stages of the initial search: (samples placed, farthest point samples of the target
#: it runs on, None for all working vertices); see ``match``.
DEFAULT_COARSE_STAGES: tuple[tuple[int, int | None], ...] = ((12, None), (20, 1000))
#: Fraction of the samples a coarse start's extension descends on after its first descent
#: (sample-level least trimmed squares; 1, the default, disables it), and how many rounds:
#: see ``match``'s ``extend_keep``.
EXTEND_KEEP = 1.0
EXTEND_ROUNDS = 3
#: Farthest point samples of the target to which the initial search is restricted (None: all
#: working vertices); the best start is then polished on all of them (see ``match``).
DEFAULT_SEARCH_VERTICES: int | None = None
#: ``match(..., orientation="prefer")`` keeps an orientation-preserving correspondence when its
#: distortion is at most this much (relative) above the best one found.
ORIENTATION_TOL = 0.1
#: A map counts as clearly direct when its orientation agreement is above 1/2 + this; "prefer"
#: takes a clearly direct alternative before one that is direct only just. A map direct on one
#: part of the shapes and mirrored on the rest (a *partial* flip: one leg sent to the other
#: side) has an agreement near 1/2 (held-out TOSCA, diffusion: 0.54-0.58; the right direct maps
#: 0.69-0.93) -- but so do some noisy right maps (geodesic: down to 0.54), hence only a preference.
DIRECT_MARGIN = 0.15
#: ... and a map obtained by composing the mirrored one with a reflection of either shape
#: (:meth:`ShapeMetric.symmetry`) when within this much; chosen on the held-out classes.
FLIP_TOL = 0.25
#: :meth:`ShapeMetric.symmetry` accepts a self-map whose RMS distortion is below this fraction of
#: the diameter.
SYMMETRY_TOL = 0.05
#: ... and repairs it up to this many times where its two halves disagree by more than
#: ``INVOLUTION_TOL`` of the diameter at a sample (a reflection is its own inverse).
INVOLUTION_REPAIRS = 2
INVOLUTION_TOL = 0.05
#: Signature-guided coarse stages (see ``match``'s ``signature_weight``): the weight of the
#: per-image cost, and how many of the candidates (the best-matching signatures first) they
#: start from.
SIGNATURE_WEIGHT = 1.0
SIGNATURE_STARTS = 32
#: Recognition (:func:`gromov.experiments.gh_matrix`) ranks a pair of shapes by the trimmed
#: distortion of the correspondence found with the heat-kernel diffusion metric at time
#: ``tau``, *measured* with the heat distance at ``RANK_TAU_SCALE * tau`` (a finer scale) on
#: the same eigenpairs (:meth:`HeatDiffusionSolver.at_tau
#: <gromov.metrics.diffusion.HeatDiffusionSolver.at_tau>`); see ``match``'s
#: ``rank_tau_scale``. Chosen on the validation sets: the margin of the diffusion ranking rises
#: in six readings of seven, e.g. synthetic welds 0.988 -> 1.427 (``.venv/bin/python
#: benchmarks/bench_rank_residual.py``, "difference @1" against "@0.5"; see
#: docs/design/recognition.md).
RANK_TAU_SCALE = 0.5
#: How recognition summarises the residuals of a correspondence (see ``match``'s
#: ``rank_residual``): ``"log"``, the trimmed RMS of the log ratios of corresponding distances
#: (:func:`gromov.gmds.log_ratio_residuals`, a multiplicative distortion), or
#: ``"difference"``, that of their differences over the larger diameter (the additive form).
#: Chosen on the validation sets: the diffusion margin is larger in seven readings of eight and
#: equal in the eighth (``.venv/bin/python benchmarks/bench_rank_residual.py``; see
#: docs/design/recognition.md).
RANK_RESIDUAL = "log"
RANK_RESIDUALS = ("difference", "log")
#: The floor of :func:`gromov.gmds.log_ratio_residuals` in recognition, a fraction of the larger
#: diameter: keeps the ratio finite where two points coincide (0.01-0.1 changed no validation
#: margin by more than 3%).
RANK_LOG_FLOOR = 0.01


class ShapeMetric:
    """A shape with its working mesh and dense metric computed once, for many matches.

    Parameters
    ----------
    shape : Mesh, PointCloud, str, os.PathLike, (vertices, faces), (n, 3) array or a mesh object
        The input mesh or point cloud, a file to load, or arrays / a mesh or point-cloud
        object (``trimesh.Trimesh``...) read by :func:`gromov.mesh.as_shape`.
    metric : {"diffusion", "geodesic", "euclidean"}, default "diffusion"
    resolution : int or None, default 3000
        Working mesh size (None: the input mesh as it is). A point cloud's working set is that
        many of its points (:func:`gromov.resolution.working_cloud`: farthest points in space).
    metric_options : dict, optional
        Passed to :func:`gromov.metrics.metric_solver`.
    working : WorkingMesh or WorkingCloud, optional
        Use this working mesh (e.g. ``reference.working.transfer(pose)`` to simplify the poses
        of a class identically) instead of simplifying ``shape``; for a point cloud, a
        :class:`~gromov.resolution.WorkingCloud` of it.

    Examples
    --------
    >>> ref = ShapeMetric("cat0.off.gz", "diffusion")          # doctest: +SKIP
    >>> [match(ref, other).distance for other in others]       # doctest: +SKIP
    """

    def __init__(self, shape, metric: str = "diffusion", *, resolution: int | None = DEFAULT_RESOLUTION,
                 metric_options: dict | None = None, working: WorkingMesh | WorkingCloud | None = None):
        if isinstance(shape, (str, os.PathLike)):
            from .io import load

            shape = load(shape)
        self.input = shape = as_shape(shape)
        self.metric = metric
        self.metric_options = dict(metric_options or {})
        if working is None:
            working = working_shape(shape, resolution)
        elif isinstance(working, WorkingMesh) != isinstance(shape, Mesh):
            raise TypeError(f"working: a {type(working).__name__} was given for a "
                            f"{type(shape).__name__} (a mesh's working shape is a WorkingMesh, a point "
                            "cloud's a WorkingCloud)")
        self.working = working
        self.solver = metric_solver(self.working.mesh, metric, **self.metric_options)
        self._surface: SurfaceDistance | None = None
        self._samples: dict = {}
        self._descriptors: np.ndarray | None = None
        self._diameter: float | None = None
        self._finite: bool | None = None
        self._owned = None
        self._lb_basis = None   # Laplace-Beltrami eigenpairs of the working mesh (gromov.dense)
        self._same_as_input: bool | None = None
        self._normals: tuple[np.ndarray, bool] | None = None
        self._symmetry: dict = {}
        self._ranking: dict = {}

    @property
    def mesh(self) -> Mesh:
        """The working mesh (a :class:`~gromov.mesh.PointCloud` for a point cloud)."""
        return self.working.mesh

    @property
    def has_faces(self) -> bool:
        """Whether the shape is a triangle mesh (else a point cloud: :func:`match` then keeps
        its images at points)."""
        return isinstance(self.mesh, Mesh)

    @property
    def distances(self) -> np.ndarray:
        """Dense ``(n, n)`` distances between working vertices (computed once)."""
        return self.solver.pairwise()

    @property
    def surface(self) -> SurfaceDistance:
        """Distances between points inside the working mesh's triangles (meshes only)."""
        if not self.has_faces:
            raise TypeError("a point cloud has no surface to interpolate distances on")
        if self._surface is None:
            self._surface = SurfaceDistance(self.mesh, self.distances)
        return self._surface

    @property
    def diameter(self) -> float:
        """Largest finite distance between working vertices (computed once)."""
        if self._diameter is None:
            d = self.distances
            top = float(d.max())  # one pass; the masked maximum only when components are apart
            self._finite = bool(np.isfinite(top))
            self._diameter = top if self._finite else float(np.max(d, where=np.isfinite(d), initial=0.0))
        return self._diameter

    @property
    def finite(self) -> bool:
        """Whether every distance between working vertices is finite (False for a shape in
        pieces in the geodesic metric: a mesh with several components, a point cloud whose
        nearest-neighbour graph falls apart)."""
        self.diameter
        return self._finite

    @property
    def descriptors(self) -> np.ndarray:
        """``(n, 16)`` isometry-invariant vertex signatures: quantiles of each vertex's distances.

        The distribution of distances from a point (the "shape distribution" of Osada et al.,
        ACM TOG 2002, restricted to one point) is unchanged by isometries; it picks candidate
        images for the first sample of the greedy initialisation.
        """
        if self._descriptors is None:
            # distances to 256 farthest point samples stand for the whole distribution
            cols = self.samples(min(256, self.mesh.n_vertices), 0)
            d = np.sort(self.distances[:, cols], axis=1)
            idx = np.round(np.linspace(0.0, 1.0, 17)[1:] * (d.shape[1] - 1)).astype(int)
            self._descriptors = np.ascontiguousarray(d[:, idx])
        return self._descriptors

    @property
    def normals(self) -> tuple[np.ndarray, bool]:
        """Outward unit normals at the working vertices (faces re-wound coherently first) and
        whether the working mesh is orientable (:func:`gromov.orientation.outward_normals`;
        computed once). A point cloud: NaN normals, not orientable (no faces say which side
        is out)."""
        if self._normals is None:
            self._normals = (outward_normals(self.mesh) if self.has_faces else
                             (np.full((self.mesh.n_vertices, 3), np.nan), False))
        return self._normals

    def symmetry(self, n_samples: int = 100, seed: int = 0) -> np.ndarray | None:
        """An intrinsic reflection of the shape: a map of its working vertices to themselves that
        reverses the orientation and nearly keeps the distances (left hand to right hand), or
        None when none is found (computed once per ``(n_samples, seed)``).

        Found as :func:`match` finds a correspondence, from the shape to itself among
        orientation-reversing maps only (the identity is excluded that way): GMDS of the
        samples from the lowest-distortion reversing start of the initial search (with up to
        as many more reversing coarse starts per stage as it extends), accepted when it
        reverses the orientation (agreement < 1/2) and its RMS distortion is below
        ``SYMMETRY_TOL`` of the diameter; every vertex then goes where its distances to the
        samples best fit those to the samples' images (:func:`anchored_images`). A reflection
        is its own inverse, so where the two halves of the self-map disagree at a sample (by
        more than ``INVOLUTION_TOL`` of the diameter) those samples are re-anchored on the
        agreeing ones and GMDS descends again (up to ``INVOLUTION_REPAIRS`` times), so that a
        leg is not sent to another leg (docs/design/initial-search.md, "Mirror images").
        :func:`match` composes a mirrored correspondence with it to get the direct one.
        """
        key = (int(n_samples), int(seed))
        if key not in self._symmetry:
            self._symmetry[key] = _self_reflection(self, *key)
        return self._symmetry[key]

    def ranking_surface(self, tau_scale: float):
        """``(EmbeddedDistance, diameter)`` of the heat distance at ``tau_scale`` times this
        shape's diffusion time, from the same eigenpairs (cached per scale), or None when the
        metric is not the heat-kernel diffusion distance. What ``match(..., rank_tau_scale=)``
        measures a correspondence with."""
        inner = getattr(self.solver, "inner", self.solver)   # through a hole-filling wrapper
        if not hasattr(inner, "at_tau"):
            return None
        key = float(tau_scale)
        if key not in self._ranking:
            scaled = self.solver.at_tau(inner.tau * key)
            psi = scaled.embedding
            sq = (psi**2).sum(1)
            # the diameter: the largest distance, in row blocks (no (n, n) matrix kept)
            top = 0.0
            for i in range(0, len(psi), 1024):
                d2 = sq[i:i + 1024, None] + sq[None, :] - 2.0 * (psi[i:i + 1024] @ psi.T)
                top = max(top, float(d2.max()))
            self._ranking[key] = (EmbeddedDistance(self.mesh, psi), float(np.sqrt(max(top, 0.0))))
        return self._ranking[key]

    def samples(self, n: int, seed: int = 0) -> np.ndarray:
        """``n`` farthest point samples (working vertex ids), cached per ``(n, seed)``."""
        key = (int(n), int(seed))
        if key not in self._samples:
            self._samples[key] = farthest_point_sampling(self.distances, n, seed=seed).indices
        return self._samples[key]

    def subset(self, k: int) -> np.ndarray:
        """``k`` farthest point samples (seed 0; all vertices if fewer): the vertex subset an
        initial search of :func:`match` runs on (``coarse_stages``, ``search_vertices``)."""
        return self.samples(min(int(k), self.mesh.n_vertices), 0)

    @property
    def owned(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR ``(indptr, input vertices)`` each working vertex owns
        (:meth:`WorkingMesh.owned`), computed once per shape."""
        if self._owned is None:
            self._owned = self.working.owned()
        return self._owned

    def locate(self, pts: SurfacePoints):
        """Carry points on the working mesh to the input mesh: (face, bary, nearest vertex) there.

        Where the working mesh is the input mesh itself (not simplified: same vertices and
        faces), the points are kept as they are (same face and coordinates, not recomputed);
        else each is projected onto its own part of the input: the closest point among the
        input faces around the input vertices that the corners of its working face, and
        their neighbours, own (:attr:`WorkingMesh.source_owner`,
        :func:`gromov._project.project_among`) -- never onto another sheet that passes
        closer in space. Meshes only."""
        if not self.has_faces:
            raise TypeError("locate needs a triangle mesh; a point cloud's images are its points")
        if self._same_as_input is None:
            m, s = self.mesh, self.input
            self._same_as_input = bool(m.n_vertices == s.n_vertices and np.array_equal(m.faces, s.faces)
                                       and np.array_equal(m.vertices, s.vertices))
        if self._same_as_input:
            face, bary = np.asarray(pts.face, dtype=np.int64), np.asarray(pts.bary, dtype=np.float64)
        else:
            pos = pts.positions(self.mesh.vertices, self.mesh.faces)
            own_ptr, own_ids = self.owned
            corners = self.mesh.faces[np.asarray(pts.face, dtype=np.int64)]   # (p, 3)
            ring_ptr, ring = ring_candidates(self.mesh, corners.ravel())   # 3 rings per point
            face, bary, _ = project_among(pos, self.input, *gather(own_ptr, own_ids, ring_ptr[::3], ring))
        vertex = self.input.faces[face, np.argmax(bary, axis=1)]
        return face, bary, self.input.input_ids[vertex]

    def __repr__(self) -> str:
        return (f"ShapeMetric(metric={self.metric!r}, working={self.mesh.n_vertices} of "
                f"{self.input.n_vertices} vertices)")


@dataclass(frozen=True, eq=False)
class MatchResult:
    """The outcome of :func:`match`. Indices refer to the input meshes (file numbering).

    Attributes
    ----------
    distance : float
        GH estimate: half the distortion in the chosen norm, in the metric's units.
    relative_distance : float
        ``distance`` divided by the larger of the two shapes' diameters in that metric.
    distortion_l2, distortion_linf : float
        RMS and maximum distortion of the final correspondence (over ordered pairs).
    x_samples, y_samples : ndarray (M,), (K,)
        Input vertex ids of the samples.
    x_to_y_face, x_to_y_bary, x_to_y_vertex : ndarray
        Images of X's samples on Y's input mesh: face, barycentric coordinates, nearest vertex.
        Vertex ids are the file's numbering. Face ids are the file's too unless loading had to
        drop degenerate or repeated faces (a ``GromovWarning`` says so); then they index the
        repaired mesh's faces. On a point cloud: face -1, NaN coordinates, and the image point.
    y_to_x_face, y_to_x_bary, y_to_x_vertex : ndarray
        The same for Y's samples on X.
    x_to_y_dense_face, x_to_y_dense_bary, x_to_y_dense_vertex : ndarray (n_X,), (n_X, 3), (n_X,)
        With ``match(..., dense=True)``: the image on Y's input mesh of *every* vertex of X's
        input (entry i for file vertex i; :mod:`gromov.dense`), as for the samples. None
        otherwise.
    y_to_x_dense_face, y_to_x_dense_bary, y_to_x_dense_vertex : ndarray (n_Y,), (n_Y, 3), (n_Y,)
        The same for every vertex of Y on X.
    input_faces : (ndarray or None, ndarray or None)
        With the dense maps: the faces of X's and Y's input meshes in file vertex ids (None
        for a point cloud), which the dense face ids index; what :meth:`transfer` interpolates on.
    orientation : float
        Fraction of small sample triangles whose sense of rotation the correspondence keeps
        (:func:`gromov.orientation.orientation_agreement`, both directions averaged): about 1
        for a direct map, about 0 for a mirrored one (left and right swapped), about 1/2 for a
        scrambled one; NaN when a mesh is not orientable or a shape is a point cloud.
    distortion_trimmed : float
        RMS distortion of the best-fitting 80% of the pairs of the final correspondence
        (:func:`gromov.gmds.trimmed_rms`, ``TRIM_KEEP``): the distortion left when the pairs a
        local topology change altered are set aside. Not the GH estimate.
    relative_trimmed : float
        Half of it divided by the larger diameter, comparable to ``relative_distance``.
    ranking_distance : float
        What recognition ranks pairs of shapes by (``PairwiseGH.trimmed``, ``gromov
        reproduce``): ``relative_trimmed``, or with ``rank_tau_scale`` and the heat-kernel
        diffusion metric, the same quantity for the same correspondence measured with the heat
        distance at ``rank_tau_scale`` times the diffusion time (diameters in that metric);
        with ``rank_residual="log"``, of the log ratios of the distances instead of their
        differences (:func:`ranking_value`).
    pair_distortion : ndarray (M+K, M+K)
        ``D_X(C) - D_Y(C)`` of the final two-sided correspondence C = (P x Q') u (P' x Q): rows
        and columns are first X's M samples (on Y: their images), then Y's K samples (on X:
        their images), in the order of ``x_samples`` and ``y_samples``. Where a shape's
        topology changed, the pairs whose paths run through the change can stand out.
    """

    distance: float
    relative_distance: float
    distortion: float
    distortion_l2: float
    distortion_linf: float
    norm: str
    metric: str
    solver: str
    n_samples: int
    x_samples: np.ndarray
    x_to_y_face: np.ndarray
    x_to_y_bary: np.ndarray
    x_to_y_vertex: np.ndarray
    y_samples: np.ndarray
    y_to_x_face: np.ndarray
    y_to_x_bary: np.ndarray
    y_to_x_vertex: np.ndarray
    n_iter: int
    converged: bool
    seconds: float
    orientation: float = float("nan")
    distortion_trimmed: float = float("nan")
    relative_trimmed: float = float("nan")
    ranking_distance: float = float("nan")
    pair_distortion: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    history: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    x_to_y_dense_face: np.ndarray | None = field(repr=False, default=None)
    x_to_y_dense_bary: np.ndarray | None = field(repr=False, default=None)
    x_to_y_dense_vertex: np.ndarray | None = field(repr=False, default=None)
    y_to_x_dense_face: np.ndarray | None = field(repr=False, default=None)
    y_to_x_dense_bary: np.ndarray | None = field(repr=False, default=None)
    y_to_x_dense_vertex: np.ndarray | None = field(repr=False, default=None)
    input_faces: tuple = field(repr=False, default=(None, None))

    def to_dict(self) -> dict:
        """The JSON fields of ``gromov match --json``."""
        return {"distance": self.distance, "relative_distance": self.relative_distance,
                "distortion": {"l2": self.distortion_l2, "linf": self.distortion_linf,
                               "trimmed": self.distortion_trimmed, self.norm: self.distortion},
                "relative_trimmed_distance": self.relative_trimmed,
                "norm": self.norm, "metric": self.metric, "solver": self.solver,
                "n_samples": self.n_samples, "n_iter": self.n_iter, "converged": self.converged,
                "orientation": self.orientation if np.isfinite(self.orientation) else None,
                "seconds": self.seconds}

    @property
    def sample_distortion(self) -> tuple[np.ndarray, np.ndarray]:
        r"""``(x, y)``: RMS distortion of each sample's pairs, for X's M samples and Y's K.

        Row ``a`` of ``pair_distortion`` without its diagonal:
        :math:`e_a = (\frac{1}{M+K-1}\sum_{b \ne a} r_{ab}^2)^{1/2}`, so that the mean of
        :math:`e_a^2` over all samples is ``distortion_l2**2``. Large where the map fits badly,
        e.g. near a change of topology (the ``pair_distortion`` note).
        """
        e = np.asarray(self.pair_distortion, dtype=float)
        n = len(e)
        if n < 2:
            return np.zeros(len(self.x_samples)), np.zeros(len(self.y_samples))
        rows = np.sqrt((e**2).sum(axis=1) / (n - 1))
        m = len(self.x_samples)
        return rows[:m], rows[m:]

    @property
    def has_dense(self) -> bool:
        """Whether the dense maps were computed (``match(..., dense=True)``)."""
        return self.x_to_y_dense_vertex is not None

    def arrays(self) -> dict:
        """The arrays of ``gromov match --out``: the correspondences, ``x_distortion``,
        ``y_distortion`` (:attr:`sample_distortion`), and the dense maps when computed."""
        keys = ["x_samples", "x_to_y_face", "x_to_y_bary", "x_to_y_vertex",
                "y_samples", "y_to_x_face", "y_to_x_bary", "y_to_x_vertex"]
        if self.has_dense:
            keys += [f"{d}_dense_{k}" for d in ("x_to_y", "y_to_x") for k in ("vertex", "face", "bary")]
        out = {k: getattr(self, k) for k in keys}
        out["x_distortion"], out["y_distortion"] = self.sample_distortion
        return out

    def transfer(self, values, *, method: str = "nearest", direction: str = "x_to_y") -> np.ndarray:
        r"""Carry a per-vertex function of X to Y (or of Y to X) through the dense map.

        ``method="nearest"``: each vertex of the target takes the value at the vertex nearest
        to its image, :math:`g(y) = f(v(T(y)))` -- for labels, segmentations and other values
        that must not be mixed. ``"barycentric"``: the value interpolated at the image,
        :math:`g(y) = \sum_c \beta_c f(c)` over the corners of the image's face -- for smooth
        functions. A map carries functions backwards: values on X reach Y through the map
        from Y to X.

        Parameters
        ----------
        values : array_like (n_X, ...) or (n_Y, ...)
            One row per file vertex of the source of the function (X for ``"x_to_y"``).
        method : {"nearest", "barycentric"}
        direction : {"x_to_y", "y_to_x"}
            Which way the function goes.

        Returns
        -------
        ndarray (n_Y, ...) or (n_X, ...)
            Rows of target vertices that loading dropped are NaN (0 for integer values).
        """
        if not self.has_dense:
            raise ValueError("transfer needs the dense maps: match(..., dense=True)")
        if direction not in ("x_to_y", "y_to_x"):
            raise ValueError(f"direction must be 'x_to_y' or 'y_to_x', got {direction!r}")
        if method not in ("nearest", "barycentric"):
            raise ValueError(f"method must be 'nearest' or 'barycentric', got {method!r}")
        back = "y_to_x" if direction == "x_to_y" else "x_to_y"  # the target's images on the source
        vertex, face, bary = (getattr(self, f"{back}_dense_{k}") for k in ("vertex", "face", "bary"))
        n_source = len(getattr(self, f"{direction}_dense_vertex"))
        v = np.asarray(values)
        if v.shape[:1] != (n_source,):
            raise ValueError(f"values must have one row per vertex of the source shape ({n_source}), "
                             f"got shape {v.shape}")
        faces = self.input_faces[0 if direction == "x_to_y" else 1]
        ok = vertex >= 0
        if method == "barycentric" and faces is None:
            raise ValueError("barycentric transfer needs faces on the shape the values live on "
                             "(a point cloud has none): use method='nearest'")
        if method == "nearest":
            out = v[np.where(ok, vertex, 0)]
        else:
            corners = faces[np.where(face >= 0, face, 0)]
            w = np.nan_to_num(bary).reshape(bary.shape + (1,) * (v.ndim - 1))
            out = (v[corners] * w).sum(axis=1)
        if not ok.all():
            out[~ok] = np.nan if out.dtype.kind in "fc" else 0
        return out


# ----------------------------------------------------------------------------- initialisation
def greedy_init(dx_pp: np.ndarray, DY: np.ndarray, candidates: np.ndarray, *,
                stages=((12, None),), n_extend: int = DEFAULT_N_EXTEND,
                domain: np.ndarray | None = None, all_starts: bool = False,
                extend_keep: float = EXTEND_KEEP):
    """Multi-resolution, multi-start initial images (vertex ids on Y) of samples of X.

    Coarse stage: for every candidate image of the first sample, place the first ``c``
    samples greedily, polish them by discrete descent (each image moves to the best vertex of
    Y) and score their distortion. Each of ``stages``, ``(c, vertices)``, is one such coarse
    stage, over the given vertices of Y (an array, e.g. farthest point samples; the
    candidates are added to it) or over all of them (None). The ``n_extend`` extended starts
    are shared out evenly among the stages, each stage's best first: they are extended to all
    samples (greedy placement, then discrete descent over all vertices of Y) and the one with
    the lowest distortion is returned. ``DY`` must be symmetric.

    ``domain``: vertices of Y to which the whole search is restricted (the stages' own
    vertex sets are then ignored); the candidates are added to it. The best start found there
    is then polished by discrete descent over all vertices of Y. The search's cost is
    proportional to the domain's size.

    Returns the images ``(m,)`` of the best start, or with ``all_starts`` a list of
    ``(images, summed squared distortion)`` of every extended start, in the order they were
    extended (without ``domain`` the best is the first of the lowest cost; with it, each
    start is polished on all vertices, and the best is the one chosen on the domain): for
    studies of the selection. ``extend_keep``: see :func:`match`.
    """
    search = _Search(dx_pp, DY, candidates, stages, n_extend, domain, extend_keep)
    every, best = search.extend_plain(polish_all=all_starts)
    return every if all_starts else every[best][0]


def _trimmed_descent(dx, DY, img, keep: float, rounds: int, R, C):
    r"""Sample-level least trimmed squares on discrete images: ``(images, summed squared
    distortion)``.

    Each round ranks the samples by their own squared residual
    :math:`\sum_j (d_X(p_i, p_j) - d_Y(q_i, q_j))^2`, descends (discrete Gauss-Seidel over
    all vertices of Y) on the best-fitting ``ceil(keep m)`` samples alone, then places the
    others greedily given them; it stops after ``rounds`` rounds or when nothing moves. A
    change of topology moves whole rows of the distances (a weld changes a nearby point's
    diffusion distance to every point: docs/design/perturbations.md), so the samples near it
    are set aside instead of pulling the others' images.
    """
    m = len(dx)
    h = max(2, int(np.ceil(keep * m - 1e-9)))
    img = np.asarray(img, dtype=np.int64).copy()
    for _ in range(rounds):
        e = dx - DY[np.ix_(img, img)]
        np.fill_diagonal(e, 0.0)
        order = np.argsort((e**2).sum(axis=1), kind="stable")
        t, u = np.sort(order[:h]), np.sort(order[h:])
        new_t, _ = _kernel.place_and_descend_blas(np.ascontiguousarray(dx[np.ix_(t, t)]), DY, img[t],
                                                  20, R[:h], C[:h])
        perm = np.concatenate([t, u])
        placed, _ = _kernel.place_and_descend_blas(np.ascontiguousarray(dx[np.ix_(perm, perm)]), DY,
                                                   new_t, 0, R, C)
        new = np.empty(m, np.int64)
        new[perm] = placed
        if np.array_equal(new, img):
            break
        img = new
    return img, float(np.sum((dx - DY[np.ix_(img, img)]) ** 2))


class _Search:
    """One direction of :func:`greedy_init`'s search, kept so that more of its coarse starts
    can be extended later (:meth:`extend_preserving`)."""

    def __init__(self, dx_pp, DY, candidates, stages, n_extend, domain, extend_keep=EXTEND_KEEP,
                 signature_costs=None):
        self.extend_keep = float(extend_keep)
        self.dx_pp = np.ascontiguousarray(dx_pp, dtype=np.float64)
        candidates = np.asarray(candidates, dtype=np.int64)
        self.DY = DY
        restricted = _on_subset(DY, domain, candidates)
        if restricted is not None:  # the whole search on the domain, then polished on all of Y
            self.dom, work, candidates = restricted
            stages = [(c, None) for c, _ in stages]
        else:
            self.dom, work = None, np.ascontiguousarray(DY, dtype=np.float64)
        self.work = work
        self.coarse = []  # per stage: (cost, images as a tuple of ids of ``work``), sorted
        runs = [(c, vertices, False) for c, vertices in stages]
        if signature_costs is not None:  # each stage again, with the signatures' costs
            if self.dom is not None:
                signature_costs = signature_costs[:, self.dom]
            runs += [(c, vertices, True) for c, vertices in stages]
        for c, vertices, signed in runs:
            c = min(int(c), len(self.dx_pp))
            head = np.ascontiguousarray(self.dx_pp[:c, :c])
            sub = _on_subset(work, vertices, candidates)
            U, k = None, len(candidates)
            if signed:  # as if each of a sample's c - 1 distances were off by its mismatch
                U, k = (c - 1) * signature_costs[:c], min(k, SIGNATURE_STARTS)
            if sub is not None:
                dom, part, cand = sub
                imgs, costs = _kernel.coarse_starts(head, part, cand[:k], 20, None if U is None else U[:, dom])
                imgs = dom[imgs]
            else:
                imgs, costs = _kernel.coarse_starts(head, work, candidates[:k], 20, U)
            self.coarse.append(sorted((float(f), tuple(img)) for f, img in zip(costs, imgs.tolist())))
        self.per_stage = -(-int(n_extend) // len(self.coarse))  # evenly, rounded up
        self.seen: set = set()
        self._R = self._C = self._plain = self._full = None
        self._polished: dict = {}

    def _extend(self, coarse_imgs, polish: bool):
        """Extend coarse starts to all samples on ``work`` (and polish them on all of Y)."""
        n = len(self.dx_pp)
        if self._R is None:
            self._R, self._C = np.empty((n, len(self.work))), np.empty((n, len(self.work)))
        out = [_kernel.place_and_descend_blas(self.dx_pp, self.work, np.asarray(img, dtype=np.int64),
                                              20, self._R, self._C) for img in coarse_imgs]
        if self.extend_keep < 1.0:
            out = [_trimmed_descent(self.dx_pp, self.work, img, self.extend_keep, EXTEND_ROUNDS,
                                    self._R, self._C) for img, _ in out]
        if self.dom is not None and polish:
            out = [self.polish(img) for img, _ in out]
        return out

    def polish(self, img):
        """``(images on Y, cost)``: discrete descent over all of Y from images on ``work``
        (each start once)."""
        key = tuple(np.asarray(img).tolist())
        if key not in self._polished:
            if self._full is None:  # Y and the work arrays of its size, once
                DY = np.ascontiguousarray(self.DY, dtype=np.float64)
                n = len(self.dx_pp)
                self._full = (DY, np.empty((n, len(DY))), np.empty((n, len(DY))))
            DY, R, C = self._full
            # all images given: no placement, discrete descent over every vertex of Y
            self._polished[key] = _kernel.place_and_descend_blas(self.dx_pp, DY, self.dom[img], 20, R, C)
        return self._polished[key]

    def extend_plain(self, polish_all: bool = True):
        """The ``n_extend`` lowest-cost coarse starts (shared out among the stages), extended:
        ``(list of (images on Y, cost), index of the best)``. Without ``polish_all`` (and with a
        domain) only the best is polished on all of Y and the others stay on the domain."""
        if self._plain is None:  # once
            todo = []
            for scored in self.coarse:
                taken = 0
                for _, img in scored:
                    if img in self.seen:
                        continue
                    self.seen.add(img)
                    todo.append(img)
                    taken += 1
                    if taken >= self.per_stage:
                        break
            self._plain = self._extend(todo, polish=False)
        every = self._plain
        costs = [cost for _, cost in every]
        best = int(np.argmin(costs))  # the first of the lowest cost
        if self.dom is not None:
            every = ([self.polish(img) for img, _ in every] if polish_all else
                     [self.polish(img) if k == best else (self.dom[img], cost)
                      for k, (img, cost) in enumerate(every)])
        return every, best

    def extend_preserving(self, orient, count: int, reversing: bool = False):
        """Up to ``count`` more starts per stage: its lowest-cost coarse starts not extended
        yet whose orientation agreement ``orient(images on Y) > 1/2`` (``< 1/2`` with
        ``reversing``); extended and polished."""
        todo = []
        for scored in self.coarse:
            rest = [img for _, img in scored if img not in self.seen]
            if not rest:
                continue
            ids = np.asarray(rest, dtype=np.int64)
            agree = orient(ids if self.dom is None else self.dom[ids])
            keep = agree < 0.5 if reversing else agree > 0.5
            chosen = [img for img, k in zip(rest, keep) if k][:count]
            self.seen.update(chosen)
            todo += chosen
        return self._extend(todo, polish=True)


def signature_mismatch(sx: "ShapeMetric", sy: "ShapeMetric", A: np.ndarray) -> np.ndarray:
    """``(len(A), n)``: squared mean absolute difference between the signatures
    (:attr:`ShapeMetric.descriptors`) of the vertices ``A`` of ``sx`` and of each working vertex
    of ``sy``, in squared distance units."""
    sb = sy.descriptors
    sa = sx.descriptors[np.asarray(A, dtype=np.int64)]
    delta = np.empty((len(sa), len(sb)))
    for k, row in enumerate(sa):  # one sample at a time: no (len(A), n, 16) temporary
        delta[k] = np.abs(sb - row).mean(axis=1)
    return delta * delta


def search_subsets(coarse_stages=DEFAULT_COARSE_STAGES, search_vertices: int | None = None) -> list[int]:
    """Sizes of the vertex subsets (:meth:`ShapeMetric.subset`) that :func:`match` searches on
    with these options, so that they can be computed once per shape."""
    if search_vertices is not None:
        return [int(search_vertices)]
    return [int(k) for _, k in coarse_stages if k is not None]


def _on_subset(DY: np.ndarray, vertices, candidates: np.ndarray):
    """``(dom, DY[dom][:, dom], candidates as positions in dom)`` with ``dom`` the given vertices
    and the candidates, sorted; None when ``vertices`` is None or ``dom`` is all of Y."""
    if vertices is None:
        return None
    dom = np.union1d(np.asarray(vertices, dtype=np.int64), candidates)
    if len(dom) >= len(DY):
        return None
    return dom, np.ascontiguousarray(DY[np.ix_(dom, dom)], dtype=np.float64), np.searchsorted(dom, candidates)


def anchored_images(DX: np.ndarray, P: np.ndarray, DY_rows: np.ndarray) -> np.ndarray:
    """Images on X of points whose distances to the images of ``P`` are ``DY_rows`` (K, M).

    Each point goes to the vertex v of X minimising sum_i (D_X(v, p_i) - d_i)^2: the
    reverse map that is consistent with a given forward map, so that the two halves of the
    two-sided correspondence start on the same branch (e.g. the same left/right choice).
    ``DX`` must be symmetric (its rows ``P`` are read for its columns).
    """
    At = DX[P]                                               # (M, n_X) = DX[:, P].T
    cost = (At * At).sum(0)[None, :] - 2.0 * (DY_rows @ At)  # + |d|^2, constant per row
    return np.argmin(cost, axis=1).astype(np.int64)


def _candidates(signature: np.ndarray, target: "ShapeMetric", k: int) -> np.ndarray:
    """The ``k`` vertices of ``target`` with the closest signatures, at least 5% of the diameter apart."""
    cost = np.abs(target.descriptors - signature).sum(axis=1)
    order = np.argsort(cost, kind="stable")
    radius = 0.05 * target.diameter
    D = target.distances
    free = np.ones(len(order), dtype=bool)  # free[i]: order[i] is farther than radius from all chosen
    chosen: list[int] = []
    while len(chosen) < k:
        i = int(np.argmax(free))
        if not free[i]:
            break
        v = int(order[i])
        chosen.append(v)
        free &= D[v][order] > radius  # D is symmetric: a row, not a column
    return np.asarray(chosen, dtype=np.int64)


def gw_coupling(dx: np.ndarray, dy: np.ndarray, *, max_iter: int = 1000) -> np.ndarray:
    """Gromov-Wasserstein coupling (M, K) of two distance matrices with uniform weights (POT)."""
    try:
        import ot
    except ImportError:  # pragma: no cover
        raise ImportError("the Gromov-Wasserstein solver needs POT: pip install pot") from None
    a = np.full(len(dx), 1.0 / len(dx))
    b = np.full(len(dy), 1.0 / len(dy))
    return ot.gromov.gromov_wasserstein(dx, dy, a, b, loss_fun="square_loss", max_iter=max_iter)


def initial_pairs(sx: "ShapeMetric", sy: "ShapeMetric", P: np.ndarray, Q: np.ndarray, *,
                  n_starts: int = DEFAULT_N_STARTS, n_extend: int = DEFAULT_N_EXTEND,
                  coarse_stages=DEFAULT_COARSE_STAGES, search_vertices: int | None = DEFAULT_SEARCH_VERTICES,
                  all_starts: bool = False, extend_keep: float = EXTEND_KEEP,
                  signature_weight: float = SIGNATURE_WEIGHT) -> list[tuple[np.ndarray, np.ndarray]]:
    """The two-sided starts of :func:`match`'s GMDS: pairs ``(images of P on Y, images of Q on X)``
    (working vertex ids).

    :func:`greedy_init` from X to Y, with the images of ``Q`` anchored on it
    (:func:`anchored_images`), then the same from Y to X: two pairs, or with ``all_starts`` one
    per extended start of each direction (``n_extend`` forward ones first). The options are
    :func:`match`'s.
    """
    st = _Starts(sx, sy, P, Q, n_starts=n_starts, n_extend=n_extend, coarse_stages=coarse_stages,
                 search_vertices=search_vertices, extend_keep=extend_keep, signature_weight=signature_weight)
    return st.plain(all_starts)


class _Starts:
    """Both directions of :func:`initial_pairs`' search, kept for more starts later."""

    def __init__(self, sx, sy, P, Q, *, n_starts, n_extend, coarse_stages, search_vertices,
                 extend_keep=EXTEND_KEEP, signature_weight=SIGNATURE_WEIGHT):
        self.sx, self.sy, self.P, self.Q = sx, sy, P, Q
        DX, DY = sx.distances, sy.distances
        self.dx_pp, self.dy_qq = DX[np.ix_(P, P)], DY[np.ix_(Q, Q)]
        cand_y = _candidates(sx.descriptors[P[0]], sy, n_starts)
        cand_x = _candidates(sy.descriptors[Q[0]], sx, n_starts)

        def search(s):  # (stages, domain): the vertex subsets of the initial search on s
            if search_vertices is not None:  # one subset for the whole search
                return [(c, None) for c, _ in coarse_stages], s.subset(search_vertices)
            return [(c, None if k is None else s.subset(k)) for c, k in coarse_stages], None

        (st_y, dom_y), (st_x, dom_x) = search(sy), search(sx)
        sig_y = sig_x = None
        if signature_weight > 0:  # per image of the first samples, on all vertices of the target
            c = max(c for c, _ in coarse_stages)
            sig_y = signature_weight * signature_mismatch(sx, sy, P[:c])
            sig_x = signature_weight * signature_mismatch(sy, sx, Q[:c])
        self.fwd = _Search(self.dx_pp, DY, cand_y, st_y, n_extend, dom_y, extend_keep, sig_y)
        self.bwd = _Search(self.dy_qq, DX, cand_x, st_x, n_extend, dom_x, extend_keep, sig_x)

    def _pairs(self, fwd, bwd):
        DX, DY, P, Q = self.sx.distances, self.sy.distances, self.P, self.Q
        return ([(f, anchored_images(DX, P, DY[np.ix_(Q, f)])) for f in fwd]
                + [(anchored_images(DY, Q, DX[np.ix_(P, b)]), b) for b in bwd])

    def plain(self, all_starts: bool):
        """Pairs of the extended starts: all of them, or each direction's best."""
        fwd, bf = self.fwd.extend_plain(polish_all=all_starts)
        bwd, bb = self.bwd.extend_plain(polish_all=all_starts)
        if not all_starts:
            return self._pairs([fwd[bf][0]], [bwd[bb][0]])
        return self._pairs([i for i, _ in fwd], [i for i, _ in bwd])

    def preserving(self, count: int, reversing: bool = False):
        """Pairs of up to ``count`` more orientation-preserving (or reversing) starts per
        stage and direction."""
        fwd = self.fwd.extend_preserving(_orient(self.sx, self.sy, self.P, self.dx_pp), count, reversing)
        bwd = self.bwd.extend_preserving(_orient(self.sy, self.sx, self.Q, self.dy_qq), count, reversing)
        return self._pairs([i for i, _ in fwd], [i for i, _ in bwd])


def _self_reflection(s: "ShapeMetric", n_samples: int, seed: int) -> np.ndarray | None:
    """:meth:`ShapeMetric.symmetry`."""
    if not s.normals[1] or n_samples > s.mesh.n_vertices:
        return None
    P = s.samples(n_samples, seed)
    # a shape against itself has no change of topology to set aside: the plain extension (with
    # the trimmed one the wolf's reflection sent 31% of its vertices astray, not 1.3%), and no
    # signature-guided stages (with them the wolf's reflection again sent 31% of its vertices
    # astray)
    search = _Starts(s, s, P, P, n_starts=DEFAULT_N_STARTS, n_extend=DEFAULT_N_EXTEND,
                     coarse_stages=DEFAULT_COARSE_STAGES, search_vertices=DEFAULT_SEARCH_VERTICES,
                     extend_keep=1.0, signature_weight=0.0)
    pairs = search.plain(all_starts=True) + search.preserving(-(-search.fwd.per_stage // 2) * 2,
                                                                 reversing=True)
    at = [_at_vertices(s, s, a, b) for a, b in pairs]
    flips = pairs_orientation(s, s, P, P, at) < 0.5
    if not flips.any():
        return None
    gm = SymmetricGMDS(s.surface, s.surface, P, P)
    scores = np.array([gm.distortion(a, b, 2.0) for a, b in at])
    img_p, img_q, _, _ = gm.solve(*at[int(np.flatnonzero(flips)[np.argmin(scores[flips])])])
    D = s.distances
    for _ in range(INVOLUTION_REPAIRS):
        # a reflection is its own inverse: both halves of the self-map must agree. Where
        # they do not (on a quadruped: a leg sent to another leg, a map of lower distortion
        # than the reflection in the diffusion metric), re-anchor those samples on the
        # agreeing ones and descend again from the one-map start
        f, g = img_p.vertex(s.mesh.faces), img_q.vertex(s.mesh.faces)
        ok = D[f, g] < INVOLUTION_TOL * s.diameter
        if ok.all() or ok.sum() < 3:
            break
        f[~ok] = anchored_images(D, f[ok], D[np.ix_(P[~ok], P[ok])])
        img_p, img_q, _, _ = gm.solve(*_at_vertices(s, s, f, f))
    if not (pair_orientation(s, s, P, P, img_p, img_q) < 0.5
            and gm.distortion(img_p, img_q, 2.0) < SYMMETRY_TOL * s.diameter):
        return None
    images = img_p.vertex(s.mesh.faces)
    return anchored_images(D, images, D[:, P])


def _at_vertices(sx, sy, img_p, img_q) -> tuple[SurfacePoints, SurfacePoints]:
    return SurfacePoints.at_vertices(sy.mesh, img_p), SurfacePoints.at_vertices(sx.mesh, img_q)


def discrete_blocks(DX: np.ndarray, DY: np.ndarray, P: np.ndarray, Q: np.ndarray, img_p: np.ndarray,
                    img_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`SymmetricGMDS.blocks` of a correspondence whose images are vertices (or points of
    a cloud): the distances on X between ``[P, img_q]`` and on Y between ``[img_p, Q]``, read
    off the dense matrices (the same values the interpolation gives at vertices)."""
    a, b = np.r_[P, img_q].astype(np.int64), np.r_[img_p, Q].astype(np.int64)
    return DX[np.ix_(a, a)], DY[np.ix_(b, b)]


def _images_at_points(s: "ShapeMetric", images: np.ndarray):
    """``(face, bary, vertex)`` in input terms of images at working vertices: on a mesh the
    input point there (:meth:`ShapeMetric.locate`), on a point cloud the input point itself with
    face -1 and NaN coordinates (a cloud has no faces)."""
    if s.has_faces:
        return s.locate(SurfacePoints.at_vertices(s.mesh, images))
    n = len(images)
    return np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan), s.working.to_input_ids(images)


def _orient(sa: "ShapeMetric", sb: "ShapeMetric", A: np.ndarray, da: np.ndarray):
    """The orientation agreement of vertex images ``(s, c)`` on ``sb`` of the first ``c`` of
    the samples ``A`` of ``sa`` (``da`` their distances)."""
    (na, _), (nb, _) = sa.normals, sb.normals
    xa, xb = sa.mesh.vertices, sb.mesh.vertices

    def agreement(imgs: np.ndarray) -> np.ndarray:
        imgs = np.asarray(imgs, dtype=np.int64)
        c = imgs.shape[1]
        head = A[:c]
        return orientation_agreements(xa[head], na[head], da[:c, :c], xb[imgs], nb[imgs])

    return agreement


def pair_orientation(sx: "ShapeMetric", sy: "ShapeMetric", P: np.ndarray, Q: np.ndarray,
                     img_p: SurfacePoints, img_q: SurfacePoints) -> float:
    """Orientation agreement of a two-sided correspondence (the mean of its two directions;
    :func:`gromov.orientation.orientation_agreement`); NaN unless both working meshes are
    orientable."""
    return float(pairs_orientation(sx, sy, P, Q, [(img_p, img_q)])[0])


def pairs_orientation(sx: "ShapeMetric", sy: "ShapeMetric", P: np.ndarray, Q: np.ndarray,
                      pairs: list) -> np.ndarray:
    """:func:`pair_orientation` of several correspondences ``(img_p, img_q)`` of the same
    samples at once (the samples' neighbour triangles are found once)."""
    (nx, okx), (ny, oky) = sx.normals, sy.normals
    if not (okx and oky):
        return np.full(len(pairs), np.nan)
    out = []
    for side, (sa, sb, A, nb) in enumerate(((sx, sy, P, ny), (sy, sx, Q, nx))):
        imgs = [pair[side] for pair in pairs]
        pos = np.stack([img.positions(sb.mesh.vertices, sb.mesh.faces) for img in imgs])
        nrm = np.stack([np.einsum("kc,kcd->kd", img.bary, nb[sb.mesh.faces[img.face]]) for img in imgs])
        out.append(orientation_agreements(sa.mesh.vertices[A], sa.normals[0][A], sa.distances[np.ix_(A, A)],
                                          pos, nrm))
    return 0.5 * (out[0] + out[1])


# ----------------------------------------------------------------------------- match
def check_rank_tau_scale(value) -> float | None:
    """``rank_tau_scale`` as a float (or None), or ``ValueError`` unless a positive finite number."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not 0.0 < value < np.inf:
        raise ValueError(f"rank_tau_scale must be a positive number or None, got {value!r}")
    return float(value)


def check_rank_residual(value) -> str:
    """``rank_residual`` if it is one of :data:`RANK_RESIDUALS`, else ``ValueError``."""
    if not isinstance(value, str) or value not in RANK_RESIDUALS:
        raise ValueError(f"rank_residual must be one of {RANK_RESIDUALS}, got {value!r}")
    return value


def ranking_value(dx: np.ndarray, dy: np.ndarray, diameter: float, residual: str = "difference") -> float:
    """Half the trimmed RMS (:func:`gromov.gmds.trimmed_rms`) of a correspondence's residuals:
    ``(dx - dy) / diameter`` (``"difference"``) or :func:`gromov.gmds.log_ratio_residuals` with
    the floor ``RANK_LOG_FLOOR * diameter`` (``"log"``). ``dx``, ``dy``: the distances between
    corresponding points (diagonal ignored); ``diameter``: the larger of the two shapes'."""
    check_rank_residual(residual)
    if residual == "log":
        return 0.5 * trimmed_rms(log_ratio_residuals(dx, dy, RANK_LOG_FLOOR * diameter))
    off = ~np.eye(len(dx), dtype=bool)
    return 0.5 * trimmed_rms((dx - dy)[off]) / diameter


def _metric_signature(s: "ShapeMetric") -> str:
    """The solver's type and parameters (not its size): what two shapes must share for their
    distances to be compared. A hole-filling wrapper is looked through (it is there or not
    depending on the mesh, not on the options)."""
    import re

    solver = getattr(s.solver, "inner", s.solver)
    return re.sub(r"n_vertices=\d+,? ?", "", repr(solver))


def match_options_for(shapes, metric: str, metric_options: dict | None) -> dict:
    """Metric options for the shapes of a correspondence that are not prepared yet.

    Given ``metric_options``: :func:`~gromov.metrics.diffusion.correspondence_options` of
    them. Not given: those of the first prepared :class:`ShapeMetric` among ``shapes`` (so
    that both sides of a match measure in the same metric), else the correspondence's
    defaults (normalised heat distributions for the heat kernel).
    """
    if metric_options is None:
        for s in shapes:
            if isinstance(s, ShapeMetric) and s.metric == metric:
                return dict(s.metric_options)
    return correspondence_options(metric, metric_options)


def _as_shape(s, metric, resolution, metric_options, name: str) -> ShapeMetric:
    if isinstance(s, ShapeMetric):
        if s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        return s
    if not isinstance(s, (str, os.PathLike)):
        s = as_shape(s, name=name)   # arrays and mesh objects: errors and warnings name X or Y
    return ShapeMetric(s, metric, resolution=resolution, metric_options=metric_options)


def match(X, Y, metric: str = "diffusion", *, n_samples: int = 100, norm="l2", solver: str = "gmds",
          init: str = "greedy", n_starts: int = DEFAULT_N_STARTS, n_extend: int = DEFAULT_N_EXTEND,
          coarse_stages=DEFAULT_COARSE_STAGES,
          search_vertices: int | None = DEFAULT_SEARCH_VERTICES, seed: int = 0,
          resolution: int | None = DEFAULT_RESOLUTION,
          metric_options: dict | None = None, max_iter: int = 100, tol: float = 1e-6,
          radius: float | None = None, orientation: str = "prefer",
          extend_keep: float = EXTEND_KEEP, signature_weight: float = SIGNATURE_WEIGHT,
          rank_tau_scale: float | None = None, rank_residual: str = "difference",
          dense: bool | str = False) -> MatchResult:
    r"""Gromov-Hausdorff distance and correspondence between two shapes.

    Minimises the distortion of a two-sided correspondence C between farthest point samples,
    :math:`\hat d_{GH}(X, Y) = \tfrac12 \min_C \mathrm{dis}_p(C)`, by symmetric GMDS from a
    multi-start initial search (Bronstein et al., IJCV 2010, §2 and §4). How the search and
    its defaults were chosen: docs/design/initial-search.md.

    Parameters
    ----------
    X, Y : Mesh, PointCloud, path, (vertices, faces), (n, 3) array, trimesh.Trimesh or ShapeMetric
        A :class:`ShapeMetric` reuses its metric. With a point cloud on either side the map is
        the search's discrete one: images at points (face -1, NaN barycentrics).
    metric : {"diffusion", "geodesic", "euclidean"}, default "diffusion"
    n_samples : int, default 100
        Farthest point samples per shape.
    norm : {"l2", "linf"} or "p:VALUE", default "l2"
        Norm of the distortion that is minimised and reported as ``distance``.
    solver, init : {"gmds", "gw"}, {"greedy", "gw"}, default "gmds", "greedy"
        Symmetric GMDS or the Gromov-Wasserstein coupling (POT); GMDS's start ("gw": the argmax).
    n_starts, n_extend : int, default 128, 8
        Candidate images of the first sample (closest signatures, at least 5% of the diameter
        apart), and coarse starts per direction extended to all samples.
    coarse_stages : sequence of (int, int or None), default ((12, None), (20, 1000))
        Each stage places the first ``c`` samples from every candidate, over ``k`` farthest
        point samples of the target (None: all its working vertices).
    search_vertices : int or None, default None
        Run the search on this many farthest point samples of each target (faster).
    seed : int, default 0
        Seeds the farthest point sampling; the rest is deterministic.
    resolution : int or None, default 3000
        Working mesh size for shapes not prepared already (None: the input as it is).
    metric_options : dict, optional
        Default: a prepared shape's, else :func:`~gromov.metrics.diffusion.correspondence_options`.
    max_iter, tol : int, float, default 100, 1e-6
        GMDS sweeps and relative stopping tolerance.
    radius : float, optional
        Partial matching: only pairs of samples closer than ``radius`` count.
    orientation : {"prefer", "ignore"}, default "prefer"
        "prefer": a mirrored map is replaced by an orientation-preserving one within
        ``ORIENTATION_TOL`` (10%) of its distortion, or by its composition with a reflection
        within ``FLIP_TOL`` (25%), clearly direct maps first (:mod:`gromov.orientation`).
    extend_keep : float, default 1
        Below 1: each extended start descends on this fraction of its samples
        (``EXTEND_ROUNDS`` rounds of sample-level least trimmed squares).
    signature_weight : float, default 1
        Weight w of the per-image cost :math:`w\,(c - 1)\,\delta(k, v)^2` (δ: signature
        mismatch) in each coarse stage's second run, from ``SIGNATURE_STARTS`` candidates; 0: off.
    rank_tau_scale, rank_residual : float or None, {"difference", "log"}, default None, "difference"
        How ``ranking_distance`` is measured (:func:`ranking_value`): with the heat distance
        at this times the diffusion time, of distance differences or log ratios.
    dense : bool, "zoomout" or "placed", default False
        Also map every input vertex (:mod:`gromov.dense`), refined by ZoomOut unless "placed".

    Returns
    -------
    MatchResult

    Examples
    --------
    >>> r = match("cat0.off.gz", "cat1.off.gz")                 # doctest: +SKIP
    >>> r.relative_distance, r.x_to_y_vertex[:3]                # doctest: +SKIP
    """
    t0 = time.perf_counter()
    p = parse_norm(norm)
    norm_name = "l2" if p == 2 else ("linf" if np.isinf(p) else f"p:{p:g}")
    if solver not in ("gmds", "gw"):
        raise ValueError(f"solver must be 'gmds' or 'gw', got {solver!r}")
    if init not in ("greedy", "gw"):
        raise ValueError(f"init must be 'greedy' or 'gw', got {init!r}")
    if orientation not in ("ignore", "prefer"):
        raise ValueError(f"orientation must be 'ignore' or 'prefer', got {orientation!r}")
    if not 0.0 < extend_keep <= 1.0:
        raise ValueError(f"extend_keep must be in (0, 1], got {extend_keep!r}")
    check_rank_tau_scale(rank_tau_scale)
    check_rank_residual(rank_residual)
    if not (np.isfinite(signature_weight) and signature_weight >= 0):
        raise ValueError(f"signature_weight must be a finite number >= 0, got {signature_weight!r}")
    checked = [("n_starts", n_starts), ("n_extend", n_extend)]
    if search_vertices is not None:
        checked.append(("search_vertices", search_vertices))
    for name, value in checked:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    try:
        coarse_stages = [(int(c), None if k is None else int(k)) for c, k in coarse_stages]
    except (TypeError, ValueError):
        raise ValueError("coarse_stages must be pairs (samples, vertices or None), got "
                         f"{coarse_stages!r}") from None
    if not coarse_stages or any(c < 1 or (k is not None and k < 1) for c, k in coarse_stages):
        raise ValueError(f"coarse_stages must be non-empty pairs of positive sizes, got {coarse_stages!r}")
    metric_options = match_options_for((X, Y), metric, metric_options)
    sx = _as_shape(X, metric, resolution, metric_options, "X")
    sy = _as_shape(Y, metric, resolution, metric_options, "Y")
    if sx.has_faces != sy.has_faces and metric != "euclidean":   # (straight lines: the same either way)
        warnings.warn(f"{'Y' if sx.has_faces else 'X'} is a point cloud and the other a mesh: their "
                      f"{metric} distances are computed differently (a mesh's own construction, a "
                      "cloud's from its nearest neighbours), so the distortion compares two metrics; "
                      "for comparable distances match the mesh's vertices as a point cloud too",
                      GromovWarning, stacklevel=2)
    elif _metric_signature(sx) != _metric_signature(sy):
        warnings.warn(f"X and Y measure distances differently ({_metric_signature(sx)} vs "
                      f"{_metric_signature(sy)}): their distortion compares two different metrics; "
                      f"prepare both ShapeMetrics with the same metric_options", GromovWarning, stacklevel=2)
    for name, s in (("X", sx), ("Y", sy)):
        if n_samples > s.mesh.n_vertices:
            raise ValueError(f"n_samples={n_samples} exceeds the {s.mesh.n_vertices} working vertices of {name}")
    if n_samples < 3:
        raise ValueError(f"n_samples must be at least 3, got {n_samples}")
    # a point cloud has no faces: images stay at points (the initial search's discrete maps)
    discrete = not (sx.has_faces and sy.has_faces)
    if discrete and radius is not None:
        raise ValueError("radius (partial matching) weighs the GMDS refinement on the surfaces, which "
                         "needs triangle meshes; X or Y is a point cloud")
    for name, s in (("X", sx), ("Y", sy)):
        if discrete and not s.finite:   # (on meshes SurfaceDistance says so)
            raise MetricError(f"{name}: matching needs finite distances, got inf or NaN (a shape in "
                              f"pieces: a point cloud whose {s.metric} neighbour graph falls apart -- "
                              "give the geodesic metric more neighbours, metric_options={'k': ...} -- "
                              "or a mesh with several components: use Mesh.largest_component())")
    P, Q = sx.samples(n_samples, seed), sy.samples(n_samples, seed)
    DX, DY = sx.distances, sy.distances
    dx_pp, dy_qq = DX[np.ix_(P, P)], DY[np.ix_(Q, Q)]
    gm = None if discrete else SymmetricGMDS(sx.surface, sy.surface, P, Q, p=p, max_iter=max_iter,
                                             tol=tol, radius=radius)

    def score(a, b):   # the two-sided L2 distortion of a start (vertex images)
        if discrete:
            ex, ey = discrete_blocks(DX, DY, P, Q, a, b)
            return norm_value((ex - ey)[~np.eye(len(ex), dtype=bool)], 2.0)
        return gm.distortion(*_at_vertices(sx, sy, a, b), 2.0)

    prefer = orientation == "prefer" and solver == "gmds" and init == "greedy" and not discrete
    if prefer and not (sx.normals[1] and sy.normals[1]):
        warnings.warn("orientation='prefer' needs orientable working meshes (a Moebius-like "
                      "piece cannot be given an outward side); ignored", GromovWarning, stacklevel=2)
        prefer = False
    if solver == "gw" or init == "gw":
        T = gw_coupling(dx_pp, dy_qq)
        img_p0, img_q0 = Q[np.argmax(T, axis=1)], P[np.argmax(T, axis=0)]
    else:
        # each direction on its own, then the other direction anchored on it; keep the
        # consistent pair with the lower two-sided distortion
        search = _Starts(sx, sy, P, Q, n_starts=n_starts, n_extend=n_extend, coarse_stages=coarse_stages,
                         search_vertices=search_vertices, extend_keep=extend_keep,
                         signature_weight=signature_weight)
        pairs = search.plain(all_starts=False)
        scores = [score(a, b) for a, b in pairs]
        img_p0, img_q0 = pairs[int(np.argmin(scores))]
    n_iter, converged, history, orient = 0, True, [], float("nan")
    if not discrete:
        img_p, img_q = _at_vertices(sx, sy, img_p0, img_q0)
        if solver == "gmds":
            img_p, img_q, n_iter, converged = gm.solve(img_p, img_q)
        history = list(gm.history)
        orient = pair_orientation(sx, sy, P, Q, img_p, img_q)
    if prefer and not orient > 0.5:
        # a mirrored (or scrambled) map: GMDS from the best orientation-preserving start too,
        # among the extended starts and more preserving ones; keep it if nearly as good
        pairs = search.plain(all_starts=True) + search.preserving(-(-search.fwd.per_stage // 2))
        at = [_at_vertices(sx, sy, a, b) for a, b in pairs]
        keep = pairs_orientation(sx, sy, P, Q, at) > 0.5
        d_first = gm.distortion(img_p, img_q, 2.0)

        def attempt(start, tol_k):
            h0 = len(gm.history)
            alt = gm.solve(*start)
            o_alt = pair_orientation(sx, sy, P, Q, alt[0], alt[1])
            if o_alt > 0.5 and gm.distortion(alt[0], alt[1], 2.0) <= (1.0 + tol_k) * d_first:
                return (*alt, gm.history[h0:], o_alt)
            return None

        # a clearly direct map (agreement above 1/2 + DIRECT_MARGIN) is taken at once; one that
        # is direct only on part of the shapes (agreement near 1/2) only if no clearly direct
        # one turns up -- first the preserving start, then the compositions
        found = partial = None
        if keep.any():  # the best orientation-preserving start
            scores = np.array([gm.distortion(a, b, 2.0) for a, b in at])
            alt = attempt(at[int(np.flatnonzero(keep)[np.argmin(scores[keep])])], ORIENTATION_TOL)
            if alt is not None and alt[-1] > 0.5 + DIRECT_MARGIN:
                found = alt
            else:
                partial = alt
        if found is None:  # the mirrored map composed with a reflection of X, then of Y
            fp, gq = img_p.vertex(sy.mesh.faces), img_q.vertex(sx.mesh.faces)
            for s_ in (sx, sy):
                sym = s_.symmetry(n_samples, seed)
                if sym is None:
                    continue
                if s_ is sx:  # f o S_X on P (f carried to S_X(P) by its distances), S_X o g on Q
                    start = (anchored_images(DY, fp, DX[np.ix_(sym[P], P)]), sym[gq])
                else:         # S_Y o f on P, g o S_Y on Q
                    start = (sym[fp], anchored_images(DX, gq, DY[np.ix_(sym[Q], Q)]))
                alt = attempt(_at_vertices(sx, sy, *start), FLIP_TOL)
                if alt is not None and alt[-1] > 0.5 + DIRECT_MARGIN:
                    found = alt
                    break
                if partial is None:
                    partial = alt
        if found is None:
            found = partial
        if found is not None:
            img_p, img_q, n_iter, converged, history, orient = found

    dx, dy = discrete_blocks(DX, DY, P, Q, img_p0, img_q0) if discrete else gm.blocks(img_p, img_q)
    residual = dx - dy
    np.fill_diagonal(residual, 0.0)   # not a pair (an interpolated self-distance need not be 0)
    r = residual[~np.eye(len(dx), dtype=bool)]
    dis = norm_value(r, p)
    d_l2, d_linf, d_trim = norm_value(r, 2.0), norm_value(r, np.inf), trimmed_rms(r)
    diam = max(sx.diameter, sy.diameter)
    mx = my = None
    if rank_tau_scale is not None:
        mx, my = sx.ranking_surface(rank_tau_scale), sy.ranking_surface(rank_tau_scale)
    if mx is not None and my is not None:   # the same correspondence in the finer heat metric
        if discrete:
            ex, ey = mx[0].block(np.r_[P, img_q0]), my[0].block(np.r_[img_p0, Q])
        else:
            ex, ey = SymmetricGMDS(mx[0], my[0], P, Q).blocks(img_p, img_q)
        ranking = ranking_value(ex, ey, max(mx[1], my[1]), rank_residual)
    else:                                   # in the match's metric ("difference": relative_trimmed)
        ranking = ranking_value(dx, dy, diam, rank_residual)
    if discrete:
        xy_face, xy_bary, xy_vertex = _images_at_points(sy, img_p0)
        yx_face, yx_bary, yx_vertex = _images_at_points(sx, img_q0)
    else:
        xy_face, xy_bary, xy_vertex = sy.locate(img_p)
        yx_face, yx_bary, yx_vertex = sx.locate(img_q)
    extra = {}
    if dense:
        from .dense import dense_maps

        on_x, on_y = ((P, img_q0), (img_p0, Q)) if discrete else ((P, img_q), (img_p, Q))
        if dense not in (True, "zoomout", "placed"):
            raise ValueError(f"dense must be True, False, 'zoomout' or 'placed', got {dense!r}")
        mxy, myx = dense_maps(sx, sy, on_x, on_y, refine=None if dense == "placed" else "zoomout")
        extra = {"x_to_y_dense_face": mxy.face, "x_to_y_dense_bary": mxy.bary, "x_to_y_dense_vertex": mxy.vertex,
                 "y_to_x_dense_face": myx.face, "y_to_x_dense_bary": myx.bary, "y_to_x_dense_vertex": myx.vertex,
                 "input_faces": (_file_faces(sx), _file_faces(sy))}
    return MatchResult(
        distance=0.5 * dis, relative_distance=0.5 * dis / diam, distortion=dis,
        distortion_l2=d_l2, distortion_linf=d_linf, norm=norm_name, metric=metric, solver=solver,
        n_samples=int(n_samples),
        x_samples=sx.working.to_input_ids(P), x_to_y_face=xy_face, x_to_y_bary=xy_bary,
        x_to_y_vertex=xy_vertex,
        y_samples=sy.working.to_input_ids(Q), y_to_x_face=yx_face, y_to_x_bary=yx_bary,
        y_to_x_vertex=yx_vertex,
        n_iter=int(n_iter), converged=bool(converged), seconds=time.perf_counter() - t0,
        orientation=orient, distortion_trimmed=d_trim, relative_trimmed=0.5 * d_trim / diam,
        ranking_distance=ranking,
        pair_distortion=residual,
        history=np.asarray(history), **extra)


def _file_faces(s: "ShapeMetric") -> np.ndarray | None:
    """Faces of the input mesh in file vertex ids (None for a point cloud)."""
    return s.input.input_ids[s.input.faces] if s.has_faces else None
