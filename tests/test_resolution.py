"""Working meshes: vertex subset, maps both ways, identical simplification of poses."""

import numpy as np
import pytest

import gromov
from gromov import MeshError, simplify
from gromov.shapes import icosphere

from conftest import body_and_debris


def test_sphere_simplification_keeps_a_vertex_subset_and_topology():
    src = icosphere(5)
    w = simplify(src, 2000)
    assert abs(w.n_vertices - 2000) <= 40
    np.testing.assert_array_equal(w.mesh.vertices, src.vertices[w.vertex_ids])
    np.testing.assert_array_equal(w.mesh.input_ids, w.vertex_ids)
    assert w.mesh.euler_characteristic == 2 and w.mesh.boundary_loops == []
    # every input vertex lies close to the working surface (a fraction of an edge)
    assert w.source_residual.max() < 0.5 * w.mesh.mean_edge_length
    # working vertices are located on themselves
    np.testing.assert_array_equal(w.source_nearest[w.vertex_ids], np.arange(w.n_vertices))
    np.testing.assert_allclose(w.source_residual[w.vertex_ids], 0.0)


def test_barycentric_map_reproduces_linear_functions():
    src = icosphere(4)
    w = simplify(src, 600)
    b = w.source_bary
    assert (b >= -1e-12).all() and np.allclose(b.sum(1), 1.0)
    # the located points, rebuilt from face + barycentric coordinates, are the closest points
    pts = w.interpolate(w.mesh.vertices)
    np.testing.assert_allclose(np.linalg.norm(pts - src.vertices, axis=1), w.source_residual, atol=1e-12)


def test_no_simplification_when_target_not_smaller():
    src = icosphere(2)
    w = simplify(src, 10_000)
    assert w.mesh.n_vertices == src.n_vertices
    np.testing.assert_array_equal(w.vertex_ids, np.arange(src.n_vertices))
    assert gromov.working_mesh(src, None).n_vertices == src.n_vertices


def test_simplify_is_deterministic():
    src = icosphere(4)
    a, b = simplify(src, 500), simplify(src, 500)
    np.testing.assert_array_equal(a.vertex_ids, b.vertex_ids)
    np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)


def test_transfer_to_a_moved_copy():
    src = icosphere(4)
    w = simplify(src, 500)
    rot = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))[0]
    moved = src.with_vertices(src.vertices @ rot.T + 3.0)
    w2 = w.transfer(moved)
    np.testing.assert_array_equal(w2.mesh.faces, w.mesh.faces)
    np.testing.assert_allclose(w2.mesh.vertices, w.mesh.vertices @ rot.T + 3.0, atol=1e-12)
    # the located points move with the shape (faces may differ only where a point is on an edge)
    np.testing.assert_allclose(w2.interpolate(w2.mesh.vertices),
                               w.interpolate(w.mesh.vertices) @ rot.T + 3.0, atol=1e-9)


def test_errors():
    src = icosphere(2)
    with pytest.raises(ValueError, match="at least 4"):
        simplify(src, 3)
    with pytest.raises(TypeError, match="needs a Mesh"):
        simplify(src.vertices, 100)
    w = simplify(src, 50)
    with pytest.raises(MeshError, match="same vertex numbering"):
        w.transfer(icosphere(1))
    with pytest.raises(ValueError, match="rows"):
        w.interpolate(np.zeros(3))


def test_tosca_poses_simplify_identically(data_dir, tosca_cat0, cat_working):
    w0 = cat_working
    assert 3000 <= w0.n_vertices <= 3060
    assert w0.mesh.n_components == 1
    # the simplification is topology-preserving
    assert w0.mesh.euler_characteristic == tosca_cat0.euler_characteristic
    assert len(w0.mesh.boundary_loops) == len(tosca_cat0.boundary_loops)
    assert w0.mesh.is_edge_manifold
    cat1 = gromov.load(data_dir / "tosca" / "cat1.off.gz")
    w1 = w0.transfer(cat1)
    # ground truth survives: working vertex i is the same input vertex in both poses
    np.testing.assert_array_equal(w1.mesh.input_ids, w0.mesh.input_ids)
    np.testing.assert_array_equal(w1.mesh.vertices, cat1.vertices[w0.vertex_ids])
    # the pose is different, the surface approximation is as good as in the reference pose
    assert np.abs(w1.mesh.vertices - w0.mesh.vertices).max() > 10.0
    assert np.median(w1.source_residual) < 0.2 * w1.mesh.mean_edge_length


def test_each_input_vertex_is_owned_by_a_working_vertex(cat_working):
    """Every input vertex was collapsed into one working vertex (working vertices own
    themselves), is located on a face around that owner or its neighbours, and its nearest
    working vertex lies within a few edges of that one along the surface."""
    import scipy.sparse.csgraph as cg

    w = cat_working
    np.testing.assert_array_equal(w.source_owner[w.vertex_ids], np.arange(w.n_vertices))
    ptr, ids = w.owned()
    assert ptr[-1] == w.source.n_vertices and np.array_equal(np.sort(ids), np.arange(w.source.n_vertices))
    ring_ptr, ring = gromov.resolution.ring_candidates(w.mesh, w.source_owner)
    corners = w.mesh.faces[w.source_face]
    for i in np.random.default_rng(0).choice(w.source.n_vertices, 300, replace=False):
        assert np.isin(corners[i], ring[ring_ptr[i]:ring_ptr[i + 1]]).any()
    hops = cg.shortest_path(w.mesh.adjacency > 0, unweighted=True,
                            indices=np.unique(w.source_owner[:2000]))
    pos = np.searchsorted(np.unique(w.source_owner[:2000]), w.source_owner[:2000])
    assert hops[pos, w.source_nearest[:2000]].max() <= 2


def test_located_vertices_stay_on_their_own_sheet():
    """Two parallel sheets 0.3 apart, the upper one coarse (simplified): a vertex of the upper
    sheet is closer in space to the lower sheet's working surface than to its own where
    the upper sheet's working triangles cut the corner, but it is located on its own sheet."""
    from gromov._project import project_among

    # lower sheet: one triangle; upper sheet: one triangle 0.3 above, whose corner vertex 3
    # owns the point; the point sits 0.25 below the upper triangle's plane, i.e. 0.05 above
    # the lower one
    V = np.array([[0.0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, 0.3], [4, 0, 0.3], [0, 4, 0.3]])
    mesh = gromov.Mesh(V, np.array([[0, 1, 2], [3, 4, 5]]))
    p = np.array([[1.0, 1.0, 0.05]])
    face, bary, dist = project_among(p, mesh, np.array([0, 1]), np.array([3]))
    assert face[0] == 1 and dist[0] == pytest.approx(0.25)
    face, _, dist = project_among(p, mesh, np.array([0, 2]), np.array([3, 0]))
    assert face[0] == 0 and dist[0] == pytest.approx(0.05)   # given both, the closer one


def test_projection_matches_brute_force_among_its_candidates(tosca_cat0, cat_working):
    """The located point is the closest point of the faces around the working vertex it was
    collapsed into and its neighbours (checked against every one of those faces), and face + coordinates rebuild it."""
    from gromov._project import closest_point_barycentric

    w = cat_working
    ring_ptr, ring = gromov.resolution.ring_candidates(w.mesh, w.source_owner)
    vf_ptr, vf = w.mesh.vertex_faces
    for i in np.random.default_rng(1).choice(tosca_cat0.n_vertices, 200, replace=False):
        p = tosca_cat0.vertices[i]
        faces = np.unique(np.concatenate([vf[vf_ptr[v]:vf_ptr[v + 1]] for v in ring[ring_ptr[i]:ring_ptr[i + 1]]]))
        best = min(np.linalg.norm(np.array(closest_point_barycentric(p, *w.mesh.vertices[w.mesh.faces[f]]))
                                  @ w.mesh.vertices[w.mesh.faces[f]] - p) for f in faces)
        assert w.source_residual[i] == pytest.approx(best, rel=1e-9, abs=1e-12)
    rebuilt = w.interpolate(w.mesh.vertices)
    np.testing.assert_allclose(np.linalg.norm(rebuilt - tosca_cat0.vertices, axis=1), w.source_residual,
                               atol=1e-9)


def test_projection_onto_a_degenerate_face_is_on_its_segment():
    """A face with two coincident corners is the segment it spans: the point found is the
    segment's closest point and the distance is measured to it."""
    from gromov._project import closest_point_barycentric, project_among

    a, c = np.zeros(3), np.array([1.0, 0.0, 0.0])
    u, v, w = closest_point_barycentric(np.array([0.5, 1.0, 0.0]), a, a.copy(), c)
    np.testing.assert_allclose(u * a + v * a + w * c, [0.5, 0.0, 0.0], atol=1e-15)
    # collinear corners, the point beyond the far end
    u, v, w = closest_point_barycentric(np.array([3.0, 1.0, 0.0]), a, c, 2 * c)
    np.testing.assert_allclose(u * a + v * c + w * 2 * c, [2.0, 0.0, 0.0], atol=1e-15)
    mesh = gromov.Mesh(np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0]]), np.array([[0, 1, 2]]))
    face, bary, dist = project_among(np.array([[0.5, 1.0, 0.0]]), mesh, np.array([0, 1]), np.array([2]))
    np.testing.assert_allclose(bary @ mesh.vertices[mesh.faces[face[0]]], [[0.5, 0.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(dist, [1.0])


def test_projection_errors():
    from gromov._project import project_among

    m = icosphere(1)
    with pytest.raises(ValueError, match=r"shape \(p, 3\), got \(3,\)"):
        project_among(np.zeros(3), m, np.array([0, 1]), np.array([0]))
    with pytest.raises(ValueError, match="2 points have NaN or infinite coordinates, first point 1"):
        project_among(np.array([[0.0, 0, 0], [np.nan, 0, 0], [np.inf, 0, 0]]), m,
                      np.array([0, 1, 2, 3]), np.array([0, 0, 0]))
    with pytest.raises(ValueError, match="cand_ptr must be"):
        project_among(np.zeros((2, 3)), m, np.array([0, 1]), np.array([0]))
    with pytest.raises(ValueError, match="candidate vertex ids must be in"):
        project_among(np.zeros((1, 3)), m, np.array([0, 1]), np.array([m.n_vertices]))
    with pytest.raises(ValueError, match="point 0 has no candidate vertex"):
        project_among(np.zeros((1, 3)), m, np.array([0, 0]), np.array([], dtype=np.int64))


def test_an_isolated_vertex_is_located_near_its_nearest_neighbour():
    """A vertex in no face survives simplification (nothing collapses it) and owns only
    itself; it is located on the surface around the nearest vertex that has faces."""
    m = icosphere(3)
    far = np.array([[1.5, 0.0, 0.0]])
    w = simplify(gromov.Mesh(np.vstack([m.vertices, far]), m.faces), 100)
    lone = m.n_vertices
    assert w.source_owner[lone] == np.flatnonzero(w.vertex_ids == lone)[0]
    point = w.source_bary[lone] @ w.mesh.vertices[w.mesh.faces[w.source_face[lone]]]
    assert np.linalg.norm(point - far[0]) == pytest.approx(w.source_residual[lone])
    # one convex sheet: the closest point of the whole surface (inscribed polyhedron: >= 0.5 away)
    from gromov._project import closest_point_barycentric

    V, F = w.mesh.vertices, w.mesh.faces
    best = min(np.linalg.norm(np.array(closest_point_barycentric(far[0], *V[f])) @ V[f] - far[0]) for f in F)
    assert w.source_residual[lone] == pytest.approx(best) and best >= 0.5


def test_gather_concatenates_the_lists_of_each_group():
    from gromov.resolution import gather

    ptr, ids = np.array([0, 2, 2, 5]), np.array([10, 11, 20, 21, 22])   # key 0: 10 11, 1: -, 2: 20 21 22
    out_ptr, out = gather(ptr, ids, np.array([0, 2, 3, 3]), np.array([2, 0, 1]))
    assert out_ptr.tolist() == [0, 5, 5, 5]
    assert out.tolist() == [20, 21, 22, 10, 11]
    out_ptr, out = gather(ptr, ids, np.array([0, 1, 3]), np.array([0, 0, 2]))
    assert out_ptr.tolist() == [0, 2, 7] and out.tolist() == [10, 11, 10, 11, 20, 21, 22]


def test_small_pieces_are_left_out_of_the_working_mesh_and_move_with_the_nearest_surface():
    mesh, n_body = body_and_debris()
    keep = gromov.resolution.main_pieces(mesh)
    assert keep[:n_body].all() and not keep[n_body:].any()
    w = gromov.working_mesh(mesh, None)
    assert w.mesh.n_vertices == n_body and w.mesh.n_components == 1
    np.testing.assert_array_equal(w.source_kept, keep)
    # each debris vertex is located on the sphere, near the point of the sphere closest to it
    located = w.interpolate(w.mesh.vertices)[~keep]
    radial = mesh.vertices[~keep] / np.linalg.norm(mesh.vertices[~keep], axis=1, keepdims=True)
    assert np.linalg.norm(located - radial, axis=1).max() < 2 * w.mesh.mean_edge_length
    ptr, ids = w.owned()   # owned by no working vertex: a map never lands on them
    assert len(ids) == n_body and not np.isin(ids, np.flatnonzero(~keep)).any()
    # the metric is the sphere's: no sample on the debris, the diameter the sphere's own
    s, alone = gromov.ShapeMetric(mesh, resolution=None), gromov.ShapeMetric(icosphere(3), resolution=None)
    assert np.isclose(s.diameter, alone.diameter, rtol=1e-9)
    assert s.samples(30).max() < n_body


def test_a_mesh_made_of_small_pieces_is_kept_whole():
    mesh, _ = body_and_debris()
    debris = mesh.submesh(np.arange(mesh.n_vertices) >= icosphere(3).n_vertices)   # 12 pieces of 1/12 each
    assert gromov.resolution.main_pieces(debris).all()
    # below 1% each, together less than half of the area: all of them
    assert gromov.resolution.main_pieces(debris, min_fraction=0.2).all()
