"""d(C, C0) and the geodesic error curve on small shapes with answers known by hand."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path
from scipy.spatial.transform import Rotation

from gromov import shapes
from gromov.experiments.correspondence import (CorrespondenceQuality, correspondence_distortion,
                                               error_curve)
from gromov.gh import MatchResult, ShapeMetric
from gromov.mesh import Mesh


def _result(x_samples, x_to_y, y_samples, y_to_x) -> MatchResult:
    z = np.zeros(len(x_samples), dtype=np.int64)
    w = np.zeros(len(y_samples), dtype=np.int64)
    return MatchResult(
        distance=0.0, relative_distance=0.0, distortion=0.0, distortion_l2=0.0, distortion_linf=0.0,
        norm="l2", metric="geodesic", solver="gmds", n_samples=len(x_samples),
        x_samples=np.asarray(x_samples), x_to_y_face=z, x_to_y_bary=np.zeros((len(z), 3)),
        x_to_y_vertex=np.asarray(x_to_y),
        y_samples=np.asarray(y_samples), y_to_x_face=w, y_to_x_bary=np.zeros((len(w), 3)),
        y_to_x_vertex=np.asarray(y_to_x), n_iter=0, converged=True, seconds=0.0)


@pytest.fixture(scope="module")
def sphere():
    return shapes.icosphere(2)  # 162 vertices


@pytest.fixture(scope="module")
def moved(sphere):
    R = Rotation.from_euler("xyz", [0.3, -1.1, 2.0]).as_matrix()
    return Mesh(sphere.vertices @ R.T + [5.0, -2.0, 1.0], sphere.faces)


def _edge_graph(mesh):
    e = mesh.edges
    w = np.linalg.norm(mesh.vertices[e[:, 0]] - mesh.vertices[e[:, 1]], axis=1)
    n = mesh.n_vertices
    return coo_matrix((np.r_[w, w], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()


def _neighbour(mesh):
    """One edge neighbour of every vertex."""
    e = mesh.edges
    nb = np.full(mesh.n_vertices, -1)
    nb[e[:, 0]] = e[:, 1]
    nb[e[:, 1]] = e[:, 0]
    assert (nb >= 0).all()
    return nb


# ----------------------------------------------------------------------------- d(C, C0)
@pytest.mark.parametrize("metric", ["geodesic", "euclidean"])
def test_ground_truth_correspondence_has_zero_distance(sphere, moved, metric):
    x = ShapeMetric(sphere, metric, resolution=None)
    y = ShapeMetric(moved, metric, resolution=None)
    s = x.samples(20, 0)
    q = y.samples(15, 1)
    q_ = _result(s, s, q, q)
    out = correspondence_distortion(q_, x, y)
    assert isinstance(out, CorrespondenceQuality)
    assert out.value < 1e-12 and out.x_to_y < 1e-12 and out.y_to_x < 1e-12
    assert out.errors_x_to_y.shape == (20,) and out.errors_y_to_x.shape == (15,)


def test_permuted_copy_with_its_ground_truth_has_zero_distance(sphere):
    rng = np.random.default_rng(0)
    p = rng.permutation(sphere.n_vertices)  # Y vertex j is X vertex p[j]
    pinv = np.argsort(p)
    permuted = Mesh(sphere.vertices[p], pinv[sphere.faces])
    x = ShapeMetric(sphere, "geodesic", resolution=None)
    y = ShapeMetric(permuted, "geodesic", resolution=None)
    s, q = np.arange(0, 162, 7), np.arange(3, 162, 11)
    res = _result(s, pinv[s], q, p[q])
    assert correspondence_distortion(res, x, y, truth_xy=pinv, truth_yx=p).value < 1e-12
    # against the identity it is wrong, clearly so
    assert correspondence_distortion(res, x, y).value > 0.1


def test_neighbour_shift_equals_mean_edge_path_over_diameter(sphere, moved):
    opts = {"method": "dijkstra"}
    x = ShapeMetric(sphere, "geodesic", resolution=None, metric_options=opts)
    y = ShapeMetric(moved, "geodesic", resolution=None, metric_options=opts)
    nb = _neighbour(sphere)
    s, q = np.arange(0, 162, 5), np.arange(1, 162, 9)
    res = _result(s, nb[s], q, nb[q])
    out = correspondence_distortion(res, x, y)

    dx = shortest_path(_edge_graph(sphere), directed=False)
    dy = shortest_path(_edge_graph(moved), directed=False)
    want_xy = dy[nb[s], s].mean() / dy.max()
    want_yx = dx[nb[q], q].mean() / dx.max()
    assert out.x_to_y == pytest.approx(want_xy, rel=1e-9)
    assert out.y_to_x == pytest.approx(want_yx, rel=1e-9)
    assert out.value == pytest.approx(0.5 * (want_xy + want_yx), rel=1e-9)
    assert out.value > 0


def test_neighbour_shift_in_euclidean_metric(sphere):
    x = ShapeMetric(sphere, "euclidean", resolution=None)
    nb = _neighbour(sphere)
    s = np.arange(0, 162, 3)
    out = correspondence_distortion(_result(s, nb[s], s, s), x, x)
    v = sphere.vertices
    diam = np.linalg.norm(v[:, None] - v[None], axis=-1).max()
    want = np.linalg.norm(v[nb[s]] - v[s], axis=1) / diam
    np.testing.assert_allclose(out.errors_x_to_y, want, rtol=1e-9)
    assert out.y_to_x == 0.0
    assert out.value == pytest.approx(0.5 * want.mean(), rel=1e-9)


def test_distortion_errors(sphere):
    x = ShapeMetric(sphere, "euclidean", resolution=None)
    s = np.arange(5)
    with pytest.raises(ValueError, match="truth_xy must be a 1-D integer"):
        correspondence_distortion(_result(s, s, s, s), x, x, truth_xy=np.zeros(162))
    with pytest.raises(ValueError, match="ground truth has 3 entries"):
        correspondence_distortion(_result(s, s, s, s), x, x, truth_yx=np.arange(3))
    with pytest.raises(ValueError, match="equal length"):
        correspondence_distortion(_result(s, s[:3], s, s), x, x)
    with pytest.raises(TypeError, match="ShapeMetric"):
        correspondence_distortion(_result(s, s, s, s), sphere, x)


# ----------------------------------------------------------------------------- error curve
def test_error_curve_by_hand():
    # area 4: sqrt = 2, so threshold e admits errors <= 2e
    t, f = error_curve([0.0, 0.1, 0.3, 0.5], 4.0, thresholds=[0.0, 0.05, 0.1, 0.2, 0.25])
    np.testing.assert_array_equal(t, [0.0, 0.05, 0.1, 0.2, 0.25])
    np.testing.assert_array_equal(f, [0.25, 0.5, 0.5, 0.75, 1.0])


def test_error_curve_default_thresholds_monotone():
    rng = np.random.default_rng(3)
    t, f = error_curve(rng.exponential(0.1, 500), 2.5)
    np.testing.assert_allclose(t, np.linspace(0, 0.25, 51))
    assert f.shape == (51,)
    assert (np.diff(f) >= 0).all() and 0 <= f[0] and f[-1] <= 1


def test_error_curve_zero_errors_all_ones():
    _, f = error_curve(np.zeros(10), 1.0)
    np.testing.assert_array_equal(f, np.ones(51))


@pytest.mark.parametrize("errors, area, thresholds, msg", [
    ([], 1.0, None, "errors must be a non-empty 1-D"),
    ([[0.1]], 1.0, None, "errors must be a non-empty 1-D"),
    ([0.1, -0.2], 1.0, None, "errors must be finite and non-negative"),
    ([0.1, np.nan], 1.0, None, "errors must be finite and non-negative"),
    ([0.1], 0.0, None, "area must be positive"),
    ([0.1], np.inf, None, "area must be positive"),
    ([0.1], 1.0, [-0.1, 0.2], "thresholds must be"),
    ([0.1], 1.0, [], "thresholds must be"),
])
def test_error_curve_errors(errors, area, thresholds, msg):
    with pytest.raises(ValueError, match=msg):
        error_curve(errors, area, thresholds)
