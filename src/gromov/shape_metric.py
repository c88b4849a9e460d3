"""The prepared shape: :class:`ShapeMetric`, a shape with its working mesh and dense metric.

Everything :func:`gromov.match` reads of one shape is computed here once and cached on the
object (distances, samples, signatures, normals, curvature, its own reflection, the rows the
initial search anchors on), so that a shape matched against many others is prepared once.
"""

from __future__ import annotations

import os

import numpy as np
from numba import njit

from ._arrays import readonly
from ._defaults import DEFAULT_RESOLUTION
from ._project import _project_among
from .gmds import EmbeddedDistance, SurfaceDistance, SurfacePoints
from .mesh import Mesh, as_shape
from .metrics import metric_solver
from .metrics.diffusion import correspondence_options
from .orientation import outward_normals
from .resolution import WorkingCloud, WorkingMesh, gather, ring_candidates, working_shape
from .sampling import farthest_point_sampling

__all__ = ["ShapeMetric"]


def _anchor_rows(DX: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(DX[P], column sums of DX[P]**2)``: what :func:`gromov.search.anchored_images` reads of
    X for the anchors ``P`` (``ShapeMetric._anchors`` keeps them for a shape's samples)."""
    At = DX[P]                                               # (M, n_X) = DX[:, P].T
    return At, (At * At).sum(0)


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
        self._relax_rings = None   # (rings, CSR, lengths): the local isometry step's (gromov.dense)
        self._same_as_input: bool | None = None
        self._normals: tuple[np.ndarray, bool] | None = None
        self._curvature: np.ndarray | None = None
        self._symmetry: dict = {}
        self._ranking: dict = {}
        self._spectrum: dict = {}   # Shape-DNA of the working mesh, per length (gromov.spectrum)
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
        samples best fit those to the samples' images (:func:`~gromov.search.anchored_images`).
        A reflection is its own inverse, so where the two halves of the self-map disagree at a
        sample (by more than ``INVOLUTION_TOL`` of the diameter) those samples are re-anchored
        on the agreeing ones and GMDS descends again (up to ``INVOLUTION_REPAIRS`` times), so
        that a leg is not sent to another leg (docs/design/initial-search.md, "Mirror images").
        :func:`match` composes a mirrored correspondence with it to get the direct one.
        """
        key = (int(n_samples), int(seed))
        if key not in self._symmetry:
            from .search import _self_reflection   # here: gromov.search imports this module

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
