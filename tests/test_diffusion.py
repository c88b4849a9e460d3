"""Diffusion distances: eq. (4) of Bronstein et al. 2010 by definition and fast, metric facts,
resolution independence of the heat-kernel variant."""

import numpy as np
import pytest

from gromov import Mesh, MetricError, PointCloud
from gromov.metrics import (
    GraphDiffusionSolver,
    HeatDiffusionSolver,
    affinity,
    brute_force_diffusion_distance,
    diffusion_operator,
    metric_solver,
)
from gromov.shapes import grid, icosphere, rolled_grid


@pytest.mark.parametrize("kernel, density", [("connectivity", False), ("connectivity", True),
                                             ("gaussian", False)])
@pytest.mark.parametrize("shape", [icosphere(3), grid(25, 13)], ids=["sphere", "grid"])
def test_fast_equals_brute_force_eq4(shape, kernel, density):
    s = GraphDiffusionSolver(shape, kernel=kernel, density_normalize=density, m=20,
                             dense_below=0)  # force the truncated spectral path
    d = s.pairwise()
    ref = brute_force_diffusion_distance(s.operator, 20)
    assert len(s.eigenvalues) < shape.n_vertices  # it really truncated
    # squared distances differ by at most the stated truncation bound
    assert np.abs(d**2 - ref**2).max() <= s.truncation_bound + 1e-12 * (ref**2).max()
    np.testing.assert_allclose(d, ref, atol=1e-5 * ref.max())


def test_operator_is_the_symmetric_normalisation():
    m = icosphere(1)
    k = affinity(m)
    v = np.asarray(k.sum(1)).ravel()
    p = diffusion_operator(k).toarray()
    np.testing.assert_allclose(p, k.toarray() / np.sqrt(np.outer(v, v)))
    # eq. (9): density normalisation first
    kt = k.toarray() / np.outer(v, v)
    vt = kt.sum(1)
    np.testing.assert_allclose(diffusion_operator(k, density_normalize=True).toarray(),
                               kt / np.sqrt(np.outer(vt, vt)))
    # the largest eigenvalue of a connected graph's operator is 1
    assert np.linalg.eigvalsh(p).max() == pytest.approx(1.0)


@pytest.mark.parametrize("solver", [lambda m: GraphDiffusionSolver(m),
                                    lambda m: HeatDiffusionSolver(m)], ids=["graph", "heat"])
def test_metric_axioms(solver):
    s = solver(icosphere(3))
    d = s.pairwise()
    assert np.array_equal(d, d.T) and np.all(np.diag(d) == 0) and d[~np.eye(len(d), dtype=bool)].min() > 0
    idx = np.random.default_rng(0).choice(len(d), 120, replace=False)
    sub = d[np.ix_(idx, idx)]
    # d(x, z) <= d(x, y) + d(y, z) for all triples
    viol = sub[:, None, :] - (sub[:, :, None] + sub[None, :, :])
    assert viol.max() <= 1e-12 * sub.max()
    np.testing.assert_allclose(s.from_sources(idx[:5]), d[idx[:5]], atol=1e-12)


def test_graph_diffusion_is_bending_invariant_and_euclidean_is_not():
    flat, rolled = grid(31, 16), rolled_grid(31, 16)
    np.testing.assert_allclose(GraphDiffusionSolver(rolled).pairwise(),
                               GraphDiffusionSolver(flat).pairwise(), atol=1e-10)
    hf, hr = HeatDiffusionSolver(flat).pairwise(), HeatDiffusionSolver(rolled).pairwise()
    assert np.abs(hf - hr).mean() < 0.01 * hf.mean()
    ef, er = metric_solver(flat, "euclidean").pairwise(), metric_solver(rolled, "euclidean").pairwise()
    assert np.abs(ef - er).mean() > 0.05 * ef.mean()


def test_heat_kernel_converges_under_refinement_graph_kernel_does_not():
    # subdivision keeps the coarse vertices first, so vertex i is the same point at every level
    levels = [icosphere(k) for k in (2, 3, 4)]  # 162, 642, 2562 vertices
    n = levels[0].n_vertices
    idx = np.arange(n)

    def rel(solver_cls):
        d = [solver_cls(m).from_sources(idx)[:, :n] for m in levels]
        return [np.abs(x - d[-1]).mean() / d[-1].mean() for x in d[:-1]]

    h2, h3 = rel(HeatDiffusionSolver)
    assert h3 < 0.02 and h3 < 0.25 * h2  # converges (about first order in the edge length^2)
    g2, g3 = rel(GraphDiffusionSolver)
    assert g3 > 0.1  # m steps cover a resolution-dependent area


def test_heat_distance_in_length_units_is_the_geodesic_distance_below_the_diffusion_radius():
    # On a plane, sqrt(32 pi) t d_t(x, y) = sqrt(8t) sqrt(1 - exp(-r^2 / 8t)) (HeatDiffusionSolver,
    # ``units``): about r below the diffusion radius, sqrt(8t) far beyond it. Unit square, the
    # centre vertex, points within 0.2 of it (the boundary's reflection is below 1e-3 there).
    m = grid(41, 41, width=1.0, height=1.0)
    s = HeatDiffusionSolver(m, tau=0.004, units="length")
    c = 20 * 41 + 20
    d = s.from_sources([c])[0]
    r = np.linalg.norm(m.vertices - m.vertices[c], axis=1)
    plane = np.sqrt(8 * s.t) * np.sqrt(1 - np.exp(-r**2 / (8 * s.t)))
    near = (r > 0) & (r < 0.2)
    assert np.abs(d[near] / plane[near] - 1).max() < 0.04   # measured 0.023 (mesh spacing 0.025)
    short = (r > 0) & (r < 0.3 * np.sqrt(8 * s.t))
    assert np.abs(d[short] / r[short] - 1).max() < 0.04
    # the factor is a constant: the raw distance times sqrt(32 pi) t
    raw = HeatDiffusionSolver(m, tau=0.004)
    np.testing.assert_allclose(raw.from_sources([c])[0] * np.sqrt(32 * np.pi) * raw.t, d, rtol=1e-9)


@pytest.mark.parametrize("units, power", [("raw", -1), ("length", 1), ("area", 0)])
def test_heat_distance_scales_with_the_shape(units, power):
    # t = tau * area: scaling a shape by s scales d_t by 1/s; in length units by s; in area
    # units (the shape at unit area) not at all
    m = icosphere(2)
    d1 = HeatDiffusionSolver(m, units=units).pairwise()
    d3 = HeatDiffusionSolver(Mesh(3.0 * m.vertices, m.faces), units=units).pairwise()
    np.testing.assert_allclose(d3, 3.0**power * d1, rtol=1e-6, atol=1e-9 * d1.max())


def test_robust_and_cotan_laplacians_agree_on_a_good_mesh():
    m = icosphere(3)
    a = HeatDiffusionSolver(m).pairwise()
    b = HeatDiffusionSolver(m, laplacian="robust").pairwise()
    assert np.abs(a - b).mean() < 0.02 * a.mean()


def test_point_cloud_diffusion():
    pts = icosphere(3).vertices
    s = metric_solver(PointCloud(pts), "diffusion", kernel="gaussian", m=20, dense_below=0)
    assert s.kernel == "gaussian"
    ref = brute_force_diffusion_distance(s.operator, 20)
    np.testing.assert_allclose(s.pairwise(), ref, atol=1e-5 * ref.max())
    h = metric_solver(PointCloud(pts), "diffusion", kernel="heat").pairwise()
    hm = metric_solver(icosphere(3), "diffusion", kernel="heat").pairwise()
    assert np.abs(h - hm).mean() < 0.1 * hm.mean()


def test_errors():
    m = icosphere(1)
    with pytest.raises(MetricError, match="connectivity kernel needs mesh edges"):
        affinity(PointCloud(m.vertices), "connectivity")
    with pytest.raises(ValueError, match="kernel must be"):
        affinity(m, "cosine")
    with pytest.raises(ValueError, match="sigma must be positive"):
        affinity(m, "gaussian", sigma=-1.0)
    with pytest.raises(ValueError, match="positive integer"):
        GraphDiffusionSolver(m, m=0)
    with pytest.raises(ValueError, match="tau must be positive"):
        HeatDiffusionSolver(m, tau=0)
    with pytest.raises(ValueError, match="laplacian must be"):
        HeatDiffusionSolver(m, laplacian="fem")
    with pytest.raises(ValueError, match="units must be one of"):
        HeatDiffusionSolver(m, units="metres")
    with pytest.raises(ValueError, match="diffusion kernel must be"):
        metric_solver(m, "diffusion", kernel="nope")
    with pytest.raises(ValueError, match="metric must be one of"):
        metric_solver(m, "hamming")
    with pytest.raises(ValueError, match=r"sources must lie in \[0, 42\)"):
        GraphDiffusionSolver(m).from_sources([42])


def test_tosca_cat_spectral_matches_dense(cat_working):
    w = cat_working.mesh
    fast = GraphDiffusionSolver(w)
    idx = np.arange(0, w.n_vertices, 7)
    d = fast.from_sources(idx)
    assert 0 < fast.truncation_bound and len(fast.eigenvalues) < w.n_vertices // 4
    exact = GraphDiffusionSolver(w, dense_below=10**9)
    ref = exact.from_sources(idx)
    assert np.abs(d**2 - ref**2).max() <= fast.truncation_bound + 1e-12
    assert np.abs(d - ref).max() < 1e-3 * ref.max()


def test_diffusion_fills_small_holes_by_default():
    """Holes are insulating for heat; on the filled surface the distances come back.

    A sphere with 8 small holes: by default (``fill_holes=0.5``) the heat-kernel distances
    between the remaining vertices are close to those of the whole sphere; with the holes
    left open they are several times farther off.
    """
    from gromov.metrics import DIFFUSION_FILL_HOLES, RestrictedSolver, metric_solver
    from gromov.perturb import holes

    sphere = icosphere(4)
    p = holes(sphere, 8, radius=0.2, seed=1)
    full = metric_solver(sphere, "diffusion").pairwise()[np.ix_(p.vertex_map, p.vertex_map)]
    filled = metric_solver(p.mesh, "diffusion")
    assert isinstance(filled, RestrictedSolver) and DIFFUSION_FILL_HOLES == 0.5
    assert filled.n_vertices == p.mesh.n_vertices and filled.inner.n_vertices == p.mesh.n_vertices + 8
    open_ = metric_solver(p.mesh, "diffusion", fill_holes=None)
    assert not isinstance(open_, RestrictedSolver)
    err_filled = np.abs(filled.pairwise() - full).max() / full.max()
    err_open = np.abs(open_.pairwise() - full).max() / full.max()
    assert err_filled < 0.05 and err_filled < 0.5 * err_open, (err_filled, err_open)
    # rows agree with the matrix; the metric axioms hold on the original vertices
    D = filled.pairwise()
    np.testing.assert_allclose(filled.from_sources([0, 7]), D[[0, 7]], rtol=1e-6, atol=1e-12)
    assert np.allclose(D, D.T) and np.all(np.diag(D) == 0) and not D.flags.writeable
    # closed meshes and the other metrics are untouched by default
    assert not isinstance(metric_solver(sphere, "diffusion"), RestrictedSolver)
    assert not isinstance(metric_solver(p.mesh, "geodesic"), RestrictedSolver)
    assert isinstance(metric_solver(p.mesh, "geodesic", fill_holes=0.5), RestrictedSolver)
    assert isinstance(metric_solver(p.mesh, "diffusion", fill_holes=np.float32(0.5)), RestrictedSolver)
    for bad in (0, -1.0, True, np.bool_(True), "big", float("inf"), float("nan")):
        with pytest.raises(ValueError, match="fill_holes must be a positive number or None"):
            metric_solver(p.mesh, "diffusion", fill_holes=bad)


@pytest.mark.parametrize("n", [1, 2, 63, 64, 65, 200])
def test_distances_from_gram_is_the_plain_formula(n):
    # the fused tile kernel gives exactly sqrt(max(|x|^2 + |y|^2 - 2 <x, y>, 0)), symmetrised,
    # with a zero diagonal, on both the threaded and the one-thread path
    from numba import get_num_threads, set_num_threads

    from gromov.metrics.diffusion import _distances_from_gram

    psi = np.random.default_rng(n).normal(size=(n, 7))
    psi[-1] = psi[0]  # two coincident points: a zero that rounding could make negative
    sq, G = (psi**2).sum(1), psi @ psi.T
    d = np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2.0 * G, 0.0))
    d = 0.5 * (d + d.T)
    np.fill_diagonal(d, 0.0)
    threads = get_num_threads()
    for t in {1, threads}:
        set_num_threads(t)
        try:
            out = _distances_from_gram(sq, G.copy())
        finally:
            set_num_threads(threads)
        np.testing.assert_array_equal(out, d)
        assert not out.flags.writeable
    # a gram it may not overwrite (Fortran-ordered, read-only) or of another type is copied
    # as float64 first: the same result, the input untouched
    ro = G.copy()
    ro.flags.writeable = False
    for g in ([np.asfortranarray(G)] if n > 1 else []) + [ro]:  # (1, 1) is C-ordered too
        before = g.copy()
        np.testing.assert_array_equal(_distances_from_gram(sq, g), d)
        np.testing.assert_array_equal(g, before)
    gi = np.round(G * 8.0).astype(np.int64)
    expect = np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2.0 * gi, 0.0))
    expect = 0.5 * (expect + expect.T)
    np.fill_diagonal(expect, 0.0)
    np.testing.assert_array_equal(_distances_from_gram(sq, gi), expect)


def test_normalized_heat_distance_is_the_chordal_distance_of_normalised_heat_distributions():
    # d^2 = 2 - 2 k_2t(x, y) / sqrt(k_2t(x, x) k_2t(y, y)) (module notes): from the raw
    # embedding's Gram matrix; at most 2 (sqrt 2 between far points), zero only on the
    # diagonal, and unchanged by scaling the shape (t = tau * area).
    m = icosphere(3)
    s = HeatDiffusionSolver(m, units="normalized")
    assert s.tau == 0.01
    d = s.pairwise()
    raw = HeatDiffusionSolver(m, units="raw", tau=0.01).embedding
    k = raw @ raw.T
    ref = np.sqrt(np.maximum(2 - 2 * k / np.sqrt(np.outer(np.diag(k), np.diag(k))), 0))
    np.testing.assert_allclose(d, ref, atol=1e-6)
    assert d.max() <= 2 and np.all(d[~np.eye(len(d), dtype=bool)] > 0)
    big = HeatDiffusionSolver(Mesh(3.0 * m.vertices, m.faces), units="normalized").pairwise()
    np.testing.assert_allclose(big, d, atol=1e-6)


def test_normalized_heat_distance_truncation_bound_holds_on_the_tosca_cat(cat_working):
    w = cat_working.mesh
    fast = HeatDiffusionSolver(w, units="normalized")
    idx = np.arange(0, w.n_vertices, 7)
    d = fast.from_sources(idx)
    assert 0 < fast.truncation_bound and len(fast.eigenvalues) < w.n_vertices // 3
    exact = HeatDiffusionSolver(w, units="normalized", rtol=1e-14)
    ref = exact.from_sources(idx)
    assert np.abs(d**2 - ref**2).max() <= fast.truncation_bound + 1e-12


def test_heat_distance_at_another_time_from_the_same_eigenpairs():
    """``at_tau``: the same eigenpairs at another diffusion time. At a larger time it equals a
    fresh solver (the truncation only shrinks); at half the time it is the heat distance
    band-limited to the first solver's eigenpairs, close to a full solve; at the same time it
    is the same embedding; normalised rows stay unit rows."""
    m = icosphere(3)   # 642 vertices: 96 eigenpairs at tau = 0.01, all at 0.005
    base = HeatDiffusionSolver(m, tau=0.01, units="raw")
    d0 = base.pairwise()
    same = base.at_tau(0.01)
    np.testing.assert_array_equal(same.embedding, base.embedding)
    for tau, tol in ((0.02, 1e-6), (0.005, 1e-3)):
        scaled, fresh = base.at_tau(tau), HeatDiffusionSolver(m, tau=tau, units="raw")
        assert scaled.tau == tau and scaled.t == pytest.approx(tau * base.area)
        assert len(scaled.eigenvalues) == len(base.eigenvalues)       # no new decomposition
        d, ref = scaled.pairwise(), fresh.pairwise()
        assert np.abs(d - ref).max() < tol * ref.max(), tau
        assert not np.allclose(d / d.max(), d0 / d0.max(), atol=1e-3)  # another metric
    assert base.at_tau(0.02).truncation_bound < base.truncation_bound
    norm = HeatDiffusionSolver(m, tau=0.02, units="normalized").at_tau(0.01)
    np.testing.assert_allclose(np.linalg.norm(norm.embedding, axis=1), 1.0, rtol=1e-12)
    ref = HeatDiffusionSolver(m, tau=0.01, units="normalized").pairwise()
    assert np.abs(norm.pairwise() - ref).max() < 1e-3 * ref.max()
    length = HeatDiffusionSolver(m, tau=0.01, units="length")
    ref = HeatDiffusionSolver(m, tau=0.02, units="length").pairwise()
    assert np.abs(length.at_tau(0.02).pairwise() - ref).max() < 1e-6 * ref.max()
    assert base._basis is None and length._basis is None   # no second (n, K) array kept
    area = HeatDiffusionSolver(m, tau=0.01, units="area")
    np.testing.assert_allclose(area.pairwise(), np.sqrt(area.area) * HeatDiffusionSolver(m, tau=0.01).pairwise(),
                               rtol=1e-9)
    ref = HeatDiffusionSolver(m, tau=0.02, units="area").pairwise()
    assert np.abs(area.at_tau(0.02).pairwise() - ref).max() < 1e-6 * ref.max()
    with pytest.raises(ValueError, match="tau must be positive"):
        base.at_tau(0.0)


def test_heat_distance_at_another_time_on_a_filled_mesh():
    """With small holes filled the restricted solver rescales its inner solver."""
    m = icosphere(4)
    keep = np.ones(m.n_faces, bool)
    keep[[0, 200, 400]] = False
    holed = Mesh(m.vertices, m.faces[keep])
    s = metric_solver(holed, "diffusion", kernel="heat", units="raw")
    half = s.at_tau(0.0025)
    assert half.n_vertices == holed.n_vertices and half.embedding.shape[0] == holed.n_vertices
    ref = metric_solver(holed, "diffusion", kernel="heat", units="raw", tau=0.0025).pairwise()
    assert np.abs(half.pairwise() - ref).max() < 1e-3 * ref.max()


def test_heat_distances_do_not_depend_on_the_blas_threads():
    """The dense heat distances are the same to the last bit whatever BLAS threads the process
    allows (they were not: a threaded product sums in another order), so a shape computed in a
    process with a thread limit in force equals one computed without."""
    from threadpoolctl import threadpool_limits

    shape = icosphere(4)   # 2,562 vertices: a product that BLAS splits between threads
    out = []
    for limit in (1, 2, None):
        with threadpool_limits(limits=limit, user_api="blas"):
            out.append(metric_solver(shape, "diffusion", kernel="heat").pairwise())
    assert out[0].tobytes() == out[1].tobytes() == out[2].tobytes()


def test_heat_diffusion_on_a_single_triangle():
    """All three eigenpairs of one triangle: the distances are finite, symmetric, zero only on
    the diagonal, and an isosceles right triangle's two legs are equally long."""
    tri = Mesh([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2]])
    D = HeatDiffusionSolver(tri).pairwise()
    assert D.shape == (3, 3) and np.isfinite(D).all() and np.allclose(D, D.T)
    assert np.all(np.diag(D) == 0) and np.all(D[~np.eye(3, dtype=bool)] > 0)
    assert D[0, 1] == pytest.approx(D[0, 2], rel=1e-9)


def test_a_slit_is_not_filled():
    """A closed sphere with a zero-area face removed has a slit (a boundary loop of three points
    on a line): a fan across it would give its centre no area, so it stays open and every
    vertex keeps positive area in the heat diffusion's mass matrix."""
    from gromov.mesh import fill_holes

    base = icosphere(2)
    V, F = np.array(base.vertices), np.array(base.faces)
    a, b, c = F[0]
    V = np.vstack([V, 0.5 * (V[a] + V[b])])
    v = len(V) - 1
    F = np.vstack([F[1:], [[a, v, c], [v, b, c]]])   # the face across a-b keeps the long edge
    m = Mesh(V, F)
    assert len(m.boundary_loops) == 1 and len(m.boundary_loops[0]) == 3
    assert fill_holes(m, 10.0) == (m, 0)
    solver = metric_solver(m, "diffusion")
    assert np.all(solver.mass.diagonal() > 0) and np.isfinite(solver.pairwise()).all()


def test_an_option_a_metric_does_not_take_is_named():
    from gromov.metrics import metric_solver

    with pytest.raises(TypeError, match="heat kernel takes no option 'knernel'; its options: tau"):
        metric_solver(icosphere(1), "diffusion", knernel="heat")
    with pytest.raises(TypeError, match="geodesic metric takes no option 'tau'"):
        metric_solver(icosphere(1), "geodesic", tau=0.1)
    with pytest.raises(TypeError, match="connectivity kernel takes no option 'tau'"):
        metric_solver(icosphere(1), "diffusion", kernel="connectivity", tau=0.1)
