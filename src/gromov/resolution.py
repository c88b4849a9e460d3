"""Working resolution: simplify a mesh and keep maps between the input and the working mesh.

Dense ``N x N`` distance matrices need a working mesh of a few thousand vertices
(the original GMDS experiments used about 3,000), while TOSCA meshes have 25k-53k.
:func:`simplify` reduces a mesh by quadric-error edge collapses (Garland & Heckbert,
SIGGRAPH 1997, via the ``fast-simplification`` package) and then *snaps* every
surviving vertex back to its own input position, so the working mesh's vertices are
a subset of the input vertices. Consequences:

- a working vertex is an input vertex (``vertex_ids``), so samples and correspondences
  found on the working mesh are input vertices, with no interpolation;
- meshes that share connectivity (the poses of one TOSCA class) are simplified
  identically by :meth:`WorkingMesh.transfer`: the same vertex subset and the same
  triangles, so the ground-truth vertex correspondence survives exactly;
- every input vertex is located on the working mesh (face + barycentric coordinates,
  and the nearest working vertex), to carry functions and points back and forth.

Connected pieces of less than :data:`MIN_PIECE` of the area (a gorilla's eyes and teeth,
scanner debris) are left out of the working mesh (:func:`main_pieces`): in the diffusion metric
a small piece lies far from everything (no heat flows to it, and its own heat stays
concentrated), so farthest point sampling would spend samples on each piece first and the
distances between pieces would dwarf those across the shape. Their vertices are located on the
nearest part of the working mesh in space, and move with it.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ._project import project_among
from .errors import GromovWarning
from .mesh import Mesh, MeshError, PointCloud

__all__ = ["WorkingMesh", "WorkingCloud", "MIN_PIECE", "main_pieces", "simplify", "working_mesh", "working_cloud",
           "working_shape"]

logger = logging.getLogger(__name__)

MIN_PIECE = 0.01
"""Connected pieces of a mesh with less than this fraction of its area are left out of its
working mesh (:func:`main_pieces`)."""


class _WorkingMaps:
    """The maps both working shapes have (:class:`WorkingMesh`, :class:`WorkingCloud`), from
    their ``mesh``, ``vertex_ids`` and ``source_nearest``."""

    @property
    def n_vertices(self) -> int:
        return self.mesh.n_vertices

    def to_input_ids(self, working_vertices) -> np.ndarray:
        """File ids (as read from the input file) of working vertices."""
        return self.mesh.input_ids[np.asarray(working_vertices, dtype=np.int64)]

    @cached_property
    def source_kept(self) -> np.ndarray:
        """Whether each source vertex lies on a piece of the source that the working shape
        covers (False on the small pieces :func:`main_pieces` leaves out)."""
        src = self.source
        if not isinstance(src, Mesh) or len(self.vertex_ids) == src.n_vertices:
            kept = np.ones(src.n_vertices, dtype=bool)
        else:
            labels = src.component_labels
            kept = np.isin(labels, labels[self.vertex_ids])
        kept.flags.writeable = False
        return kept

    def to_source(self, working_vertices) -> np.ndarray:
        """Indices in ``source`` of working vertices."""
        return self.vertex_ids[np.asarray(working_vertices, dtype=np.int64)]

    def from_source(self, source_vertices) -> np.ndarray:
        """Nearest working vertex of each given ``source`` vertex."""
        return self.source_nearest[np.asarray(source_vertices, dtype=np.int64)]


@dataclass(frozen=True, eq=False)
class WorkingMesh(_WorkingMaps):
    """A simplified mesh together with the maps to and from the mesh it came from.

    Attributes
    ----------
    mesh : Mesh
        The working mesh. Its ``input_ids`` are the file ids of its vertices
        (``source.input_ids[vertex_ids]``).
    source : Mesh
        The mesh that was simplified.
    vertex_ids : ndarray, shape (n_work,)
        Working vertex ``i`` is vertex ``vertex_ids[i]`` of ``source``.
    source_face : ndarray, shape (n_source,)
        Face of the working mesh on which each source vertex lies (closest point).
    source_bary : ndarray, shape (n_source, 3)
        Barycentric coordinates of that closest point in ``source_face``.
    source_nearest : ndarray, shape (n_source,)
        Working vertex nearest to each source vertex (along the surface: the corner of
        ``source_face`` with the largest barycentric weight).
    source_residual : ndarray, shape (n_source,)
        Euclidean distance from each source vertex to its located point.
    source_owner : ndarray, shape (n_source,)
        Working vertex each source vertex was collapsed into (a working vertex owns itself).
        Each source vertex is located (``source_face``, ``source_bary``) at the closest point
        of the faces around that working vertex and its neighbours: on its own part of the
        surface, never on another sheet that passes closer in space (a hand resting on a
        thigh). These do not depend on the pose, so :meth:`transfer` keeps them.
    """

    mesh: Mesh
    source: Mesh
    vertex_ids: np.ndarray
    source_face: np.ndarray
    source_bary: np.ndarray
    source_nearest: np.ndarray
    source_residual: np.ndarray
    source_owner: np.ndarray

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """Carry a function on working vertices, ``(n_work, ...)``, to all source vertices.

        Linear (barycentric) interpolation on the face where each source vertex lies.
        """
        values = np.asarray(values)
        if values.shape[0] != self.mesh.n_vertices:
            raise ValueError(f"values must have {self.mesh.n_vertices} rows (working vertices), "
                             f"got shape {values.shape}")
        corners = self.mesh.faces[self.source_face]  # (n_source, 3)
        w = self.source_bary.reshape(self.source_bary.shape + (1,) * (values.ndim - 1))
        return (values[corners] * w).sum(axis=1)

    def transfer(self, other: Mesh) -> "WorkingMesh":
        """Simplify ``other`` exactly as ``source`` was simplified.

        ``other`` must have the same number of vertices with the same numbering (a
        different pose of the same shape, as within a TOSCA class). The working mesh of
        ``other`` uses the same vertex subset and the same triangles, so working vertex
        ``i`` of both results is the same point of the shape.
        """
        if not isinstance(other, Mesh):
            raise TypeError(f"other must be a Mesh, got {type(other).__name__}")
        if other.n_vertices != self.source.n_vertices:
            raise MeshError(f"transfer needs a mesh with the same vertex numbering: source has "
                            f"{self.source.n_vertices} vertices, other has {other.n_vertices}")
        work = Mesh(other.vertices[self.vertex_ids], self.mesh.faces,
                    input_ids=other.input_ids[self.vertex_ids])
        return _locate(work, other, self.vertex_ids, self.source_owner)

    def owned(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR ``(indptr, source_ids)``: the source vertices working vertex i owns are
        ``source_ids[indptr[i]:indptr[i + 1]]`` (itself among them)."""
        kept = np.flatnonzero(self.source_kept)   # a left-out piece's vertices are owned by none
        owner = self.source_owner[kept]
        order = kept[np.argsort(owner, kind="stable")]
        indptr = np.zeros(self.n_vertices + 1, dtype=np.int64)
        np.cumsum(np.bincount(owner, minlength=self.n_vertices), out=indptr[1:])
        return indptr, order.astype(np.int64)


def gather(ptr: np.ndarray, ids: np.ndarray, groups_ptr: np.ndarray, groups: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(indptr, ids)``: for each group ``groups[groups_ptr[g]:groups_ptr[g + 1]]`` of keys,
    the concatenation of the lists ``ids[ptr[k]:ptr[k + 1]]`` of its keys (duplicates kept)."""
    groups = np.asarray(groups, dtype=np.int64)
    lens = ptr[groups + 1] - ptr[groups]
    out_ptr = np.concatenate([[0], np.cumsum(lens)])[np.asarray(groups_ptr, dtype=np.int64)]
    within = np.arange(int(lens.sum())) - np.repeat(np.cumsum(lens) - lens, lens)
    return out_ptr, ids[np.repeat(ptr[groups], lens) + within]


def ring_candidates(mesh: Mesh, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(indptr, ids)`` of each centre vertex followed by its neighbours in ``mesh``."""
    centres = np.asarray(centres, dtype=np.int64)
    adj = mesh.adjacency
    # each vertex's list: itself, then its neighbours
    ptr = adj.indptr + np.arange(mesh.n_vertices + 1)
    ids = np.empty(ptr[-1], dtype=np.int64)
    ids[ptr[:-1]] = np.arange(mesh.n_vertices)
    ids[np.delete(np.arange(ptr[-1]), ptr[:-1])] = adj.indices
    return gather(ptr, ids, np.arange(len(centres) + 1), centres)


def _locate(work: Mesh, source: Mesh, vertex_ids: np.ndarray, owner: np.ndarray) -> WorkingMesh:
    owner = np.asarray(owner, dtype=np.int64)
    indptr, fids = work.vertex_faces
    has_faces = np.diff(indptr) > 0
    around = owner
    lonely = ~has_faces[owner]
    if lonely.any():
        # an isolated vertex (in no face) owns only itself: locate it around the nearest
        # vertex that has faces
        from scipy.spatial import cKDTree

        ref = np.flatnonzero(has_faces)
        if len(ref) == 0:
            raise MeshError("cannot locate vertices on a working mesh without faces")
        around = owner.copy()
        around[lonely] = ref[cKDTree(work.vertices[ref]).query(source.vertices[lonely])[1]]
    face, bary, dist = project_among(source.vertices, work, *ring_candidates(work, around))
    # working vertices are source vertices: locate them on one of their own faces exactly
    w = np.flatnonzero(has_faces)
    own = fids[indptr[w]]
    face[vertex_ids[w]] = own
    corner = np.argmax(work.faces[own] == w[:, None], axis=1)
    bary[vertex_ids[w]] = np.eye(3)[corner]
    dist[vertex_ids[w]] = 0.0
    nearest = work.faces[face, np.argmax(bary, axis=1)]
    owner = np.array(owner, dtype=np.int64)
    for a in (face, bary, nearest, dist, vertex_ids, owner):
        a.flags.writeable = False
    return WorkingMesh(work, source, vertex_ids, face, bary, nearest, dist, owner)


def _corner_angles(V, F):
    e0 = V[F[:, 2]] - V[F[:, 1]]
    e1 = V[F[:, 0]] - V[F[:, 2]]
    e2 = V[F[:, 1]] - V[F[:, 0]]

    def ang(u, v):
        c = np.einsum("ij,ij->i", u, v) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1), 1e-300)
        return np.arccos(np.clip(c, -1.0, 1.0))

    return np.stack([ang(-e2, e1), ang(-e0, e2), ang(-e1, e0)], axis=1)


def delaunay_flips(vertices: np.ndarray, faces: np.ndarray, *, max_dihedral_deg: float = 20.0,
                   max_rounds: int = 50) -> np.ndarray:
    """Improve triangle shapes by flipping non-Delaunay edges of nearly flat quads.

    An interior edge ab between faces (c, a, b) and (d, b, a) is replaced by cd when the
    angles opposite it add up to more than pi (the edge is not locally Delaunay), the two
    faces' normals differ by less than ``max_dihedral_deg`` (the flip barely moves the
    surface), cd is not an edge already (so the flip keeps the mesh manifold and its
    topology), and the smallest angle of the pair grows. Vertices never move. Independent
    flips are applied in rounds until none is left.
    """
    from ._gmds_kernel import face_neighbours

    V = np.asarray(vertices, dtype=float)
    F = np.array(faces, dtype=np.int64)
    cos_max = np.cos(np.radians(max_dihedral_deg))
    n = len(V)
    for _ in range(max_rounds):
        fn = face_neighbours(F)
        ang = _corner_angles(V, F)
        f_idx, k_idx = np.nonzero(fn >= 0)
        g_idx = fn[f_idx, k_idx]
        keep = f_idx < g_idx
        f_idx, k_idx, g_idx = f_idx[keep], k_idx[keep], g_idx[keep]
        l_idx = np.argmax(fn[g_idx] == f_idx[:, None], axis=1)
        opp = ang[f_idx, k_idx] + ang[g_idx, l_idx]
        cand = opp > np.pi + 1e-9
        if not cand.any():
            break
        f_idx, k_idx, g_idx, l_idx = f_idx[cand], k_idx[cand], g_idx[cand], l_idx[cand]
        c, d = F[f_idx, k_idx], F[g_idx, l_idx]
        a, b = F[f_idx, (k_idx + 1) % 3], F[f_idx, (k_idx + 2) % 3]
        cr = lambda p, q, r: np.cross(V[q] - V[p], V[r] - V[p])  # noqa: E731
        nf, ng = cr(c, a, b), cr(d, b, a)
        n1, n2 = cr(c, a, d), cr(d, b, c)
        unit = lambda x: x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-300)  # noqa: E731
        flat = np.einsum("ij,ij->i", unit(nf), unit(ng)) > cos_max
        same_side = (np.einsum("ij,ij->i", n1, nf) > 0) & (np.einsum("ij,ij->i", n2, nf) > 0)
        new_f = np.stack([c, a, d], 1)
        new_g = np.stack([d, b, c], 1)
        better = np.minimum(_corner_angles(V, new_f).min(1), _corner_angles(V, new_g).min(1)) > \
            np.minimum(ang[f_idx].min(1), ang[g_idx].min(1))
        edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        existing = np.unique(edges[:, 0] * n + edges[:, 1])
        cd = np.sort(np.stack([c, d], 1), axis=1)
        fresh = ~np.isin(cd[:, 0] * n + cd[:, 1], existing)
        ok = np.flatnonzero(flat & same_side & better & fresh)
        if len(ok) == 0:
            break
        ok = ok[np.argsort(-opp[ok])]  # worst edges first
        used = np.zeros(len(F), bool)
        new_edges: set = set()
        applied = 0
        for i in ok:
            f, g = f_idx[i], g_idx[i]
            key = (int(cd[i, 0]), int(cd[i, 1]))
            if used[f] or used[g] or key in new_edges:
                continue
            used[f] = used[g] = True
            new_edges.add(key)
            F[f], F[g] = new_f[i], new_g[i]
            applied += 1
        if applied == 0:
            break
    return F


def simplify(mesh: Mesh, n_vertices: int, *, aggressiveness: float = 7.0,
             min_quality: float = 0.1) -> WorkingMesh:
    """Simplify ``mesh`` to about ``n_vertices`` vertices, keeping a vertex subset.

    Parameters
    ----------
    mesh : Mesh
        Input mesh (any number of components; boundaries allowed).
    n_vertices : int
        Target number of working vertices (reached within about 2%: collapses that are
        not topology-safe are skipped). When it is not
        smaller than ``mesh.n_vertices`` the mesh is used as it is.
    aggressiveness : float, default 7.0
        Passed to the quadric simplifier (``agg``); lower values give better triangles
        and a slower reduction.
    min_quality : float, default 0.1
        Collapses that would create a triangle of shape quality
        ``2 sqrt(3) area / sum(edge^2)`` below this (1 = equilateral; 0.2 is about a 10 degree
        smallest angle) are skipped.

    Returns
    -------
    WorkingMesh
        Deterministic: the same input gives the same working mesh.

    Notes
    -----
    Quadric-error simplification (Garland & Heckbert 1997) proposes the order of edge
    collapses ``(i0, i1)`` (``i1`` merged into ``i0``). We replay that order keeping each
    survivor ``i0`` at its input position -- so the working vertices are a subset of the
    input vertices -- and skip every collapse that is not a topology-preserving edge
    contraction (link condition of Dey et al. 1999, no pinched boundary) or that would flip a
    face (see :mod:`gromov._collapse`). The working mesh therefore has the input's Euler
    characteristic, components and boundary loops; the simplifier alone does not guarantee
    this (it creates non-manifold edges on some TOSCA shapes). Finally, non-Delaunay edges of
    nearly flat quads are flipped (:func:`delaunay_flips`), which removes most of the sliver
    triangles that snapping leaves (they cost accuracy in fast marching and GMDS).
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"simplify needs a Mesh, got {type(mesh).__name__}")
    n_vertices = int(n_vertices)
    if n_vertices < 4:
        raise ValueError(f"n_vertices must be at least 4, got {n_vertices}")
    if n_vertices >= mesh.n_vertices:
        ids = np.arange(mesh.n_vertices)
        work = Mesh(mesh.vertices, mesh.faces, input_ids=mesh.input_ids, file_index=mesh.file_index)
        return _locate(work, mesh, ids, ids)

    import fast_simplification

    from ._collapse import replay_collapses

    # Replay the quadric simplifier's collapse order, skipping collapses that would change
    # the topology or flip a face at the snapped positions; repeat on the result while the
    # skipped collapses leave us more than 1% above the target.
    survivors = np.arange(mesh.n_vertices)
    owner = np.arange(mesh.n_vertices)  # per input vertex: the current vertex it collapsed into
    faces = mesh.faces
    for _ in range(12):
        cur_v = mesh.vertices[survivors]
        target_faces = int(round(len(faces) * n_vertices / len(survivors)))
        _, _, collapses = fast_simplification.simplify(
            np.array(cur_v), faces.astype(np.int32), target_count=target_faces,
            agg=aggressiveness, return_collapses=True)
        alive, new_faces, applied, merged = replay_collapses(cur_v, faces, np.asarray(collapses),
                                                             min_quality=min_quality)
        skipped = int((~applied).sum())
        if skipped:
            logger.info("simplify: skipped %d of %d collapses that were not topology-safe",
                        skipped, len(applied))
        new_index = np.cumsum(alive) - 1
        owner = new_index[merged[owner]]
        faces, survivors = new_index[new_faces], survivors[alive]
        if len(survivors) <= 1.01 * n_vertices or applied.sum() == 0:
            break
    faces = delaunay_flips(mesh.vertices[survivors], faces)
    work = Mesh(mesh.vertices[survivors], faces, input_ids=mesh.input_ids[survivors])
    logger.info("simplify: %d -> %d vertices, %d faces", mesh.n_vertices, work.n_vertices, work.n_faces)
    return _locate(work, mesh, survivors.astype(np.int64), owner)



def main_pieces(mesh: Mesh, min_fraction: float = MIN_PIECE) -> np.ndarray:
    """Whether each vertex lies on a connected piece holding at least ``min_fraction`` of the
    area: ``(n,)`` bool. All True for a mesh in one piece, and where those pieces hold less than
    half of the area (a shape made of many small pieces is measured as it is)."""
    if mesh.n_components == 1:
        return np.ones(mesh.n_vertices, dtype=bool)
    labels = mesh.component_labels
    area = np.bincount(labels, weights=mesh.vertex_areas, minlength=mesh.n_components)
    big = area >= min_fraction * area.sum()
    if area[big].sum() < 0.5 * area.sum():
        return np.ones(mesh.n_vertices, dtype=bool)
    return big[labels]


def working_mesh(mesh: Mesh, n_vertices: int | None) -> WorkingMesh:
    """The working mesh of ``mesh``: its :func:`main_pieces`, simplified by :func:`simplify` when
    ``n_vertices`` is given and smaller than them; every vertex of ``mesh`` located on it (those
    of a left-out piece around the working vertex nearest in space)."""
    keep = main_pieces(mesh, MIN_PIECE)
    if keep.all():
        return simplify(mesh, mesh.n_vertices if n_vertices is None else n_vertices)
    from scipy.spatial import cKDTree

    ids = np.flatnonzero(keep)
    sub = simplify(mesh.submesh(keep), int(keep.sum()) if n_vertices is None else n_vertices)
    owner = np.empty(mesh.n_vertices, dtype=np.int64)
    owner[ids] = sub.source_owner
    out = np.flatnonzero(~keep)
    owner[out] = cKDTree(sub.mesh.vertices).query(mesh.vertices[out])[1]
    logger.info("working mesh: %d pieces of under %g%% of the area left out (%d vertices)",
                len(np.unique(mesh.component_labels[out])), 100 * MIN_PIECE, len(out))
    return _locate(sub.mesh, mesh, ids[sub.vertex_ids], owner)


@dataclass(frozen=True, eq=False)
class WorkingCloud(_WorkingMaps):
    """The working subset of a point cloud, with the maps to and from the cloud it came from:
    :class:`WorkingMesh`'s counterpart for shapes without faces.

    Attributes
    ----------
    mesh : PointCloud
        The working points (named as :attr:`WorkingMesh.mesh`, so that both are used alike).
        Its ``input_ids`` are the input ids of its points (``source.input_ids[vertex_ids]``).
    source : PointCloud
        The cloud it was taken from.
    vertex_ids : ndarray, shape (n_work,)
        Working point ``i`` is point ``vertex_ids[i]`` of ``source`` (increasing).
    source_nearest : ndarray, shape (n_source,)
        Working point nearest (Euclidean) to each source point; a working point is its own.
    """

    mesh: PointCloud
    source: PointCloud
    vertex_ids: np.ndarray
    source_nearest: np.ndarray

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """Carry a function on working points, ``(n_work, ...)``, to all source points: the
        value of the nearest working point (a cloud has no faces to interpolate on)."""
        values = np.asarray(values)
        if values.shape[0] != self.mesh.n_vertices:
            raise ValueError(f"values must have {self.mesh.n_vertices} rows (working points), "
                             f"got shape {values.shape}")
        return values[self.source_nearest]


def working_shape(shape: PointCloud, n_vertices: int | None) -> WorkingMesh | WorkingCloud:
    """:func:`working_mesh` of a :class:`Mesh`, :func:`working_cloud` of a point cloud."""
    return working_mesh(shape, n_vertices) if isinstance(shape, Mesh) else working_cloud(shape, n_vertices)


def working_cloud(cloud: PointCloud, n_points: int | None) -> WorkingCloud:
    """The working subset of a point cloud: ``n_points`` farthest points in space.

    Farthest point sampling in the Euclidean distance (an even cover of the cloud, which the
    k-nearest-neighbour graph of the geodesic metric and the point-cloud Laplacian of the
    diffusion metric want), started from the point farthest from the centroid, so that the
    subset does not depend on the order of the points (up to ties). With ``n_points`` None or
    not smaller than the cloud: all points -- but points with identical coordinates only once
    (the first of them; with a ``GromovWarning``), as loading a mesh merges duplicate vertices:
    a point and its copy are no edge of a nearest-neighbour graph, so both metrics would put
    them far apart. Every source point maps to the working point at its place
    (``source_nearest``).

    Parameters
    ----------
    cloud : PointCloud
    n_points : int or None

    Returns
    -------
    WorkingCloud
    """
    from scipy.spatial import cKDTree

    from .metrics import EuclideanSolver
    from .sampling import farthest_point_sampling

    if not isinstance(cloud, PointCloud):
        raise TypeError(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    n = cloud.n_vertices
    if n_points is not None and (isinstance(n_points, bool) or int(n_points) != n_points or n_points < 1):
        raise ValueError(f"n_points must be a positive integer or None, got {n_points!r}")
    V = cloud.vertices
    if n_points is None or n_points >= n:
        _, first = np.unique(V, axis=0, return_index=True)
        keep = np.sort(first).astype(np.int64)
        if len(keep) < n:
            warnings.warn(f"point cloud: {n - len(keep)} of its {n} points repeat another point's "
                          "coordinates; each place is kept once", GromovWarning, stacklevel=3)
    else:
        first = int(np.argmax(((V - V.mean(axis=0)) ** 2).sum(axis=1)))
        keep = np.sort(farthest_point_sampling(EuclideanSolver(cloud), int(n_points), first=first).indices)
    work = PointCloud(V[keep], input_ids=cloud.input_ids[keep])
    nearest = cKDTree(V[keep]).query(V)[1].astype(np.int64)
    nearest[keep] = np.arange(len(keep))   # a working point is its own, even where points coincide
    keep.flags.writeable = nearest.flags.writeable = False
    return WorkingCloud(work, cloud, keep, nearest)
