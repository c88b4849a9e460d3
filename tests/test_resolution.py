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
