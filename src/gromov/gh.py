r"""The Gromov-Hausdorff distance between two shapes: :func:`match` and :class:`ShapeMetric`.

:math:`\hat d_{GH}(X, Y) = \tfrac12 \min_C \mathrm{dis}(C)` over two-sided correspondences
between farthest-point samples, minimised by symmetric GMDS (:mod:`gromov.gmds`) from a
global initial guess (Bronstein et al., IJCV 2010, §2 and §4). ``solver="gw"`` instead
takes the Gromov-Wasserstein coupling of the two sample distance matrices (POT) and reads a
correspondence off it, so both are judged by the same distortion.
"""

from __future__ import annotations

import inspect
import logging
import numbers
import os
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit

from ._arrays import one_blas_thread, readonly
from ._project import _project_among
from .errors import GromovWarning, MetricError
from .gmds import (EmbeddedDistance, SurfaceDistance, SurfacePoints, SymmetricGMDS, log_ratio_residuals,
                   norm_value, parse_norm, trimmed_rms)
from .mesh import Mesh, as_shape
from .metrics import metric_solver
from .metrics.diffusion import correspondence_options
from .orientation import outward_normals
from .resolution import WorkingCloud, WorkingMesh, gather, ring_candidates, working_shape
from .sampling import farthest_point_sampling
# the initial search (its names stay importable from here)
from .search import (DEFAULT_COARSE_STAGES, DEFAULT_N_EXTEND, DEFAULT_N_STARTS,  # noqa: F401
                     DEFAULT_SEARCH_VERTICES, EXTEND_KEEP, EXTEND_ROUNDS, INVOLUTION_REPAIRS, INVOLUTION_TOL,
                     SIGNATURE_STARTS, SIGNATURE_WEIGHT, SYMMETRY_TOL, SearchOptions, _at_vertices,
                     _anchor_rows, _candidates, _on_subset, _orient, _Search, _self_reflection, _Starts,
                     _trimmed_descent, anchored_images, greedy_init, initial_pairs, pair_orientation,
                     pairs_orientation, search_subsets, signature_mismatch)

__all__ = ["ShapeMetric", "MatchResult", "match", "SearchOptions"]

logger = logging.getLogger(__name__)

from ._defaults import DEFAULT_RESOLUTION  # noqa: E402
#: ``match(..., orientation="prefer")`` keeps an orientation-preserving correspondence when its
#: distortion is at most this much (relative) above the best one found.
ORIENTATION_TOL = 0.1
#: A map counts as clearly direct when its orientation agreement is above 1/2 + this; "prefer"
#: takes a clearly direct alternative before one that is direct only just. A map direct on one
#: part of the shapes and mirrored on the rest (a *partial* flip: one leg sent to the other
#: side) has an agreement near 1/2 (held-out TOSCA, diffusion: 0.54-0.58; the right direct maps
#: 0.69-0.93) -- but so do some noisy right maps (geodesic: down to 0.54), hence only a preference.
DIRECT_MARGIN = 0.15
#: A direct map is also weighed against the other clearly direct starts of the search whose
#: distortion is at most this much (relative) above its own: a body's half turn about its long
#: axis (left to right and front to back) keeps the orientation and nearly the distances
#: (:mod:`gromov.curvature`) ...
TURN_TOL = 0.1
#: ... and replaced by the one whose images keep the smoothed mean curvature best, when that
#: one's mismatch is lower by at least this fraction (docs/design/initial-search.md, "Half turns").
TURN_MARGIN = 0.1
#: ... and a map obtained by composing the mirrored one with a reflection of either shape
#: (:meth:`ShapeMetric.symmetry`) when within this much; chosen on the held-out classes.
FLIP_TOL = 0.25
#: Recognition (:func:`gromov.experiments.gh_matrix`) ranks a pair of shapes by the trimmed
#: distortion of the correspondence found with the heat-kernel diffusion metric at time
#: ``tau``, *measured* with the heat distance at ``RANK_TAU_SCALE * tau`` (a finer scale) on
#: the same eigenpairs (:meth:`HeatDiffusionSolver.at_tau
#: <gromov.metrics.diffusion.HeatDiffusionSolver.at_tau>`); see
#: :func:`gromov.experiments.gh_matrix`'s ``rank_tau_scale``. Chosen on the validation sets: the margin of the diffusion ranking rises
#: in six readings of seven, e.g. synthetic welds 0.988 -> 1.427 (``.venv/bin/python
#: benchmarks/bench_rank_residual.py``, "difference @1" against "@0.5"; see
#: docs/design/recognition.md).
from ._defaults import RANK_TAU_SCALE  # noqa: E402
#: How recognition summarises the residuals of a correspondence (see
#: :func:`gromov.experiments.gh_matrix`'s ``rank_residual``): ``"log"``, the trimmed RMS of the log ratios of corresponding distances
#: (:func:`gromov.gmds.log_ratio_residuals`, a multiplicative distortion), or
#: ``"difference"``, that of their differences over the larger diameter (the additive form).
#: Chosen on the validation sets: the diffusion margin is larger in seven readings of eight and
#: equal in the eighth (``.venv/bin/python benchmarks/bench_rank_residual.py``; see
#: docs/design/recognition.md).
from ._defaults import RANK_RESIDUAL  # noqa: E402
from ._defaults import RANK_RESIDUALS  # noqa: E402
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
        Passed to :func:`gromov.metrics.metric_solver` as they are: without ``units`` or
        ``tau``, the heat kernel measures in raw units (recognition's,
        :func:`gromov.experiments.gh_matrix`). :func:`match` measures a correspondence in
        :func:`~gromov.metrics.diffusion.correspondence_options` of them (normalised units
        unless named), as it would the file: where those differ, it matches this shape's
        :meth:`for_correspondence`, so that ``match(ShapeMetric(f), g)`` and ``match(f, g)``
        give the same result.
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
        self._anchor_cache: dict = {}   # (rows, column sums of squares) at the samples, per samples key
        self._rings = None   # CSR of each working vertex and its neighbours (locate)
        self._descriptors: np.ndarray | None = None
        self._diameter: float | None = None
        self._finite: bool | None = None
        self._owned = None
        self._lb_basis = None   # Laplace-Beltrami eigenpairs of the working mesh (gromov.dense)
        self._input_basis = None   # ... and of the input mesh
        self._input_rings = None   # (rings, CSR): each input vertex's neighbourhood (gromov.dense)
        self._same_as_input: bool | None = None
        self._normals: tuple[np.ndarray, bool] | None = None
        self._curvature: np.ndarray | None = None
        self._symmetry: dict = {}
        self._ranking: dict = {}
        self._correspondence: ShapeMetric | None = None

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

    @property
    def curvature(self) -> np.ndarray:
        """Smoothed, scale-free signed mean curvature at the working vertices
        (:func:`gromov.curvature.mean_curvature`; computed once; zeros for a point cloud)."""
        if self._curvature is None:
            if self.has_faces:
                from .curvature import mean_curvature

                self._curvature = mean_curvature(self.mesh, self.normals[0])
            else:
                self._curvature = np.zeros(self.mesh.n_vertices)
        return self._curvature

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
        metric is not the heat-kernel diffusion distance. What recognition measures a
        correspondence with (:func:`gromov.experiments.gh_matrix`'s ``rank_tau_scale``)."""
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

    def for_correspondence(self) -> ShapeMetric:
        """This shape in the metric :func:`match` measures a correspondence in: itself when its
        options are already :func:`~gromov.metrics.diffusion.correspondence_options` of
        themselves, else a ShapeMetric of the same input and working mesh with those options
        (made once). Matching a file prepares it the same way, so both give the same result."""
        options = correspondence_options(self.metric, self.metric_options)
        if options == self.metric_options:
            return self
        if self._correspondence is None:
            self._correspondence = ShapeMetric(self.input, self.metric, metric_options=options,
                                               working=self.working)
        return self._correspondence

    def samples(self, n: int, seed: int = 0) -> np.ndarray:
        """``n`` farthest point samples (working vertex ids), cached per ``(n, seed)``."""
        key = (int(n), int(seed))
        if key not in self._samples:
            self._samples[key] = farthest_point_sampling(self.distances, n, seed=seed).indices
        return self._samples[key]

    def _anchors(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(distances[P], column sums of distances[P]**2)``: what the initial search reads of
        this shape to anchor images on it (:func:`gromov.search.anchored_images`); kept for its
        farthest point samples (:meth:`samples`), computed afresh for other vertices."""
        P = np.asarray(P, dtype=np.int64)
        for key, samples in self._samples.items():
            if samples is P or np.array_equal(samples, P):
                if key not in self._anchor_cache:
                    self._anchor_cache[key] = tuple(readonly(a) for a in _anchor_rows(self.distances, samples))
                return self._anchor_cache[key]
        return _anchor_rows(self.distances, P)

    def subset(self, k: int) -> np.ndarray:
        """``k`` farthest point samples (seed 0; all vertices if fewer): the vertex subset an
        initial search of :func:`match` runs on (:class:`SearchOptions`' ``coarse_stages``,
        ``search_vertices``)."""
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
            face, bary = self._project(pts)
        vertex = self.input.faces[face, np.argmax(bary, axis=1)]
        return face, bary, self.input.input_ids[vertex]

    def _project(self, pts: SurfacePoints) -> tuple[np.ndarray, np.ndarray]:
        """``(face, bary)`` on the input mesh of points on the working mesh: what
        :func:`gromov._project.project_among` gives for the input vertices that each point's
        three rings own, with each input face tried once, where first met (the same closest
        point: a face tried again can only tie with itself)."""
        if self._rings is None:   # per shape: each working vertex, then its neighbours
            n = self.mesh.n_vertices
            self._rings = ring_candidates(self.mesh, np.arange(n))
        own_ptr, own_ids = self.owned
        corners = self.mesh.faces[np.asarray(pts.face, dtype=np.int64)].ravel()   # 3 per point
        ring_ptr, ring = gather(*self._rings, np.arange(len(corners) + 1), corners)
        cand_ptr, cand = gather(own_ptr, own_ids, ring_ptr[::3], ring)   # input vertices per point
        vf_ptr, vf_ids = self.input.vertex_faces
        face_ptr, faces = _first_faces(cand_ptr, cand, vf_ptr, vf_ids, len(self.input.faces))
        if (face_ptr[1:] == face_ptr[:-1]).any():
            i = int(np.argmax(face_ptr[1:] == face_ptr[:-1]))
            raise ValueError(f"point {i} has no candidate vertex with a face")
        one = np.arange(len(faces) + 1, dtype=np.int64)   # each candidate is one face
        pos = np.ascontiguousarray(pts.positions(self.mesh.vertices, self.mesh.faces), dtype=np.float64)
        face, bary, _ = _project_among(*(readonly(a) for a in (
            pos, np.ascontiguousarray(self.input.vertices, dtype=np.float64),
            np.ascontiguousarray(self.input.faces, dtype=np.int64), one, faces, face_ptr,
            np.ascontiguousarray(one[:-1]))))
        return face, bary

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
        reproduce``): from :func:`match`, ``relative_trimmed``; from
        :func:`gromov.experiments.gh_matrix`, with its ``rank_tau_scale`` and the heat-kernel
        diffusion metric, the same quantity for the same correspondence measured with the heat
        distance at ``rank_tau_scale`` times the diffusion time (diameters in that metric);
        with its ``rank_residual="log"``, of the log ratios of the distances instead of their
        differences (:func:`ranking_value`).
    pair_distortion : ndarray (M+K, M+K)
        ``D_X(C) - D_Y(C)`` of the final two-sided correspondence C = (P x Q') u (P' x Q): rows
        and columns are first X's M samples (on Y: their images), then Y's K samples (on X:
        their images), in the order of ``x_samples`` and ``y_samples``. Where a shape's
        topology changed, the pairs whose paths run through the change can stand out.
    gh_interval : (float, float)
        A certified interval ``(lower, upper)`` around the Gromov-Hausdorff distance between
        the two sample sets, :math:`d_{GH}(P, Q)` with the shapes' distances (the metric of the
        match, the L-infinity GH; :mod:`gromov.bounds`): the lower bound from the sets of
        distances each sample sees (Mémoli 2011, §6), which holds whatever correspondence was
        found; the upper bound half the largest distortion of the correspondence found, each
        image snapped to the nearest sample of the other shape. Only :func:`match` computes it
        (NaN from :func:`gromov.experiments.gh_matrix`, whose pairs skip it).
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
    gh_interval: tuple[float, float] = (float("nan"), float("nan"))
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
                "gh_interval": [v if np.isfinite(v) else None for v in self.gh_interval],
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


# ----------------------------------------------------------------------------- match
@dataclass
class _Fit:
    """A two-sided correspondence during :func:`match`: the images of P on Y and of Q on X
    (surface points, or vertex ids where a point cloud keeps the maps discrete), with the
    GMDS run that gave it."""

    img_p: SurfacePoints | np.ndarray
    img_q: SurfacePoints | np.ndarray
    n_iter: int = 0
    converged: bool = True
    history: list = field(default_factory=list)
    orientation: float = float("nan")


def match(X, Y, metric: str = "diffusion", *, n_samples: int = 100, norm="l2", solver: str = "gmds",
          init: str = "greedy", seed: int = 0, resolution: int | None = DEFAULT_RESOLUTION,
          metric_options: dict | None = None, radius: float | None = None, orientation: str = "prefer",
          search: SearchOptions | None = None, dense: bool | str = False, **deprecated) -> MatchResult:
    r"""Gromov-Hausdorff distance and correspondence between two shapes.

    Minimises the distortion of a two-sided correspondence C between farthest point samples,
    :math:`\hat d_{GH}(X, Y) = \tfrac12 \min_C \mathrm{dis}_p(C)`, by symmetric GMDS from a
    multi-start initial search (Bronstein et al., IJCV 2010, §2 and §4): the metrics, the
    samples, the search (:mod:`gromov.search`), GMDS, the distortion, the images.

    Parameters
    ----------
    X : Mesh, PointCloud, path, (vertices, faces), (n, 3) array, trimesh.Trimesh or ShapeMetric
        The first shape. A :class:`ShapeMetric` reuses its working mesh and, when its options
        are the correspondence's, its metric (see ``metric_options``). With a point cloud on
        either side the map is the search's discrete one: images at points.
    Y : same as X
        The second shape.
    metric : {"diffusion", "geodesic", "euclidean"}, default "diffusion"
    n_samples : int, default 100
        Farthest point samples per shape.
    norm : {"l2", "linf"} or "p:VALUE", default "l2"
        Norm of the distortion that is minimised and reported as ``distance``.
    solver : {"gmds", "gw"}, default "gmds"
        Symmetric GMDS, or the Gromov-Wasserstein coupling (POT) read off as a map.
    init : {"greedy", "gw"}, default "greedy"
        GMDS's start: the initial search, or the argmax of the Gromov-Wasserstein coupling.
    seed : int, default 0
        Seeds the farthest point sampling; the rest is deterministic.
    resolution : int or None, default 3000
        Working mesh size for shapes not prepared already (None: the input as it is).
    metric_options : dict, optional
        Passed through :func:`~gromov.metrics.diffusion.correspondence_options`, as is every
        ShapeMetric's own (so a prepared shape and its file give the same match). Default:
        those of a prepared shape, else the correspondence's (normalised heat units).
    radius : float, optional
        Partial matching: only pairs of samples closer than ``radius`` count.
    orientation : {"prefer", "ignore"}, default "prefer"
        "prefer": a mirrored map is replaced by an orientation-preserving one within
        ``ORIENTATION_TOL`` (10%) of its distortion, or by its composition with a reflection
        within ``FLIP_TOL`` (25%), clearly direct maps first (:mod:`gromov.orientation`); a
        direct map by another within ``TURN_TOL`` (10%) that keeps the smoothed mean
        curvature better by ``TURN_MARGIN`` (a body turned half about its long axis against
        the right map: :mod:`gromov.curvature`). "ignore": the lowest distortion found.
    search : SearchOptions, optional
        The initial search's options and GMDS's stopping rule (default: ``SearchOptions()``).
    dense : bool, "input", "zoomout" or "placed", default False
        Also map every input vertex (:mod:`gromov.dense`). True or "input": placed from the
        samples, then refined by ZoomOut on the input meshes; "zoomout": refined on the
        working meshes instead; "placed": not refined.

    Returns
    -------
    MatchResult

    Examples
    --------
    >>> r = match("cat0.off.gz", "cat1.off.gz")                 # doctest: +SKIP
    >>> r.relative_distance, r.x_to_y_vertex[:3]                # doctest: +SKIP
    """
    options = _upgrade_options({**deprecated, "search": search}, "match")
    return _match(X, Y, metric, n_samples=n_samples, norm=norm, solver=solver, init=init, seed=seed,
                  resolution=resolution, metric_options=metric_options, radius=radius,
                  orientation=orientation, dense=dense, interval=True, **options)


#: Keywords of :func:`match` that moved into :class:`SearchOptions`.
_MOVED_TO_SEARCH = ("n_starts", "n_extend", "coarse_stages", "search_vertices", "extend_keep",
                    "signature_weight", "max_iter", "tol")
#: Keywords of :func:`match` that belong to recognition's ranking
#: (:func:`gromov.experiments.gh_matrix`).
_MOVED_TO_RANKING = ("rank_tau_scale", "rank_residual")


def _upgrade_options(options: dict, caller: str = "match", stacklevel: int = 3) -> dict:
    """``options`` of :func:`match` with the keywords that moved, for one release: those of
    the search into ``search`` (a :class:`SearchOptions`), each with a ``DeprecationWarning``
    that names the replacement; ``search=None`` is dropped. ``TypeError`` for any other
    unknown keyword."""
    options = dict(options)
    if options.get("search") is None:
        options.pop("search", None)
    elif not isinstance(options["search"], SearchOptions):
        raise TypeError(f"search must be a gromov.SearchOptions, got {type(options['search']).__name__}")
    moved = {k: options.pop(k) for k in _MOVED_TO_SEARCH if k in options}
    if moved:
        names = ", ".join(f"{k}=..." for k in moved)
        warnings.warn(f"{caller}({names}) is deprecated: use {caller}(search=gromov.SearchOptions({names}))",
                      DeprecationWarning, stacklevel=stacklevel)
        options["search"] = replace(options.get("search", SearchOptions()), **moved)
    ranked = [k for k in _MOVED_TO_RANKING if k in options]
    if ranked:
        names = ", ".join(f"{k}=..." for k in ranked)
        warnings.warn(f"{caller}({names}) is deprecated: recognition's ranking is set on "
                      f"gromov.experiments.gh_matrix({names})", DeprecationWarning, stacklevel=stacklevel)
    known = set(inspect.signature(_match).parameters) - {"X", "Y", "metric", "as_prepared"}
    unknown = sorted(set(options) - known)
    if unknown:
        raise TypeError(f"{caller}() got an unexpected keyword argument {unknown[0]!r}")
    return options


def _match(X, Y, metric: str = "diffusion", *, n_samples: int = 100, norm="l2", solver: str = "gmds",
           init: str = "greedy", seed: int = 0, resolution: int | None = DEFAULT_RESOLUTION,
           metric_options: dict | None = None, radius: float | None = None, orientation: str = "prefer",
           search: SearchOptions = SearchOptions(), dense: bool | str = False,
           rank_tau_scale: float | None = None, rank_residual: str = "difference",
           as_prepared: bool = False, interval: bool = False) -> MatchResult:
    """:func:`match`, and what recognition ranks by (:func:`gromov.experiments.gh_matrix`):
    ``ranking_distance`` measured with the heat distance at ``rank_tau_scale`` times the
    diffusion time, of ``rank_residual`` (:func:`ranking_value`). ``as_prepared``: use prepared
    shapes in their own metric (recognition's units) instead of the correspondence's.
    ``interval``: compute :attr:`MatchResult.gh_interval`."""
    t0 = time.perf_counter()
    p = parse_norm(norm)
    _check_choices(solver, init, orientation, dense, rank_tau_scale, rank_residual)
    # the metrics, and farthest point samples of each shape
    sx, sy = _prepared_pair(X, Y, metric, resolution, metric_options, as_prepared)
    discrete = _check_pair(sx, sy, n_samples, radius)
    P, Q = sx.samples(n_samples, seed), sy.samples(n_samples, seed)
    gm = None if discrete else SymmetricGMDS(sx.surface, sy.surface, P, Q, p=p, max_iter=search.max_iter,
                                             tol=search.tol, radius=radius)
    prefer = _prefers_direct(sx, sy, orientation, solver, init, discrete)
    # the initial search, then GMDS, mirror images replaced by direct maps where nearly as good
    # (BLAS on one thread: small products, and one summation order whatever the machine's threads)
    with one_blas_thread():
        starts, img_p0, img_q0 = _initial_images(sx, sy, P, Q, gm, solver, init, search, discrete)
        fit = _refine(sx, sy, P, Q, gm, img_p0, img_q0, solver, discrete)
        if prefer:
            candidates = _direct_candidates(sx, sy, P, Q, gm, starts, more=not fit.orientation > 0.5)
            if not fit.orientation > 0.5:
                fit = _prefer_direct(sx, sy, P, Q, gm, candidates, fit, n_samples, seed)
            if fit.orientation > 0.5:
                fit = _prefer_curvature(sx, sy, P, Q, gm, candidates, fit)
    # the distortion of the final correspondence, and its images on the input meshes
    dx, dy = discrete_blocks(sx.distances, sy.distances, P, Q, fit.img_p, fit.img_q) if discrete else \
        gm.blocks(fit.img_p, fit.img_q)
    residual = dx - dy
    np.fill_diagonal(residual, 0.0)   # not a pair (an interpolated self-distance need not be 0)
    r = residual[~np.eye(len(dx), dtype=bool)]
    dis, diam, d_trim = norm_value(r, p), max(sx.diameter, sy.diameter), trimmed_rms(r)
    ranking = _ranking(sx, sy, P, Q, fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual)
    locate = _images_at_points if discrete else lambda s, img: s.locate(img)
    xy_face, xy_bary, xy_vertex = locate(sy, fit.img_p)
    yx_face, yx_bary, yx_vertex = locate(sx, fit.img_q)
    extra = _dense_fields(sx, sy, P, Q, fit, dense) if dense else {}
    if interval:
        extra["gh_interval"] = _gh_interval(sx, sy, P, Q, fit, discrete)
    norm_name = "l2" if p == 2 else ("linf" if np.isinf(p) else f"p:{p:g}")
    return MatchResult(
        distance=0.5 * dis, relative_distance=0.5 * dis / diam, distortion=dis,
        distortion_l2=norm_value(r, 2.0), distortion_linf=norm_value(r, np.inf), norm=norm_name,
        metric=metric, solver=solver, n_samples=int(n_samples),
        x_samples=sx.working.to_input_ids(P), x_to_y_face=xy_face, x_to_y_bary=xy_bary, x_to_y_vertex=xy_vertex,
        y_samples=sy.working.to_input_ids(Q), y_to_x_face=yx_face, y_to_x_bary=yx_bary, y_to_x_vertex=yx_vertex,
        n_iter=int(fit.n_iter), converged=bool(fit.converged), seconds=time.perf_counter() - t0,
        orientation=fit.orientation, distortion_trimmed=d_trim, relative_trimmed=0.5 * d_trim / diam,
        ranking_distance=ranking, pair_distortion=residual, history=np.asarray(fit.history), **extra)


def _gh_interval(sx, sy, P, Q, fit: _Fit, discrete: bool) -> tuple[float, float]:
    """:func:`gromov.bounds.sample_gh_interval` of the samples, each image snapped to the
    nearest sample of the other shape (in that shape's metric)."""
    from .bounds import sample_gh_interval

    DX, DY = sx.distances, sy.distances

    def vertices(s, img):
        return np.asarray(img, dtype=np.int64) if discrete else img.vertex(s.mesh.faces)

    p_to_q = np.argmin(DY[np.ix_(vertices(sy, fit.img_p), Q)], axis=1)
    q_to_p = np.argmin(DX[np.ix_(vertices(sx, fit.img_q), P)], axis=1)
    lower, upper = sample_gh_interval(DX[np.ix_(P, P)], DY[np.ix_(Q, Q)], p_to_q, q_to_p)
    return float(lower), float(upper)


def _check_choices(solver, init, orientation, dense, rank_tau_scale, rank_residual) -> None:
    """``ValueError`` for an option of :func:`match` that names no method."""
    if solver not in ("gmds", "gw"):
        raise ValueError(f"solver must be 'gmds' or 'gw', got {solver!r}")
    if init not in ("greedy", "gw"):
        raise ValueError(f"init must be 'greedy' or 'gw', got {init!r}")
    if orientation not in ("ignore", "prefer"):
        raise ValueError(f"orientation must be 'ignore' or 'prefer', got {orientation!r}")
    if dense and dense not in (True, "input", "zoomout", "placed"):
        raise ValueError(f"dense must be True, False, 'input', 'zoomout' or 'placed', got {dense!r}")
    check_rank_tau_scale(rank_tau_scale)
    check_rank_residual(rank_residual)


def _prepared_pair(X, Y, metric, resolution, metric_options, as_prepared) -> tuple[ShapeMetric, ShapeMetric]:
    """The two shapes with their metrics (:func:`match_options_for`), and a warning where the
    two measure distances differently."""
    metric_options = match_options_for((X, Y), metric, metric_options)
    sx = _as_shape(X, metric, resolution, metric_options, "X", as_prepared)
    sy = _as_shape(Y, metric, resolution, metric_options, "Y", as_prepared)
    if sx.has_faces != sy.has_faces and metric != "euclidean":   # (straight lines: the same either way)
        warnings.warn(f"{'Y' if sx.has_faces else 'X'} is a point cloud and the other a mesh: their "
                      f"{metric} distances are computed differently (a mesh's own construction, a "
                      "cloud's from its nearest neighbours), so the distortion compares two metrics; "
                      "for comparable distances match the mesh's vertices as a point cloud too",
                      GromovWarning, stacklevel=4)
    elif _metric_signature(sx) != _metric_signature(sy):
        warnings.warn(f"X and Y measure distances differently ({_metric_signature(sx)} vs "
                      f"{_metric_signature(sy)}): their distortion compares two different metrics; "
                      f"prepare both ShapeMetrics with the same metric_options", GromovWarning, stacklevel=4)
    return sx, sy


def _check_pair(sx: ShapeMetric, sy: ShapeMetric, n_samples: int, radius) -> bool:
    """Whether the maps stay discrete (a point cloud on either side: images at points), after
    the checks that the pair can be matched with these options."""
    for name, s in (("X", sx), ("Y", sy)):
        if n_samples > s.mesh.n_vertices:
            raise ValueError(f"n_samples={n_samples} exceeds the {s.mesh.n_vertices} working vertices of {name}")
    if n_samples < 3:
        raise ValueError(f"n_samples must be at least 3, got {n_samples}")
    discrete = not (sx.has_faces and sy.has_faces)
    if discrete and radius is not None:
        raise ValueError("radius (partial matching) weighs the GMDS refinement on the surfaces, which "
                         "needs triangle meshes; X or Y is a point cloud")
    for name, s in (("X", sx), ("Y", sy)):
        if discrete and not s.finite:   # (on meshes SurfaceDistance says so)
            raise MetricError(f"{name}: matching needs finite distances, got inf or NaN (a shape in "
                              f"pieces: a point cloud whose {s.metric} neighbour graph falls apart -- "
                              "more neighbours (--neighbors K, metric_options={'k': ...}), or --metric "
                              "diffusion, which measures across the pieces; a mesh in several "
                              "components: keep its largest, Mesh.largest_component())")
    return discrete


def _prefers_direct(sx, sy, orientation, solver, init, discrete) -> bool:
    """Whether ``orientation="prefer"`` applies: GMDS from the initial search on two orientable
    meshes (a warning where a working mesh is not orientable)."""
    prefer = orientation == "prefer" and solver == "gmds" and init == "greedy" and not discrete
    if prefer and not (sx.normals[1] and sy.normals[1]):
        warnings.warn("orientation='prefer' needs orientable working meshes (a Moebius-like "
                      "piece cannot be given an outward side); ignored", GromovWarning, stacklevel=4)
        return False
    return prefer


def _initial_images(sx, sy, P, Q, gm, solver, init, search, discrete):
    """``(search or None, images of P on Y, images of Q on X)``: GMDS's start, vertex ids.

    The initial search (:class:`gromov.search._Starts`): each direction on its own, then the
    other direction anchored on it; the consistent pair of lower two-sided L2 distortion is
    kept. With ``init="gw"`` or ``solver="gw"``: the argmax of the Gromov-Wasserstein coupling.
    """
    DX, DY = sx.distances, sy.distances
    if solver == "gw" or init == "gw":
        T = gw_coupling(DX[np.ix_(P, P)], DY[np.ix_(Q, Q)])
        return None, Q[np.argmax(T, axis=1)], P[np.argmax(T, axis=0)]

    def score(a, b):   # the two-sided L2 distortion of a start (vertex images)
        if discrete:
            ex, ey = discrete_blocks(DX, DY, P, Q, a, b)
            return norm_value((ex - ey)[~np.eye(len(ex), dtype=bool)], 2.0)
        return gm.distortion(*_at_vertices(sx, sy, a, b), 2.0)

    starts = _Starts(sx, sy, P, Q, search)
    pairs = starts.plain(all_starts=False)
    from ._arrays import argmin_stable

    img_p0, img_q0 = pairs[argmin_stable([score(a, b) for a, b in pairs])]
    return starts, img_p0, img_q0


def _refine(sx, sy, P, Q, gm, img_p0, img_q0, solver, discrete) -> _Fit:
    """GMDS from the start (``solver="gmds"``), and the orientation agreement of the result; a
    discrete map (point clouds) as it is."""
    if discrete:
        return _Fit(img_p0, img_q0)
    img_p, img_q = _at_vertices(sx, sy, img_p0, img_q0)
    n_iter, converged = 0, True
    if solver == "gmds":
        img_p, img_q, n_iter, converged = gm.solve(img_p, img_q)
    return _Fit(img_p, img_q, n_iter, converged, list(gm.history),
                pair_orientation(sx, sy, P, Q, img_p, img_q))


def _prefer_direct(sx, sy, P, Q, gm, candidates, fit: _Fit, n_samples: int, seed: int) -> _Fit:
    """``orientation="prefer"`` for a mirrored (or scrambled) ``fit``: GMDS from the best
    orientation-preserving start too, among the extended starts and more preserving ones
    (within ``ORIENTATION_TOL`` of its distortion), then from its compositions with a
    reflection of X or Y (:meth:`ShapeMetric.symmetry`, within ``FLIP_TOL``). A clearly direct
    map (agreement above 1/2 + ``DIRECT_MARGIN``) is taken at once; one direct only on part of
    the shapes (agreement near 1/2) only if no clearly direct one turns up. ``fit`` if none."""
    from ._arrays import argmin_stable

    at, agreement, scores = candidates
    keep = agreement > 0.5
    d_first = gm.distortion(fit.img_p, fit.img_q, 2.0)

    def attempt(start, tol_k):
        h0 = len(gm.history)
        alt = gm.solve(*start)
        o_alt = pair_orientation(sx, sy, P, Q, alt[0], alt[1])
        if o_alt > 0.5 and gm.distortion(alt[0], alt[1], 2.0) <= (1.0 + tol_k) * d_first:
            return _Fit(*alt, gm.history[h0:], o_alt)
        return None

    found = partial = None
    if keep.any():  # the best orientation-preserving start
        alt = attempt(at[int(np.flatnonzero(keep)[argmin_stable(scores[keep])])], ORIENTATION_TOL)
        if alt is not None and alt.orientation > 0.5 + DIRECT_MARGIN:
            found = alt
        else:
            partial = alt
    if found is None:  # the mirrored map composed with a reflection of X, then of Y
        DX, DY = sx.distances, sy.distances
        fp, gq = fit.img_p.vertex(sy.mesh.faces), fit.img_q.vertex(sx.mesh.faces)
        for s_ in (sx, sy):
            sym = s_.symmetry(n_samples, seed)
            if sym is None:
                continue
            if s_ is sx:  # f o S_X on P (f carried to S_X(P) by its distances), S_X o g on Q
                start = (anchored_images(DY, fp, DX[np.ix_(sym[P], P)]), sym[gq])
            else:         # S_Y o f on P, g o S_Y on Q
                start = (sym[fp], anchored_images(DX, gq, DY[np.ix_(sym[Q], Q)]))
            alt = attempt(_at_vertices(sx, sy, *start), FLIP_TOL)
            if alt is not None and alt.orientation > 0.5 + DIRECT_MARGIN:
                found = alt
                break
            if partial is None:
                partial = alt
    return found or partial or fit


def _direct_candidates(sx, sy, P, Q, gm, starts, more: bool):
    """``(starts as surface points, their orientation agreements, their two-sided L2
    distortions)`` that ``orientation="prefer"`` weighs: every extended start of the search and,
    with ``more`` (a mirrored first map), more orientation-preserving ones (half as many per
    stage as it extends)."""
    pairs = starts.plain(all_starts=True)
    if more:
        pairs += starts.preserving(-(-starts.fwd.per_stage // 2))
    at = [_at_vertices(sx, sy, a, b) for a, b in pairs]
    return at, pairs_orientation(sx, sy, P, Q, at), np.array([gm.distortion(a, b, 2.0) for a, b in at])


def curvature_mismatch(sx, sy, P, Q, img_p, img_q) -> float:
    """How far a two-sided correspondence is from keeping the smoothed mean curvature
    (:attr:`ShapeMetric.curvature`): the median of ``|H_X(p) - H_Y(f(p))|`` over X's samples,
    averaged with the same from Y's. Images inside faces are read at their nearest corner."""
    hx, hy = sx.curvature, sy.curvature
    fp, gq = img_p.vertex(sy.mesh.faces), img_q.vertex(sx.mesh.faces)
    return 0.5 * float(np.median(np.abs(hx[P] - hy[fp])) + np.median(np.abs(hy[Q] - hx[gq])))


def _prefer_curvature(sx, sy, P, Q, gm, candidates, fit: _Fit) -> _Fit:
    """``orientation="prefer"`` for a direct ``fit``: a half turn against the right map.

    Among the clearly direct starts (agreement above 1/2 + ``DIRECT_MARGIN``) whose distortion
    is within ``TURN_TOL`` of the fit's, the one whose images keep the smoothed mean curvature
    best (:func:`curvature_mismatch`); if it beats the fit's mismatch by ``TURN_MARGIN``, GMDS
    from it, and its result replaces the fit when it is still clearly direct, within
    ``TURN_TOL`` of the distortion and ``TURN_MARGIN`` of the mismatch (:mod:`gromov.curvature`).
    """
    from ._arrays import argmin_stable

    at, agreement, scores = candidates
    d_fit = gm.distortion(fit.img_p, fit.img_q, 2.0)
    c_fit = curvature_mismatch(sx, sy, P, Q, fit.img_p, fit.img_q)
    near = np.flatnonzero((agreement > 0.5 + DIRECT_MARGIN) & (scores <= (1.0 + TURN_TOL) * d_fit))
    if not len(near):
        return fit
    mismatch = np.array([curvature_mismatch(sx, sy, P, Q, *at[i]) for i in near])
    best = int(near[argmin_stable(mismatch)])
    if not mismatch.min() < (1.0 - TURN_MARGIN) * c_fit:
        return fit
    h0 = len(gm.history)
    alt = gm.solve(*at[best])
    o_alt = pair_orientation(sx, sy, P, Q, alt[0], alt[1])
    if (o_alt > 0.5 + DIRECT_MARGIN and gm.distortion(alt[0], alt[1], 2.0) <= (1.0 + TURN_TOL) * d_fit
            and curvature_mismatch(sx, sy, P, Q, alt[0], alt[1]) < (1.0 - TURN_MARGIN) * c_fit):
        return _Fit(*alt, gm.history[h0:], o_alt)
    return fit


def _ranking(sx, sy, P, Q, fit: _Fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual) -> float:
    """``MatchResult.ranking_distance``: :func:`ranking_value` of the final correspondence, in
    the heat distance at ``rank_tau_scale`` times the diffusion time where that applies (the
    heat kernel), else in the match's metric (``dx``, ``dy``)."""
    mx = my = None
    if rank_tau_scale is not None:
        mx, my = sx.ranking_surface(rank_tau_scale), sy.ranking_surface(rank_tau_scale)
    if mx is None or my is None:
        return ranking_value(dx, dy, diam, rank_residual)
    if discrete:
        ex, ey = mx[0].block(np.r_[P, fit.img_q]), my[0].block(np.r_[fit.img_p, Q])
    else:
        ex, ey = SymmetricGMDS(mx[0], my[0], P, Q).blocks(fit.img_p, fit.img_q)
    return ranking_value(ex, ey, max(mx[1], my[1]), rank_residual)


def _dense_fields(sx, sy, P, Q, fit: _Fit, dense) -> dict:
    """The dense maps' fields of :class:`MatchResult` (:func:`gromov.dense.dense_maps`)."""
    from .dense import dense_maps

    refine = {True: "input", "placed": None}.get(dense, dense)
    mxy, myx = dense_maps(sx, sy, (P, fit.img_q), (fit.img_p, Q), refine=refine)
    return {"x_to_y_dense_face": mxy.face, "x_to_y_dense_bary": mxy.bary, "x_to_y_dense_vertex": mxy.vertex,
            "y_to_x_dense_face": myx.face, "y_to_x_dense_bary": myx.bary, "y_to_x_dense_vertex": myx.vertex,
            "input_faces": (_file_faces(sx), _file_faces(sy))}


def gw_coupling(dx: np.ndarray, dy: np.ndarray, *, max_iter: int = 1000) -> np.ndarray:
    """Gromov-Wasserstein coupling (M, K) of two distance matrices with uniform weights (POT)."""
    try:
        import ot
    except ImportError:  # pragma: no cover
        raise ImportError("the Gromov-Wasserstein solver needs POT: pip install pot") from None
    a = np.full(len(dx), 1.0 / len(dx))
    b = np.full(len(dy), 1.0 / len(dy))
    return ot.gromov.gromov_wasserstein(dx, dy, a, b, loss_fun="square_loss", max_iter=max_iter)

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

    :func:`~gromov.metrics.diffusion.correspondence_options` of ``metric_options``, or when
    not given of those of the first prepared :class:`ShapeMetric` among ``shapes`` (so that
    both sides of a match measure in the same metric, the one :func:`match` measures the
    prepared shape in), else the correspondence's defaults (normalised heat distributions for
    the heat kernel).
    """
    if metric_options is None:
        for s in shapes:
            if isinstance(s, ShapeMetric) and s.metric == metric:
                return correspondence_options(metric, s.metric_options)
    return correspondence_options(metric, metric_options)


def _as_shape(s, metric, resolution, metric_options, name: str, as_prepared: bool = False) -> ShapeMetric:
    """``s`` with its metric: a prepared shape in the correspondence's metric
    (:meth:`ShapeMetric.for_correspondence`) or, ``as_prepared``, in its own."""
    if isinstance(s, ShapeMetric):
        if s.metric != metric:
            raise ValueError(f"a ShapeMetric prepared for {s.metric!r} was given for metric {metric!r}")
        return s if as_prepared else s.for_correspondence()
    if not isinstance(s, (str, os.PathLike)):
        s = as_shape(s, name=name)   # arrays and mesh objects: errors and warnings name X or Y
    return ShapeMetric(s, metric, resolution=resolution, metric_options=metric_options)


def _file_faces(s: "ShapeMetric") -> np.ndarray | None:
    """Faces of the input mesh in file vertex ids (None for a point cloud)."""
    return s.input.input_ids[s.input.faces] if s.has_faces else None


@njit(cache=True)
def _first_faces(ptr, ids, vf_ptr, vf_ids, n_faces):
    """CSR ``(indptr, faces)``: for each group ``ids[ptr[i]:ptr[i + 1]]`` of vertices, the faces
    incident to them (``vf_ptr``, ``vf_ids``: a mesh's vertex-face CSR), each once, in the
    order first met."""
    total = 0
    for k in range(ids.shape[0]):
        total += vf_ptr[ids[k] + 1] - vf_ptr[ids[k]]
    n = ptr.shape[0] - 1
    out = np.empty(total, np.int64)
    out_ptr = np.zeros(n + 1, np.int64)
    seen = np.full(n_faces, -1, np.int64)   # the last group that met each face
    c = 0
    for i in range(n):
        for k in range(ptr[i], ptr[i + 1]):
            v = ids[k]
            for j in range(vf_ptr[v], vf_ptr[v + 1]):
                f = vf_ids[j]
                if seen[f] != i:
                    seen[f] = i
                    out[c] = f
                    c += 1
        out_ptr[i + 1] = c
    return out_ptr, out[:c]
