"""Working meshes: vertex subset, maps both ways, identical simplification of poses."""

import numpy as np
import pytest

import gromov
from gromov import MeshError, simplify
from gromov.shapes import icosphere


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


def _closest_by_brute_force(points, mesh):
    """Distance to the surface, every face tried (the definition, for checking)."""
    from gromov._project import closest_point_barycentric

    V, F = mesh.vertices, mesh.faces
    out = np.empty(len(points))
    for i, p in enumerate(points):
        best = np.inf
        for a, b, c in V[F]:
            u, v, w = closest_point_barycentric(p, a, b, c)
            best = min(best, np.linalg.norm(u * a + v * b + w * c - p))
        out[i] = best
    return out


def test_projection_is_exact_among_long_thin_triangles():
    """The closest point of a long, thin triangle whose corners are all farther than another
    sheet's vertices is found (a search around the nearest vertices misses it: the 4
    nearest here are the patch's, and their faces are 0.5 away)."""
    from gromov._project import project_points

    big = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [5.0, -8.0, 0.0]]
    patch = [[4.5 + dx, -0.3 + dy, 0.5] for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1))]
    mesh = gromov.Mesh(np.array(big + patch), np.array([[0, 2, 1], [3, 4, 5], [4, 6, 5]]))
    p = np.array([[5.0, -0.48, 0.0], [5.0, -0.48, 0.1]])
    face, bary, dist = project_points(p, mesh)
    np.testing.assert_array_equal(face, [0, 0])
    np.testing.assert_allclose(dist, [0.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(bary @ mesh.vertices[mesh.faces[0]], [[5.0, -0.48, 0.0]] * 2, atol=1e-12)


def test_projection_matches_brute_force_on_a_simplified_tosca_pose(tosca_cat0, cat_working):
    """Input vertices located on the 3,000-vertex cat: the reported residual is the distance to
    the closest point over all faces, and face + coordinates rebuild that point. Checked on the
    hard cases: vertices whose face has none of their 4 nearest working vertices as a corner
    (about 1% of the cat's; a search among the faces around those vertices cannot find it)."""
    from scipy.spatial import cKDTree

    _, near = cKDTree(cat_working.mesh.vertices).query(tosca_cat0.vertices, k=4)
    corners = cat_working.mesh.faces[cat_working.source_face]
    hard = np.flatnonzero(~(corners[:, :, None] == near[:, None, :]).any(axis=(1, 2)))
    assert 0.002 * tosca_cat0.n_vertices < len(hard) < 0.05 * tosca_cat0.n_vertices
    rng = np.random.default_rng(0)
    ids = np.concatenate([rng.choice(hard, 40, replace=False),
                          rng.choice(tosca_cat0.n_vertices, 20, replace=False)])
    truth = _closest_by_brute_force(tosca_cat0.vertices[ids], cat_working.mesh)
    np.testing.assert_allclose(cat_working.source_residual[ids], truth, rtol=1e-9, atol=1e-9)
    rebuilt = cat_working.interpolate(cat_working.mesh.vertices)[ids]
    np.testing.assert_allclose(np.linalg.norm(rebuilt - tosca_cat0.vertices[ids], axis=1), truth,
                               rtol=1e-9, atol=1e-9)


def test_projection_onto_a_degenerate_face_is_on_its_segment():
    """A face with two coincident corners is the segment it spans: the point found is the
    segment's closest point and the distance is measured to it."""
    from gromov._project import closest_point_barycentric, project_points

    a, c = np.zeros(3), np.array([1.0, 0.0, 0.0])
    u, v, w = closest_point_barycentric(np.array([0.5, 1.0, 0.0]), a, a.copy(), c)
    np.testing.assert_allclose(u * a + v * a + w * c, [0.5, 0.0, 0.0], atol=1e-15)
    # collinear corners, the point beyond the far end
    u, v, w = closest_point_barycentric(np.array([3.0, 1.0, 0.0]), a, c, 2 * c)
    np.testing.assert_allclose(u * a + v * c + w * 2 * c, [2.0, 0.0, 0.0], atol=1e-15)
    mesh = gromov.Mesh(np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0]]), np.array([[0, 1, 2]]))
    face, bary, dist = project_points(np.array([[0.5, 1.0, 0.0]]), mesh)
    np.testing.assert_allclose(bary @ mesh.vertices[mesh.faces[face[0]]], [[0.5, 0.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(dist, [1.0])


def test_projection_errors_and_tree_reuse():
    from gromov._project import project_points, surface_tree

    m = icosphere(1)
    tree = surface_tree(m)
    p = np.array([[0.0, 0.0, 2.0], [0.3, -0.2, 0.1]])
    f1, b1, d1 = project_points(p, m)
    f2, b2, d2 = project_points(p, m, tree=tree)
    np.testing.assert_array_equal(f1, f2)
    np.testing.assert_allclose(d1, d2)
    assert d1[0] == pytest.approx(1.0, abs=0.1) and (b1 >= 0).all()
    face, bary, dist = project_points(np.zeros((0, 3)), m, tree=tree)
    assert face.shape == (0,) and bary.shape == (0, 3) and dist.shape == (0,)
    with pytest.raises(ValueError, match=r"shape \(p, 3\), got \(3,\)"):
        project_points(np.zeros(3), m)
    with pytest.raises(ValueError, match="2 points have NaN or infinite coordinates, first point 1"):
        project_points(np.array([[0.0, 0, 0], [np.nan, 0, 0], [np.inf, 0, 0]]), m, tree=tree)
    moved = gromov.Mesh(m.vertices + [5.0, 0.0, 0.0], m.faces)
    with pytest.raises(ValueError, match="tree was built for"):
        project_points(p, moved, tree=tree)
