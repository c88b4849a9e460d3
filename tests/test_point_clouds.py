"""Matching point clouds (shapes without faces): working sets, discrete images, the CLI."""

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

import gromov
from gromov import Mesh, PointCloud, match
from gromov.cli import main
from gromov.gh import ShapeMetric, SymmetricGMDS, _at_vertices, discrete_blocks
from gromov.mesh import MeshError, as_shape
from gromov.resolution import WorkingCloud, working_cloud
from gromov.shapes import torus


def bumpy_torus_points(n=1800, seed=7) -> np.ndarray:
    """``n`` random points on a torus with an asymmetric bump field, its upper half thicker than
    the lower (no self-isometry; random, not on a grid, where the point-cloud Laplacian's local
    triangulations would be ambiguous)."""
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, 2 * np.pi, n)
    r = 1 + 0.35 * np.cos(b)
    v = np.c_[r * np.cos(a), r * np.sin(a), 0.35 * np.sin(b)]
    v *= (1 + 0.15 * np.exp(-((a - 1.0) ** 2) / 0.2) + 0.05 * np.sin(3 * a + 0.4))[:, None]
    v[:, 2] *= 1 + 0.3 * np.tanh(3 * v[:, 2])
    return v


def moved(points: np.ndarray, seed=0):
    """A rigidly moved copy with its points in another order, and the order (copy i = points[perm[i]])."""
    rng = np.random.default_rng(seed)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    perm = rng.permutation(len(points))
    return points[perm] @ rot.T + rng.normal(size=3), perm


def test_as_shape_tells_point_clouds_from_meshes():
    pts = bumpy_torus_points(60)
    assert type(as_shape(pts)) is PointCloud
    cloud = PointCloud(pts)
    assert as_shape(cloud) is cloud
    t = torus(8, 6)
    assert type(as_shape((t.vertices, t.faces))) is Mesh

    class Obj:   # trimesh.PointCloud-like: vertices, no faces
        vertices = pts
    assert type(as_shape(Obj())) is PointCloud
    with pytest.raises(MeshError, match=r"shape \(n, 3\)"):
        as_shape(np.zeros((5, 2)))
    with pytest.raises(TypeError, match="must be a gromov Mesh"):
        as_shape("not a shape")


def test_working_cloud_is_an_even_cover_that_ignores_the_order_of_the_points():
    pts = bumpy_torus_points()
    w = working_cloud(PointCloud(pts), 300)
    assert isinstance(w, WorkingCloud) and w.n_vertices == 300
    assert np.all(np.diff(w.vertex_ids) > 0)
    np.testing.assert_array_equal(w.mesh.vertices, pts[w.vertex_ids])
    np.testing.assert_array_equal(w.to_input_ids(np.arange(300)), w.vertex_ids)
    # each point's nearest working point, a working point its own
    d = np.linalg.norm(pts[:, None] - w.mesh.vertices[None], axis=2)
    np.testing.assert_allclose(d[np.arange(len(pts)), w.source_nearest], d.min(axis=1))
    np.testing.assert_array_equal(w.from_source(w.vertex_ids), np.arange(300))
    np.testing.assert_array_equal(w.interpolate(np.arange(300.0))[w.vertex_ids], np.arange(300.0))
    # farthest points: the covering radius is at most that of 300 random points
    rnd = np.random.default_rng(1).choice(len(pts), 300, replace=False)
    assert d.min(axis=1).max() < np.linalg.norm(pts[:, None] - pts[rnd][None], axis=2).min(axis=1).max()
    # the same points, moved and in another order: the same working points
    y, perm = moved(pts)
    wy = working_cloud(PointCloud(y), 300)
    assert set(perm[wy.vertex_ids].tolist()) == set(w.vertex_ids.tolist())
    # all of a small cloud; errors
    assert working_cloud(PointCloud(pts), None).n_vertices == len(pts)
    assert working_cloud(PointCloud(pts), 10**6).n_vertices == len(pts)
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="n_points must be"):
            working_cloud(PointCloud(pts), bad)
    with pytest.raises(TypeError, match="must be a PointCloud"):
        working_cloud(pts, 10)


@pytest.mark.parametrize("metric", ["geodesic", "diffusion", "euclidean"])
@pytest.mark.parametrize("resolution", [None, 600])
def test_gh_of_a_moved_reordered_cloud_is_zero_and_maps_each_point_to_itself(metric, resolution):
    pts = bumpy_torus_points()          # 1,800 points
    y, perm = moved(pts)
    r = match(pts, y, metric, n_samples=30, resolution=resolution)
    assert r.relative_distance < 1e-3
    # images are points of the clouds, given as their indices; no faces
    assert np.all(r.x_to_y_face == -1) and np.isnan(r.x_to_y_bary).all()
    assert np.all(r.y_to_x_face == -1) and np.isnan(r.y_to_x_bary).all()
    np.testing.assert_array_equal(perm[r.x_to_y_vertex], r.x_samples)   # the same points
    np.testing.assert_array_equal(r.y_to_x_vertex, perm[r.y_samples])
    assert r.n_iter == 0 and r.converged and np.isnan(r.orientation) and r.to_dict()["orientation"] is None
    assert len(r.history) == 0


def test_discrete_blocks_are_the_blocks_at_vertex_images():
    m = gromov.simplify(torus(40, 20), 300).mesh
    sx = ShapeMetric(m, "geodesic", resolution=None)
    rng = np.random.default_rng(0)
    P, Q = sx.samples(12, 0), sx.samples(12, 1)
    a, b = rng.integers(0, m.n_vertices, 12), rng.integers(0, m.n_vertices, 12)
    gm = SymmetricGMDS(sx.surface, sx.surface, P, Q)
    dx, dy = gm.blocks(*_at_vertices(sx, sx, a, b))
    ex, ey = discrete_blocks(sx.distances, sx.distances, P, Q, a, b)
    np.testing.assert_allclose(ex, dx, atol=1e-9)
    np.testing.assert_allclose(ey, dy, atol=1e-9)


def test_a_mesh_and_the_cloud_of_its_vertices():
    w = gromov.simplify(torus(60, 30), 800).mesh
    m = Mesh(w.vertices, w.faces)   # numbered 0..n-1 (a working mesh keeps its input's ids)
    pts = m.vertices
    y, perm = moved(pts, seed=3)
    # the euclidean metric is the same on both: GH 0 (and no warning about mixing the two);
    # images on the mesh are points of its faces, images on the cloud its points
    with warnings.catch_warnings():
        warnings.simplefilter("error", gromov.GromovWarning)
        r = match(m, y, "euclidean", n_samples=25, resolution=None)
    assert r.relative_distance < 1e-3
    assert np.all(r.x_to_y_face == -1)
    np.testing.assert_array_equal(perm[r.x_to_y_vertex], r.x_samples)
    assert np.all(r.y_to_x_face >= 0)
    np.testing.assert_allclose(r.y_to_x_bary.sum(axis=1), 1.0)
    assert np.all((m.faces[r.y_to_x_face] == r.y_to_x_vertex[:, None]).any(axis=1))
    np.testing.assert_array_equal(r.y_to_x_vertex, perm[r.y_samples])


def test_point_cloud_neighbours_are_an_option_of_the_diffusion_metric():
    from gromov.metrics.diffusion import POINT_CLOUD_NEIGHBORS, BiharmonicSolver, HeatDiffusionSolver

    cloud = PointCloud(bumpy_torus_points(300))
    a, b = HeatDiffusionSolver(cloud), HeatDiffusionSolver(cloud, neighbors=10)
    assert a.neighbors == POINT_CLOUD_NEIGHBORS and "neighbors=20" in repr(a)
    assert not np.allclose(a.pairwise(), b.pairwise())       # it is used
    assert "neighbors" not in repr(HeatDiffusionSolver(torus(12, 6)))   # meshes: not used
    assert BiharmonicSolver(cloud, neighbors=12).neighbors == 12
    for bad in (2, 2.5, True, "20"):
        with pytest.raises(ValueError, match="neighbors must be an integer >= 3"):
            HeatDiffusionSolver(cloud, neighbors=bad)


def test_what_a_point_cloud_cannot_do():
    pts = bumpy_torus_points(200)
    s = ShapeMetric(pts, "euclidean", resolution=None)
    assert not s.has_faces and not s.normals[1]
    with pytest.raises(TypeError, match="no surface"):
        s.surface
    with pytest.raises(TypeError, match="locate needs a triangle mesh"):
        s.locate(None)
    with pytest.raises(ValueError, match="radius"):
        match(pts, pts, "euclidean", n_samples=10, resolution=None, radius=1.0)
    assert s.symmetry(10) is None


def test_recognition_ranks_point_clouds_with_the_finer_heat_distance():
    pts = bumpy_torus_points(450)
    y, _ = moved(pts)
    far = bumpy_torus_points(450) * np.array([1.0, 1.0, 1.6])   # a thicker torus
    opts = {"kernel": "heat", "units": "raw"}
    from gromov.gh import _match   # recognition's match (gh_matrix)

    near = _match(pts, y, "diffusion", n_samples=20, resolution=None, metric_options=opts,
                  rank_tau_scale=0.5, rank_residual="log")
    other = _match(pts, far, "diffusion", n_samples=20, resolution=None, metric_options=opts,
                   rank_tau_scale=0.5, rank_residual="log")
    assert near.ranking_distance < 1e-3 < other.ranking_distance


def test_tosca_clouds_same_class_is_closer(data_dir):
    tosca = data_dir / "tosca"
    shapes = [ShapeMetric(gromov.load(tosca / f"{n}.off.gz").vertices, "diffusion", resolution=1500,
                          metric_options={"kernel": "heat", "units": "raw"})
              for n in ("cat0", "cat1", "dog0")]
    same = match(shapes[0], shapes[1], "diffusion", n_samples=50).relative_distance
    other = match(shapes[0], shapes[2], "diffusion", n_samples=50).relative_distance
    assert same < other


def test_cli_matches_point_cloud_files(tmp_path):
    pts = bumpy_torus_points(450)
    y, perm = moved(pts)
    gromov.save(PointCloud(pts), tmp_path / "x.ply")
    gromov.save(PointCloud(y), tmp_path / "y.xyz")
    out = tmp_path / "m.npz"
    cmd = [sys.executable, "-m", "gromov", "match", str(tmp_path / "x.ply"), str(tmp_path / "y.xyz"),
           "--metric", "euclidean", "--samples", "20", "--json", "--out", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    d = json.loads(res.stdout)
    assert d["relative_distance"] < 1e-3 and d["orientation"] is None
    a = np.load(out)
    assert np.all(a["x_to_y_face"] == -1)
    np.testing.assert_array_equal(perm[a["x_to_y_vertex"]], a["x_samples"])
    res = subprocess.run(cmd[:-3] + ["--plot", str(tmp_path / "p.png")], capture_output=True, text=True)
    assert res.returncode != 0 and "is a point cloud" in res.stderr


def test_a_finer_heat_time_from_all_eigenpairs_of_a_small_cloud_stays_finite():
    # all 450 eigenpairs are computed; with 30 neighbours the top ones have lambda t ~ 1,500,
    # where exp(-lambda t) underflows and exp(lambda t / 2) overflows: 0 * inf would be NaN
    # without the cap on the factor
    from gromov.metrics.diffusion import HeatDiffusionSolver

    cloud = PointCloud(bumpy_torus_points(450))
    a = HeatDiffusionSolver(cloud, units="raw", neighbors=30)
    a.embedding   # computed on first use
    assert a.eigenvalues[-1] * a.t / 2 > np.log(np.finfo(float).max)   # exp(lambda t / 2) overflows
    finer = a.at_tau(a.tau / 2).pairwise()
    direct = HeatDiffusionSolver(cloud, tau=a.tau / 2, units="raw", neighbors=30).pairwise()
    assert np.isfinite(finer).all()
    np.testing.assert_allclose(finer, direct, atol=1e-9 * direct.max())


def test_a_cloud_in_pieces_is_refused_clearly():
    pts = bumpy_torus_points(400)
    two = np.vstack([pts, pts + [10.0, 0.0, 0.0]])   # two far copies: the 10-NN graph falls apart
    s = ShapeMetric(two, "geodesic", resolution=None)
    assert not s.finite and np.isfinite(s.diameter)
    assert ShapeMetric(pts, "geodesic", resolution=None).finite
    with pytest.raises(gromov.MetricError, match="X: matching needs finite distances"):
        match(s, pts, "geodesic", n_samples=10)


def test_cli_pairwise_recognises_point_clouds(tmp_path):
    # two shapes, each sampled twice at other random points: recognition of clouds by gh_matrix
    files = []
    for name, scale in (("thin", 1.0), ("thick", 1.6)):
        for seed in (1, 2):
            f = tmp_path / f"{name}{seed}.xyz"
            gromov.save(PointCloud(bumpy_torus_points(500, seed=seed) * [1.0, 1.0, scale]), f)
            files.append(str(f))
    res = subprocess.run([sys.executable, "-m", "gromov", "pairwise", *files, "--samples", "20",
                          "--labels-from-names", "--jobs", "1", "--json"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    d = json.loads(res.stdout)
    assert d["eer"] == 0.0
    D = np.array(d["relative_trimmed_distance"])
    assert D[0, 1] < min(D[0, 2], D[0, 3]) and D[2, 3] < min(D[2, 0], D[2, 1])


def test_repeated_points_are_kept_once():
    pts = bumpy_torus_points(600)
    twice = np.vstack([pts, pts[:50], np.repeat(pts[:1], 30, axis=0)])   # 80 repeats
    with pytest.warns(gromov.GromovWarning, match="80 of its 680 points repeat"):
        w = working_cloud(PointCloud(twice), None)
    np.testing.assert_array_equal(w.vertex_ids, np.arange(600))
    np.testing.assert_array_equal(w.source_nearest[600:650], np.arange(50))   # each copy at its place
    assert np.all(w.source_nearest[650:] == 0)
    assert not w.vertex_ids.flags.writeable and not w.source_nearest.flags.writeable
    # so the copies change nothing: GH 0 to the cloud without them, in both metrics
    y, perm = moved(pts)
    for metric in ("geodesic", "diffusion"):
        with pytest.warns(gromov.GromovWarning, match="repeat"):
            r = match(twice, y, metric, n_samples=20, resolution=None)
        assert r.relative_distance < 1e-3


def test_clouds_of_a_few_points():
    pts = bumpy_torus_points(15)     # fewer points than the Laplacian's 20 neighbours
    r = match(pts, pts[::-1].copy(), "diffusion", n_samples=5)
    assert r.relative_distance < 1e-9
    with pytest.raises(gromov.MetricError, match="at least 4 points"):
        match(pts[:3], pts[:3], "diffusion", n_samples=3)


@pytest.mark.parametrize("metric", ["geodesic", "diffusion"])
def test_a_mesh_matched_with_a_cloud_is_warned_about(metric):
    w = gromov.simplify(torus(40, 20), 400).mesh
    m = Mesh(w.vertices, w.faces)
    with pytest.warns(gromov.GromovWarning, match="Y is a point cloud and the other a mesh"):
        r = match(m, m.vertices, metric, n_samples=15, resolution=None)
    assert np.all(r.x_to_y_face == -1) and np.all(r.y_to_x_face >= 0)


def test_working_shape_must_fit_the_shape():
    pts = bumpy_torus_points(300)
    m = gromov.simplify(torus(30, 15), 200).mesh
    with pytest.raises(TypeError, match="a WorkingCloud was given for a Mesh"):
        ShapeMetric(m, "euclidean", working=working_cloud(PointCloud(m.vertices), None))
    with pytest.raises(TypeError, match="a WorkingMesh was given for a PointCloud"):
        ShapeMetric(pts, "euclidean", working=gromov.simplify(m, 100))
    s = ShapeMetric(pts, "euclidean", working=working_cloud(PointCloud(pts), 100))
    assert s.mesh.n_vertices == 100


def test_as_shape_reads_lists_of_points_and_objects_with_no_faces():
    pts = bumpy_torus_points(10)
    assert type(as_shape(pts.tolist())) is PointCloud

    class Scan:   # e.g. trimesh.Trimesh(vertices, faces=None): an empty face array
        vertices = pts
        faces = np.zeros((0, 3), dtype=int)
    assert type(as_shape(Scan())) is PointCloud


def test_cli_distances_on_a_point_cloud(tmp_path):
    pts = bumpy_torus_points(700)
    f = tmp_path / "c.xyz"
    gromov.save(PointCloud(pts), f)
    out = tmp_path / "d.npz"
    res = subprocess.run([sys.executable, "-m", "gromov", "distances", str(f), "--metric", "geodesic",
                          "--resolution", "300", "--samples", "20", "--out", str(out)],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    a = np.load(out)
    w = working_cloud(PointCloud(pts), 300)   # the same working set, whatever the seed
    assert set(a["samples"].tolist()) <= set(w.vertex_ids.tolist())
    assert a["distances"].shape == (20, 20) and np.all(np.isfinite(a["distances"]))


def test_cli_neighbours_of_point_clouds(tmp_path, capsys):
    pts = bumpy_torus_points(400)
    f = tmp_path / "c.xyz"
    gromov.save(PointCloud(pts), f)
    base = [sys.executable, "-m", "gromov", "match", str(f), str(f), "--samples", "10", "--json"]
    for metric, key, k in (("geodesic", "k", 6), ("diffusion", "neighbors", 12)):
        res = subprocess.run(base + ["--metric", metric, "--neighbors", str(k)], capture_output=True, text=True)
        assert res.returncode == 0, res.stderr
        d = json.loads(res.stdout)
        assert d["metric_options"][key] == k and d["relative_distance"] < 1e-9
    # (the refusals run in this process: they stop before any metric)
    assert main(base[3:] + ["--metric", "diffusion", "--kernel", "connectivity", "--neighbors", "5"]) == 2
    assert "--neighbors applies to point clouds" in capsys.readouterr().err
    # meshes alone would ignore it: refused, in every command that takes it, before any metric
    mesh, other = tmp_path / "t.off", tmp_path / "u.ply"
    gromov.save(torus(12, 6), mesh)
    gromov.save(torus(14, 7), other)
    for argv in (["match", str(mesh), str(other)], ["pairwise", str(mesh), str(other)],
                 ["distances", str(mesh), "--out", str(tmp_path / "never.npz")]):
        assert main([*argv, "--samples", "10", "--neighbors", "8"]) == 2, argv
        assert "every input here is a mesh" in capsys.readouterr().err, argv
    assert not (tmp_path / "never.npz").exists()
    # a mesh beside a cloud: the cloud uses it
    res = subprocess.run([sys.executable, "-m", "gromov", "match", str(mesh), str(f), "--samples", "10",
                          "--neighbors", "8", "--json"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def test_coincident_points_are_neighbours_at_distance_zero_in_the_knn_graph():
    from gromov.metrics import GeodesicSolver

    pts = bumpy_torus_points(300)
    twice = np.vstack([pts, pts[:5]])       # a raw cloud with repeated points (no working set)
    d = GeodesicSolver(PointCloud(twice), k=10).from_sources(np.arange(5))
    np.testing.assert_allclose(d[np.arange(5), 300 + np.arange(5)], 0.0, atol=1e-12)
