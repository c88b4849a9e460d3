"""Topological noise (welds and holes): topology changes as stated, ground truth exact.

Facts checked: a geodesic disk removed from a sphere leaves chi = 2 - k and k boundary
loops; a tube weld is a handle (chi - 2, boundary unchanged, still an oriented manifold),
a pinch weld lowers chi by one; a weld turns a long way around the surface into a short
hop across the gap; output vertices are input vertices (coordinates and file ids).
"""

import json

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from gromov import Mesh
from gromov.metrics import GeodesicSolver
from gromov.perturb import Perturbation, _star_cycle, holes, weld
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
