"""Fast marching geodesics (gromov.metrics._fmm): accuracy against known distances and facts."""

from __future__ import annotations

import numpy as np
import pytest

from gromov.metrics._fmm import (
    FastMarching,
    _delaunay_flips,
    _face_adjacency,
    _face_lengths,
    _march,
    _polar,
    subdivide,
)
from gromov.shapes import grid, icosphere, rolled_grid


def _rel_err(D, exact):
    """Relative errors over the entries where the exact distance is positive (not sources)."""
    m = np.isfinite(exact) & (exact > 1e-6)
    return np.abs(D[m] - exact[m]) / exact[m]


@pytest.fixture(scope="module")
def sphere4():
    m = icosphere(4)
    return np.asarray(m.vertices), np.asarray(m.faces)


@pytest.fixture(scope="module")
def sphere3_solver():
    m = icosphere(3)
    return FastMarching(m.vertices, m.faces)


def _sheared_sheet():
    """Flat 4 x 0.2 sheet (41 x 11 vertices) sheared so that every face has an obtuse angle."""
    g = grid(41, 11, width=4.0, height=0.2)
    v = np.asarray(g.vertices).copy()
    v[:, 0] += 1.0 * v[:, 1]  # 0.1 x 0.02 cells, sheared by 0.02 per row
    return v, np.asarray(g.faces)


def _n_obtuse(v, f):
    p = v[f]
    n = 0
    for j in range(3):
        dot = ((p[:, (j + 1) % 3] - p[:, j]) * (p[:, (j + 2) % 3] - p[:, j])).sum(1)
        n += int((dot < 0).sum())
    return n


# ----------------------------------------------------------------------------------------
# accuracy
# ----------------------------------------------------------------------------------------
def test_sphere_all_pairs_match_great_circles(sphere4):
    v, f = sphere4
    D = FastMarching(v, f).pairwise()
    G = np.arccos(np.clip(v @ v.T, -1.0, 1.0))
    off = ~np.eye(len(v), dtype=bool)
    rel = np.abs(D[off] - G[off]) / G[off]
    assert rel.mean() <= 0.01, rel.mean()
    assert rel.max() <= 0.03, rel.max()


def test_planar_wavefront_update_is_the_weaker_one(sphere4):
    # Kimmel & Sethian's planar update, kept privately for comparison: its O(h/r) error
    # near the source is what the point-source update removes.
    v, f = sphere4
    src = np.arange(0, len(v), 97)
    G = np.arccos(np.clip(v[src] @ v.T, -1.0, 1.0))
    e_src = _rel_err(FastMarching(v, f).distances(src), G)
    e_pla = _rel_err(FastMarching(v, f, _update="planar").distances(src), G)
    assert e_pla.mean() > 2 * e_src.mean()
    assert e_pla.max() > 0.05 > 0.03 > e_src.max()


def test_obtuse_unfolding_matters_on_flat_sheet():
    # on the given triangulation (no Delaunay flips, which would remove most obtuse angles)
    v, f = _sheared_sheet()
    exact = np.linalg.norm(v[:, None] - v[None], axis=-1)
    n_obtuse = _n_obtuse(v, f)
    assert n_obtuse >= 0.9 * len(f)  # (nearly) every face is obtuse

    fm = FastMarching(v, f, _delaunay=False)
    assert fm._n_split + fm._n_unsplit == n_obtuse
    assert fm._n_split >= 0.75 * n_obtuse  # the others sit on the boundary
    e_on = _rel_err(fm.pairwise(), exact)
    e_off = _rel_err(FastMarching(v, f, _unfold=False, _delaunay=False).pairwise(), exact)
    assert e_off.mean() > 1e-3 and e_off.max() > 0.1
    assert e_on.max() < 1e-9  # a flat triangulation: exact once every angle is acute
    # the paper's planar update benefits as well
    p_on = _rel_err(FastMarching(v, f, _update="planar", _delaunay=False).pairwise(), exact)
    p_off = _rel_err(FastMarching(v, f, _update="planar", _unfold=False,
                                  _delaunay=False).pairwise(), exact)
    assert p_on.mean() < 0.5 * p_off.mean()


def test_against_exact_geodesics_on_jittered_sphere():
    geodesic = pytest.importorskip("pygeodesic.geodesic")
    m = icosphere(3)
    rng = np.random.default_rng(0)
    v = np.asarray(m.vertices) + rng.normal(0.0, 0.01, m.vertices.shape)
    f = np.asarray(m.faces)
    src = np.arange(0, len(v), 32)
    algo = geodesic.PyGeodesicAlgorithmExact(v, f)
    exact = np.stack([algo.geodesicDistances(np.array([s]), None)[0] for s in src])
    rel = _rel_err(FastMarching(v, f).distances(src), exact)
    assert rel.mean() <= 0.01, rel.mean()
    assert rel.max() <= 0.03, rel.max()


def test_against_exact_geodesics_on_rolled_sheet():
    # the rolled sheet is a developable polyhedron: fast marching is exact on it
    geodesic = pytest.importorskip("pygeodesic.geodesic")
    m = rolled_grid(31, 16)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    src = np.arange(0, len(v), 25)
    algo = geodesic.PyGeodesicAlgorithmExact(v, f)
    exact = np.stack([algo.geodesicDistances(np.array([s]), None)[0] for s in src])
    rel = _rel_err(FastMarching(v, f).distances(src), exact)
    assert rel.mean() <= 1e-9 and rel.max() <= 1e-8


def _jittered_sheet():
    """Flat irregular sheet: a 21 x 21 grid on [0, 2]^2, interior vertices moved in the plane.

    The boundary stays a square, so geodesics are straight segments.
    """
    g = grid(21, 21, width=2.0, height=2.0)
    v = np.asarray(g.vertices).copy()
    rng = np.random.default_rng(3)
    inner = (v[:, 0] > 0) & (v[:, 0] < 2) & (v[:, 1] > 0) & (v[:, 1] < 2)
    # cells 0.1 wide: stays a triangulation
    v[inner, :2] += rng.uniform(-0.03, 0.03, (int(inner.sum()), 2))
    return v, np.asarray(g.faces)


def test_directions_are_exact_on_a_flat_irregular_sheet():
    v, f = _jittered_sheet()
    fm = FastMarching(v, f)
    pol = fm._tables[4]
    interior = pol[:, 1] > 0
    np.testing.assert_allclose(pol[interior, 0], 2 * np.pi, rtol=1e-12)
    corner = np.isclose(pol[~interior, 0], np.pi / 2, rtol=1e-12)
    assert corner.sum() == 4 and np.allclose(pol[~interior, 0][~corner], np.pi, rtol=1e-12)
    s = 220  # near the middle
    n = len(v)
    T, dirs = np.empty(n), np.empty((n, 4))
    _march(fm._tables, np.array([s]), T, np.empty(n, np.int32), np.empty(n),
           np.empty(n, np.int32), np.empty(n, np.int32), dirs, 2)
    np.testing.assert_allclose(T, np.linalg.norm(v - v[s], axis=1), rtol=0, atol=1e-12)
    # the recorded direction to the source, against the true one: the polar angle at c
    # of the direction to s, minus that of a known edge, is their planar angle
    phi = dirs[:, 0] + np.arctan2(dirs[:, 1], dirs[:, 2])
    ok = np.isfinite(phi) & interior
    assert ok.sum() > 0.4 * n  # the others were reached by a direction-aware update
    tc, geo = fm._tc, fm._geo
    trig = np.repeat(np.arange(n), np.diff(fm._ptr))
    first = np.isfinite(geo[:, 6])  # entry (x -> c) with the polar angle at x of the edge
    checked = 0
    for e in np.flatnonzero(first & ok[trig]):
        x, c = trig[e], tc[e]
        ang = lambda p: np.arctan2(p[1] - v[x, 1], p[0] - v[x, 0])  # noqa: E731
        planar = ang(v[s]) - ang(v[c])  # counter-clockwise faces: polar = planar angle
        diff = (phi[x] - geo[e, 6]) - planar
        assert abs((diff + np.pi) % (2 * np.pi) - np.pi) < 1e-9
        checked += 1
    assert checked > 2 * n


def _cat_and_exact(cat_working, n_sources):
    """Working cat ``(v, f)``, ``n_sources`` random sources (seed 0) and exact MMP distances."""
    pytest.importorskip("pygeodesic.geodesic")
    from gromov.metrics import GeodesicSolver

    w = cat_working.mesh
    src = np.random.default_rng(0).choice(w.n_vertices, n_sources, replace=False)
    exact = GeodesicSolver(w, method="exact").from_sources(src)
    return np.asarray(w.vertices), np.asarray(w.faces), src, exact


def test_cat_working_mesh_against_exact_geodesics(cat_working):
    v, f, src, exact = _cat_and_exact(cat_working, 12)
    rel = _rel_err(FastMarching(v, f).distances(src), exact)
    rel_plain = _rel_err(FastMarching(v, f, _update="source").distances(src), exact)
    # measured: 0.198%, 0.82%, 3.4% (0.38%, 1.04%, 4.8% without directions; 0.20%,
    # 0.93%, 8.5% on the given triangulation, without the consistency test). A 3% max is
    # not reached on the working mesh itself: the 3.4% is an underestimate at a
    # shock, where a rejected fit falls back to a planar value that is too small (see
    # _fmm's docstring); with refine=2 it is (next test).
    assert rel.mean() <= 0.005, rel.mean()
    assert np.percentile(rel, 99) <= 0.012, np.percentile(rel, 99)
    assert rel.max() <= 0.05, rel.max()
    assert rel.mean() < 0.75 * rel_plain.mean()


def test_refined_marching_on_the_cat_is_within_3_percent(cat_working):
    # 1% mean and 3% max relative error against exact MMP on the 3,000-vertex cat, with the
    # fast marching run on the twice-subdivided mesh; 100 random sources,
    # not the 12 above. Measured max / p99 / mean: refine 0 -- 7.89% /
    # 1.00% / 0.209%; 1 -- 3.69% / 0.55% / 0.113%; 2 -- 1.74% / 0.33% / 0.066%.
    v, f, src, exact = _cat_and_exact(cat_working, 100)
    rel = [_rel_err(FastMarching(v, f, refine=r).distances(src), exact) for r in (0, 1, 2)]
    assert rel[2].mean() <= 0.01 and rel[2].max() <= 0.03, (rel[2].mean(), rel[2].max())
    # each level lowers the mean, the 99th percentile and the largest error
    for a, b in zip(rel, rel[1:]):
        for q in (np.mean, lambda x: np.percentile(x, 99), np.max):
            assert q(b) < q(a)


def test_subdivide_keeps_the_surface():
    from gromov.mesh import Mesh

    for v, f in (_sheared_sheet(), (np.asarray(icosphere(2).vertices), np.asarray(icosphere(2).faces))):
        m = Mesh(v, f)
        V, F = subdivide(v, f)
        r = Mesh(V, F)
        n_edges = len(np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1), axis=0))
        assert (r.n_vertices, r.n_faces) == (m.n_vertices + n_edges, 4 * m.n_faces)
        np.testing.assert_array_equal(V[: len(v)], v)  # input vertices first, unchanged
        assert r.euler_characteristic == m.euler_characteristic
        assert len(r.boundary_loops) == len(m.boundary_loops)
        np.testing.assert_allclose(r.area, m.area, rtol=1e-12)
        # same orientation: every child face has the normal of its parent
        nrm = lambda V, F: np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])  # noqa: E731
        assert (np.einsum("ij,ij->i", nrm(V, F), np.tile(nrm(v, f), (4, 1))) > 0).all()
        # the angle sum at each input vertex is unchanged; midpoints are flat (2 pi inside)
        ang = lambda FL: np.arccos(np.clip((FL[:, [1, 2, 0]] ** 2 + FL[:, [2, 0, 1]] ** 2 - FL ** 2)  # noqa: E731
                                           / (2 * FL[:, [1, 2, 0]] * FL[:, [2, 0, 1]]), -1, 1))
        th, TH = np.zeros(len(v)), np.zeros(len(V))
        np.add.at(th, f, ang(_face_lengths(v, f)))
        np.add.at(TH, F, ang(_face_lengths(V, F)))
        np.testing.assert_allclose(TH[: len(v)], th, atol=1e-9)
        rim = np.concatenate(r.boundary_loops) if r.boundary_loops else np.zeros(0, int)
        inner = np.setdiff1d(np.arange(len(v), len(V)), rim)
        assert len(inner) > 0.5 * (len(V) - len(v))
        np.testing.assert_allclose(TH[inner], 2 * np.pi, atol=1e-9)


def test_refine_keeps_flat_sheets_exact_and_refers_to_input_vertices():
    v, f = _sheared_sheet()
    fm = FastMarching(v, f, refine=1)
    assert fm.n_vertices == len(v) and "refine=1" in repr(fm)
    D = fm.pairwise()
    assert D.shape == (len(v), len(v))
    exact = np.linalg.norm(v[:, None] - v[None], axis=-1)
    assert _rel_err(D, exact).max() < 1e-9
    src = np.arange(0, len(v), 37)
    rows = fm.distances(src)
    np.testing.assert_array_equal(rows, fm.distances(src, parallel=False))
    np.testing.assert_array_equal(fm.distance(src[:1]), rows[0])
    np.testing.assert_allclose(fm.distance(src), rows.min(axis=0), atol=1e-9)


def test_refine_lowers_the_error_on_a_sphere(sphere4):
    v, f = sphere4
    src = np.arange(0, len(v), 97)
    G = np.arccos(np.clip(v[src] @ v.T, -1.0, 1.0))
    e0 = _rel_err(FastMarching(v, f).distances(src), G)
    e1 = _rel_err(FastMarching(v, f, refine=1).distances(src), G)
    assert e1.mean() < 0.7 * e0.mean() and e1.max() < e0.max()


def test_refine_keeps_components_apart_and_unreferenced_vertices_unreached():
    a, b = grid(6, 5), grid(5, 4)
    v = np.vstack([a.vertices, b.vertices + [0.0, 0.0, 3.0], [[9.0, 9.0, 9.0]]])
    f = np.vstack([a.faces, b.faces + a.n_vertices])
    na, n = a.n_vertices, len(v)
    for r in (0, 1, 2):
        D = FastMarching(v, f, refine=r).distances([0, na, n - 1])
        assert D.shape == (3, n)
        assert np.isfinite(D[0, :na]).all() and np.isinf(D[0, na:]).all()
        assert np.isfinite(D[1, na:-1]).all() and np.isinf(D[1, :na]).all() and np.isinf(D[1, -1])
        assert D[2, -1] == 0.0 and np.isinf(D[2, :-1]).all()
        # flat pieces: exact straight-line distances within each
        np.testing.assert_allclose(D[0, :na], np.linalg.norm(v[:na] - v[0], axis=1), atol=1e-9)


@pytest.mark.parametrize("bad", [-1, 4, 1.5, True, "1"])
def test_bad_refine_raises(bad):
    from gromov.metrics import GeodesicSolver

    m = icosphere(1)
    with pytest.raises(ValueError, match=r"refine must be an integer in \[0, 3\]"):
        FastMarching(m.vertices, m.faces, refine=bad)
    with pytest.raises(ValueError, match="refine must be an integer"):
        GeodesicSolver(m, refine=bad)


def test_refine_only_for_fast_marching():
    from gromov.metrics import GeodesicSolver

    with pytest.raises(ValueError, match="refine applies to method='fmm'"):
        GeodesicSolver(icosphere(1), method="dijkstra", refine=1)


def _delaunay(v, f):
    """The intrinsic Delaunay triangulation of ``(v, f)``: faces, edge lengths, flips."""
    F, FL = f.astype(np.int64).copy(), _face_lengths(v, f)
    flips = _delaunay_flips(F, FL, _face_adjacency(F, len(v)), len(v), 20 * len(F))
    return F, FL, flips


def _opposite_angle_sums(F, FL):
    """Sum of the two angles opposite every interior edge."""
    ang = np.arccos(np.clip((FL[:, [1, 2, 0]] ** 2 + FL[:, [2, 0, 1]] ** 2 - FL ** 2)
                            / (2 * FL[:, [1, 2, 0]] * FL[:, [2, 0, 1]]), -1, 1))
    opp = _face_adjacency(F, F.max() + 1)
    f, j = np.nonzero(opp >= 0)
    g = opp[f, j]
    edge = np.sort(np.stack([F[f, (j + 1) % 3], F[f, (j + 2) % 3]], 1), 1)
    k = np.array([[x for x in range(3) if F[gg, x] not in e][0] for gg, e in zip(g, edge)])
    return ang[f, j] + ang[g, k]


def test_delaunay_flips_on_a_flat_sheet():
    # every face of the sheared sheet is obtuse; the flips give the planar Delaunay
    # triangulation, whose edges are straight segments between the vertices
    v, f = _sheared_sheet()
    assert _opposite_angle_sums(f, _face_lengths(v, f)).max() > np.pi + 0.1
    F, FL, flips = _delaunay(v, f)
    assert flips > 0.5 * len(f)
    assert _opposite_angle_sums(F, FL).max() <= np.pi + 1e-9
    np.testing.assert_allclose(FL, _face_lengths(v, F), rtol=1e-12)
    assert len(np.unique(np.sort(F, 1), axis=0)) == len(F)  # still a simplicial complex
    fm = FastMarching(v, f)
    assert fm._n_flips == flips and fm._n_split == 0  # no obtuse interior angle left
    exact = np.linalg.norm(v[:, None] - v[None], axis=-1)
    assert _rel_err(fm.pairwise(), exact).max() < 1e-9


def test_delaunay_flips_keep_the_surface():
    # on a curved mesh the flips change the triangles but not the surface: the same total
    # area and the same angle sum (Gaussian curvature) at every vertex
    m = icosphere(3)
    v = np.asarray(m.vertices) + np.random.default_rng(1).normal(0, 0.04, m.vertices.shape)
    f = np.asarray(m.faces)
    F, FL, flips = _delaunay(v, f)
    assert flips > 100
    assert _opposite_angle_sums(F, FL).max() <= np.pi + 1e-9

    def area_and_angle_sums(F, FL):
        a, b, c = FL.T
        area = 0.25 * np.sqrt((a + b + c) * (-a + b + c) * (a - b + c) * (a + b - c))
        theta = _polar(len(v), F, FL, _face_adjacency(F, len(v)))[2]
        return area.sum(), theta

    area0, theta0 = area_and_angle_sums(f, _face_lengths(v, f))
    area1, theta1 = area_and_angle_sums(F, FL)
    assert abs(area1 - area0) < 1e-10 * area0
    np.testing.assert_allclose(theta1, theta0, rtol=0, atol=1e-9)


def test_wide_angles_add_stencils_only_where_wide():
    # the jittered sheet has acute angles over 75 degrees, the icosphere none
    v, f = _jittered_sheet()
    wide, plain = FastMarching(v, f), FastMarching(v, f, _wide=False)
    assert len(wide._tc) > len(plain._tc)
    for fm in (wide, plain):  # flat: exact from the middle either way
        np.testing.assert_allclose(fm.distance(220), np.linalg.norm(v - v[220], axis=1),
                                   rtol=0, atol=1e-12)
    m = icosphere(3)
    assert len(FastMarching(m.vertices, m.faces)._tc) == \
        len(FastMarching(m.vertices, m.faces, _wide=False)._tc)


# ----------------------------------------------------------------------------------------
# facts
# ----------------------------------------------------------------------------------------
def test_pairwise_symmetric_zero_diagonal(sphere3_solver):
    fm = sphere3_solver
    raw = fm.distances(np.arange(fm.n_vertices))
    D = fm.pairwise()
    assert D.shape == (fm.n_vertices,) * 2
    np.testing.assert_array_equal(D, D.T)
    np.testing.assert_array_equal(np.diag(D), 0.0)
    np.testing.assert_allclose(D, (raw + raw.T) / 2 - np.diag(np.diag(raw)), rtol=0, atol=0)
    off = ~np.eye(fm.n_vertices, dtype=bool)
    assert (np.abs(raw - raw.T)[off] / raw[off]).max() < 0.02  # nearly symmetric already
    assert (D[off] > 0).all()


def test_zero_at_sources_and_positive_elsewhere(sphere3_solver):
    fm = sphere3_solver
    d = fm.distance([7, 300])
    assert d[7] == 0.0 and d[300] == 0.0
    assert (np.delete(d, [7, 300]) > 0).all()
    rows = fm.distances([7, 300])
    assert rows[0, 7] == 0.0 and rows[1, 300] == 0.0
    np.testing.assert_array_equal(fm.distance(7), fm.distances([7])[0])
    np.testing.assert_array_equal(fm.distance(np.int32(7)), fm.distance([7]))


def test_multi_source_is_min_over_single_sources(sphere3_solver):
    fm = sphere3_solver
    src = [0, 100, 200, 400]
    multi = fm.distance(src)
    single = fm.distances(src).min(axis=0)
    np.testing.assert_allclose(multi, single, rtol=0.01, atol=1e-12)
    # far from the shocks where the fronts meet they agree to rounding
    owner = fm.distances(src).argmin(axis=0)
    assert np.isclose(multi, single, rtol=1e-12).mean() > 0.8
    assert len(np.unique(owner)) == len(src)
    # repeated sources change nothing
    np.testing.assert_array_equal(fm.distance(src + src), multi)


def test_disconnected_components_are_infinite():
    a, b = icosphere(2), icosphere(2)
    v = np.vstack([a.vertices, np.asarray(b.vertices) + [5.0, 0.0, 0.0]])
    f = np.vstack([a.faces, np.asarray(b.faces) + len(a.vertices)])
    v = np.vstack([v, [[9.0, 9.0, 9.0]]])  # plus a vertex in no face
    n1 = len(a.vertices)
    fm = FastMarching(v, f)
    d = fm.distance([0])
    assert np.isfinite(d[:n1]).all()
    assert np.isinf(d[n1:]).all()
    D = fm.pairwise()
    assert np.isinf(D[:n1, n1:]).all() and np.isinf(D[n1:, :n1]).all()
    assert np.isfinite(D[:n1, :n1]).all() and np.isfinite(D[n1:-1, n1:-1]).all()
    assert D[-1, -1] == 0.0
    # the two copies agree
    np.testing.assert_allclose(D[:n1, :n1], D[n1:-1, n1:-1], rtol=1e-12)


def test_parallel_equals_serial(sphere3_solver):
    fm = sphere3_solver
    src = np.arange(0, fm.n_vertices, 7)
    np.testing.assert_array_equal(fm.distances(src, parallel=True),
                                  fm.distances(src, parallel=False))


def test_boundary_nonmanifold_and_degenerate_faces_do_not_break_it():
    v, f = _sheared_sheet()
    # a degenerate (zero-area) sliver on the boundary and a fin sharing an interior edge
    v = np.vstack([v, (v[0] + v[11]) / 2, v[12] + [0.0, 0.0, 0.3]])
    k = len(v)
    f = np.vstack([f, [[0, 11, k - 2]], [[12, 13, k - 1]]])
    d = FastMarching(v, f).distance([0])
    assert np.isfinite(d).all()
    assert np.isclose(d[k - 2], np.linalg.norm(v[k - 2] - v[0]))


@pytest.mark.parametrize(
    "bad",
    [[], -1, 451, [0, 451], [0.0, 1.0], 1.5, [[0, 1], [2, 3]], "a", None, True, [True, False]],
)
def test_bad_sources_raise_value_error(bad):
    v, f = _sheared_sheet()
    fm = FastMarching(v, f)
    for call in (fm.distance, fm.distances):
        with pytest.raises(ValueError, match="sources"):
            call(bad)


def test_bad_sources_message_names_the_input():
    v, f = _sheared_sheet()
    fm = FastMarching(v, f)
    with pytest.raises(ValueError, match="451"):
        fm.distance([3, 451])
    with pytest.raises(ValueError, match="float"):
        fm.distances([0.5])


def _rows_in_a_forked_worker(solver, sources):
    return solver.distances(sources)


def test_forked_single_thread_workers_take_the_serial_kernel(sphere3_solver):
    """After the parent used numba's threads, a forked child must not enter them (the
    OpenMP layer aborts it); with one thread, as the pair workers run, the rows still come."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from gromov.experiments.pairwise import _one_thread_per_worker

    src = np.arange(12)
    parent = sphere3_solver.distances(src)  # the parallel kernel, in this process
    with ProcessPoolExecutor(1, mp_context=mp.get_context("fork"),
                             initializer=_one_thread_per_worker) as ex:
        child = ex.submit(_rows_in_a_forked_worker, sphere3_solver, src).result(timeout=120)
    np.testing.assert_array_equal(child, parent)


@pytest.mark.parametrize("n", [1, 2, 63, 64, 65, 130])
def test_symmetrise_inplace_is_the_numpy_expression(n):
    """Parallel and serial kernels give exactly 0.5 * (D + D.T) with a zero diagonal, at sizes
    around the block size, and on a non-contiguous view; bad input is refused."""
    from numba import get_num_threads, set_num_threads

    from gromov.metrics._base import symmetrise_inplace

    rng = np.random.default_rng(n)
    d = rng.random((n, n))
    want = 0.5 * (d + d.T)
    np.fill_diagonal(want, 0.0)
    threads = get_num_threads()
    try:
        for t in sorted({1, threads}):
            set_num_threads(t)
            e = d.copy()
            symmetrise_inplace(e)
            np.testing.assert_array_equal(e, want)
            big = np.zeros((n, 2 * n))
            big[:, ::2] = d
            view = big[:, ::2]
            symmetrise_inplace(view)
            np.testing.assert_array_equal(view, want)
    finally:
        set_num_threads(threads)
    with pytest.raises(ValueError, match="floating-point"):
        symmetrise_inplace(np.ones((3, 3), dtype=np.int64))
    ro = d.copy()
    ro.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        symmetrise_inplace(ro)
    with pytest.raises(ValueError, match="square"):
        symmetrise_inplace(np.ones((2, 3)))


def test_distances_to_stops_early_with_the_full_marches_values(sphere4):
    """A march stopped once its targets are final gives them the values of the full march,
    whatever the limit; targets beyond the limit are inf; repeated targets and a target that is
    the source itself are fine."""
    V, F = sphere4
    fm = FastMarching(V, F)
    rng = np.random.default_rng(4)
    n = len(V)
    src = rng.choice(n, 40, replace=False)
    full = fm.distances(src)
    targets = rng.integers(0, n, (40, 3))
    targets[::5, 1] = targets[::5, 0]
    targets[::7, 2] = src[::7]
    exact = np.take_along_axis(full, targets, axis=1)
    for limit in (np.inf, 0.3, 1.0):
        got = fm.distances_to(src, targets, limit=limit)
        np.testing.assert_array_equal(got, np.where(exact <= limit, exact, np.inf))
    assert np.isinf(fm.distances_to(src, targets, limit=0.3)).any()
