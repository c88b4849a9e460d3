"""Biharmonic distance: the spectral definition, the time integral of diffusion distances,
metric facts, scale and bending behaviour, components, real data."""

import numpy as np
import pytest
from scipy.linalg import eigh

import gromov
from gromov import Mesh, MetricError, PointCloud
from gromov.metrics import BiharmonicSolver, cotan_laplacian, metric_solver
from gromov.shapes import grid, icosphere, rolled_grid


def _spectral(mesh):
    """(eigenvalues, M-orthonormal eigenvectors) of L phi = lambda M phi, dense."""
    stiffness, mass = cotan_laplacian(mesh)
    return eigh(stiffness.toarray(), mass.toarray())


@pytest.mark.parametrize("shape", [icosphere(2), grid(13, 7)], ids=["sphere", "grid"])
def test_equals_the_spectral_definition(shape):
    lam, phi = _spectral(shape)
    psi = phi[:, 1:] / lam[1:]  # drop the constant eigenvector (lambda_0 = 0)
    ref = np.sqrt(np.maximum(((psi[:, None, :] - psi[None, :, :]) ** 2).sum(-1), 0.0))
    d = BiharmonicSolver(shape).pairwise()
    np.testing.assert_allclose(d, ref, atol=1e-8 * ref.max())


def test_is_four_times_the_time_integral_of_t_times_squared_diffusion_distance():
    shape = icosphere(1)
    lam, phi = _spectral(shape)
    x, y = 0, 7
    diff2 = (phi[x] - phi[y]) ** 2
    # d_t^2 = sum_k exp(-2 lambda_k t) (phi_k(x) - phi_k(y))^2, integrated on a log grid in t
    t = np.geomspace(1e-6, 1e3, 40001) / lam[1]
    f = t * (np.exp(-2.0 * np.outer(t, lam)) @ diff2)
    integral = np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t))
    d = BiharmonicSolver(shape).pairwise()[x, y]
    assert d**2 == pytest.approx(4.0 * integral, rel=1e-4)


def test_metric_axioms_and_rows():
    s = metric_solver(icosphere(3), "diffusion", kernel="biharmonic")
    assert isinstance(s, BiharmonicSolver)
    d = s.pairwise()
    assert np.array_equal(d, d.T) and np.all(np.diag(d) == 0)
    assert d[~np.eye(len(d), dtype=bool)].min() > 0
    idx = np.random.default_rng(0).choice(len(d), 120, replace=False)
    sub = d[np.ix_(idx, idx)]
    viol = sub[:, None, :] - (sub[:, :, None] + sub[None, :, :])
    assert viol.max() <= 1e-10 * sub.max()
    np.testing.assert_array_equal(s.from_sources(idx[:5]), d[idx[:5]])


def test_units_of_length_and_bending_invariance():
    m = icosphere(2)
    d1 = BiharmonicSolver(m).pairwise()
    d3 = BiharmonicSolver(Mesh(3.0 * m.vertices, m.faces)).pairwise()
    np.testing.assert_allclose(d3, 3.0 * d1, rtol=1e-7, atol=1e-12)
    flat, rolled = BiharmonicSolver(grid(31, 16)).pairwise(), BiharmonicSolver(rolled_grid(31, 16)).pairwise()
    assert np.abs(flat - rolled).mean() < 0.01 * flat.mean()
    ef = metric_solver(grid(31, 16), "euclidean").pairwise()
    er = metric_solver(rolled_grid(31, 16), "euclidean").pairwise()
    assert np.abs(ef - er).mean() > 0.05 * ef.mean()


def test_components_are_solved_apart_and_infinitely_far():
    a, b = icosphere(1), icosphere(2, radius=0.5)
    b = Mesh(b.vertices + [5.0, 0.0, 0.0], b.faces)
    both = Mesh(np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + a.n_vertices]))
    d = BiharmonicSolver(both).pairwise()
    n = a.n_vertices
    assert np.all(np.isinf(d[:n, n:])) and np.all(np.isinf(d[n:, :n]))
    for block, alone in ((d[:n, :n], BiharmonicSolver(a).pairwise()), (d[n:, n:], BiharmonicSolver(b).pairwise())):
        np.testing.assert_allclose(block, alone, atol=1e-10 * alone.max())
    assert not d.flags.writeable
    # a point cloud of two far clusters: components from the robust Laplacian's graph
    pts = np.vstack([a.vertices, b.vertices])
    dc = BiharmonicSolver(PointCloud(pts)).pairwise()
    assert np.all(np.isinf(dc[:n, n:])) and np.all(np.isfinite(dc[:n, :n])) and np.all(np.isfinite(dc[n:, n:]))


def test_point_cloud_and_errors():
    m = icosphere(3)
    pc = BiharmonicSolver(PointCloud(m.vertices))
    assert pc.laplacian == "robust"
    a, b = pc.pairwise(), BiharmonicSolver(m).pairwise()
    assert np.abs(a - b).mean() < 0.05 * b.mean()
    with pytest.raises(ValueError, match="laplacian must be"):
        BiharmonicSolver(m, laplacian="fem")
    with pytest.raises(TypeError):
        BiharmonicSolver(m, tau=0.1)
    loose = Mesh(np.vstack([m.vertices, [[9.0, 9.0, 9.0]]]), m.faces)
    with pytest.raises(MetricError, match="positive vertex areas"):
        BiharmonicSolver(loose)


def test_tosca_cat_poses_agree(data_dir):
    """Bending: cat0 and cat1 simplified identically have close biharmonic distances.

    Measured at 1,500 vertices: mean |d0 - d1| / mean d0 = 0.085 for biharmonic, 0.126 for
    geodesic (fast marching), 0.033 for the heat kernel (tau = 0.005) -- TOSCA's poses are
    only nearly isometric.
    """
    tosca = data_dir / "tosca"
    w0 = gromov.simplify(gromov.load(tosca / "cat0.off.gz"), 1500)
    w1 = w0.transfer(gromov.load(tosca / "cat1.off.gz"))
    d0 = BiharmonicSolver(w0.mesh).pairwise()
    d1 = BiharmonicSolver(w1.mesh).pairwise()
    change = np.abs(d0 - d1).mean() / d0.mean()
    g0, g1 = (metric_solver(w.mesh, "geodesic").pairwise() for w in (w0, w1))
    assert change < 0.1 and change < np.abs(g0 - g1).mean() / g0.mean()
    # and a different shape at the same resolution does not
    dog = BiharmonicSolver(gromov.simplify(gromov.load(tosca / "dog0.off.gz"), 1500).mesh).pairwise()
    q = np.linspace(0, 1, 101)
    qc, qd = np.quantile(d0 / d0.max(), q), np.quantile(dog / dog.max(), q)
    assert np.abs(np.quantile(d1 / d1.max(), q) - qc).max() < np.abs(qd - qc).max()
