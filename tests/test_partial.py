"""Partial matching (gromov.partial, ``match(part, whole, partial=True)``): a part cut from a
shape is found in that shape, the covered region is the kept one, a permuted whole gives the
permuted map, the dense map's refinement on the input meshes (ZoomOut with a rectangular
functional map) takes a part to its own vertices, and ``partial=False`` is the full match."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import gromov
from gromov.match_result import MatchResult
from gromov.partial import (boundary_distance, bridged_distances, covered_region, match_partial, partial_zoomout,
                            sample_weights, whole_shape)
from gromov.perturb import cut
from gromov.shape_metric import ShapeMetric
from gromov.shapes import grid, icosphere, torus


@pytest.fixture(scope="module")
def cat_part(cat_working):
    """cat0 at about 3,000 vertices (numbered 0..n-1), a plane cut keeping 60% of its area,
    and the part matched into it."""
    whole = gromov.Mesh(cat_working.mesh.vertices, cat_working.mesh.faces)
    p = cut(whole, 0.6, kind="plane", seed=1)
    part = gromov.Mesh(p.mesh.vertices, p.mesh.faces)
    r = gromov.match(part, whole, partial=True, dense=True, resolution=None)
    return whole, part, p.vertex_map, r


@pytest.fixture(scope="module")
def cat_part_metrics(cat_part):
    """The part and the whole of ``cat_part`` as geodesic metrics at the input resolution,
    shared by the tests that match them again (their distance rows are computed once)."""
    whole, part, _, _ = cat_part
    return ShapeMetric(part, "geodesic", resolution=None), ShapeMetric(whole, "geodesic", resolution=None)


def _errors(whole, images, truth):
    """Euclidean distance between the images and the true vertices, ÷ sqrt(area)."""
    return np.linalg.norm(whole.vertices[images] - whole.vertices[truth], axis=1) / np.sqrt(whole.area)


def test_part_maps_to_itself(cat_part):
    whole, part, truth, r = cat_part
    assert r.partial and r.x_to_y_dense_vertex.shape == (part.n_vertices,)
    e = _errors(whole, r.x_to_y_dense_vertex, truth)
    # every vertex near its own place: the mean within 1% of sqrt(area) (a working mesh's edge
    # is about 2%), nine in ten exactly on it or its neighbours
    assert e.mean() < 0.01
    assert np.mean(e < 0.03) > 0.9
    samples = _errors(whole, r.x_to_y_vertex, truth[r.x_samples])
    assert np.median(samples) < 0.01


def test_refined_part_lands_on_its_own_vertices(cat_part, cat_part_metrics):
    """The part shares the whole's triangles where it was cut from it: after the refinement
    (the default, ``dense=True``) nine vertices in ten are mapped onto themselves, the others
    onto a neighbour. The placed map (``dense="placed"``) of the distortion alone (``curvature=0``)
    has seven in ten on themselves, and the refinement lands the others."""
    whole, part, truth, r = cat_part
    sx, sy = cat_part_metrics
    placed = gromov.match(sx, sy, partial=True, dense="placed", resolution=None)
    exact = np.mean(r.x_to_y_dense_vertex == truth)
    assert exact > 0.88
    assert np.mean(_errors(whole, r.x_to_y_dense_vertex, truth) < 1.5 * whole.mean_edge_length
                   / np.sqrt(whole.area)) > 0.97
    # the refined images are vertices; the placed ones points on faces
    corner = whole.faces[r.x_to_y_dense_face, np.argmax(r.x_to_y_dense_bary, axis=1)]
    assert np.array_equal(corner, r.x_to_y_dense_vertex) and np.allclose(r.x_to_y_dense_bary.max(axis=1), 1.0)
    # the samples are the same; the covered region is read off each dense map, and the refined
    # one covers the kept region (the part's own vertices) at least as well
    assert placed.distance == r.distance and np.array_equal(placed.x_to_y_vertex, r.x_to_y_vertex)
    kept = np.zeros(whole.n_vertices, bool)
    kept[truth] = True

    def iou(region):
        return (region & kept).sum() / (region | kept).sum()

    assert iou(r.y_covered) >= iou(placed.y_covered) - 0.01 and iou(r.y_covered) > 0.9
    # from a placement less exact, the refinement lands most of the vertices on themselves
    p0 = match_partial(sx, sy, dense="placed", resolution=None, curvature=0.0)
    r0 = match_partial(sx, sy, dense=True, resolution=None, curvature=0.0)
    exact0, exact_placed0 = np.mean(r0.x_to_y_dense_vertex == truth), np.mean(p0.x_to_y_dense_vertex == truth)
    assert exact0 > 0.88 and exact0 > exact_placed0 + 0.15
    assert _errors(whole, r0.x_to_y_dense_vertex, truth).mean() < _errors(whole, p0.x_to_y_dense_vertex,
                                                                          truth).mean()


def test_true_map_is_a_fixed_point_and_a_ring_off_is_pulled_back(cat_part, cat_part_metrics):
    """ZoomOut's steps keep the true map (nearly: a part's eigenfunctions are not the whole's
    restricted to it) and take a map moved by one ring back onto it."""
    whole, part, truth, _ = cat_part
    sx, sy = cat_part_metrics
    assert np.mean(partial_zoomout(sx, sy, truth) == truth) > 0.9
    nbr = whole.adjacency.tocsr()
    off = nbr.indices[nbr.indptr[truth]]           # a neighbour of each true image
    assert np.mean(off == truth) == 0
    assert np.mean(partial_zoomout(sx, sy, off) == truth) > 0.9


def test_partial_zoomout_checks_its_inputs():
    x = torus(16, 8)
    sx = ShapeMetric(x, "geodesic", resolution=None)
    T = np.arange(x.n_vertices)
    with pytest.raises(ValueError, match="T must have"):
        partial_zoomout(sx, sx, T[:-1])
    for bad in ({"k_start": 0}, {"k_end": 5, "k_start": 10}, {"step": 0}, {"rings": -1}, {"ky_max": 0},
                {"step": 2.5}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            partial_zoomout(sx, sx, T, **bad)
    # a point cloud: nothing to refine on
    cloud = ShapeMetric(gromov.PointCloud(x.vertices), "geodesic", resolution=None)
    assert np.array_equal(partial_zoomout(sx, cloud, T[::-1]), T[::-1])
    with pytest.raises(ValueError, match="'input' or 'placed'"):
        match_partial(x, x, n_samples=10, dense="zoomout")


def test_refinement_helps_on_another_pose(data_dir):
    """A TOSCA horse cut by a plane (60% of its area) matched into another pose: refining the
    placed map lowers its error (mean and median) and puts half the vertices on their true one
    (the poses share their triangles: simplified alike)."""
    from gromov.perturb import cut as cut_mesh

    w0 = gromov.simplify(gromov.load(data_dir / "tosca" / "horse0.off.gz"), 3000)
    source = gromov.Mesh(w0.mesh.vertices, w0.mesh.faces)
    m = w0.transfer(gromov.load(data_dir / "tosca" / "horse5.off.gz")).mesh
    whole = gromov.Mesh(m.vertices, m.faces)
    p = cut_mesh(source, 0.6, kind="plane", seed=0)
    part, truth = gromov.Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map
    sx, sy = ShapeMetric(part, "geodesic"), ShapeMetric(whole, "geodesic")
    placed = gromov.match(sx, sy, partial=True, dense="placed").x_to_y_dense_vertex
    refined = partial_zoomout(sx, sy, placed)
    e0, e1 = _errors(whole, placed, truth), _errors(whole, refined, truth)
    assert e1.mean() < e0.mean() and np.median(e1) < np.median(e0)
    assert np.mean(refined == truth) > 0.45 > np.mean(placed == truth)


def test_curvature_term_places_a_part_the_distortion_alone_misplaces(data_dir):
    """A horse's front cut by a plane (55% of its area) into another pose: the search by the
    one-sided distortion alone lands on a wrong region, whose curvature differs far more from
    the part's than the truth's does; with the curvature term the samples land near their true
    places. Errors of the sample images: mean geodesic distance on the whole ÷ its
    diameter, the better of the direct and the mirrored truth."""
    from gromov.experiments.reproduce import reflection_map
    from gromov.partial import curvature_costs

    w0 = gromov.simplify(gromov.load(data_dir / "tosca" / "horse0.off.gz"), 4000)
    poses = [w0.transfer(gromov.load(data_dir / "tosca" / f"horse{k}.off.gz")).mesh for k in (5, 6)]
    source, whole = (gromov.Mesh(m.vertices, m.faces) for m in poses)
    mirror = reflection_map(gromov.Mesh(w0.mesh.vertices, w0.mesh.faces))
    p = cut(source, 0.55, kind="plane", seed=1)
    part, truth = gromov.Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map
    sx, sy = ShapeMetric(part, "geodesic"), ShapeMetric(whole, "geodesic")
    D = sy.distances

    def working(s, ids):
        return s.working.from_source(s.input.from_input_ids(np.asarray(ids)))

    def error(r):
        v = working(sy, r.x_to_y_vertex)
        return min(D[v, working(sy, truth[r.x_samples])].mean(),
                   D[v, working(sy, mirror[truth[r.x_samples]])].mean()) / sy.diameter

    alone, weighed = match_partial(sx, sy, curvature=0.0), match_partial(sx, sy)
    assert error(alone) > 0.15 and error(weighed) < 0.05
    P = working(sx, alone.x_samples)
    found, true = working(sy, alone.x_to_y_vertex), working(sy, truth[alone.x_samples])
    costs = curvature_costs(sx, sy, P, 1.0)
    rows = np.arange(len(P))
    assert np.median(costs[rows, true]) < 0.25 * np.median(costs[rows, found])
    # without the term, parts are ranked by the distortion alone
    assert alone.ranking_distance == pytest.approx(alone.relative_distance, rel=1e-12)


def test_the_ranking_distance_is_the_objective_of_the_search(cat_part_metrics):
    """``ranking_distance`` (what parts are ranked by) adds to the weighted squared residuals of
    ``relative_distance`` each sample's curvature cost times its total weight:
    R^2 - (D / diam)^2 = (1 / (2 diam))^2 sum_i (sum_j w_i w_j) cost_i(q_i) / sum_ij w_i w_j."""
    from gromov.partial import PARTIAL_CURVATURE, curvature_costs

    sx, sy = cat_part_metrics
    r = match_partial(sx, sy)
    W = np.outer(r.x_weight, r.x_weight)
    np.fill_diagonal(W, 0.0)
    P = sx.working.from_source(r.x_samples)   # numbered 0..n-1, the working meshes are the input
    costs = curvature_costs(sx, sy, P, PARTIAL_CURVATURE)[np.arange(len(P)), r.x_to_y_vertex]
    extra = (0.5 / sy.diameter) ** 2 * np.sum(W.sum(axis=1) * costs) / W.sum()
    assert extra > 0
    assert r.ranking_distance ** 2 - r.relative_distance ** 2 == pytest.approx(extra, rel=1e-9)


def test_covered_region_is_the_kept_one(cat_part):
    whole, part, truth, r = cat_part
    kept = np.zeros(whole.n_vertices, bool)
    kept[truth] = True
    covered = r.y_covered
    iou = (covered & kept).sum() / (covered | kept).sum()
    assert iou > 0.9
    # its area: the part's share of the whole (the cut kept 60%), within 5 points
    assert abs(r.covered_fraction - part.area / whole.area) < 0.05
    # and nothing far from the kept region: an uncovered vertex of the part's area at most 2 rings off
    ring2 = kept | (whole.adjacency @ kept.astype(float) > 0)
    ring2 = ring2 | (whole.adjacency @ ring2.astype(float) > 0)
    assert not (covered & ~ring2).any()


def test_permuted_whole_gives_the_permuted_map(cat_part):
    whole, part, _, r = cat_part
    perm = np.random.default_rng(3).permutation(whole.n_vertices)   # new vertex i is old perm[i]
    inv = np.argsort(perm)
    faces = inv[whole.faces]
    permuted = gromov.Mesh(whole.vertices[perm], faces)
    r2 = gromov.match(part, permuted, partial=True, dense=True, resolution=None)
    # the same places: old vertex v is new vertex inv[v]
    moved = np.linalg.norm(permuted.vertices[r2.x_to_y_dense_vertex] - whole.vertices[r.x_to_y_dense_vertex],
                           axis=1) / np.sqrt(whole.area)
    assert np.mean(moved < 0.03) > 0.9
    assert np.array_equal(r2.y_covered, r.y_covered[perm]) or \
        ((r2.y_covered & r.y_covered[perm]).sum() / (r2.y_covered | r.y_covered[perm]).sum() > 0.9)


def test_dense_back_map_only_inside_the_region(cat_part):
    whole, part, truth, r = cat_part
    inside = r.y_to_x_dense_vertex >= 0
    assert np.array_equal(inside, r.y_covered)
    # a function of the whole carried to the part and back is found where it was
    values = whole.vertices[:, 0]
    on_part = r.transfer(values, direction="y_to_x")
    assert np.median(np.abs(on_part - part.vertices[:, 0])) < 0.02 * np.sqrt(whole.area)


def test_partial_false_is_the_full_match():
    x, y = icosphere(2), icosphere(2, radius=1.2)
    a = gromov.match(x, y, n_samples=20, resolution=None)
    b = gromov.match(x, y, n_samples=20, resolution=None, partial=False)
    for name in ("distance", "relative_distance", "distortion", "n_iter"):
        assert getattr(a, name) == getattr(b, name)
    for name in ("x_to_y_face", "x_to_y_bary", "y_to_x_face", "y_to_x_bary", "pair_distortion"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    assert not b.partial and b.y_covered is None and np.isnan(b.covered_fraction)


def test_old_results_load_without_the_partial_fields():
    r = gromov.match(icosphere(1), icosphere(1), n_samples=10, resolution=None)
    state = {k: v for k, v in r.__dict__.items() if k not in ("partial", "y_covered", "covered_fraction", "x_weight")}
    old = MatchResult.__new__(MatchResult)
    old.__dict__.update(state)          # what unpickling a result saved before these fields does
    back = pickle.loads(pickle.dumps(old))
    assert back.partial is False and back.y_covered is None and np.isnan(back.covered_fraction)
    assert back.to_dict()["distance"] == r.distance


def _capless_sphere():
    """An icosphere and the part of it below z = 0.6 (a polar cap removed): ``(whole, part,
    the part's vertices' ids on the whole)``."""
    m = icosphere(4)
    kept = m.vertices[:, 2] < 0.6
    faces = m.faces[kept[m.faces].all(axis=1)]
    used = np.unique(faces)
    index = np.full(m.n_vertices, -1)
    index[used] = np.arange(len(used))
    return m, gromov.Mesh(m.vertices[used], index[faces]), used


def test_bridged_distances_bound_the_whole_distances_across_a_hole():
    """A sphere with a polar cap removed: the part's geodesic distance bounds the whole
    sphere's from above, the lower bound with chords across the hole bounds it from below
    (within the meshes' discretisation, a quarter of an edge), and their middle is closer to
    the whole's distance than the part's own; a closed shape keeps its distances."""
    m, part, used = _capless_sphere()
    s = ShapeMetric(m, "geodesic", resolution=None)
    P = s.samples(20, 0)
    np.testing.assert_array_equal(bridged_distances(s, P), s.distances[P])
    assert len(part.boundary_loops) == 1
    sx = ShapeMetric(part, "geodesic", resolution=None)
    P = sx.samples(30, 0)
    whole = s.distances[np.ix_(used, used)][P]
    own = sx.distances[P]
    middle = bridged_distances(sx, P)
    low = 2.0 * middle - own
    tol = 0.25 * part.mean_edge_length
    assert np.all(low <= whole + tol) and np.all(whole <= own + tol)
    assert np.mean(low < own - tol) > 0.05   # the hole shortens some pairs' bound
    assert np.abs(middle - whole).mean() < 0.5 * np.abs(own - whole).mean()


def test_bridged_distances_with_fewer_chord_ends_stay_between(monkeypatch):
    """Beyond BRIDGE_BOUNDARY boundary vertices only every k-th ends a chord: fewer ways across
    the hole, so the result lies between the one with every chord and the part's own."""
    import gromov.partial as gp

    sx = ShapeMetric(_capless_sphere()[1], "geodesic", resolution=None)
    P = sx.samples(30, 0)
    every = bridged_distances(sx, P)
    monkeypatch.setattr(gp, "BRIDGE_BOUNDARY", 10)
    fewer = bridged_distances(sx, P)
    assert np.all(fewer >= every - 1e-12) and np.all(fewer <= sx.distances[P] + 1e-12)
    assert np.any(fewer > every + 1e-9)


def test_interval_misfit_is_zero_for_the_truth_and_not_for_shuffled_samples():
    """The sphere without its cap matched into the whole sphere: the identity keeps every
    distance between the bridged bound and the part's own (within the discretisation), the
    samples exchanged at random do not."""
    from gromov.gmds import SurfacePoints
    from gromov.partial import interval_misfit

    m, part, used = _capless_sphere()
    s = ShapeMetric(m, "geodesic", resolution=None)
    sx = ShapeMetric(part, "geodesic", resolution=None)
    P = sx.samples(30, 0)
    own = sx.distances[np.ix_(P, P)]
    low = 2.0 * bridged_distances(sx, P)[:, P] - own
    W = 1.0 - np.eye(len(P))
    truth = interval_misfit(s, SurfacePoints.at_vertices(m, used[P]), low, own, W)
    shuffled = used[P][np.random.default_rng(0).permutation(len(P))]
    wrong = interval_misfit(s, SurfacePoints.at_vertices(m, shuffled), low, own, W)
    h = m.mean_edge_length
    assert truth < 0.05 * h and wrong > 5 * h


def test_bridge_choose_keeps_a_closed_part_as_it_is():
    x, y = icosphere(2), icosphere(2)
    a = match_partial(x, y, n_samples=20, bridge="choose", resolution=None)
    b = match_partial(x, y, n_samples=20, bridge=False, resolution=None)
    assert a.distance == b.distance
    np.testing.assert_array_equal(a.x_to_y_vertex, b.x_to_y_vertex)
    for bad in ("both", 1, 0.5):
        with pytest.raises(ValueError, match="bridge"):
            match_partial(x, y, n_samples=20, bridge=bad)


def test_boundary_weights_on_a_grid():
    g = grid(11, 11, width=1.0, height=1.0)
    b = boundary_distance(g)
    assert b.max() == pytest.approx(0.5, abs=1e-9)     # the centre, five edges of 0.1 from each side
    assert np.all(b[np.unique(g.boundary_edges.ravel())] == 0)
    w = sample_weights(b, 0.2)
    assert w.min() == 0 and w.max() == 1 and sample_weights(b, 0).min() == 1
    assert np.all(np.isinf(boundary_distance(icosphere(1))))


def test_covered_region_closes_small_gaps():
    g = grid(21, 21, width=2.0, height=2.0)
    h = g.mean_edge_length
    every_other = np.flatnonzero((np.arange(g.n_vertices) % 2 == 0) & (g.vertices[:, 0] < 1.0))
    plain = covered_region(g, every_other, 0.0)
    closed = covered_region(g, every_other, 0.0, close=2 * h)
    assert plain.sum() == len(every_other)
    # the gaps between the images filled, the outline kept within an edge
    assert closed[g.vertices[:, 0] < 1.0 - 2 * h].all()
    assert not closed[g.vertices[:, 0] > 1.0 + h].any()


def test_partial_options_are_checked():
    x = icosphere(1)
    with pytest.raises(ValueError, match="partial=True takes"):
        gromov.match(x, x, n_samples=10, partial=True, norm="linf")
    with pytest.raises(ValueError, match="n_samples"):
        match_partial(x, x, n_samples=2)
    with pytest.raises(ValueError, match="point cloud"):
        match_partial(gromov.PointCloud(x.vertices), x, n_samples=10)
    for bad in (-0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="curvature"):
            match_partial(x, x, n_samples=10, curvature=bad)


def test_cli_partial(tmp_path, capsys):
    import json

    from gromov.cli import main

    whole = torus(32, 16)
    p = cut(whole, 0.6, kind="plane", seed=0)
    gromov.save(whole, tmp_path / "whole.off")
    gromov.save(p.mesh, tmp_path / "part.off")
    out = tmp_path / "m.npz"
    argv = ["match", str(tmp_path / "part.off"), str(tmp_path / "whole.off"), "--partial", "--samples", "20",
            "--dense", "placed", "--out", str(out), "--json", "-q"]
    assert main(argv) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["partial"] is True and got["metric"] == "geodesic" and 0.3 < got["covered_fraction"] <= 1.0
    assert got["ranking_distance"] >= got["relative_distance"]
    arrays = np.load(out)
    assert arrays["y_covered"].shape == (whole.n_vertices,) and arrays["x_weight"].shape == (20,)
    assert arrays["x_to_y_dense_vertex"].shape == (p.mesh.n_vertices,)
    assert main(argv[:-2] + ["-q"]) == 0
    assert "as a part of" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(argv[:-3] + ["--norm", "linf"])
    # the part's dense map is refined on the input meshes, or placed; not on the working meshes
    argv[argv.index("placed")] = "zoomout"
    assert main(argv) == 2
    assert "--dense placed" in capsys.readouterr().err


def test_a_whole_shape_is_matched_as_gromov_match_does():
    """Nothing of a closed shape is missing, nor of one whose holes are narrower than the mesh
    resolves: ``partial=True`` gives gromov.match's two-sided correspondence and distance. A
    plane cut is a part."""
    x = icosphere(2)
    y = gromov.Mesh(x.vertices * [1.3, 1.0, 0.8], x.faces)
    holed = gromov.Mesh(x.vertices, np.delete(x.faces, 7, axis=0))   # one triangle missing
    plane = cut(x, 0.6, kind="plane", seed=0).mesh
    assert whole_shape(x) and whole_shape(holed) and not whole_shape(plane)
    for shape in (x, holed):
        full = gromov.match(shape, y, "geodesic", n_samples=20, resolution=None)
        part = gromov.match(shape, y, "geodesic", n_samples=20, resolution=None, partial=True)
        assert part.partial and full.distance > 0
        assert part.distance == full.distance and part.relative_distance == full.relative_distance
        assert part.ranking_distance == part.relative_distance   # no curvature term in a full match
        np.testing.assert_array_equal(part.x_to_y_vertex, full.x_to_y_vertex)
        assert part.covered_fraction > 0.9
    assert match_partial(plane, y, n_samples=20, resolution=None).pair_distortion.shape == (20, 20)
