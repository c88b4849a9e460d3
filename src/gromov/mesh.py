"""Immutable triangle meshes and point clouds with cached derived quantities.

A :class:`Mesh` holds ``vertices`` ``(n, 3)`` float64 and ``faces`` ``(m, 3)`` int64
(0-based). Both arrays are private read-only copies, so every cached quantity
(edges, areas, adjacency, boundary loops, components...) stays valid for the
object's lifetime. Operations that change a mesh return a new one.

Every mesh also carries ``input_ids``: for each vertex, the index of the vertex it
came from in the mesh as the user gave it (as read from the file). Repairs,
component extraction and simplification compose these maps, so whatever gromov
reports can be expressed in the user's own vertex numbering.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .errors import GromovWarning, MeshError

__all__ = ["Mesh", "PointCloud", "RepairReport", "repair", "fill_holes", "component_areas", "as_vertices",
           "as_faces", "as_mesh", "as_shape"]

logger = logging.getLogger(__name__)


def paired_half_edges(u: np.ndarray, v: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The two half-edges ``(h0, h1)`` of every manifold edge.

    ``u[h], v[h]``: the end vertices of half-edge ``h`` (vertex ids below ``n``). An edge is
    manifold when exactly two half-edges join its two vertices (either way round); boundary
    and non-manifold edges are left out.
    """
    key = np.minimum(u, v).astype(np.int64) * np.int64(n) + np.maximum(u, v)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[start, len(ks)])
    pair = start[count == 2]
    return order[pair], order[pair + 1]


def _simple_cycles(walk: list[int]) -> list[np.ndarray]:
    """Split a closed walk along boundary edges (``walk[-1]`` back to ``walk[0]``) that passes
    a vertex more than once into simple cycles, one per return to a vertex.

    Where two holes touch at a vertex (two fans of faces meeting there, a bow-tie), the walk
    may go round both holes before it closes: ``w, a1 .. ap, w, b1 .. bq``. Cutting it at the
    second visit of ``w`` gives each hole's own loop, whichever way the walk turned at ``w``.
    """
    path: list[int] = []
    at: dict[int, int] = {}
    cycles = []
    for v in list(walk) + [walk[0]]:
        if v in at:
            i = at[v]
            cycles.append(np.asarray(path[i:], dtype=np.int64))
            for u in path[i + 1:]:
                del at[u]
            del path[i + 1:]
        else:
            at[v] = len(path)
            path.append(v)
    return cycles


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


#: Coordinates gromov accepts: at most this large in magnitude, and a shape at least
#: ``1 / COORDINATE_LIMIT`` across (unless all its points coincide). Areas, squared lengths
#: and the products of two of them (the cotangent Laplacian, fast marching's quadratic, the
#: quadric simplifier) must stay finite and normal in double precision (about 1e+-308): a
#: torus scaled by 1e100 made fast marching divide by zero and the sparse factorisation
#: singular, one scaled by 1e-100 lost every triangle to underflow; scaled by 1e75 and 1e-75,
#: ``gromov info``, both metrics, simplification and ``match`` work and scale exactly. The
#: same bound as the file readers' :data:`gromov.io.MAX_COORDINATE`.
COORDINATE_LIMIT = 1e75


def as_vertices(vertices, *, name: str = "vertices") -> np.ndarray:
    """Coerce to a finite ``(n, 3)`` float64 array within :data:`COORDINATE_LIMIT` or raise
    :class:`MeshError`."""
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MeshError(f"{name} must be numeric, got {type(vertices).__name__}: {exc}") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"{name} must have shape (n, 3), got {v.shape}")
    if v.shape[0] == 0:
        raise MeshError(f"{name} is empty: a shape needs at least one vertex")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise MeshError(
            f"{name} has {int(bad.sum())} non-finite (NaN or inf) coordinates, first at vertex "
            f"{int(np.flatnonzero(bad)[0])}"
        )
    big = float(np.abs(v).max())
    if big > COORDINATE_LIMIT:
        raise MeshError(f"{name} reach {big:.3g} in magnitude; gromov computes squared lengths and "
                        f"areas in double precision, which overflow there: scale the shape to "
                        f"coordinates below {COORDINATE_LIMIT:.0e} (distances scale with it, "
                        "correspondences do not change)")
    extent = float(np.ptp(v, axis=0).max())
    if 0.0 < extent < 1.0 / COORDINATE_LIMIT:
        raise MeshError(f"{name} span only {extent:.3g}; gromov computes squared lengths and areas in "
                        f"double precision, which underflow there: scale the shape to span more than "
                        f"{1.0 / COORDINATE_LIMIT:.0e} (distances scale with it, correspondences do "
                        "not change)")
    return v


def as_faces(faces, n_vertices: int, *, name: str = "faces") -> np.ndarray:
    """Coerce to an ``(m, 3)`` int64 array of valid 0-based indices or raise :class:`MeshError`."""
    f = np.asarray(faces)
    if f.size == 0:
        raise MeshError(f"{name} is empty: a mesh needs at least one triangle")
    if f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"{name} must have shape (m, 3) (triangles), got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if np.issubdtype(f.dtype, np.floating) and np.all(np.isfinite(f)) and np.all(f == np.round(f)):
            f = f.astype(np.int64)
        else:
            raise MeshError(f"{name} must hold integer vertex indices, got dtype {f.dtype}")
    f = f.astype(np.int64, copy=False)
    if f.min() < 0:
        raise MeshError(f"{name} has negative vertex index {int(f.min())} (indices are 0-based)")
    if f.max() >= n_vertices:
        raise MeshError(
            f"{name} refers to vertex {int(f.max())} but the mesh has only {n_vertices} vertices"
        )
    return f


class PointCloud:
    """An immutable set of points in R^3 (``points`` ``(n, 3)`` float64).

    Parameters
    ----------
    points : array_like, shape (n, 3)
    input_ids : array_like of int, shape (n,), optional
        Index of each point in the user's input; defaults to ``arange(n)``.
    file_index : array_like of int, shape (n_file,), optional
        For each point of the user's input (the file), the point of this shape that stands
        for it, or -1 where there is none; defaults to the inverse of ``input_ids`` over
        ``0 .. input_ids.max()``. See :attr:`file_index`.
    """

    _coords_name = "points"

    def __init__(self, points, *, input_ids=None, file_index=None):
        v = as_vertices(points, name=self._coords_name)
        self._vertices = _readonly(v)
        ids = np.arange(len(v)) if input_ids is None else np.asarray(input_ids, dtype=np.int64)
        if ids.shape != (len(v),):
            raise MeshError(f"input_ids must have shape ({len(v)},), got {ids.shape}")
        self._input_ids = _readonly(ids)
        self._file_index = _readonly(_check_file_index(file_index, ids, len(v)))

    @property
    def vertices(self) -> np.ndarray:
        """Point coordinates, ``(n, 3)`` float64, read-only."""
        return self._vertices

    points = vertices

    @property
    def input_ids(self) -> np.ndarray:
        """Index of each point in the user's input, ``(n,)`` int64."""
        return self._input_ids

    @property
    def n_vertices(self) -> int:
        return self._vertices.shape[0]

    @property
    def file_index(self) -> np.ndarray:
        """For each vertex of the user's input (the file, in its numbering), the vertex of
        this shape that stands for it, ``(n_file,)`` int64: the vertex itself, the vertex a
        duplicate was merged into (same coordinates), or -1 where loading dropped it (a vertex
        no face uses). Its length is the file's vertex count, whatever was dropped."""
        return self._file_index

    @property
    def n_file_vertices(self) -> int:
        """Number of vertices of the user's input (the file), dropped ones included."""
        return len(self._file_index)

    def per_file_vertex(self, values, fill=None) -> np.ndarray:
        """Per-vertex ``values`` of this shape as one row per vertex of the user's input file.

        The one place where results indexed by this shape's vertices become results indexed
        by the file's numbering: row ``i`` is the value of the vertex standing for file vertex
        ``i`` (:attr:`file_index`; a merged duplicate takes the value of the vertex it was
        merged into), and ``fill`` where loading dropped file vertex ``i``.

        Parameters
        ----------
        values : array_like, shape (n_vertices, ...)
        fill : scalar, optional
            Value of dropped rows; default -1 for integer values, NaN for floats, False for
            booleans.

        Returns
        -------
        ndarray, shape (n_file_vertices, ...)
        """
        v = np.asarray(values)
        if v.shape[:1] != (self.n_vertices,):
            raise ValueError(f"values must have one row per vertex ({self.n_vertices}), got shape {v.shape}")
        if fill is None:
            fill = False if v.dtype == bool else (-1 if v.dtype.kind in "iu" else np.nan)
        dtype = np.float64 if v.dtype.kind in "iub" and isinstance(fill, float) and \
            not fill.is_integer() else v.dtype     # NaN rows make integer values float
        idx = self._file_index
        out = np.full((len(idx),) + v.shape[1:], fill, dtype=dtype)
        kept = idx >= 0
        out[kept] = v[idx[kept]]
        return out

    def from_input_ids(self, ids) -> np.ndarray:
        """Vertex indices of this shape for ids of the user's input (inverse of ``input_ids``;
        a file vertex merged into another gives that one, :attr:`file_index`).

        Raises ``ValueError`` for an id that is not (or no longer, after repair) a vertex.
        """
        if not hasattr(self, "_input_inverse"):
            n_file = len(self._file_index)
            inv = np.full(max(int(self._input_ids.max()) + 1, n_file), -1, dtype=np.int64)
            inv[:n_file] = self._file_index
            inv[self._input_ids] = np.arange(self.n_vertices)
            inv.flags.writeable = False
            self._input_inverse = inv
        ids = np.asarray(ids, dtype=np.int64)
        inv = self._input_inverse
        bad = (ids < 0) | (ids >= len(inv))
        out = np.where(bad, -1, inv[np.clip(ids, 0, len(inv) - 1)])
        if (out < 0).any():
            raise ValueError(f"input vertex id {int(ids[out < 0][0])} is not a vertex of this shape")
        return out

    @cached_property
    def bbox(self) -> np.ndarray:
        """``(2, 3)`` array: minimum and maximum corner."""
        return _readonly(np.stack([self._vertices.min(0), self._vertices.max(0)]))

    def knn_graph(self, k: int = 10) -> sp.csr_matrix:
        """Symmetric sparse graph of Euclidean distances to the ``k`` nearest neighbours."""
        return _knn_graph(self._vertices, k)

    def __repr__(self) -> str:
        return f"PointCloud(n_vertices={self.n_vertices})"


def _check_file_index(file_index, ids: np.ndarray, n: int) -> np.ndarray:
    """``file_index`` as int64, or by default the inverse of ``ids`` over ``0 .. ids.max()``."""
    if file_index is None:
        inv = np.full(int(ids.max()) + 1 if len(ids) else 0, -1, dtype=np.int64)
        inv[ids] = np.arange(n)
        return inv
    idx = np.asarray(file_index, dtype=np.int64)
    if idx.ndim != 1 or (len(idx) and (idx.min() < -1 or idx.max() >= n)):
        raise MeshError(f"file_index must be a 1-d array of vertex indices below {n} (or -1), got "
                        f"shape {idx.shape}" + (f" with values in [{idx.min()}, {idx.max()}]" if idx.size else ""))
    return idx


def _compose_file_index(file_index: np.ndarray, new: np.ndarray) -> np.ndarray:
    """The file index after the vertices were renumbered by ``new`` (old vertex -> new vertex,
    -1 for one removed)."""
    return np.where(file_index >= 0, new[np.maximum(file_index, 0)], -1)


def _knn_graph(points: np.ndarray, k: int) -> sp.csr_matrix:
    from scipy.spatial import cKDTree

    n = len(points)
    if not 1 <= k < n:
        raise ValueError(f"k must be in [1, {n - 1}] for {n} points, got {k} (the number of neighbours "
                         f"of a point: --neighbors)")
    dist, idx = cKDTree(points).query(points, k=k + 1)
    rows = np.repeat(np.arange(n), k)
    # coincident points are neighbours at distance 0, but a stored 0 is no edge for a sparse
    # graph: the smallest positive float keeps it (paths through it are as long as without)
    w = np.maximum(dist[:, 1:].ravel(), np.finfo(np.float64).tiny)
    g = sp.csr_matrix((w, (rows, idx[:, 1:].ravel())), shape=(n, n))
    return g.maximum(g.T).tocsr()


class Mesh(PointCloud):
    """An immutable triangle mesh.

    Parameters
    ----------
    vertices : array_like, shape (n, 3)
        Coordinates; converted to float64. NaN/inf raise :class:`~gromov.errors.MeshError`.
    faces : array_like of int, shape (m, 3)
        0-based vertex indices of the triangles.
    input_ids : array_like of int, shape (n,), optional
        Index of each vertex in the user's input mesh (defaults to ``arange(n)``).
    file_index : array_like of int, shape (n_file,), optional
        The vertex standing for each vertex of the user's input, -1 for none
        (:attr:`PointCloud.file_index`; defaults to the inverse of ``input_ids``).

    Notes
    -----
    The constructor only validates; it does not repair. Use :func:`repair` (which
    :func:`gromov.load` calls) to remove degenerate faces, duplicate and unreferenced
    vertices. Derived quantities are computed on first access and cached.
    """

    _coords_name = "vertices"

    def __init__(self, vertices, faces, *, input_ids=None, file_index=None):
        super().__init__(vertices, input_ids=input_ids, file_index=file_index)
        self._faces = _readonly(as_faces(faces, self.n_vertices))

    # ------------------------------------------------------------------ basics
    @property
    def faces(self) -> np.ndarray:
        """Triangles, ``(m, 3)`` int64, read-only."""
        return self._faces

    @property
    def n_faces(self) -> int:
        return self._faces.shape[0]

    def __repr__(self) -> str:
        return (f"Mesh(n_vertices={self.n_vertices}, n_faces={self.n_faces}, "
                f"components={self.n_components}, boundary_loops={len(self.boundary_loops)})")

    # ------------------------------------------------------------------ edges
    @cached_property
    def _half_edges(self) -> np.ndarray:
        f = self._faces
        return np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])

    @cached_property
    def _edge_data(self):
        he = np.sort(self._half_edges, axis=1)
        edges, inverse, counts = np.unique(he, axis=0, return_inverse=True, return_counts=True)
        return edges, inverse.reshape(-1), counts

    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected edges ``(e, 2)`` int64, each row sorted ascending."""
        return _readonly(self._edge_data[0])

    @cached_property
    def edge_face_count(self) -> np.ndarray:
        """Number of faces incident to each edge of :attr:`edges` (1 boundary, 2 interior, >2 non-manifold)."""
        return _readonly(self._edge_data[2])

    @cached_property
    def face_edges(self) -> np.ndarray:
        """``(m, 3)`` index into :attr:`edges` of the edges (v0v1, v1v2, v2v0) of each face."""
        return _readonly(self._edge_data[1].reshape(3, -1).T)

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        e = self.edges
        return _readonly(np.linalg.norm(self._vertices[e[:, 0]] - self._vertices[e[:, 1]], axis=1))

    @cached_property
    def mean_edge_length(self) -> float:
        return float(self.edge_lengths.mean())

    @cached_property
    def nonmanifold_edges(self) -> np.ndarray:
        """Edges shared by more than two faces, ``(k, 2)``."""
        return _readonly(self.edges[self.edge_face_count > 2])

    @cached_property
    def is_edge_manifold(self) -> bool:
        return bool(len(self.nonmanifold_edges) == 0)

    # ------------------------------------------------------------------ areas
    @cached_property
    def _face_cross(self) -> np.ndarray:
        v, f = self._vertices, self._faces
        return np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])

    @cached_property
    def face_areas(self) -> np.ndarray:
        """Area of each triangle, ``(m,)``."""
        return _readonly(0.5 * np.linalg.norm(self._face_cross, axis=1))

    @cached_property
    def face_normals(self) -> np.ndarray:
        """Unit normal of each triangle (zero for degenerate ones), ``(m, 3)``."""
        c = self._face_cross
        n = np.linalg.norm(c, axis=1, keepdims=True)
        return _readonly(np.divide(c, n, out=np.zeros_like(c), where=n > 0))

    @cached_property
    def vertex_areas(self) -> np.ndarray:
        """Barycentric (lumped) vertex areas: a third of the area of each incident face, ``(n,)``."""
        a = np.zeros(self.n_vertices)
        np.add.at(a, self._faces.ravel(), np.repeat(self.face_areas / 3.0, 3))
        return _readonly(a)

    @cached_property
    def area(self) -> float:
        return float(self.face_areas.sum())

    # ------------------------------------------------------------------ connectivity
    @cached_property
    def adjacency(self) -> sp.csr_matrix:
        """Symmetric ``(n, n)`` sparse matrix with the edge length at each mesh edge."""
        e, w, n = self.edges, self.edge_lengths, self.n_vertices
        a = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([e[:, 0], e[:, 1]]),
                                                      np.concatenate([e[:, 1], e[:, 0]]))), shape=(n, n))
        return a.tocsr()

    @cached_property
    def vertex_faces(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR-style incidence ``(indptr, face_ids)``: faces of vertex i are ``face_ids[indptr[i]:indptr[i+1]]``."""
        flat = self._faces.ravel()
        order = np.argsort(flat, kind="stable")
        indptr = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(np.bincount(flat, minlength=self.n_vertices), out=indptr[1:])
        return _readonly(indptr), _readonly(order // 3)

    @cached_property
    def referenced(self) -> np.ndarray:
        """Boolean mask of vertices used by at least one face."""
        m = np.zeros(self.n_vertices, bool)
        m[self._faces.ravel()] = True
        return _readonly(m)

    @cached_property
    def _components(self) -> tuple[int, np.ndarray]:
        n, labels = connected_components(self.adjacency, directed=False)
        return n, labels

    @property
    def n_components(self) -> int:
        """Number of connected components (an unreferenced vertex is its own component)."""
        return self._components[0]

    @property
    def component_labels(self) -> np.ndarray:
        """Component index of each vertex, ``(n,)``."""
        return self._components[1]

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Edges with exactly one incident face, ``(b, 2)``."""
        return _readonly(self.edges[self.edge_face_count == 1])

    @cached_property
    def boundary_loops(self) -> list[np.ndarray]:
        """Closed loops of boundary vertices (each a vertex-index array), longest first.

        Boundary edges are walked as an undirected graph; a vertex where several
        loops touch (a bow-tie) is visited once per loop.
        """
        be = self.boundary_edges
        if len(be) == 0:
            return []
        nb = sp.coo_matrix((np.ones(2 * len(be)), (be.ravel(), be[:, ::-1].ravel())),
                           shape=(self.n_vertices,) * 2).tocsr()
        used = np.zeros(len(be), bool)
        # edge lookup: (min, max) -> edge row
        key = {(int(a), int(b)): i for i, (a, b) in enumerate(be)}
        loops = []
        for start in range(len(be)):
            if used[start]:
                continue
            used[start] = True
            a, b = int(be[start, 0]), int(be[start, 1])
            loop = [a]
            cur = b
            while cur != a:
                loop.append(cur)
                nxt = None
                for w in nb.indices[nb.indptr[cur]:nb.indptr[cur + 1]]:
                    w = int(w)
                    i = key[(min(cur, w), max(cur, w))]
                    if not used[i]:
                        used[i] = True
                        nxt = w
                        break
                if nxt is None:  # open chain (non-manifold boundary); stop here
                    break
                cur = nxt
            if cur == a and len(set(loop)) < len(loop):
                loops.extend(_simple_cycles(loop))
            else:
                loops.append(np.asarray(loop, dtype=np.int64))
        loops.sort(key=len, reverse=True)
        return loops

    @cached_property
    def euler_characteristic(self) -> int:
        """V - E + F over referenced vertices."""
        return int(self.referenced.sum()) - len(self.edges) + self.n_faces

    @cached_property
    def genus(self) -> float:
        """Genus of an orientable surface: ``(2c - chi - b) / 2``.

        ``c`` components (of referenced vertices), ``b`` boundary loops. Only meaningful for
        edge-manifold meshes; returned as a float so that a non-integer value flags a problem.
        """
        c = int(len(np.unique(self.component_labels[self.referenced])))
        return (2 * c - self.euler_characteristic - len(self.boundary_loops)) / 2.0

    @cached_property
    def bbox(self) -> np.ndarray:
        v = self._vertices[self.referenced]
        return _readonly(np.stack([v.min(0), v.max(0)]))

    # ------------------------------------------------------------------ derived meshes
    def submesh(self, vertex_mask) -> "Mesh":
        """The mesh induced by the vertices where ``vertex_mask`` is true (faces with all three kept)."""
        keep = np.asarray(vertex_mask, bool)
        if keep.shape != (self.n_vertices,):
            raise MeshError(f"vertex_mask must have shape ({self.n_vertices},), got {keep.shape}")
        new = np.full(self.n_vertices, -1, np.int64)
        new[keep] = np.arange(int(keep.sum()))
        faces = new[self._faces]
        faces = faces[(faces >= 0).all(axis=1)]
        return Mesh(self._vertices[keep], faces, input_ids=self._input_ids[keep],
                    file_index=_compose_file_index(self._file_index, new))

    def largest_component(self) -> "Mesh":
        """The connected component with the largest area, as a new mesh (``input_ids`` kept)."""
        if self.n_components == 1:
            return self
        area = np.bincount(self.component_labels, weights=self.vertex_areas, minlength=self.n_components)
        return self.submesh(self.component_labels == int(np.argmax(area)))

    def with_vertices(self, vertices) -> "Mesh":
        """Same connectivity and ``input_ids``, new coordinates (e.g. another pose)."""
        v = as_vertices(vertices)
        if v.shape != self._vertices.shape:
            raise MeshError(f"vertices must have shape {self._vertices.shape}, got {v.shape}")
        return Mesh(v, self._faces, input_ids=self._input_ids, file_index=self._file_index)

    def summary(self) -> dict:
        """Counts and topology as a plain dict (what ``gromov info`` prints)."""
        lo, hi = self.bbox
        return {
            "vertices": self.n_vertices,
            "faces": self.n_faces,
            "edges": len(self.edges),
            "components": int(len(np.unique(self.component_labels[self.referenced]))),
            "boundary_loops": len(self.boundary_loops),
            "nonmanifold_edges": len(self.nonmanifold_edges),
            "euler_characteristic": self.euler_characteristic,
            "genus": self.genus,
            "area": self.area,
            "mean_edge_length": self.mean_edge_length,
            "bbox_min": lo.tolist(),
            "bbox_max": hi.tolist(),
        }


@dataclass(frozen=True)
class RepairReport:
    """What :func:`repair` changed. Counts refer to the mesh that was given.

    ``duplicate_vertices`` were merged into a vertex at the same coordinates;
    ``coincident_vertices_kept`` share their coordinates with another vertex but were left
    apart, because merging them would join two sheets of the surface (a fold that touches
    itself, two parts meeting at a point) into a non-manifold mesh.
    """

    degenerate_faces: int = 0
    duplicate_faces: int = 0
    duplicate_vertices: int = 0
    unreferenced_vertices: int = 0
    messages: list[str] = field(default_factory=list)
    coincident_vertices_kept: int = 0

    @property
    def changed(self) -> bool:
        return bool(self.degenerate_faces or self.duplicate_faces or self.duplicate_vertices
                    or self.unreferenced_vertices)


def _fans(faces: np.ndarray, centres: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(pieces, crowded)`` for each vertex (``(n,)``, zero and False except at ``centres``):
    the number of fans of ``faces`` around the vertex (the connected pieces of its link, the
    opposite edges of its faces: one for a disk or half-disk, two where two disks meet at the
    vertex), and whether one of its edges has more than two faces. ``faces`` have no repeated
    vertex."""
    pieces, crowded = np.zeros(n, np.int64), np.zeros(n, bool)
    is_centre = np.zeros(n, bool)
    is_centre[centres] = True
    w, a, b = [], [], []
    for k in range(3):   # each face once per corner that is a centre, that corner first
        hit = is_centre[faces[:, k]]
        w.append(faces[hit, k])
        a.append(faces[hit, (k + 1) % 3])
        b.append(faces[hit, (k + 2) % 3])
    w, a, b = np.concatenate(w), np.concatenate(a), np.concatenate(b)
    if not len(w):
        return pieces, crowded
    ends, inv = np.unique(np.c_[np.r_[w, w], np.r_[a, b]], axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    crowded[ends[np.bincount(inv) > 2, 0]] = True              # an edge of three or more faces
    m = len(w)
    g = sp.coo_matrix((np.ones(m), (inv[:m], inv[m:])), shape=(len(ends), len(ends)))
    _, label = connected_components(g, directed=False)
    np.add.at(pieces, np.unique(np.c_[ends[:, 0], label], axis=0)[:, 0], 1)
    return pieces, crowded


def _proper(f: np.ndarray) -> np.ndarray:
    """The faces with three different vertices, each vertex set once (the first face kept)."""
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    return f[np.sort(np.unique(np.sort(f, axis=1), axis=0, return_index=True)[1])]


def _merge_targets(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, int]:
    """``(target, kept)``: the vertex each vertex merges into (itself if it stays) and how
    many vertices stay apart from another one at the same coordinates.

    Vertices with identical coordinates are merged where the merge leaves no edge of more
    than two faces and joins their fans into fewer: the two sides of a seam (a surface cut
    open along a curve, a polygon soup), a vertex split into pieces that together close a
    disk (or meet as a bow-tie where two holes touch), and any copy that no face uses. Where
    the merge would join separate sheets (a thin fold touching itself, two parts meeting at a
    point: as many fans as before, or an edge of three faces once repeated faces are removed),
    the vertices of that position stay apart, as the file has them.
    """
    n = len(v)
    _, group = np.unique(v, axis=0, return_inverse=True)
    group = group.reshape(-1)
    size = np.bincount(group)
    if size.max() < 2:
        return np.arange(n), 0
    used = np.zeros(n, bool)
    used[f.ravel()] = True
    # representative of each group: its first vertex that a face uses (else its first vertex)
    order = np.lexsort((np.arange(n), ~used, group))
    first = order[np.r_[0, np.cumsum(size)[:-1]]]
    shared = size[group] > 1
    n_used = np.bincount(group, weights=used, minlength=len(size))
    merging = n_used >= 2                       # groups where faces use two or more copies
    before = np.bincount(group, weights=_fans(_proper(f), np.flatnonzero(shared & used), n)[0],
                         minlength=len(size))
    while True:
        target = np.arange(n)
        copy = shared & (~used | merging[group])  # unused copies always go to the representative
        target[copy] = first[group[copy]]
        centres = first[np.flatnonzero(merging)]
        pieces, crowded = _fans(_proper(target[f]), centres, n)
        g = group[centres]
        bad = crowded[centres] | ((pieces[centres] > 1) & (pieces[centres] >= before[g]))
        if not bad.any():
            break
        merging[g[bad]] = False
    kept = int(np.sum(used & ~merging[group] & (n_used[group] >= 2)))
    return target, kept


def repair(mesh: Mesh, *, warn: bool = True, source: str | None = None) -> tuple[Mesh, RepairReport]:
    """Remove what breaks intrinsic metrics, never what a valid mesh needs; keep the map to
    the input vertices.

    In order:

    1. merge vertices with identical coordinates where the merge keeps the surface manifold
       around them (the two sides of a seam, corners of a polygon soup, copies no face uses);
       coincident vertices on separate sheets -- a fold where a closed surface touches itself,
       two parts meeting at a point -- stay apart, so a closed manifold mesh is never changed;
    2. drop faces with a repeated vertex or zero area;
    3. drop repeated faces (the same three vertices, either orientation), keeping the first;
    4. drop vertices no face uses any more.

    Every vertex left is in a face of positive area. The result's ``input_ids`` still name
    the vertices of ``mesh``'s input (a merged vertex keeps the smallest input id of those that
    faces use), and its :attr:`~PointCloud.file_index` gives for every input vertex the vertex
    that stands for it: itself, the vertex it was merged into, or -1 where it was dropped.

    Parameters
    ----------
    mesh : Mesh
    warn : bool, default True
        Emit a :class:`~gromov.errors.GromovWarning` describing each repair.
    source : str, optional
        Name of the file, used in the warnings.

    Returns
    -------
    repaired : Mesh
        ``mesh`` itself when nothing needed repair.
    report : RepairReport
    """
    v, f, ids, fidx = mesh.vertices, mesh.faces, mesh.input_ids, mesh.file_index
    where = f" in {source}" if source else ""
    msgs: list[str] = []
    n0 = len(v)

    # 1. coincident vertices, where merging keeps the mesh manifold
    target, n_kept = _merge_targets(v, f)
    stays = target == np.arange(n0)
    n_dup = int(n0 - stays.sum())
    if n_dup:
        new = np.cumsum(stays) - 1
        remap = new[target]
        f = remap[f]
        v, ids = v[stays], ids[stays]
        fidx = _compose_file_index(fidx, remap)
        msgs.append(f"merged {n_dup} duplicate vertices{where} into the vertices at the same "
                    "coordinates (results give them their images)")
    if n_kept:
        logger.info("%d vertices%s share their coordinates with a vertex of another sheet of the "
                    "surface (a fold or a touching point); kept apart, as the file has them",
                    n_kept, where)

    # 2. degenerate faces: repeated index or zero area
    rep = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    scale = max(float(np.ptp(v, axis=0).max()), np.finfo(float).tiny)
    zero = np.linalg.norm(cross, axis=1) <= (1e-14 * scale * scale)
    degenerate = rep | zero
    n_deg = int(degenerate.sum())
    if n_deg:
        f = f[~degenerate]
        msgs.append(f"removed {n_deg} degenerate (zero-area) faces{where}")

    # 3. repeated faces (same vertex set)
    n_dupf = 0
    if len(f):
        _, keep = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
        n_dupf = len(f) - len(keep)
        if n_dupf:
            f = f[np.sort(keep)]
            msgs.append(f"removed {n_dupf} repeated faces{where} (the same three vertices; the "
                        "first of each kept)")
    if len(f) == 0:
        raise MeshError(f"no valid triangle left{where}: every face has zero area or a repeated "
                        "vertex, so there is no surface to match")

    # 4. unreferenced vertices
    used = np.zeros(len(v), bool)
    used[f.ravel()] = True
    n_unref = int((~used).sum())
    if n_unref:
        new = np.where(used, np.cumsum(used) - 1, -1)
        f = new[f]
        v, ids = v[used], ids[used]
        fidx = _compose_file_index(fidx, new)
        msgs.append(f"dropped {n_unref} unreferenced vertices{where} (no face of positive area "
                    "uses them; per-vertex results give them -1 or NaN)")

    report = RepairReport(n_deg, n_dupf, n_dup, n_unref, msgs, n_kept)
    if not report.changed:
        return mesh, report
    for m in msgs:
        logger.info(m)
        if warn:
            warnings.warn(m, GromovWarning, stacklevel=2)
    return Mesh(v, f, input_ids=ids, file_index=fidx), report


def component_areas(mesh: Mesh) -> np.ndarray:
    """Surface area of each connected component, ``(mesh.n_components,)`` (0 for an
    unreferenced vertex), indexed like ``mesh.component_labels``."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"component_areas needs a Mesh, got {type(mesh).__name__}")
    labels = mesh.component_labels[mesh.faces[:, 0]] if mesh.n_faces else np.zeros(0, np.int64)
    return np.bincount(labels, weights=mesh.face_areas, minlength=mesh.n_components)


#: :func:`fill_holes` leaves a loop open when a face of its fan would have less area than
#: this times the loop's squared perimeter (an equilateral triangle's fan faces have about
#: 0.005): a slit, such as a removed zero-area face leaves, has no surface to fill.
FAN_MIN_AREA = 1e-6


def fill_holes(mesh: Mesh, max_perimeter) -> tuple[Mesh, int]:
    """Close every boundary loop shorter than ``max_perimeter`` by a fan of triangles.

    Each such loop ``(l_0, ..., l_{k-1})`` gets one new vertex ``c`` at the centroid of its
    vertices and the faces ``(l_i, l_{i+1}, c)``, ordered against the face that holds the
    boundary edge ``(l_i, l_{i+1})`` so that an oriented mesh stays oriented. Loops as long as
    ``max_perimeter`` or longer (real open ends of a scan, a partial shape) are left open, and
    so is the boundary of a triangle that hangs from the rest by one vertex (filling it would
    add a closed bubble, not close a hole) and a slit, a loop whose fan would have a face of
    (almost) no area (:data:`FAN_MIN_AREA`): its vertices would get no area of their own. Holes that touch at a vertex are filled each on its
    own (:attr:`Mesh.boundary_loops` gives each its own loop).

    Small holes are usually acquisition noise: the surface was there and was not captured.
    Metrics computed on the filled surface see a hole as the patch that closes it; the
    diffusion metric uses this by default (:func:`gromov.metrics.metric_solver`, option
    ``fill_holes``), because an insulating boundary raises the return probability of heat
    near it and with it every diffusion distance from there (held-out TOSCA classes,
    ``benchmarks/bench_heldout.py``: the ground-truth map's distortion with 20 holes
    falls from 0.063 to 0.012, against 0.010 without holes).

    Parameters
    ----------
    mesh : Mesh
    max_perimeter : float or array_like, shape (mesh.n_components,)
        Loops whose length (sum of their edge lengths) is below this are filled; an array
        gives one bound per connected component (``mesh.component_labels``), e.g. a fraction
        of the square root of each component's area (:func:`component_areas`).

    Returns
    -------
    filled : Mesh
        The mesh with the fans; its first ``mesh.n_vertices`` vertices are ``mesh``'s, in
        order, with their ``input_ids``; the centroids follow, with ids past the largest
        input id and the file's vertex count (they are not in the user's file).
    n_filled : int
        Number of loops filled (0: ``filled`` is ``mesh`` itself).
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"fill_holes needs a Mesh, got {type(mesh).__name__}")
    bound = np.asarray(max_perimeter, dtype=float)
    if bound.ndim == 0:
        bound = np.full(mesh.n_components, float(bound))
    if bound.shape != (mesh.n_components,):
        raise ValueError(f"max_perimeter must be a number or one per connected component "
                         f"({mesh.n_components}), got shape {bound.shape}")
    if not (np.isfinite(bound) & (bound > 0)).all():
        raise ValueError(f"max_perimeter must be a positive number (or one per component), got "
                         f"{max_perimeter!r}")
    labels = mesh.component_labels
    V, F = mesh.vertices, mesh.faces
    n = mesh.n_vertices
    # directed edges of the faces: a loop edge (a, b) found here runs along its face's order
    directed = set((F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2) @ np.array([n, 1])).tolist())
    be = np.sort(mesh.boundary_edges, axis=1)
    boundary = set((be @ np.array([n, 1])).tolist())
    indptr, incident = mesh.vertex_faces
    centres, fans = [], []
    for loop in mesh.boundary_loops:
        nxt = np.roll(loop, -1)
        lo, hi = np.minimum(loop, nxt), np.maximum(loop, nxt)
        # only simple closed loops: a loop through a vertex twice or not closed by boundary
        # edges is left open, and so is a triangle's own boundary (a triangle hanging by a vertex)
        if len(np.unique(loop)) < len(loop) or not all(int(k) in boundary for k in lo * n + hi):
            continue
        if len(loop) == 3 and any(set(F[f].tolist()) == set(loop.tolist())
                                  for f in incident[indptr[loop[0]]:indptr[loop[0] + 1]]):
            continue
        perimeter = np.linalg.norm(V[nxt] - V[loop], axis=1).sum()
        if perimeter >= bound[labels[loop[0]]]:
            continue
        centre = V[loop].mean(axis=0)
        # a slit (a loop of no area, e.g. where a zero-area face was removed) is left open: a
        # fan across it would have faces of no area, vertices with no area
        fan_areas = 0.5 * np.linalg.norm(np.cross(V[loop] - centre, V[nxt] - centre), axis=1)
        if fan_areas.min() <= FAN_MIN_AREA * perimeter ** 2:
            continue
        c = np.full(len(loop), n + len(centres))
        # each fan face runs against the face on the other side of its loop edge
        along = np.array([int(k) in directed for k in loop * n + nxt])
        fans.append(np.where(along[:, None], np.c_[nxt, loop, c], np.c_[loop, nxt, c]))
        centres.append(centre)
    if not centres:
        return mesh, 0
    first = max(int(mesh.input_ids.max()) + 1, mesh.n_file_vertices)   # never a file vertex's id
    filled = Mesh(np.vstack([V, centres]), np.vstack([F, *fans]),
                  input_ids=np.r_[mesh.input_ids, first + np.arange(len(centres))],
                  file_index=mesh.file_index)
    return filled, len(centres)


def as_mesh(shape, *, name: str = "shape") -> Mesh:
    """A :class:`Mesh` from what users hold a triangle mesh in.

    Parameters
    ----------
    shape : Mesh, (vertices, faces) or an object with ``vertices`` and ``faces``
        A :class:`Mesh` is returned as it is. A pair of arrays ``(vertices (n, 3), faces
        (m, 3))`` or an object with such attributes (``trimesh.Trimesh``, Open3D's
        ``TriangleMesh`` via ``np.asarray``, ...) is validated and then repaired like a file
        read by :func:`gromov.load` (:func:`repair`: duplicate vertices merged, degenerate
        faces dropped, with a warning); ``input_ids`` index the given vertex array, so
        results refer to it.
    name : str, default "shape"
        Used in error messages and repair warnings.

    Returns
    -------
    Mesh

    Raises
    ------
    TypeError
        If ``shape`` is none of these (e.g. a point cloud: matching needs faces).
    MeshError
        If the arrays are not a valid triangle mesh.
    """
    if isinstance(shape, Mesh):
        return shape
    if isinstance(shape, PointCloud):
        raise TypeError(f"{name} is a point cloud; a triangle mesh (vertices and faces) is needed")
    if isinstance(shape, (tuple, list)) and len(shape) == 2:
        vertices, faces = shape
    elif hasattr(shape, "vertices") and hasattr(shape, "faces"):
        vertices, faces = shape.vertices, shape.faces
    elif hasattr(shape, "vertices") and hasattr(shape, "triangles"):  # Open3D
        vertices, faces = shape.vertices, shape.triangles
    else:
        raise TypeError(f"{name} must be a gromov Mesh, a mesh file, a (vertices, faces) pair or an "
                        f"object with vertices and faces, got {type(shape).__name__}")
    try:
        vertices, faces = np.asarray(vertices), np.asarray(faces)
    except (TypeError, ValueError) as exc:   # ragged nested lists and the like
        raise MeshError(f"{name}: vertices and faces must be arrays of shape (n, 3) and (m, 3): "
                        f"{exc}") from None
    return repair(Mesh(vertices, faces), source=name)[0]


def as_shape(shape, *, name: str = "shape") -> Mesh | PointCloud:
    """A :class:`Mesh` or, for points without faces, a :class:`PointCloud`.

    Parameters
    ----------
    shape : Mesh, PointCloud, (vertices, faces), an ``(n, 3)`` array or an object with vertices
        What :func:`as_mesh` takes, and also point clouds: a :class:`PointCloud` is returned as
        it is; an array of shape ``(n, 3)`` (not a pair of arrays) or an object with
        ``vertices`` (or Open3D's ``points``) and no faces (or an empty face array) becomes a
        :class:`PointCloud` whose ``input_ids`` index the given points.
    name : str, default "shape"
        Used in error messages.

    Returns
    -------
    Mesh or PointCloud

    Raises
    ------
    TypeError
        If ``shape`` is none of these.
    MeshError
        If the arrays are not valid points or a valid triangle mesh.
    """
    if isinstance(shape, PointCloud):
        return shape
    if isinstance(shape, np.ndarray) and shape.ndim == 2:
        return PointCloud(shape)
    if isinstance(shape, (tuple, list)) and len(shape) != 2:   # a list of points (a pair: vertices, faces)
        return PointCloud(shape)
    if not isinstance(shape, (tuple, list)):
        faces = getattr(shape, "faces", getattr(shape, "triangles", None))
        points = getattr(shape, "vertices", getattr(shape, "points", None))
        if points is not None and (faces is None or np.size(faces) == 0):
            return PointCloud(points)
        if points is None:
            raise TypeError(f"{name} must be a gromov Mesh or PointCloud, a mesh file, a (vertices, "
                            f"faces) pair, an (n, 3) array of points or an object with vertices (and "
                            f"faces), got {type(shape).__name__}")
    return as_mesh(shape, name=name)
