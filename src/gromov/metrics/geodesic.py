"""Geodesic distance: the length of the shortest path on the surface.

Backends (``method=``):

``"fmm"`` (default for meshes)
    Our compiled fast marching on triangulated domains with the unfolding treatment
    of obtuse triangles (Kimmel & Sethian, PNAS 95, 1998); first-order accurate.
``"heat"``
    The heat method (Crane, Weischedel & Wardetzky, ACM TOG 2013) through potpourri3d
    (meshes and point clouds).
``"exact"``
    Exact polyhedral geodesics (Mitchell, Mount & Papadimitriou 1987; Surazhsky et al.
    2005) through pygeodesic; slow, used as the test oracle.
``"dijkstra"`` (default for point clouds)
    Shortest paths along mesh edges (or the k-nearest-neighbour graph of a point cloud);
    overestimates surface distances (metrication error) but never fails.

Distances between different connected components are ``inf``.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.csgraph import dijkstra

from ..errors import MetricError
from ..mesh import Mesh
from ._base import MetricSolver, check_shape

__all__ = ["GeodesicSolver", "GEODESIC_METHODS"]

GEODESIC_METHODS = ("fmm", "heat", "exact", "dijkstra")


class GeodesicSolver(MetricSolver):
    """Geodesic distances on a mesh or point cloud.

    Parameters
    ----------
    shape : Mesh or PointCloud
    method : {"fmm", "heat", "exact", "dijkstra"}, optional
        Default ``"fmm"`` for meshes, ``"dijkstra"`` for point clouds (``"heat"`` also
        works on point clouds).
    k : int, default 10
        Neighbours of the k-NN graph used by ``"dijkstra"`` on point clouds.
    heat_t_coef : float, default 1.0
        Time step factor of the heat method (potpourri3d's ``t_coef``).
    refine : int, default 0
        ``"fmm"`` only: march on the mesh with every triangle split into 4 this many times
        (:func:`gromov.metrics.subdivide`: the same surface, about ``4**refine`` times
        the vertices), distances read at the input vertices. The fast marching's error is
        first order in the edge length and largest next to strongly curved vertices, which
        keep their curvature but get nearer flat neighbours. Measured on the 3,000-vertex
        TOSCA cat against exact geodesics from 100 random sources (max / mean relative
        error; all-pairs time on 2 cores, ``benchmarks/bench_foundation.py`` of 2026-11-24):
        0 -- 7.9% / 0.21%, 1.9 s; 1 -- 3.7% / 0.11%, 9.5 s; 2 -- 1.7% / 0.066%, 43 s.

    Examples
    --------
    >>> from gromov.shapes import icosphere
    >>> d = GeodesicSolver(icosphere(3)).from_sources([0])   # (1, 642)
    """

    name = "geodesic"

    def __init__(self, shape, *, method: str | None = None, k: int = 10, heat_t_coef: float = 1.0,
                 refine: int = 0):
        shape = check_shape(shape, metric="geodesic")
        super().__init__(shape)
        is_mesh = isinstance(shape, Mesh)
        if method is None:
            method = "fmm" if is_mesh else "dijkstra"
        if method not in GEODESIC_METHODS:
            raise ValueError(f"method must be one of {GEODESIC_METHODS}, got {method!r}")
        if not is_mesh and method in ("fmm", "exact"):
            raise MetricError(f"geodesic method {method!r} needs a triangle mesh; point clouds "
                              "support 'dijkstra' and 'heat'")
        from ._fmm import check_refine

        refine = check_refine(refine)
        if refine and method != "fmm":
            raise ValueError(f"refine applies to method='fmm' (fast marching), got method={method!r}")
        self.method = method
        self.refine = refine
        self.k = k
        self.heat_t_coef = heat_t_coef
        self._impl = None

    def _engine(self):
        if self._impl is not None:
            return self._impl
        shape, m = self.shape, self.method
        if m == "fmm":
            from ._fmm import FastMarching

            self._impl = FastMarching(shape.vertices, shape.faces, refine=self.refine)
        elif m == "heat":
            import potpourri3d as pp3d

            v = np.array(shape.vertices)
            if isinstance(shape, Mesh):
                if shape.n_components > 1:
                    raise MetricError(f"the heat method of the geodesic metric needs a connected mesh, "
                                      f"this one has {shape.n_components} components: the fast "
                                      "marching (--geodesic-method fmm; method='fmm') measures each "
                                      "piece")
                self._impl = pp3d.MeshHeatMethodDistanceSolver(v, np.array(shape.faces),
                                                               t_coef=self.heat_t_coef)
            else:
                self._impl = pp3d.PointCloudHeatSolver(v, t_coef=self.heat_t_coef)
        elif m == "exact":
            try:
                import pygeodesic.geodesic as pyg
            except ImportError:  # pragma: no cover - depends on the environment
                raise MetricError("method='exact' needs pygeodesic: pip install 'gromov[exact]'") from None
            self._impl = pyg.PyGeodesicAlgorithmExact(np.array(shape.vertices), np.array(shape.faces))
        else:
            self._impl = shape.adjacency if isinstance(shape, Mesh) else shape.knn_graph(self.k)
        return self._impl

    def _rows(self, sources):
        eng, m = self._engine(), self.method
        if m == "fmm":
            return eng.distances(sources)
        if m == "dijkstra":
            return dijkstra(eng, directed=False, indices=sources)
        out = np.empty((len(sources), self.n_vertices))
        for i, s in enumerate(sources):
            if m == "heat":
                out[i] = eng.compute_distance(int(s))
            else:
                d, _ = eng.geodesicDistances(np.array([s], dtype=np.int32), None)
                d = np.asarray(d, dtype=float)
                d[~np.isfinite(d) | (d >= 1e300)] = np.inf
                out[i] = d
        return out

    def distance_from_set(self, sources) -> np.ndarray:
        """Distance ``(n,)`` to the nearest of several sources (a multi-source front)."""
        from ._base import check_sources

        s = check_sources(sources, self.n_vertices)
        if self.method == "fmm":
            return self._engine().distance(s)
        if self.method == "dijkstra":
            return dijkstra(self._engine(), directed=False, indices=s, min_only=True)
        return self.from_sources(s).min(axis=0)

    def __repr__(self) -> str:
        ref = f", refine={self.refine}" if self.refine else ""
        return f"GeodesicSolver(n_vertices={self.n_vertices}, method={self.method!r}{ref})"
