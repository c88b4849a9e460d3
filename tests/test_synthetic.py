"""The built-in synthetic data set: TOSCA-like classes of posed shapes made from numbers.

Facts checked: every shape is one closed, consistently oriented 2-manifold of genus 0 with
about the requested number of vertices and no sliver triangles; all poses of a class share
their faces, so vertex i is the same body point in every pose; the rest pose ignores the
seed, the other poses follow it reproducibly; poses are nearly isometric (geodesic
distances change by less than 3 % on average) and keep their volume; every deformation
brings parts within the weld radius without letting two parts that were apart come
within a mesh edge of each other, so ``weld`` finds its sites and ``holes`` works; the GH
distance is smaller within a class than between the two similar classes, and that smaller
than between a quadruped and a person; bad arguments raise the documented errors.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import gromov
from gromov.experiments.datasets import experiment1, experiment2
from gromov.experiments.synthetic import (
    CLASSES,
    CONTACT_GAP,
    MAX_VERTICES,
    MIN_VERTICES,
    POSE_NAMES,
    Synthetic,
)
from gromov.perturb import holes, weld

N = 1500


@pytest.fixture(scope="module")
def data():
    return Synthetic(n_vertices=N, seed=0)


@pytest.fixture(scope="module")
def shapes(data):
    return {key: data.load(*key) for key in data.shapes()}


def deformations(data):
    return [(c, p) for c, p in data.shapes() if p != 0]


def smallest_angles(mesh):
    """Smallest angle of each triangle, in degrees."""
    p = mesh.vertices[mesh.faces]
    angles = []
    for k in range(3):
        u, v = p[:, (k + 1) % 3] - p[:, k], p[:, (k + 2) % 3] - p[:, k]
        cos = np.einsum("ij,ij->i", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        angles.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return np.min(angles, axis=0)


def volume(mesh):
    v = mesh.vertices[mesh.faces]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6)


# ---------------------------------------------------------------------------- interface
def test_reads_like_tosca(data):
    assert data.classes == sorted(CLASSES) == ["cat", "david", "dog", "victoria"]
    assert all(data.poses(c) == list(range(7)) for c in data.classes)
    assert data.shapes() == [(c, p) for c in data.classes for p in range(7)]
    assert data.pose_name("cat", 0) == "rest" and data.pose_name("cat", 1) == POSE_NAMES["cat"][1]
    assert "n_vertices=1500" in repr(data) and "28 shapes" in repr(data)
    # TOSCA's class names and at least six deformations per class: the paper's subsets apply
    assert len(experiment1(data)) == 40 and len(experiment2(data)) == 20


# ---------------------------------------------------------------------------- meshes
def test_every_shape_is_an_oriented_sphere(shapes):
    for key, mesh in shapes.items():
        s = mesh.summary()
        assert (s["components"], s["boundary_loops"], s["nonmanifold_edges"]) == (1, 0, 0), key
        assert s["euler_characteristic"] == 2 and s["genus"] == 0.0, key
        # consistently oriented: every directed edge once, each with its reverse
        f = mesh.faces
        half = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        n = mesh.n_vertices
        keys = half[:, 0] * n + half[:, 1]
        assert len(np.unique(keys)) == len(keys), key
        assert np.isin(half[:, 1] * n + half[:, 0], keys).all(), key
        assert volume(mesh) > 0, key           # ... and outwards


def test_vertex_count_near_target(data, shapes):
    for c in data.classes:
        assert abs(shapes[c, 0].n_vertices - N) <= 0.05 * N, c
    small = Synthetic(n_vertices=800).load("victoria", 2)
    assert abs(small.n_vertices - 800) <= 0.05 * 800
    assert small.genus == 0.0 and small.n_components == 1 and not small.boundary_loops


def test_no_sliver_triangles(data, shapes):
    for key, mesh in shapes.items():
        smallest = smallest_angles(mesh)
        assert smallest.min() >= 5.0, key
        if key[1] == 0:
            assert np.percentile(smallest, 1) >= 15.0, key


# ---------------------------------------------------------------------------- ground truth
def test_poses_share_faces_and_vertex_numbering(data, shapes):
    for c in data.classes:
        rest = shapes[c, 0]
        for p in data.poses(c)[1:]:
            mesh = shapes[c, p]
            assert np.array_equal(mesh.faces, rest.faces)
            assert np.array_equal(mesh.input_ids, np.arange(rest.n_vertices))
            # an articulation: some part moved by many edge lengths
            moved = np.linalg.norm(mesh.vertices - rest.vertices, axis=1)
            assert moved.max() > 5 * rest.mean_edge_length, (c, p)


def test_seed_moves_the_poses_not_the_rest(data, shapes):
    again = Synthetic(n_vertices=N, seed=0)
    other = Synthetic(n_vertices=N, seed=1)
    for key in deformations(data):
        assert np.array_equal(again.load(*key).vertices, shapes[key].vertices), key
        assert np.array_equal(other.load(*key).faces, shapes[key].faces), key
        assert not np.allclose(other.load(*key).vertices, shapes[key].vertices), key
    for c in data.classes:
        assert np.array_equal(other.load(c, 0).vertices, shapes[c, 0].vertices)


# ---------------------------------------------------------------------------- poses
def test_poses_are_nearly_isometric(data, shapes):
    """Relative change of geodesic distances (fast marching) from 16 vertices to all."""
    for c in data.classes:
        rest = shapes[c, 0]
        sources = np.linspace(0, rest.n_vertices - 1, 16).astype(int)
        d0 = gromov.metric_solver(rest, "geodesic").from_sources(sources)
        far = d0 > 0.05 * d0.max()
        changes = []
        for p in data.poses(c)[1:]:
            d = gromov.metric_solver(shapes[c, p], "geodesic").from_sources(sources)
            changes.append(float(np.mean(np.abs(d[far] - d0[far]) / d0[far])))
        assert np.mean(changes) < 0.03, (c, changes)
        assert max(changes) < 0.04, (c, changes)
        assert min(changes) > 0.002, (c, changes)    # and they are deformations


def test_poses_keep_their_volume(data, shapes):
    for c in data.classes:
        v0 = volume(shapes[c, 0])
        for p in data.poses(c)[1:]:
            assert abs(volume(shapes[c, p]) / v0 - 1) < 0.03, (c, p)


def test_parts_come_close_but_do_not_touch(data, shapes):
    """Vertex pairs at least 6 edges apart at rest: none within 1 edge, some within 5."""
    for c, p in deformations(data):
        rest, mesh = shapes[c, 0], shapes[c, p]
        e = rest.mean_edge_length
        pairs = cKDTree(mesh.vertices).query_pairs(5 * e, output_type="ndarray")
        d = np.linalg.norm(mesh.vertices[pairs[:, 0]] - mesh.vertices[pairs[:, 1]], axis=1)
        d0 = np.linalg.norm(rest.vertices[pairs[:, 0]] - rest.vertices[pairs[:, 1]], axis=1)
        apart = d[d0 >= 6 * e]
        assert len(apart) > 0 and apart.min() > e, (c, p)
        assert data.clearance(c, p) == pytest.approx(apart.min() / e)
    for c in data.classes:
        assert data.clearance(c, 0) == 3 * CONTACT_GAP


def test_weld_finds_sites_on_the_deformations(data, shapes):
    done = 0
    for c, p in deformations(data):
        try:
            w = weld(shapes[c, p], 3, seed=p)
        except ValueError:
            continue
        done += 1
        assert w.mesh.euler_characteristic == 2 - 2 * 3 and w.mesh.n_components == 1
    assert done >= len(deformations(data)) / 2
    assert done == len(deformations(data))       # in fact on all of them


def test_holes(data, shapes):
    for c in data.classes:
        h = holes(shapes[c, 1], 10, seed=0)
        assert len(h.mesh.boundary_loops) == 10 and h.mesh.euler_characteristic == 2 - 10


def test_gh_distance_separates_the_classes(shapes):
    """Diffusion GH (30 samples, 300-vertex working meshes): within < similar < dissimilar."""
    metric = {k: gromov.ShapeMetric(shapes[k], "diffusion", resolution=300, metric_options={"units": "raw"})
              for k in [("cat", 0), ("cat", 3), ("dog", 0), ("david", 0), ("david", 4),
                        ("victoria", 0)]}

    def gh(a, b):
        return gromov.match(metric[a], metric[b], metric="diffusion", n_samples=30).relative_distance

    assert gh(("cat", 0), ("cat", 3)) < gh(("cat", 0), ("dog", 0)) < gh(("cat", 0), ("david", 0))
    assert gh(("david", 0), ("david", 4)) < gh(("david", 0), ("victoria", 0)) \
        < gh(("david", 0), ("dog", 0))


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize("n", [True, 1500.0, "1500", None])
def test_n_vertices_must_be_an_integer(n):
    with pytest.raises(TypeError, match="n_vertices must be an integer"):
        Synthetic(n_vertices=n)


@pytest.mark.parametrize("n", [MIN_VERTICES - 1, 0, -5, MAX_VERTICES + 1])
def test_n_vertices_in_range(n):
    with pytest.raises(ValueError, match=f"n_vertices must be in .*got {n}"):
        Synthetic(n_vertices=n)


def test_seed_must_be_a_non_negative_integer():
    with pytest.raises(ValueError, match="seed must be >= 0, got -1"):
        Synthetic(seed=-1)
    with pytest.raises(TypeError, match="seed must be an integer"):
        Synthetic(seed=0.5)
    assert Synthetic(n_vertices=np.int64(600), seed=np.int32(3)).seed == 3


def test_unknown_class_or_pose(data):
    with pytest.raises(KeyError, match="no synthetic class 'horse'.*cat, david, dog, victoria"):
        data.load("horse", 0)
    with pytest.raises(KeyError, match="no synthetic class"):
        data.poses("wolf")
    for pose in (7, -1, True, 1.0, "1"):
        with pytest.raises(KeyError, match="no pose .* of synthetic class 'cat'; poses: 0, 1"):
            data.load("cat", pose)
    assert data.load("cat", np.int64(2)) is data.load("cat", 2)


def test_victoria_blend_moves_her_body_towards_his(data, shapes):
    """victoria_blend in (0, 1]: 1 is the default woman; between, her size lies between the
    man's and hers, and she is still a posed oriented sphere with the same numbering."""
    half = Synthetic(n_vertices=N, victoria_blend=0.5)
    np.testing.assert_array_equal(Synthetic(n_vertices=N, victoria_blend=1.0).load("victoria", 2).vertices,
                                  shapes["victoria", 2].vertices)
    np.testing.assert_array_equal(half.load("david", 2).vertices, shapes["david", 2].vertices)
    v0, v3 = half.load("victoria", 0), half.load("victoria", 3)
    assert not v0.boundary_loops and v0.genus == 0 and v0.is_edge_manifold and np.array_equal(v0.faces, v3.faces)
    area = lambda m: m.area  # noqa: E731
    lo, hi = sorted((area(shapes["david", 0]), area(shapes["victoria", 0])))
    assert lo < area(v0) < hi
    assert "victoria_blend=0.5" in repr(half)
    for bad in (0, -0.5, 1.5, True, "1"):
        with pytest.raises(ValueError, match="victoria_blend must be a number in"):
            Synthetic(victoria_blend=bad)


def test_pose_stretch_makes_poses_non_isometric(data, shapes):
    """pose_stretch = 0 is the default set; > 0 stretches poses 1-6 (same joint angles, same
    numbering and faces, still oriented spheres) so that geodesic distances change by a few
    percent, as between TOSCA's poses, while the rest pose stays as it was."""
    stretched = Synthetic(n_vertices=N, pose_stretch=0.1)
    np.testing.assert_array_equal(Synthetic(n_vertices=N, pose_stretch=0.0).load("david", 2).vertices,
                                  shapes["david", 2].vertices)
    np.testing.assert_array_equal(stretched.load("david", 0).vertices, shapes["david", 0].vertices)
    sources = np.linspace(0, shapes["david", 0].n_vertices - 1, 16).astype(int)
    d0 = gromov.metric_solver(shapes["david", 0], "geodesic").from_sources(sources)
    far = d0 > 0.05 * d0.max()
    change = lambda m: float(np.median(np.abs(  # noqa: E731
        gromov.metric_solver(m, "geodesic").from_sources(sources)[far] - d0[far]) / d0[far]))
    plain, bent = change(shapes["david", 1]), change(stretched.load("david", 1))
    assert plain < 0.01 and 0.02 < bent < 0.1, (plain, bent)
    m = stretched.load("david", 1)
    assert not m.boundary_loops and m.genus == 0 and m.is_edge_manifold
    assert np.array_equal(m.faces, shapes["david", 1].faces)
    assert stretched.clearance("david", 1) > 1.0          # parts still do not touch
    assert "pose_stretch=0.1" in repr(stretched)
    for bad in (-0.1, 0.5, True, "0.1"):
        with pytest.raises(ValueError, match="pose_stretch must be a number in"):
            Synthetic(pose_stretch=bad)
