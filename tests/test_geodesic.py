"""Geodesic distance through the common interface: isometry invariance, backends, real data.

The fast marching kernel's own accuracy tests are in test_fmm.py.
"""

import numpy as np
import pytest

from gromov import Mesh, MetricError, PointCloud
from gromov.metrics import GeodesicSolver, metric_solver
from gromov.shapes import grid, icosphere, rolled_grid


def great_circle(v, idx):
    return np.arccos(np.clip(v[idx] @ v.T, -1.0, 1.0))


@pytest.mark.parametrize("method", ["fmm", "heat", "exact", "dijkstra"])
def test_isometry_flat_sheet_vs_half_cylinder(method):
    # the same sheet, flat and rolled: intrinsic distances agree, extrinsic ones do not
    flat, rolled = grid(31, 16), rolled_grid(31, 16)
    idx = np.arange(0, flat.n_vertices, 23)
    a = GeodesicSolver(flat, method=method).from_sources(idx)
    b = GeodesicSolver(rolled, method=method).from_sources(idx)
    off = a > 0
    assert np.abs(a - b)[off].max() / a.max() < 0.005
    if method == "exact":  # exact polyhedral distance on the flat sheet is the Euclidean one
        np.testing.assert_allclose(a, metric_solver(flat, "euclidean").from_sources(idx), atol=1e-9)
    ea = metric_solver(flat, "euclidean").from_sources(idx)
    eb = metric_solver(rolled, "euclidean").from_sources(idx)
    assert np.abs(ea - eb).max() / ea.max() > 0.2


def test_backends_on_the_sphere():
    m = icosphere(3)
    idx = np.arange(0, m.n_vertices, 41)
    truth = great_circle(m.vertices, idx)
    off = truth > 1e-6  # arccos is inaccurate near the source itself
    rel = {}
    for method in ("fmm", "heat", "exact", "dijkstra"):
        d = GeodesicSolver(m, method=method).from_sources(idx)
        rel[method] = np.abs(d - truth)[off] / truth[off]
        assert np.abs(d[~off]).max() < 1e-9
    # exact polyhedral distances are within the chord/arc gap of the smooth ones
    assert rel["exact"].max() < 0.01
    exact = GeodesicSolver(m, method="exact").from_sources(idx)
    dijkstra = GeodesicSolver(m, method="dijkstra").from_sources(idx)
    assert np.all(dijkstra >= exact - 1e-9)  # an edge path is one of the surface paths
    assert rel["fmm"].mean() < rel["dijkstra"].mean()


def test_disconnected_components_are_infinitely_far():
    a, b = icosphere(1), icosphere(1)
    m = Mesh(np.vstack([a.vertices, b.vertices + 3.0]), np.vstack([a.faces, b.faces + 42]))
    for method in ("fmm", "dijkstra"):
        d = GeodesicSolver(m, method=method).from_sources([0])[0]
        assert np.isfinite(d[:42]).all() and np.isinf(d[42:]).all()
    with pytest.raises(MetricError, match="connected mesh"):
        GeodesicSolver(m, method="heat").from_sources([0])
    # the diameter ignores the infinite pairs
    assert np.isfinite(GeodesicSolver(m).diameter())


def test_point_cloud_geodesics():
    m = icosphere(4)
    pc = PointCloud(m.vertices)
    idx = np.arange(0, pc.n_vertices, 97)
    truth = great_circle(m.vertices, idx)
    off = truth > 1e-6
    for method, tol in (("dijkstra", 0.12), ("heat", 0.05)):
        d = GeodesicSolver(pc, method=method).from_sources(idx)
        assert np.mean(np.abs(d - truth)[off] / truth[off]) < tol, method


def test_multi_source_distance():
    s = GeodesicSolver(icosphere(2), method="dijkstra")
    np.testing.assert_allclose(s.distance_from_set([0, 7, 9]), s.from_sources([0, 7, 9]).min(0))


def test_errors():
    m = icosphere(1)
    with pytest.raises(ValueError, match="method must be one of"):
        GeodesicSolver(m, method="mmp")
    with pytest.raises(MetricError, match="needs a triangle mesh"):
        GeodesicSolver(PointCloud(m.vertices), method="fmm")
    with pytest.raises(TypeError, match="expected a gromov Mesh"):
        GeodesicSolver("mesh.off")
    with pytest.raises(ValueError, match="sources is empty"):
        GeodesicSolver(m).from_sources([])
    with pytest.raises(ValueError, match="integer vertex indices"):
        GeodesicSolver(m).from_sources([0.5])


def test_tosca_cat_fast_marching_against_exact(cat_working):
    """Fast marching vs exact MMP on the 3,000-vertex cat: mean relative error below 1%.

    A max of 3% is NOT reached by the default marching on this mesh
    (it is with ``refine=2``: test_fmm.py's test_refined_marching_...): a few pairs where fronts
    from both sides of a strongly curved vertex meet reach 3-6% (measured: mean 0.21%, 99th
    percentile 0.81%, max 3.4% from these 12 sources; 4.2-6.1% with 20-40 other sources;
    without the intrinsic Delaunay flips and the consistency test of the fast marching:
    0.20%, 0.93%, 8.5%). The mean and the 99th percentile are asserted so that a regression
    of the bulk shows; the max is documented (docs/design/metrics.md), not asserted.
    """
    w = cat_working.mesh
    src = np.random.default_rng(0).choice(w.n_vertices, 12, replace=False)
    fmm = GeodesicSolver(w).from_sources(src)
    exact = GeodesicSolver(w, method="exact").from_sources(src)
    off = exact > 0
    rel = np.abs(fmm - exact)[off] / exact[off]
    assert rel.mean() < 0.005
    assert np.quantile(rel, 0.99) < 0.012
