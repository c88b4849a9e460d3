"""Topological noise (welds and holes) and parts (cuts): topology changes as stated, ground
truth exact.

Facts checked: a geodesic disk removed from a sphere leaves chi = 2 - k and k boundary
loops; a tube weld is a handle (chi - 2, boundary unchanged, still an oriented manifold),
a pinch weld lowers chi by one; a weld turns a long way around the surface into a short
hop across the gap; a plane cut of the unit sphere keeping a fraction f of the area lies at
offset 2f - 1 (Archimedes' hat-box theorem); output vertices are input vertices
(coordinates and file ids).
"""

import json

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from gromov import Mesh
from gromov.metrics import GeodesicSolver
from gromov.perturb import Perturbation, _star_cycle, cut, holes, weld
from gromov.shapes import grid, icosphere

# ---------------------------------------------------------------------------- helpers

RHO = 0.15  # half the gap between the two layers of the hairpin


def hairpin(nu: int = 61, nv: int = 11, width: float = 6.0, rho: float = RHO) -> Mesh:
    """A 6 x 1 sheet folded in two: layers z=0 and z=2*rho joined by a half-cylinder.

    Arc length ``s`` along the sheet maps to x on the lower layer (``s < a``), a half
    circle of radius ``rho``, then back along the upper layer; the surface geodesic between
    ``s1`` and ``s2`` is ``hypot(s2 - s1, y2 - y1)`` (the sheet unrolls isometrically).
    """
    flat = grid(nu, nv, width, 1.0)
    s, y = flat.vertices[:, 0], flat.vertices[:, 1]
    a = (width - np.pi * rho) / 2
    th = np.clip((s - a) / rho, 0.0, np.pi)
    x = np.where(s < a, s, np.where(s <= a + np.pi * rho, a + rho * np.sin(th), a - (s - a - np.pi * rho)))
    z = np.where(s < a, 0.0, np.where(s <= a + np.pi * rho, rho * (1 - np.cos(th)), 2 * rho))
    return Mesh(np.stack([x, y, z], axis=1), flat.faces, input_ids=np.arange(flat.n_vertices) + 1000)


def graph_distance(mesh: Mesh, a, b) -> float:
    """Shortest edge path between two vertex sets."""
    d = GeodesicSolver(mesh, method="dijkstra").distance_from_set(np.atleast_1d(a))
    return float(d[np.atleast_1d(b)].min())


def check_ground_truth(p: Perturbation, mesh: Mesh) -> None:
    vm = p.vertex_map
    assert vm.dtype == np.int64 and vm.shape == (p.mesh.n_vertices,)
    assert np.all(np.diff(vm) > 0)  # a subset, in input order
    np.testing.assert_array_equal(p.mesh.vertices, mesh.vertices[vm])
    np.testing.assert_array_equal(p.mesh.input_ids, mesh.input_ids[vm])
    assert p.mesh.referenced.all()
    assert p.euler_before == mesh.euler_characteristic and p.euler_after == p.mesh.euler_characteristic
    assert p.boundary_loops_before == len(mesh.boundary_loops)
    assert p.boundary_loops_after == len(p.mesh.boundary_loops)


def check_oriented_manifold(m: Mesh) -> None:
    f = m.faces
    he = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    assert len(np.unique(he, axis=0)) == len(he), "a directed edge is used twice: orientation broken"
    assert m.is_edge_manifold
    # every vertex: 0 boundary edges (interior) or 2 (one boundary fan)
    bv = np.bincount(m.boundary_edges.ravel(), minlength=m.n_vertices)
    assert set(np.unique(bv)) <= {0, 2}


# ---------------------------------------------------------------------------- holes

def test_holes_on_sphere_topology_and_ground_truth():
    sphere = icosphere(4)
    p = holes(sphere, 10, seed=3)
    assert p.kind == "holes" and p.sites.shape == (10,)
    assert (p.boundary_loops_before, p.boundary_loops_after) == (0, 10)
    assert (p.euler_before, p.euler_after) == (2, 2 - 10)   # sphere minus 10 disks
    assert p.mesh.n_components == 1 and p.mesh.genus == 0
    check_ground_truth(p, sphere)
    check_oriented_manifold(p.mesh)

    # the default radius is 3% of sqrt(area)
    r = p.params["radius"]
    assert r == pytest.approx(0.03 * np.sqrt(sphere.area))
    # every vertex within r of a centre is gone, centres are >= 3 r apart
    d = dijkstra(sphere.adjacency, directed=False, indices=p.sites)
    assert not np.isin(np.flatnonzero((d <= r).any(axis=0)), p.vertex_map).any()
    off = d[:, p.sites][~np.eye(10, dtype=bool)]
    assert off.min() >= 3 * r
    # each hole is a small disk: about half a percent of the area each
    assert 0.03 < 1 - p.mesh.area / sphere.area < 0.07


def test_holes_reproducible_and_seeded():
    sphere = icosphere(3)
    a, b, c = (holes(sphere, 20, seed=s, radius=0.12) for s in (5, 5, 6))
    np.testing.assert_array_equal(a.sites, b.sites)
    np.testing.assert_array_equal(a.vertex_map, b.vertex_map)
    np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
    assert set(a.sites.tolist()) != set(c.sites.tolist())
    assert (a.euler_after, c.euler_after) == (2 - 20, 2 - 20)
    assert len(c.mesh.boundary_loops) == 20


def test_holes_on_sheet_keep_away_from_the_boundary():
    sheet = grid(41, 41, 1.0, 1.0)
    p = holes(sheet, 3, radius=0.06, seed=0)
    assert (p.euler_before, p.euler_after) == (1, 1 - 3)
    assert (p.boundary_loops_before, p.boundary_loops_after) == (1, 4)
    # the outer loop is intact: centres stay 2 r from the boundary
    assert len(p.mesh.boundary_loops[0]) == len(sheet.boundary_loops[0])
    check_ground_truth(p, sheet)


def test_holes_on_tosca_cat(cat_working):
    cat = cat_working.mesh
    for k in (10, 20):   # the paper's hole counts
        p = holes(cat, k, seed=0)
        assert (p.euler_before, p.euler_after) == (cat.euler_characteristic, cat.euler_characteristic - k)
        assert p.boundary_loops_after == len(cat.boundary_loops) + k
        assert p.mesh.n_components == 1
        check_ground_truth(p, cat)
        check_oriented_manifold(p.mesh)
        # file ids of the working mesh survive: they are ids of the full-resolution cat
        np.testing.assert_array_equal(p.mesh.input_ids, cat_working.mesh.input_ids[p.vertex_map])


# ---------------------------------------------------------------------------- weld

def test_weld_tube_on_hairpin_is_a_handle_and_a_shortcut():
    sheet = hairpin()
    assert (sheet.euler_characteristic, len(sheet.boundary_loops)) == (1, 1)
    p = weld(sheet, 3, seed=0)
    assert p.kind == "weld" and p.sites.shape == (3, 2)
    # a tube per weld: chi - 2, same boundary, genus 3, still one oriented manifold piece
    assert (p.euler_before, p.euler_after) == (1, 1 - 2 * 3)
    assert (p.boundary_loops_before, p.boundary_loops_after) == (1, 1)
    assert p.mesh.n_components == 1 and p.mesh.genus == 3
    check_oriented_manifold(p.mesh)
    check_ground_truth(p, sheet)
    assert not np.isin(p.sites, p.vertex_map).any()   # u and v make way for the tube

    # the (graph) diameter of the folded sheet is the diagonal of the flat one
    assert np.hypot(6, 1) <= p.params["diameter"] <= 1.1 * np.hypot(6, 1)
    X = sheet.vertices
    flat = grid(61, 11, 6.0, 1.0).vertices   # the unfolded sheet: arc length and y
    new = np.full(sheet.n_vertices, -1)
    new[p.vertex_map] = np.arange(p.mesh.n_vertices)
    for u, v in p.sites:
        gap = np.linalg.norm(X[u] - X[v])
        # one end on each layer, across the 2 rho gap
        assert {round(X[u, 2], 6), round(X[v, 2], 6)} == {0.0, round(2 * RHO, 6)}
        assert 2 * RHO - 1e-9 <= gap <= p.params["radius"]
        # before: around the fold; graph distance >= the exact (unrolled) surface distance
        exact = np.hypot(*(flat[u, :2] - flat[v, :2]))
        before = graph_distance(sheet, u, v)
        assert before >= exact - 1e-9
        assert before > max(4 * gap, 0.1 * p.params["diameter"])
        # after: the rings of u and v are one band edge apart, at most the Euclidean gap
        # between the rings (distances in space are unchanged)
        ru, rv = _star_cycle(sheet, u), _star_cycle(sheet, v)
        ring_gap = np.linalg.norm(X[ru][:, None] - X[rv][None], axis=-1).min()
        after = graph_distance(p.mesh, new[ru], new[rv])
        assert after == pytest.approx(ring_gap, rel=1e-12)
        assert after < before / 4


def test_weld_pinch_identifies_the_two_vertices():
    sheet = hairpin()
    tube = weld(sheet, 2, seed=1)
    p = weld(sheet, 2, seed=1, join="pinch")
    np.testing.assert_array_equal(p.sites, tube.sites)       # same sites, other gluing
    assert (p.euler_before, p.euler_after) == (1, 1 - 2)    # one pinch vertex per weld
    assert p.boundary_loops_after == 1 and p.mesh.is_edge_manifold
    check_ground_truth(p, sheet)
    u, v = p.sites.T
    assert np.isin(u, p.vertex_map).all() and not np.isin(v, p.vertex_map).any()
    new = np.full(sheet.n_vertices, -1)
    new[p.vertex_map] = np.arange(p.mesh.n_vertices)
    for a, b in p.sites:
        # v is u now (distance 0): v's old neighbours are u's neighbours, one edge away
        nb = sheet.adjacency[b].indices
        assert set(new[nb]) <= set(p.mesh.adjacency[new[a]].indices)
        gap = np.linalg.norm(sheet.vertices[a] - sheet.vertices[b])
        before = graph_distance(sheet, a, nb)
        after = graph_distance(p.mesh, new[a], new[nb])
        assert after == pytest.approx(np.linalg.norm(sheet.vertices[nb] - sheet.vertices[a], axis=1).min())
        assert before > 4 * gap and after <= gap + sheet.edge_lengths.max()
        assert _star_cycle(p.mesh, int(new[a])) is None      # two fans: a non-manifold vertex


def test_weld_on_tosca_cat(cat_working):
    cat = cat_working.mesh
    p = weld(cat, 4, seed=0)
    assert (p.euler_before, p.euler_after) == (cat.euler_characteristic, cat.euler_characteristic - 8)
    assert p.boundary_loops_after == p.boundary_loops_before == len(cat.boundary_loops)
    assert p.mesh.n_components == 1
    check_oriented_manifold(p.mesh)
    check_ground_truth(p, cat)
    np.testing.assert_array_equal(p.sites, weld(cat, 4, seed=0).sites)    # reproducible

    X = cat.vertices
    new = np.full(cat.n_vertices, -1)
    new[p.vertex_map] = np.arange(p.mesh.n_vertices)
    d_before = dijkstra(cat.adjacency, directed=False, indices=p.sites[:, 0])
    for k, (u, v) in enumerate(p.sites):
        gap = np.linalg.norm(X[u] - X[v])
        assert gap <= 5 * cat.mean_edge_length
        assert d_before[k, v] > max(4 * gap, 0.1 * p.params["diameter"])
        ru, rv = _star_cycle(cat, u), _star_cycle(cat, v)
        after = graph_distance(p.mesh, new[ru], new[rv])
        assert after == pytest.approx(np.linalg.norm(X[ru][:, None] - X[rv][None], axis=-1).min())
        assert after < d_before[k, v] / 4
    # separated sites
    d = d_before[:, p.sites.ravel()]
    for k in range(4):
        others = np.delete(d[k], [2 * k, 2 * k + 1])
        assert others.min() >= p.params["separation"]


def test_weld_without_contacts_says_how_many_were_found(cat_working):
    with pytest.raises(ValueError, match="found only 0 separated weld site"):
        weld(icosphere(3), 1)     # convex: nothing is close in space and far on the surface
    v = cat_working.mesh.vertices
    radius = 0.03 * np.linalg.norm(v.max(0) - v.min(0))   # given: searched once, not grown
    with pytest.raises(ValueError, match=r"found only \d+ separated weld site\(s\) for count=50"):
        weld(cat_working.mesh, 50, radius=radius)


# ---------------------------------------------------------------------------- errors

@pytest.mark.parametrize("fn", [weld, holes])
def test_errors(fn):
    sphere = icosphere(2)
    with pytest.raises(TypeError, match="mesh must be a gromov.Mesh, got ndarray"):
        fn(sphere.vertices, 1)
    for bad in (0, -2, 2.5, True, "3"):
        with pytest.raises(ValueError, match=f"count must be a positive integer, got {bad!r}"):
            fn(sphere, bad)
    for bad in (0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=f"radius must be a finite number > 0, got {bad!r}"):
            fn(sphere, 1, radius=bad)
    with pytest.raises(ValueError, match="radius must be a positive number, got 'big'"):
        fn(sphere, 1, radius="big")


def test_weld_and_holes_specific_errors():
    sheet = hairpin()
    with pytest.raises(ValueError, match=r"join must be one of \('tube', 'pinch'\), got 'glue'"):
        weld(sheet, 1, join="glue")
    with pytest.raises(ValueError, match="min_geodesic_ratio must be a finite number >= 1, got 0.5"):
        weld(sheet, 1, min_geodesic_ratio=0.5)
    with pytest.raises(ValueError, match=r"only \d+ hole\(s\) of radius 0.5 fit for count=30"):
        holes(icosphere(3), 30, radius=0.5)


def test_cli_weld_join(tmp_path, capsys):
    """`gromov perturb weld --join`: a handle per weld (default, chi - 2) or a pinch (chi - 1)."""
    import gromov
    from gromov.cli import main

    sheet = hairpin()
    src = tmp_path / "hairpin.off"
    gromov.save(sheet, src)
    chi = sheet.euler_characteristic
    for join, drop in ((None, 2), ("tube", 2), ("pinch", 1)):
        out = tmp_path / f"welded-{join}.off"
        args = ["perturb", "weld", str(src), str(out), "--count", "2", "--seed", "1"]
        assert main(args + ([] if join is None else ["--join", join])) == 0, capsys.readouterr().err
        assert f"Euler characteristic {chi} -> {chi - 2 * drop}" in capsys.readouterr().out
        assert gromov.load(out).euler_characteristic == chi - 2 * drop
        z = np.load(tmp_path / f"welded-{join}.map.npz")
        params = json.loads(str(z["params"]))
        assert params["join"] == (join or "tube") and len(params["gaps"]) == 2


def test_weld_sites_searched_on_a_coarse_copy_are_glued_on_the_mesh(tmp_path, capsys):
    """Above ``resolution`` vertices the sites come from a simplified copy; the weld is made on
    the mesh itself at its own vertices, with the same guarantees."""
    sheet = hairpin(121, 21)
    p = weld(sheet, 2, seed=1, resolution=600)
    assert p.params["search_vertices"] <= 620 < sheet.n_vertices
    assert p.mesh.n_vertices == sheet.n_vertices - 4        # full resolution, u and v removed
    check_ground_truth(p, sheet)
    check_oriented_manifold(p.mesh)
    assert p.euler_after == sheet.euler_characteristic - 4
    X = sheet.vertices
    for u, v in p.sites:   # each site joins the two layers, far apart along the surface
        assert abs(X[u, 2] - X[v, 2]) == pytest.approx(2 * RHO)
        assert graph_distance(sheet, u, v) > 4 * np.linalg.norm(X[u] - X[v])
    full = weld(sheet, 2, seed=1, resolution=None)
    assert full.params["search_vertices"] == sheet.n_vertices and full.mesh.n_vertices == p.mesh.n_vertices


def test_weld_default_radius_grows_until_the_sites_fit():
    sheet = hairpin(61, 11, rho=0.45)       # layers 0.9 apart: more than 5 edges (0.1 each)
    p = weld(sheet, 1, seed=0)
    assert p.params["radius"] > 5 * sheet.mean_edge_length
    with pytest.raises(ValueError, match=r"radius up to [\d.]+ \(25.3 mean edge lengths\)"):
        weld(sheet, 40, seed=0)
    with pytest.raises(ValueError, match="found only 0 separated weld site"):
        weld(sheet, 1, seed=0, radius=5 * sheet.mean_edge_length)   # a given radius is kept


def test_cli_weld_options(tmp_path, capsys, monkeypatch):
    import sys

    import gromov
    from gromov.cli import main

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)   # status lines go to a terminal

    src = tmp_path / "hairpin.off"
    gromov.save(hairpin(121, 21), src)
    out = tmp_path / "w.off"
    assert main(["perturb", "weld", str(src), str(out), "--count", "2", "--resolution", "600",
                 "--min-geodesic-ratio", "3", "--separation", "0.5"]) == 0
    err = capsys.readouterr().err
    assert "weld x2 on 2541 vertices (sites searched on a 600-vertex copy)" in err
    params = json.loads(str(np.load(tmp_path / "w.map.npz")["params"]))
    assert (params["resolution"], params["min_geodesic_ratio"], params["separation"]) == (600, 3.0, 0.5)
    assert main(["perturb", "holes", str(src), str(out), "--count", "1", "--separation", "1"]) == 2
    assert "--separation applies to weld, not to holes" in capsys.readouterr().err
    assert main(["perturb", "weld", str(src), str(out), "--count", "1", "-q"]) == 0
    assert capsys.readouterr().err == ""


def test_far_pairs_is_the_edge_graph_distance_against_each_threshold():
    """The weld candidates' test ``d_G(u, v) > threshold`` is exact for every pair, also when a
    pair's gap exceeds the smallest threshold (its vertices then lie far apart in space)."""
    from scipy.spatial import cKDTree

    from gromov.perturb import _far_pairs

    m = hairpin()
    rng = np.random.default_rng(0)
    pairs = cKDTree(m.vertices).query_pairs(1.5, output_type="ndarray")
    pairs = pairs[rng.permutation(len(pairs))]
    gap = np.linalg.norm(m.vertices[pairs[:, 0]] - m.vertices[pairs[:, 1]], axis=1)
    threshold = np.maximum(rng.uniform(0.5, 4.0, len(pairs)) * gap, 0.3)
    assert (gap > threshold.min()).sum() > 100          # the case a bounded subgraph search misreads
    d = dijkstra(m.adjacency, directed=False)[pairs[:, 0], pairs[:, 1]]
    far = _far_pairs(m, pairs, threshold)
    assert 0 < far.sum() < len(pairs)
    np.testing.assert_array_equal(far, d > threshold)


# ---------------------------------------------------------------------------- cut

def two_spheres() -> Mesh:
    """Two unit icospheres 3 apart: two components of equal area."""
    s = icosphere(3)
    return Mesh(np.vstack([s.vertices, s.vertices + [3.0, 0.0, 0.0]]),
                np.vstack([s.faces, s.faces + s.n_vertices]))


def area_fraction(p: Perturbation, mesh: Mesh) -> float:
    return p.mesh.area / mesh.area


@pytest.mark.parametrize("keep", [0.25, 0.6, 0.8])
def test_cut_plane_on_sphere_is_a_cap_at_the_hat_box_offset(keep):
    sphere = icosphere(4)   # unit sphere
    p = cut(sphere, keep, kind="plane", seed=1)
    assert p.kind == "cut" and p.params["kind"] == "plane" and p.sites.shape == (0,)
    assert abs(area_fraction(p, sphere) - keep) <= 0.02
    assert p.params["kept"] == pytest.approx(area_fraction(p, sphere))
    check_ground_truth(p, sphere)
    check_oriented_manifold(p.mesh)
    # one side of the plane: every part vertex, and every input vertex on that side is kept
    # (a cap of a convex shape is one piece)
    n, t = np.asarray(p.params["normal"]), p.params["offset"]
    assert np.linalg.norm(n) == pytest.approx(1.0)
    assert (p.mesh.vertices @ n <= t).all()
    np.testing.assert_array_equal(p.vertex_map, np.flatnonzero(sphere.vertices @ n <= t))
    # a cap {n.x <= t} of the unit sphere holds (1 + t) / 2 of its area; the faces across the
    # plane are lost, so the discrete offset lies within about an edge of 2 keep - 1
    assert abs(t - (2 * keep - 1)) < 2 * sphere.edge_lengths.max()
    # a disk: one component, one boundary loop
    assert p.mesh.n_components == 1 and (p.euler_after, p.boundary_loops_after) == (1, 1)


def test_cut_holes_on_sphere_removes_disks_around_the_centres():
    sphere = icosphere(4)
    p = cut(sphere, 0.7, kind="holes", count=4, seed=2)
    assert p.params["kind"] == "holes" and p.params["count"] == 4 and p.sites.shape == (4,)
    assert abs(area_fraction(p, sphere) - 0.7) <= 0.02
    check_ground_truth(p, sphere)
    check_oriented_manifold(p.mesh)
    # every part vertex is at least the radius from every centre (edge-graph distance); the
    # centres are gone and nothing farther than the radius plus an edge is lost but slivers
    d = dijkstra(sphere.adjacency, directed=False, indices=p.sites, min_only=True)
    r = p.params["radius"]
    assert d[p.vertex_map].min() >= r and not np.isin(p.sites, p.vertex_map).any()
    far = np.flatnonzero(d > r + sphere.edge_lengths.max())
    assert np.isin(far, p.vertex_map).mean() > 0.99
    assert p.mesh.n_components == 1 and p.boundary_loops_after >= 1


def test_cut_is_seeded():
    sphere = icosphere(3)
    for kind in ("plane", "holes"):
        a, b, c = (cut(sphere, 0.6, kind=kind, seed=s) for s in (7, 7, 8))
        np.testing.assert_array_equal(a.vertex_map, b.vertex_map)
        np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
        np.testing.assert_array_equal(a.sites, b.sites)
        assert a.params == b.params
        assert not np.array_equal(a.vertex_map, c.vertex_map)
    g = cut(sphere, 0.6, seed=np.random.default_rng(7))   # a Generator: used, not recorded
    assert g.params["seed"] is None and np.array_equal(g.vertex_map, cut(sphere, 0.6, seed=7).vertex_map)


def test_cut_keeps_the_largest_piece():
    """Two equal spheres: a plane keeping 40% leaves one piece; 80% can't be one piece. Holes
    on one sphere (the other is infinitely far from their centres) leave it whole or in part."""
    m = two_spheres()
    p = cut(m, 0.4, kind="plane", seed=0)
    assert abs(area_fraction(p, m) - 0.4) <= 0.02 and p.mesh.n_components == 1
    check_ground_truth(p, m)
    for keep in (0.3, 0.45):
        h = cut(m, keep, kind="holes", count=2, seed=1)
        assert abs(area_fraction(h, m) - keep) <= 0.02 and h.mesh.n_components == 1
        check_ground_truth(h, m)
    with pytest.raises(ValueError, match=r"no plane direction out of max_tries=3 keeps 0.8 \+- 0.02 of "
                                         r"the area in one piece \(nearest: 0.500\)"):
        cut(m, 0.8, seed=0, max_tries=3)


def test_cut_on_tosca_cat_is_a_valid_part_with_exact_ground_truth(tosca_cat0, cat_working, tmp_path):
    """Parts of the working cat: fraction within 2%, one clean piece that gromov loads as it is,
    and each part vertex's file id gives its coordinates on the full-resolution cat."""
    import warnings

    import gromov

    cat = cat_working.mesh
    for kind in ("plane", "holes"):
        for keep in (0.4, 0.8):
            p = cut(cat, keep, kind=kind, seed=3)
            assert abs(area_fraction(p, cat) - keep) <= 0.02
            check_ground_truth(p, cat)
            check_oriented_manifold(p.mesh)
            assert p.mesh.n_components == 1 and (p.mesh.face_areas > 0).all()
            np.testing.assert_array_equal(p.mesh.vertices, tosca_cat0.vertices[p.mesh.input_ids])
            path = tmp_path / f"{kind}{keep}.off"
            gromov.save(p.mesh, path)
            with warnings.catch_warnings():
                warnings.simplefilter("error")           # repair would warn
                back = gromov.load(path)
            np.testing.assert_array_equal(back.faces, p.mesh.faces)
            np.testing.assert_allclose(back.vertices, p.mesh.vertices)


def test_cut_errors():
    sphere = icosphere(2)
    with pytest.raises(TypeError, match="mesh must be a gromov.Mesh, got ndarray"):
        cut(sphere.vertices, 0.5)
    for bad in (0, 1, 0.0, 1.0, -0.2, 1.5, float("nan"), float("inf"), True, "0.5"):
        with pytest.raises(ValueError, match=f"keep must be a fraction of the area strictly between 0 and 1, "
                                             f"got {bad!r}"):
            cut(sphere, bad)
    with pytest.raises(ValueError, match=r"kind must be one of \('plane', 'holes'\), got 'slice'"):
        cut(sphere, 0.5, kind="slice")
    with pytest.raises(ValueError, match="count applies to kind='holes', not to kind='plane'"):
        cut(sphere, 0.5, count=3)
    with pytest.raises(ValueError, match="count must be a positive integer, got 0"):
        cut(sphere, 0.5, kind="holes", count=0)
    with pytest.raises(ValueError, match="tol must be a fraction of the area strictly between 0 and 1, got 0"):
        cut(sphere, 0.5, tol=0)
    with pytest.raises(ValueError, match="count=1000 exceeds the 162 vertices"):
        cut(sphere, 0.5, kind="holes", count=1000)


def test_cli_cut_writes_the_part_and_its_ground_truth(tmp_path, capsys):
    import gromov
    from gromov.cli import main

    sphere = icosphere(4)
    src = tmp_path / "sphere.off"
    gromov.save(sphere, src)
    for kind in (None, "holes"):
        out = tmp_path / f"part-{kind}.ply"
        args = ["perturb", "cut", str(src), str(out), "--keep", "0.6", "--seed", "4"]
        assert main(args + ([] if kind is None else ["--kind", kind, "--count", "3"])) == 0
        said = capsys.readouterr().out
        assert f"cut ({kind or 'plane'}), 6" in said and f"part-{kind}.map.npz" in said
        part = gromov.load(out)
        z = np.load(tmp_path / f"part-{kind}.map.npz")
        assert str(z["kind"]) == "cut"
        params = json.loads(str(z["params"]))
        assert params["kind"] == (kind or "plane") and abs(part.area / sphere.area - 0.6) <= 0.02
        # part vertex i is input vertex vertex_map[i] (0-based file ids)
        np.testing.assert_allclose(part.vertices, sphere.vertices[z["vertex_map"]])
        same = cut(sphere, 0.6, kind=kind or "plane", count=None if kind is None else 3, seed=4)
        np.testing.assert_array_equal(z["vertex_map"], same.vertex_map)
        if kind == "holes":
            np.testing.assert_array_equal(z["sites"], same.sites)
    out = str(tmp_path / "p.off")
    for bad in ("1.5", "0", "x"):     # refused by the parser: usage and exit status 2
        with pytest.raises(SystemExit) as exit_:
            main(["perturb", "cut", str(src), out, "--keep", bad])
        assert exit_.value.code == 2
        assert "argument --keep: expected a fraction" in capsys.readouterr().err
    for extra, message in (([], "cut needs --keep"),
                           (["--keep", "0.5", "--radius", "1"], "--radius applies to weld and holes, not to cut"),
                           (["--keep", "0.5", "--count", "2"], "--count applies to cut --kind holes"),
                           (["--keep", "0.5", "--join", "tube"], "--join applies to weld, not to cut")):
        assert main(["perturb", "cut", str(src), out] + extra) == 2
        assert message in capsys.readouterr().err
    assert main(["perturb", "holes", str(src), out, "--count", "1", "--keep", "0.5"]) == 2
    assert "--keep applies to cut, not to holes" in capsys.readouterr().err
    assert main(["perturb", "weld", str(src), out]) == 2
    assert "weld needs --count: the number of welds" in capsys.readouterr().err
