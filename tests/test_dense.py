"""Dense maps: every input vertex gets an image, without reading the vertex order."""

import numpy as np
import pytest

import gromov
from gromov.cli import main
from gromov.dense import anchored_map, landmark_distances, local_anchored_map
import gromov.evaluate as evaluate
from gromov.evaluate import GeodesicReference, dense_error, dense_errors
from gromov.mesh import Mesh
from gromov.metrics._fmm import FastMarching
from gromov.shapes import grid, icosphere, rolled_grid

from test_gmds import bumpy_torus as _bumpy_torus


def bumpy_torus() -> Mesh:
    """An asymmetric torus of 700 vertices numbered 0..699 (as read from a file)."""
    t = _bumpy_torus()
    return Mesh(t.vertices, t.faces)


def permutation_of(m: Mesh, seed: int):
    """``(copy, perm)``: copy vertex j is vertex perm[j] of ``m`` (moved and rotated too)."""
    rng = np.random.default_rng(seed)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    perm = rng.permutation(m.n_vertices)
    return Mesh(m.vertices[perm] @ rot.T + rng.normal(size=3), np.argsort(perm)[m.faces]), perm


@pytest.fixture(scope="module")
def torus_pair():
    x = bumpy_torus()
    y, perm = permutation_of(x, 4)
    return x, y, perm, gromov.match(x, y, "diffusion", n_samples=30, resolution=None, dense=True)


def test_a_permuted_copy_gets_the_permuted_map(torus_pair):
    x, y, perm, r = torus_pair
    inv = np.argsort(perm)   # vertex i of x is vertex inv[i] of y
    assert r.x_to_y_dense_vertex.shape == (x.n_vertices,)
    assert r.y_to_x_dense_vertex.shape == (y.n_vertices,)
    # the vertex order carries no hint: the map is the permutation, not the identity
    assert np.mean(r.x_to_y_dense_vertex == inv) > 0.97
    assert np.mean(r.y_to_x_dense_vertex == perm) > 0.97
    assert np.mean(r.x_to_y_dense_vertex == np.arange(x.n_vertices)) < 0.05
    e = dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, y, inv)
    assert e.mean < 1e-3 and e.branch == "direct"


def test_a_shape_matched_with_itself_maps_every_vertex_home():
    x = bumpy_torus()
    r = gromov.match(x, x, "geodesic", n_samples=30, resolution=None, dense=True)
    ids = np.arange(x.n_vertices)
    assert np.mean(r.x_to_y_dense_vertex == ids) > 0.97
    e = dense_error(r.y_to_x_dense_face, r.y_to_x_dense_bary, x, ids)
    assert e.mean < 1e-3


def test_sheet_and_rolled_sheet_dense_error_near_zero():
    flat, rolled = grid(31, 16), rolled_grid(31, 16)   # isometric, same numbering
    r = gromov.match(flat, rolled, "geodesic", n_samples=40, resolution=None, dense=True)
    ids = np.arange(flat.n_vertices)
    # the sheet has four isometries (flips of u and of v): the best reading counts
    nu, nv = 31, 16
    i, j = ids // nv, ids % nv
    readings = [ids, (nu - 1 - i) * nv + j, i * nv + (nv - 1 - j), (nu - 1 - i) * nv + (nv - 1 - j)]
    errs = [dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, rolled, t) for t in readings]
    best = min(errs, key=lambda e: e.mean)
    assert best.mean < 0.01
    assert best.per_diameter().mean() < 0.01
    assert max(e.mean for e in errs) > 0.1   # the readings differ: the test can fail


def test_transfer_keeps_constants_and_labels(torus_pair):
    x, y, perm, r = torus_pair
    for method in ("nearest", "barycentric"):
        out = r.transfer(np.full(x.n_vertices, 2.5), method=method)
        assert out.shape == (y.n_vertices,)
        np.testing.assert_allclose(out, 2.5)
        back = r.transfer(np.full((y.n_vertices, 3), -1.0), method=method, direction="y_to_x")
        np.testing.assert_allclose(back, -1.0)
    labels = np.arange(x.n_vertices) % 7
    moved = r.transfer(labels)
    assert moved.dtype == labels.dtype and set(np.unique(moved)) <= set(range(7))
    # a smooth function (a coordinate) arrives nearly unchanged on the permuted copy
    f = x.vertices[:, 2]
    g = r.transfer(f, method="barycentric")
    np.testing.assert_allclose(g, f[perm], atol=0.02 * np.ptp(f))


def test_transfer_marks_target_vertices_without_an_image(torus_pair):
    """A target vertex without an image (dropped by loading, or outside a partial match's
    region) gets NaN, -1 for signed integer labels (0 is a label), or the ``fill`` given."""
    import dataclasses

    x, y, _, r = torus_pair
    gone = np.array([0, 5])
    v, f, b = r.y_to_x_dense_vertex.copy(), r.y_to_x_dense_face.copy(), r.y_to_x_dense_bary.copy()
    v[gone], f[gone], b[gone] = -1, -1, np.nan
    s = dataclasses.replace(r, y_to_x_dense_vertex=v, y_to_x_dense_face=f, y_to_x_dense_bary=b)
    labels = np.arange(x.n_vertices) % 7
    moved = s.transfer(labels)
    kept = np.setdiff1d(np.arange(y.n_vertices), gone)
    assert moved.dtype == labels.dtype and (moved[gone] == -1).all()
    np.testing.assert_array_equal(moved[kept], r.transfer(labels)[kept])
    assert np.isnan(s.transfer(labels.astype(float))[gone]).all()
    assert np.isnan(s.transfer(labels, method="barycentric")[gone]).all()
    assert (s.transfer(labels, fill=99)[gone] == 99).all()
    with pytest.raises(ValueError, match="give fill="):
        s.transfer(labels > 3)
    assert not s.transfer(labels > 3, fill=False)[gone].any()


def test_transfer_errors(torus_pair):
    x, _, _, r = torus_pair
    with pytest.raises(ValueError, match="one row per vertex"):
        r.transfer(np.zeros(x.n_vertices + 1))
    with pytest.raises(ValueError, match="method"):
        r.transfer(np.zeros(x.n_vertices), method="cubic")
    sparse = gromov.match(x, x, "geodesic", n_samples=10, resolution=None)
    assert not sparse.has_dense and sparse.x_to_y_dense_vertex is None
    with pytest.raises(ValueError, match="dense=True"):
        sparse.transfer(np.zeros(x.n_vertices))


def test_anchored_map_with_exact_landmark_distances_is_the_identity():
    m = icosphere(3)
    d = gromov.metric_solver(m, "geodesic").pairwise()
    rng = np.random.default_rng(0)
    L = rng.choice(m.n_vertices, 40, replace=False)
    np.testing.assert_array_equal(anchored_map(d[:, L], d[:, L]), np.arange(m.n_vertices))
    # a few landmarks placed wrongly on Y are set aside by the trimming
    bad = L.copy()
    bad[:5] = rng.choice(m.n_vertices, 5, replace=False)
    t = anchored_map(d[:, L], d[:, bad])
    assert np.mean(t == np.arange(m.n_vertices)) > 0.95


def test_anchored_map_sets_aside_each_pairs_own_corrupted_landmarks():
    """Least trimmed squares per pair: when each vertex's distances to a different fifth of
    the landmarks are corrupted (shortened, as a shortcut would), the true vertex still fits the
    other landmarks exactly and is chosen wherever it is among the candidates; one landmark set
    trimmed for all vertices alike cannot set aside corruptions that differ per vertex."""
    m = icosphere(3)
    d = gromov.metric_solver(m, "geodesic").pairwise()
    rng = np.random.default_rng(1)
    L = rng.choice(m.n_vertices, 40, replace=False)
    ax = d[:, L].copy()
    for v in range(m.n_vertices):
        hit = rng.choice(len(L), 8, replace=False)
        ax[v, hit] *= rng.uniform(0.2, 0.6, size=len(hit))
    per_pair = anchored_map(ax, d[:, L], candidates=32)
    assert np.mean(per_pair == np.arange(m.n_vertices)) > 0.99
    alike = anchored_map(ax, d[:, L], candidates=0)
    assert np.mean(alike == np.arange(m.n_vertices)) < 0.9
    with pytest.raises(ValueError, match="candidates"):
        anchored_map(ax, d[:, L], candidates=-1)


def test_local_anchored_map_with_exact_landmark_distances_is_the_identity():
    m = icosphere(3)
    d = gromov.metric_solver(m, "geodesic").pairwise()
    L = np.random.default_rng(0).choice(m.n_vertices, 40, replace=False)
    np.testing.assert_array_equal(local_anchored_map(d[:, L], d[:, L], 16), np.arange(m.n_vertices))
    with pytest.raises(ValueError, match="ax and ay"):
        local_anchored_map(d[:, L], d[:, L[:-1]])
    with pytest.raises(ValueError, match="local"):
        gromov.dense.dense_maps(None, None, (), (), local=-1)


def test_a_weld_does_not_carry_vertices_to_the_part_they_were_glued_to(data_dir):
    """david0 with three welds against itself, each vertex placed from the diffusion distances
    to 100 landmarks whose images are exact: the welds shorten the distances to the landmarks
    across them, which pull vertices over to the part they were glued to when every landmark
    counts (trimmed or not); from the 16 nearest none goes further than a tenth of the
    diameter."""
    from gromov.metrics.diffusion import correspondence_options
    from gromov.perturb import weld
    from gromov.resolution import simplify
    from gromov.shape_metric import ShapeMetric

    s = simplify(gromov.load(data_dir / "tosca" / "david0.off.gz"), 2000).mesh
    clean = Mesh(s.vertices, s.faces)
    p = weld(clean, 3)
    welded, home = Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map
    opts = correspondence_options("diffusion", None)   # as gromov.match measures them
    sx = ShapeMetric(welded, "diffusion", resolution=None, metric_options=opts)
    sy = ShapeMetric(clean, "diffusion", resolution=None, metric_options=opts)
    L = sx.samples(100, 0)
    ax, ay = landmark_distances(sx, L), landmark_distances(sy, home[L])
    geodesic = gromov.metric_solver(clean, "geodesic").pairwise()
    far = 0.1 * geodesic.max()
    assert np.mean(geodesic[local_anchored_map(ax, ay, 16), home] > far) == 0.0
    assert np.mean(geodesic[anchored_map(ax, ay), home] > far) > 0.01


def test_point_clouds_get_images_at_points():
    x = bumpy_torus()
    y, perm = permutation_of(x, 5)
    r = gromov.match(x.vertices, y.vertices, "geodesic", n_samples=30, resolution=None, dense=True)
    inv = np.argsort(perm)
    assert np.all(r.x_to_y_dense_face == -1) and np.all(np.isnan(r.x_to_y_dense_bary))
    assert np.mean(r.x_to_y_dense_vertex == inv) > 0.9
    with pytest.raises(ValueError, match="faces"):
        r.transfer(np.zeros(x.n_vertices), method="barycentric")


def test_fast_marching_to_targets_stops_at_the_limit():
    m = icosphere(3)
    fm = FastMarching(m.vertices, m.faces)
    src = np.array([0, 5, 17])
    tg = np.array([[1, 2, 3], [100, 200, 300], [17, 40, 600]])
    full = fm.distances(src)[np.arange(3)[:, None], tg]
    np.testing.assert_array_equal(fm.distances_to(src, tg), full)
    lim = 0.5
    np.testing.assert_array_equal(fm.distances_to(src, tg, limit=lim), np.where(full <= lim, full, np.inf))


def test_dense_errors_on_a_sphere_are_geodesic():
    m = icosphere(3)
    ref = GeodesicReference(m)
    fm = ref.fmm
    # images exactly at vertex 10, truth at vertices 0..4: the errors are the marched distances
    indptr, fids = m.vertex_faces
    f = fids[indptr[10]]
    corner = int(np.argmax(m.faces[f] == 10))
    face = np.full(5, f)
    bary = np.tile(np.eye(3)[corner], (5, 1))
    e = dense_errors(face, bary, m, np.arange(5), fmm=ref)
    np.testing.assert_allclose(e, fm.distances(np.arange(5))[:, 10], rtol=1e-12)
    # on the unit sphere the geodesic distance is the angle
    ang = np.arccos(np.clip(m.vertices[:5] @ m.vertices[10], -1, 1))
    np.testing.assert_allclose(e, ang, rtol=0.03, atol=1e-3)


def test_an_image_on_another_piece_is_infinitely_far():
    """Two separate spheres: an image on one, its truth on the other, is at infinite distance
    (not NaN), whether the image is a vertex (two corners of weight 0) or inside a face."""
    a = icosphere(2)
    m = Mesh(np.vstack([a.vertices, a.vertices + [5.0, 0.0, 0.0]]),
             np.vstack([a.faces, a.faces + a.n_vertices]))
    indptr, fids = m.vertex_faces
    f = fids[indptr[3]]
    face = np.array([f, f, f])
    bary = np.vstack([np.eye(3)[int(np.argmax(m.faces[f] == 3))], [1 / 3, 1 / 3, 1 / 3], np.eye(3)[0]])
    truth = np.array([a.n_vertices + 3, a.n_vertices + 7, 3])   # two on the other sphere, one on this
    e = dense_errors(face, bary, m, truth)
    assert np.isinf(e[:2]).all() and np.isfinite(e[2])
    assert np.isinf(dense_error(face[:1], bary[:1], m, truth[:1]).mean)


def _random_images_on_a_sphere(seed: int, k: int = 400):
    """A sphere, its reference, and ``k`` random image points with random true vertices, and
    the full marches' distances from each true vertex to its image's corners."""
    m = icosphere(3)
    ref = GeodesicReference(m)
    rng = np.random.default_rng(seed)
    face = rng.integers(0, m.n_faces, k)
    bary = rng.dirichlet(np.ones(3), k)
    truth = rng.integers(0, m.n_vertices, k)
    corners = ref.fmm.distances(truth)[np.arange(k)[:, None], m.faces[face]]
    return m, ref, face, bary, truth, corners


def test_dense_errors_are_the_marched_distances_near_and_far():
    """Near images (done at a limit) and far ones (marched in full at the end): every error is
    the full march's value."""
    m, ref, face, bary, truth, D = _random_images_on_a_sphere(3)
    e = dense_errors(face, bary, m, truth, fmm=ref)
    np.testing.assert_array_equal(e, np.sqrt((bary * D**2).sum(axis=1)))
    scale = np.sqrt(m.area)
    assert (e < evaluate.DENSE_LIMITS[0] * scale).any() and (e > evaluate.DENSE_LIMITS[-1] * scale).sum() > 100


def test_the_mirror_probe_bound_is_below_the_errors_and_exact_where_reached():
    """The lower bounds that decide the mirrored reading's probe: at most the errors, equal to
    them where the march up to the last limit reached the image's corners."""
    from gromov.evaluate import DENSE_LIMITS, _errors_at_least

    m, ref, face, bary, truth, corners = _random_images_on_a_sphere(2)
    scale = np.sqrt(m.area)
    exact = dense_errors(face, bary, m, truth, fmm=ref) / scale
    low = _errors_at_least(face, bary, m, truth, ref)
    assert np.all(low <= exact)
    near = (corners <= DENSE_LIMITS[-1] * scale).all(axis=1)   # every corner within the limit
    assert 0 < near.sum() < len(near)
    np.testing.assert_array_equal(low[near], exact[near])
    assert np.all(low[~near] < exact[~near])


def test_cli_dense_outputs(tmp_path):
    x = bumpy_torus()
    y, perm = permutation_of(x, 6)
    px, py = tmp_path / "x.ply", tmp_path / "y.obj"
    gromov.save(x, px)
    gromov.save(y, py)
    out, mp, page = tmp_path / "m.npz", tmp_path / "map.txt", tmp_path / "m.html"
    rc = main(["match", str(px), str(py), "--samples", "30", "--resolution", "700", "--dense",
               "--out", str(out), "--map", str(mp), "--html", str(page), "-q"])
    assert rc == 0
    text = page.read_text()
    assert '"mesh3d"' in text and '<script src="http' not in text
    z = np.load(out)
    n_x, n_y = x.n_vertices, y.n_vertices
    assert z["x_to_y_dense_vertex"].shape == (n_x,) and z["x_to_y_dense_face"].shape == (n_x,)
    assert z["x_to_y_dense_bary"].shape == (n_x, 3)
    assert z["y_to_x_dense_vertex"].shape == (n_y,) and z["y_to_x_dense_bary"].shape == (n_y, 3)
    for d, n_target, m in (("x_to_y", n_y, y), ("y_to_x", n_x, x)):
        v, f, b = z[f"{d}_dense_vertex"], z[f"{d}_dense_face"], z[f"{d}_dense_bary"]
        assert v.min() >= 0 and v.max() < n_target
        assert f.min() >= 0 and f.max() < m.n_faces
        assert b.min() >= 0 and np.allclose(b.sum(axis=1), 1.0)
    ids = np.loadtxt(mp, dtype=np.int64)
    assert ids.shape == (n_x,) and ids.min() >= 1 and ids.max() <= n_y
    np.testing.assert_array_equal(ids - 1, z["x_to_y_dense_vertex"])
    assert np.mean(ids - 1 == np.argsort(perm)) > 0.97


@pytest.fixture(scope="module")
def wolves(data_dir):
    """wolf0 and wolf1 of TOSCA (4,344 vertices, one triangulation) and their metrics as
    :func:`gromov.match` makes them by default, shared by the tests that match them (the
    metrics and the input meshes' eigenpairs are computed once)."""
    from gromov.shape_metric import ShapeMetric

    a = gromov.load(data_dir / "tosca" / "wolf0.off.gz")
    b = gromov.load(data_dir / "tosca" / "wolf1.off.gz")
    return a, b, ShapeMetric(a, "diffusion"), ShapeMetric(b, "diffusion")


def test_dense_map_on_real_data_ignores_the_vertex_order(wolves):
    """wolf0 -> wolf1 of TOSCA (same numbering) and wolf0 -> a permuted wolf1: both precise."""
    a, b, sa, sb = wolves
    c, perm = permutation_of(b, 7)
    inv = np.argsort(perm)
    ids = np.arange(a.n_vertices)
    means = []
    for target, mesh, truth in ((sb, b, ids), (c, c, inv[ids])):
        r = gromov.match(sa, target, dense=True)
        means.append(dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, mesh, truth).mean)
    assert max(means) < 0.03


def test_far_errors_beyond_the_march_budget_come_from_a_coarse_copy(monkeypatch):
    m = icosphere(4)   # 2,562 vertices; the coarse copy has 600
    ref = GeodesicReference(m)
    rng = np.random.default_rng(1)
    truth = rng.integers(0, m.n_vertices, 300)
    img = rng.integers(0, m.n_vertices, 300)   # a scrambled map: most errors are large
    indptr, fids = m.vertex_faces
    face = fids[indptr[img]]
    bary = np.eye(3)[np.argmax(m.faces[face] == img[:, None], axis=1)]
    exact = dense_errors(face, bary, m, truth, fmm=ref)
    monkeypatch.setattr(evaluate, "MAX_FULL_MARCHES", 10)
    monkeypatch.setattr(evaluate, "COARSE_VERTICES", 600)
    approx = dense_errors(face, bary, m, truth, fmm=GeodesicReference(m))
    limit = evaluate.DENSE_LIMITS[-1] * np.sqrt(m.area)
    far, near = exact > limit, exact < 0.8 * limit   # (a face's far corner can pass the limit)
    assert far.sum() > 200 and near.sum() > 20
    np.testing.assert_array_equal(approx[near], exact[near])   # near ones are marched exactly
    assert np.median(np.abs(approx[far] - exact[far]) / exact[far]) < 0.03
    # each end snapped to the nearest coarse vertex: off by about an edge at most
    edge = gromov.simplify(m, 600).mesh.mean_edge_length
    assert np.max(np.abs(approx[far] - exact[far])) < 1.5 * edge


def test_the_placed_map_alone_is_the_permuted_map_too():
    x = bumpy_torus()
    y, perm = permutation_of(x, 8)
    r = gromov.match(x, y, "diffusion", n_samples=30, resolution=None, dense="placed")
    assert np.mean(r.x_to_y_dense_vertex == np.argsort(perm)) > 0.97
    assert np.mean(r.y_to_x_dense_vertex == perm) > 0.97
    with pytest.raises(ValueError, match="dense must be"):
        gromov.match(x, y, "diffusion", n_samples=30, resolution=None, dense="spectral")


def test_zoomout_on_exact_maps_is_a_fixed_point():
    """The identity map of a shape onto itself is what ZoomOut returns from it."""
    from gromov.dense import zoomout
    from gromov.gh import ShapeMetric

    s = ShapeMetric(bumpy_torus(), "diffusion", resolution=None)
    ids = np.arange(s.mesh.n_vertices)
    np.testing.assert_array_equal(zoomout(s, s, ids), ids)


def test_input_zoomout_keeps_the_identity_and_brings_back_a_shaken_map():
    """On a shape and itself (input finer than the working mesh) the identity is a fixed point,
    and each vertex moved to a random neighbour comes home."""
    from gromov.dense import input_zoomout, ring_neighbourhoods
    from gromov.gh import ShapeMetric

    s = ShapeMetric(bumpy_torus(), "diffusion", resolution=300)
    n = s.input.n_vertices
    assert s.mesh.n_vertices < n
    ids = np.arange(n)
    np.testing.assert_array_equal(input_zoomout(s, s, ids, k_end=40), ids)
    ptr, nbr = ring_neighbourhoods(s.input, 1)
    rng = np.random.default_rng(3)
    shaken = nbr[ptr[:-1] + rng.integers(0, np.diff(ptr))]
    assert np.mean(shaken == ids) < 0.3
    back = input_zoomout(s, s, shaken, k_end=40)
    assert np.mean(back == ids) > 0.95


def test_input_zoomout_brings_back_a_region_placed_far_away():
    """A patch of the map sent to the far side of the shape, beyond any ring search, comes back
    by the steps that search all of Y; without them it stays."""
    from gromov.dense import input_zoomout
    from gromov.gh import ShapeMetric

    s = ShapeMetric(bumpy_torus(), "diffusion", resolution=300)
    v = s.input.vertices
    ids = np.arange(s.input.n_vertices)
    d = np.linalg.norm(v - v[0], axis=1)
    patch = d < np.quantile(d, 0.06)
    far = np.argsort(np.linalg.norm(v - (-v[0]), axis=1))[:patch.sum()]
    wrong = ids.copy()
    wrong[patch] = far
    back = input_zoomout(s, s, wrong, k_end=40)
    assert np.mean(back[patch] == ids[patch]) > 0.9
    assert np.mean(back == ids) > 0.95
    stuck = input_zoomout(s, s, wrong, k_end=40, global_k=0)
    assert np.mean(stuck[patch] == ids[patch]) < 0.5


def test_zoomout_energy_is_zero_for_the_identity_and_grows_with_a_misplaced_region():
    """E_k(T) = mean ||Phi_X(v) - Phi_Y(T(v)) C^T||^2: the identity of a shape is carried exactly
    (C = I), and a patch sent to the far side makes a jump no functional map of k smooth
    eigenfunctions carries."""
    from gromov.dense import zoomout_energy
    from gromov.gh import ShapeMetric

    s = ShapeMetric(bumpy_torus(), "diffusion", resolution=300)
    v = s.input.vertices
    ids = np.arange(s.input.n_vertices)
    assert zoomout_energy(s, s, ids, 40) < 1e-9
    d = np.linalg.norm(v - v[0], axis=1)
    patch = d < np.quantile(d, 0.06)
    wrong = ids.copy()
    wrong[patch] = np.argsort(np.linalg.norm(v - (-v[0]), axis=1))[:patch.sum()]
    assert zoomout_energy(s, s, wrong, 40) > 0.01
    assert zoomout_energy(s, s, wrong, 40) > zoomout_energy(s, s, wrong, 20)   # more of it seen at higher k


def test_refine_better_keeps_the_start_of_lower_energy_and_refines_it_as_one_run(monkeypatch):
    """Splitting the steps at ``split`` changes nothing: one start gives input_zoomout's map; of a
    right and a far-off start (the global steps disabled, so that it stays off), the right one
    is kept, whichever comes first."""
    import gromov.dense as gd
    from gromov.dense import input_zoomout, refine_better
    from gromov.gh import ShapeMetric

    s = ShapeMetric(bumpy_torus(), "diffusion", resolution=300)
    rng = np.random.default_rng(0)
    start = rng.permutation(s.input.n_vertices)   # no map: the steps make of it what they can
    got, k = refine_better(s, s, [start], split=28)
    np.testing.assert_array_equal(got, input_zoomout(s, s, start))
    assert k == 0
    v = s.input.vertices
    ids = np.arange(s.input.n_vertices)
    d = np.linalg.norm(v - v[0], axis=1)
    patch = d < np.quantile(d, 0.1)
    wrong = ids.copy()
    wrong[patch] = np.argsort(np.linalg.norm(v - (-v[0]), axis=1))[:patch.sum()]
    monkeypatch.setattr(gd, "INPUT_GLOBAL", 0)
    assert np.mean(input_zoomout(s, s, wrong, global_k=0)[patch] == ids[patch]) < 0.5
    for order in ([wrong, ids], [ids, wrong]):
        got, k = refine_better(s, s, order)
        assert order[k] is ids
        assert np.mean(got == ids) > 0.99
    with pytest.raises(ValueError, match="at least one"):
        refine_better(s, s, [])


def test_a_welded_shape_gets_the_placement_its_refinement_explains_better(data_dir):
    """david0 (5,000 vertices) with three welds matched to itself without them: the placement
    from all landmarks carries parts of the welded limbs to the parts they were glued to (3.4% of
    the vertices more than a tenth of the diameter from their truth, mean error 1.25 x 100 /
    sqrt(area), with ``DENSE_CHOICE = 0``: a diagnostic run); the refinement of the placement from the nearest
    landmarks has the lower ZoomOut energy, is kept, and places every vertex near its truth."""
    from gromov.perturb import weld
    from gromov.resolution import simplify

    s = simplify(gromov.load(data_dir / "tosca" / "david0.off.gz"), 5000).mesh
    clean = Mesh(s.vertices, s.faces)
    p = weld(clean, 3)
    welded, home = Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map
    r = gromov.match(welded, clean, dense=True)
    e = dense_errors(r.x_to_y_dense_face, r.x_to_y_dense_bary, clean, home) / np.sqrt(clean.area)
    radius = FastMarching(clean.vertices, clean.faces).distances(np.array([0])).max() / np.sqrt(clean.area)
    assert np.mean(e > 0.1 * radius) == 0.0   # a tenth of vertex 0's eccentricity: at most the diameter's
    assert 100 * e.mean() < 0.5


def test_ring_neighbourhoods_grow_by_one_edge_per_ring():
    from gromov.dense import ring_neighbourhoods

    m = grid(5, 5)   # vertex 12 is the centre of a 5 x 5 sheet, its diagonal neighbours
    ptr, ids = ring_neighbourhoods(m, 0)
    np.testing.assert_array_equal(ids, np.arange(m.n_vertices))
    ptr, ids = ring_neighbourhoods(m, 1)
    one = set(ids[ptr[12]:ptr[13]])
    assert one == {12} | set(m.adjacency[12].indices)
    ptr, ids = ring_neighbourhoods(m, 2)
    two = set(ids[ptr[12]:ptr[13]])
    assert one < two and two == set().union(*(set(m.adjacency[v].indices) | {v} for v in one))
    # every vertex, many rings (lists longer than the short-list sort): the powers of the
    # adjacency matrix with the identity, each list sorted
    import scipy.sparse as sp

    m = grid(15, 15)
    a = (m.adjacency + sp.identity(m.n_vertices, format="csr")).astype(bool).astype(int)
    for rings in (1, 3, 6):
        ptr, ids = ring_neighbourhoods(m, rings)
        reach = (a ** rings).tocsr()
        reach.sort_indices()
        assert rings < 6 or np.diff(ptr).max() > 64
        np.testing.assert_array_equal(ptr, reach.indptr)
        np.testing.assert_array_equal(ids, reach.indices)
    with pytest.raises(ValueError, match="rings must be non-negative"):
        ring_neighbourhoods(m, -1)


def test_the_input_refinement_maps_a_permuted_finer_copy():
    """Matched at a working resolution below the input's, the refined map is still the
    permutation (the refinement reads no vertex order)."""
    x = bumpy_torus()
    y, perm = permutation_of(x, 5)
    r = gromov.match(x, y, "diffusion", n_samples=30, resolution=300, dense=True)
    inv = np.argsort(perm)
    assert np.mean(r.x_to_y_dense_vertex == inv) > 0.9
    assert np.mean(r.y_to_x_dense_vertex == perm) > 0.9
    e = dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, y, inv)
    assert e.mean < 0.01
    with pytest.raises(ValueError, match="refine must be one of"):
        from gromov.dense import dense_maps
        from gromov.gh import ShapeMetric

        s = ShapeMetric(x, "diffusion", resolution=300)
        dense_maps(s, s, (np.arange(3), np.arange(3)), (np.arange(3), np.arange(3)), refine="spectral")


def test_the_input_refinement_sharpens_a_real_map(wolves):
    """wolf0 -> wolf1 of TOSCA (4,344 vertices, matched on a 3,000-vertex working mesh): the
    refinement on the input meshes brings most vertices to their very image and cuts the mean
    error of the placed map by more than half."""
    a, b, sa, sb = wolves
    ids = np.arange(a.n_vertices)
    placed, refined = (gromov.match(sa, sb, dense=mode) for mode in ("placed", True))
    e_placed, e_refined = (dense_error(r.x_to_y_dense_face, r.x_to_y_dense_bary, b, ids) for r in (placed, refined))
    assert e_refined.mean < 0.5 * e_placed.mean
    assert np.median(e_refined.errors) == 0.0 < np.median(e_placed.errors)
    assert np.mean(refined.x_to_y_dense_vertex == ids) > 0.6


def test_small_pieces_move_with_the_surface_under_a_similarity():
    """A shape with 30 small pieces beside it against a rotated, scaled copy with its vertices
    in another order: the pieces, left out of the metric, follow the motion of the surface
    nearest to them, so every vertex lands on its own copy."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("make_corpus", Path(__file__).parent / "corpus" / "make_corpus.py")
    corpus = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(corpus)
    v, f = corpus.small_pieces()
    X = gromov.Mesh(v, f)
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))                      # a rotation
    perm = np.random.default_rng(2).permutation(X.n_vertices)
    rank = np.argsort(perm)
    Y = gromov.Mesh(1.3 * v[perm] @ q.T + [2.0, -1.0, 0.5], rank[f])
    assert not gromov.resolution.main_pieces(X).all()
    r = gromov.match(X, Y, n_samples=50, dense=True)
    np.testing.assert_array_equal(r.x_to_y_dense_vertex, rank)
    np.testing.assert_array_equal(r.y_to_x_dense_vertex, perm)


@pytest.mark.parametrize("factorisation", ["cholmod", "superlu"])
def test_input_eigenpairs_are_the_dense_generalised_eigenpairs(monkeypatch, factorisation):
    """``laplace_beltrami_basis`` gives the first eigenpairs of ``L phi = lambda M phi`` that a
    dense generalised eigensolver gives, M-orthonormal, with the Cholesky factor (CHOLMOD) and
    with SuperLU for the shift-invert operator."""
    import sys

    import scipy.linalg
    import scipy.sparse as sp

    from gromov._eigen import spd_solver
    from gromov.dense import laplace_beltrami_basis
    from gromov.metrics.diffusion import cotan_laplacian

    if factorisation == "cholmod":
        pytest.importorskip("cholespy")
    else:
        monkeypatch.setitem(sys.modules, "cholespy", None)   # import fails: the scipy path
    assert spd_solver(sp.identity(3, format="csr"))[1] == factorisation
    m = bumpy_torus()
    L, M = cotan_laplacian(m)
    lam_ref, phi_ref = scipy.linalg.eigh(L.toarray(), M.toarray(), subset_by_index=[0, 39])
    phi, mass = laplace_beltrami_basis(m, 40)
    assert phi.shape == (m.n_vertices, 40)
    np.testing.assert_allclose(mass, M.diagonal())
    np.testing.assert_allclose(phi.T @ (mass[:, None] * phi), np.eye(40), atol=1e-10)
    lam = np.einsum("ij,ij->j", phi, L @ phi)
    np.testing.assert_allclose(lam, lam_ref, rtol=1e-9, atol=1e-12)
    # the same eigenvectors up to sign (the torus's eigenvalues are simple)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->j", phi_ref, mass[:, None] * phi)), 1.0, atol=1e-8)


def test_spd_solver_falls_back_to_lu_where_cholesky_fails():
    """A matrix that is not positive definite gets SuperLU, and the solve is right either way."""
    import scipy.sparse as sp

    from gromov._eigen import spd_solver

    spd = sp.csr_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]))
    indefinite = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]]))
    solve, name = spd_solver(indefinite)
    assert name == "superlu"
    np.testing.assert_allclose(indefinite @ solve(np.array([1.0, 2.0])), [1.0, 2.0])
    solve, _ = spd_solver(spd)
    b = np.arange(6.0).reshape(3, 2)
    np.testing.assert_allclose(spd @ solve(b), b)


def test_prolonged_eigenpairs_bound_the_true_ones_and_converge_to_them():
    """``prolonged_basis``: M-orthonormal Ritz pairs whose values are never below the true
    eigenvalues of the same rank (Poincare separation) and come nearer with each subspace
    iteration; a mesh no larger than its working mesh gets the exact eigenpairs."""
    import scipy.linalg

    from gromov.dense import laplace_beltrami_basis, prolonged_basis
    from gromov.metrics.diffusion import cotan_laplacian
    from gromov.resolution import working_mesh

    m = bumpy_torus()
    L, M = cotan_laplacian(m)
    lam_ref, phi_ref = scipy.linalg.eigh(L.toarray(), M.toarray(), subset_by_index=[0, 39])
    w = working_mesh(m, m.n_vertices // 4)
    assert w.mesh.n_vertices < m.n_vertices
    worst = []
    for iterations in (0, 1, 2):
        phi, mass = prolonged_basis(w, 40, iterations=iterations)
        assert phi.shape == (m.n_vertices, 40)
        np.testing.assert_allclose(phi.T @ (mass[:, None] * phi), np.eye(40), atol=1e-10)
        lam = np.einsum("ij,ij->j", phi, L @ phi)
        assert np.all(lam >= lam_ref - 1e-10 * lam_ref[-1])
        worst.append(float(np.max((lam[1:] - lam_ref[1:]) / lam_ref[1:])))
    assert worst[0] > worst[1] > worst[2]
    assert worst[2] < 0.05
    # the first 20 functions span the true first 20 eigenfunctions' space closely
    overlap = phi_ref[:, :20].T @ (mass[:, None] * phi[:, :20])
    assert np.linalg.svd(overlap, compute_uv=False).min() > 0.99
    # with nothing to prolong from, the Lanczos eigenpairs themselves
    same = working_mesh(m, m.n_vertices)
    np.testing.assert_array_equal(prolonged_basis(same, 10)[0], laplace_beltrami_basis(same.source, 10)[0])


def test_the_two_input_bases_computed_at_once_are_the_sequential_ones(monkeypatch, tmp_path):
    """``_input_bases``: with both shapes' input eigenpairs missing and two cores free, Y's are
    computed in a forked process (which reports its pid here), then ``alongside`` there, while
    ``meanwhile`` and X's are computed in this one; both equal, bit for bit, what the sequential
    computation gives, and what ``meanwhile`` and ``alongside`` return comes back either way."""
    import os

    import gromov.dense as dense
    from gromov.shape_metric import ShapeMetric

    m = bumpy_torus()
    stretched = Mesh(np.asarray(m.vertices) * [1.0, 1.2, 0.9], m.faces)

    def pair():
        return (ShapeMetric(m, "diffusion", resolution=m.n_vertices // 4),
                ShapeMetric(stretched, "diffusion", resolution=m.n_vertices // 4))

    orig = dense.prolonged_basis

    def spy(working, k, **kw):
        (tmp_path / f"pid{os.getpid()}").touch()
        return orig(working, k, **kw)

    monkeypatch.setattr(dense, "prolonged_basis", spy)
    monkeypatch.setattr(dense, "_may_fork", lambda: True)
    sx, sy = pair()
    calls = []
    got = dense._input_bases(sx, sy, 30, meanwhile=lambda: calls.append(os.getpid()) or "placed",
                             alongside=lambda: ("there", os.getpid()))
    assert calls == [os.getpid()]   # once, here
    pids = {p.name for p in tmp_path.iterdir()}
    assert f"pid{os.getpid()}" in pids and len(pids) == 2   # one solve here, one in a child
    assert got[0] == "placed" and got[1][0] == "there" and f"pid{got[1][1]}" in pids - {f"pid{os.getpid()}"}
    monkeypatch.setattr(dense, "_may_fork", lambda: False)
    rx, ry = pair()
    got = dense._input_bases(rx, ry, 30, meanwhile=lambda: calls.append(0) or "placed",
                             alongside=lambda: ("there", os.getpid()))
    assert got == ("placed", ("there", os.getpid())) and calls == [os.getpid(), 0]
    for a, b in ((sx, rx), (sy, ry)):
        assert a._input_basis[0].shape == (m.n_vertices, 30)
        np.testing.assert_array_equal(a._input_basis[0], b._input_basis[0])
        np.testing.assert_array_equal(a._input_basis[1], b._input_basis[1])
    # computed: nothing to do the second time
    for p in tmp_path.iterdir():
        p.unlink()
    dense._input_bases(sx, sy, 30)
    assert not list(tmp_path.iterdir())


def test_forked_input_basis_of_a_shape_with_a_piece_left_out(monkeypatch):
    """The forked process's eigenpairs come back through memory sized for the kept input
    vertices: with a small piece left out of the working mesh they equal, bit for bit, those of
    the sequential computation (rows 0 on the piece)."""
    import gromov.dense as dense
    from gromov.shape_metric import ShapeMetric

    big, small = icosphere(4), icosphere(1)
    v = np.r_[np.asarray(big.vertices), np.asarray(small.vertices) * 0.05 + [3.0, 0.0, 0.0]]
    f = np.r_[np.asarray(big.faces), np.asarray(small.faces) + big.n_vertices]
    m, m2 = Mesh(v, f), Mesh(v * [1.0, 1.1, 0.9], f)

    def pair():
        return ShapeMetric(m, "diffusion", resolution=600), ShapeMetric(m2, "diffusion", resolution=600)

    monkeypatch.setattr(dense, "_may_fork", lambda: True)
    sx, sy = pair()
    assert not sy.working.source_kept.all()
    dense._input_bases(sx, sy, 30)
    monkeypatch.setattr(dense, "_may_fork", lambda: False)
    rx, ry = pair()
    dense._input_bases(rx, ry, 30)
    for a, b in ((sx, rx), (sy, ry)):
        np.testing.assert_array_equal(a._input_basis[0], b._input_basis[0])
        np.testing.assert_array_equal(a._input_basis[1], b._input_basis[1])
    assert not sy._input_basis[0][~sy.working.source_kept].any()


def test_relax_keeps_an_isometry_of_any_size_and_brings_back_moved_images():
    """The identity onto a copy twice as large is a fixed point (the distances are compared at
    the two shapes' scales); images moved one edge, a few rings apart, all come home; so do
    most of a map whose every image was moved one edge."""
    from gromov.dense import relax_isometric, ring_neighbourhoods
    from gromov.gh import ShapeMetric

    x = bumpy_torus()
    sx = ShapeMetric(x, "diffusion", resolution=300)
    sy = ShapeMetric(Mesh(2.0 * x.vertices, x.faces), "diffusion", resolution=300)
    n = x.n_vertices
    ids = np.arange(n)
    np.testing.assert_array_equal(relax_isometric(sx, sy, ids), ids)
    ptr, nbr = ring_neighbourhoods(x, 1)
    rng = np.random.default_rng(5)
    moved = ids.copy()
    far = ids[::37]   # at least a few rings apart on the 700-vertex torus
    for v in far:
        ring = nbr[ptr[v]:ptr[v + 1]]
        moved[v] = rng.choice(ring[ring != v])
    assert np.all(moved[far] != far)
    np.testing.assert_array_equal(relax_isometric(sx, sy, moved), ids)
    shaken = nbr[ptr[:-1] + rng.integers(0, np.diff(ptr))]
    assert np.mean(shaken == ids) < 0.3
    assert np.mean(relax_isometric(sx, sy, shaken) == ids) > 0.9
    with pytest.raises(ValueError, match="edges must be positive"):
        relax_isometric(sx, sy, ids, edges=0)


def test_relax_sweeps_are_the_plain_minimisation():
    """The compiled sweeps (neighbours gathered once, a candidate's sum stopped once above the
    best) move every image exactly as the plain rule does: each image to the argmin over its
    image and that image's neighbours of the capped stress, all at once, ties kept."""
    from gromov.dense import _relax, ring_neighbourhoods

    x = bumpy_torus()
    y = Mesh(1.3 * x.vertices + 0.02 * np.sin(7 * x.vertices[:, ::-1]), x.faces)   # not an isometry
    nptr, nids = ring_neighbourhoods(x, 2)
    src = np.repeat(np.arange(x.n_vertices), np.diff(nptr))
    dist = 1.3 * np.linalg.norm(x.vertices[src] - x.vertices[nids], axis=1)
    yptr, yids = ring_neighbourhoods(y, 1)
    rng = np.random.default_rng(3)
    T0 = yids[yptr[:-1] + rng.integers(0, np.diff(yptr))]
    cap2 = (2.0 * y.mean_edge_length) ** 2

    def plain(T, sweeps):
        for _ in range(sweeps):
            new = T.copy()
            for v in range(len(T)):
                nb = [(u, dist[j]) for j, u in enumerate(nids[nptr[v]:nptr[v + 1]], nptr[v]) if u != v]
                best, arg = np.inf, T[v]
                for w in yids[yptr[T[v]]:yptr[T[v] + 1]]:
                    c = 0.0
                    for u, d in nb:
                        a, b = y.vertices[w], y.vertices[T[u]]
                        e = (d - np.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)) ** 2
                        c += min(e, cap2)
                    if c < best or (c == best and w == T[v]):
                        best, arg = c, w
                new[v] = arg
            if np.array_equal(new, T):
                break
            T = new
        return T

    for sweeps in (1, 3):
        out = _relax(nptr, nids, dist, np.ascontiguousarray(y.vertices), yptr, yids, T0.astype(np.int64), cap2,
                     sweeps)
        expected = plain(T0.copy(), sweeps)
        assert np.mean(expected != T0) > 0.3   # the sweeps move many images
        np.testing.assert_array_equal(out, expected)


def test_relax_reads_no_vertex_order():
    """Every image moves at once (Jacobi sweeps): on a permuted copy of X, the relaxed map of
    the permuted map is the permuted relaxed map."""
    from gromov.dense import relax_isometric, ring_neighbourhoods
    from gromov.gh import ShapeMetric

    x = bumpy_torus()
    xp, perm = permutation_of(x, 6)   # vertex j of xp is vertex perm[j] of x
    sx, sxp = (ShapeMetric(m, "diffusion", resolution=300) for m in (x, xp))
    sy = ShapeMetric(bumpy_torus(), "diffusion", resolution=300)
    ptr, nbr = ring_neighbourhoods(x, 1)
    rng = np.random.default_rng(7)
    shaken = nbr[ptr[:-1] + rng.integers(0, np.diff(ptr))]
    out = relax_isometric(sx, sy, shaken)
    np.testing.assert_array_equal(relax_isometric(sxp, sy, shaken[perm]), out[perm])


def test_relax_sharpens_a_real_refined_map(wolves, monkeypatch):
    """wolf0 -> wolf1 of TOSCA (one triangulation, so the truth is each vertex itself): the
    local isometry step after the refinement brings more vertices to their very image and
    lowers the mean error; the default dense map is the refined map so relaxed, given DENSE_ALIGN
    rounds of local rigid alignment, then DENSE_INVERSE rounds of the other direction's inverse
    and the alignment again where those changed it, which bring still more to their very
    image."""
    import gromov.dense as dense
    from gromov.dense import _at_vertices, relax_isometric

    a, b, sa, sb = wolves
    ids = np.arange(a.n_vertices)
    default = b.from_input_ids(gromov.match(sa, sb, dense=True).x_to_y_dense_vertex[a.input_ids])
    align_rounds = dense.DENSE_ALIGN
    monkeypatch.setattr(dense, "DENSE_RELAX", False)
    monkeypatch.setattr(dense, "DENSE_ALIGN", 0)
    r = gromov.match(sa, sb, dense=True)
    refined = b.from_input_ids(r.x_to_y_dense_vertex[a.input_ids])
    relaxed = relax_isometric(a, b, refined)
    back = relax_isometric(b, a, a.from_input_ids(r.y_to_x_dense_vertex[b.input_ids]))
    aligned = dense.align_locally(a, b, relaxed, rounds=align_rounds)
    consistent = dense.consistent_maps(a, b, aligned, dense.align_locally(b, a, back, rounds=align_rounds),
                                       rounds=dense.DENSE_INVERSE, sweeps=dense.INVERSE_SWEEPS)[0]
    np.testing.assert_array_equal(default, dense.align_locally(a, b, consistent, rounds=align_rounds,
                                                               since=aligned))
    errors = [dense_error(*_at_vertices(b, t), b, ids).mean for t in (refined, relaxed, default)]
    assert np.mean(relaxed == ids) > np.mean(refined == ids) + 0.03
    assert errors[1] < 0.8 * errors[0]
    assert align_rounds > 0 and np.mean(default == ids) > np.mean(relaxed == ids) + 0.01
    assert errors[2] < errors[1]


def test_gather_rows_is_numpy_indexing():
    """The refinement's compiled row gather is ``src[idx, :k]``, contiguous, for single and double
    precision, a column slice as source and ``k`` beyond its columns."""
    from gromov.dense import _gather_rows

    rng = np.random.default_rng(1)
    for dtype in (np.float32, np.float64):
        a = rng.standard_normal((50, 12)).astype(dtype)
        idx = rng.integers(0, 50, 70)
        for src in (a, a[:, :9]):
            for k in (1, 5, 9, 20):
                got = _gather_rows(src, idx, k)
                assert got.flags.c_contiguous and got.dtype == dtype
                np.testing.assert_array_equal(got, src[idx, :k])


def test_relax_neighbourhoods_are_kept_per_shape(monkeypatch):
    """X's neighbourhoods are built once per shape and ring count: a second relaxation of the
    same shape builds none and gives the same map."""
    import gromov.dense as dense
    from gromov.gh import ShapeMetric

    x = bumpy_torus()
    sx, sy = (ShapeMetric(m, "diffusion", resolution=300) for m in (x, bumpy_torus()))
    ptr, nbr = dense.ring_neighbourhoods(x, 1)
    shaken = nbr[ptr[:-1] + np.random.default_rng(2).integers(0, np.diff(ptr))]
    first = dense.relax_isometric(sx, sy, shaken)
    built = []
    real = dense.ring_neighbourhoods
    monkeypatch.setattr(dense, "ring_neighbourhoods", lambda m, r: built.append(r) or real(m, r))
    np.testing.assert_array_equal(dense.relax_isometric(sx, sy, shaken), first)
    assert built == [1]   # Y's one ring only
    # the kept lengths: each vertex's Euclidean distance to each neighbour
    nptr, nids, lengths = sx._relax_rings[1]
    src = np.repeat(np.arange(x.n_vertices), np.diff(nptr))
    np.testing.assert_array_equal(lengths, np.linalg.norm(x.vertices[src] - x.vertices[nids], axis=1))


def test_inverse_map_of_a_bijection_is_its_inverse():
    """S a bijection Y -> X (a permuted copy): every vertex of X has one preimage, and the
    inverse read off S is S's inverse, whatever T was."""
    from gromov.dense import inverse_map

    x = bumpy_torus()
    y, perm = permutation_of(x, 4)   # vertex j of y is vertex perm[j] of x
    inv = inverse_map(x, y, perm, np.zeros(x.n_vertices, dtype=np.int64))
    np.testing.assert_array_equal(perm[inv], np.arange(x.n_vertices))
    with pytest.raises(ValueError, match="S must hold one vertex of X"):
        inverse_map(x, y, perm[:-1], inv)


def test_inverse_map_fills_vertices_without_preimages_from_their_neighbours():
    """S from a coarser copy of the surface reaches only some vertices of X; the others go to
    the vertex of Y nearest their neighbours' images: on one surface at two densities, with S
    each coarse vertex's nearest fine vertex, almost every fine vertex goes to a vertex of the
    coarse mesh within one coarse edge of it."""
    from scipy.spatial import cKDTree

    from gromov.dense import inverse_map

    fine = bumpy_torus()
    c = gromov.simplify(fine, 200).mesh
    coarse = Mesh(c.vertices, c.faces)
    S = cKDTree(fine.vertices).query(coarse.vertices)[1]
    reached = np.isin(np.arange(fine.n_vertices), S)
    assert reached.mean() < 0.5
    inv = inverse_map(fine, coarse, S, np.zeros(fine.n_vertices, dtype=np.int64))
    off = np.linalg.norm(coarse.vertices[inv] - fine.vertices, axis=1)
    assert np.mean(off < coarse.mean_edge_length) > 0.95
    assert np.mean(inv == 0) < 0.05   # T kept only where no neighbour is reached


def test_isometric_stress_is_zero_at_an_isometry_and_counts_a_moved_image():
    """The identity onto a copy scaled by 2 has no stress; moving one image raises the stress of
    that vertex and of its neighbours only."""
    from gromov.dense import isometric_stress, ring_neighbourhoods

    x = bumpy_torus()
    y = Mesh(2.0 * x.vertices, x.faces)
    ids = np.arange(x.n_vertices)
    np.testing.assert_allclose(isometric_stress(x, y, ids), 0.0, atol=1e-18)
    ptr, nbr = ring_neighbourhoods(x, 1)
    moved = ids.copy()
    moved[0] = nbr[ptr[0]:ptr[1]][nbr[ptr[0]:ptr[1]] != 0][0]
    e = isometric_stress(x, y, moved)
    assert e[0] > 0
    rptr, rids = ring_neighbourhoods(x, 8)
    near = set(rids[rptr[0]:rptr[1]])
    assert all(i in near for i in np.flatnonzero(e > 0))


def test_reach_caps_the_neighbourhood_at_a_part_of_the_shape():
    """The steps' radius is the smaller of ``edges`` mean edges and ``reach`` sqrt(area of Y): a
    reach beyond the edges changes nothing; a smaller one is the same neighbourhood as the
    edges it reaches; each step takes it; a reach must be positive."""
    from gromov.dense import RELAX_EDGES, _relax_setup, align_locally, isometric_stress, relax_isometric

    x = bumpy_torus()
    y = Mesh(1.5 * x.vertices + 0.01 * np.sin(5 * x.vertices[:, ::-1]), x.faces)
    h = max(x.mean_edge_length * np.sqrt(y.area / x.area), y.mean_edge_length)
    far = RELAX_EDGES * h / np.sqrt(y.area)   # the reach of the edges alone
    rng = np.random.default_rng(2)
    T = rng.permutation(x.n_vertices)

    def rings(**kw):
        nptr = _relax_setup(x, y, T, kw.pop("edges", RELAX_EDGES), RELAX_EDGES, kw["reach"])[0]
        return np.diff(nptr)

    np.testing.assert_array_equal(rings(reach=2 * far), rings(reach=None))
    assert rings(reach=far / 4).sum() < rings(reach=None).sum()
    np.testing.assert_array_equal(rings(reach=far / 4), rings(edges=RELAX_EDGES / 4, reach=None))
    for step in (isometric_stress, relax_isometric, align_locally):
        np.testing.assert_array_equal(step(x, y, T, reach=far / 4), step(x, y, T, edges=RELAX_EDGES / 4, reach=None))
        np.testing.assert_array_equal(step(x, y, T, reach=2 * far), step(x, y, T, reach=None))
    with pytest.raises(ValueError, match="reach must be positive"):
        relax_isometric(x, y, T, reach=0.0)


def test_consistent_maps_repair_a_slid_map_from_the_other_direction():
    """T: X -> Y with a patch put on the wrong side of the torus (a local minimum of the
    one-edge moves) and S: Y -> X exact: the inverse of S is the identity, of no stress, so T
    becomes the identity and S stays; both directions read alike (swapping X and Y swaps the
    result) and no vertex order is read."""
    from gromov.dense import consistent_maps, relax_isometric, ring_neighbourhoods

    x = bumpy_torus()
    y = Mesh(1.5 * x.vertices, x.faces)
    ids = np.arange(x.n_vertices)
    ptr, nbr = ring_neighbourhoods(x, 3)
    patch = nbr[ptr[0]:ptr[1]]
    far = int(np.argmax(np.linalg.norm(x.vertices - x.vertices[0], axis=1)))
    T = ids.copy()
    T[patch] = far
    assert not np.array_equal(relax_isometric(x, y, T), ids)   # one-edge moves cannot bring it home
    t, s = consistent_maps(x, y, T, ids)   # one round
    np.testing.assert_array_equal(t, ids)
    np.testing.assert_array_equal(s, ids)
    s2, t2 = consistent_maps(y, x, ids, T)
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(s2, s)
    xp, perm = permutation_of(x, 9)   # vertex j of xp is vertex perm[j] of x
    inv = np.argsort(perm)
    tp, sp = consistent_maps(xp, y, T[perm], inv[ids])
    np.testing.assert_array_equal(tp, t[perm])
    np.testing.assert_array_equal(sp, inv[s])
    np.testing.assert_array_equal(consistent_maps(x, y, T, ids, rounds=0)[0], T)
    with pytest.raises(ValueError, match="rounds must be"):
        consistent_maps(x, y, T, ids, rounds=-1)


@pytest.fixture(scope="module")
def torus_densities():
    """A bumpy torus, the same surface subdivided (4 times the faces), and their metrics as
    :func:`gromov.match` makes them by default (computed once for the tests that match them)."""
    import trimesh

    from gromov.shape_metric import ShapeMetric

    x = bumpy_torus()
    fine = trimesh.Trimesh(x.vertices, x.faces, process=False).subdivide()
    y = Mesh(fine.vertices, fine.faces)
    return x, y, ShapeMetric(x, "diffusion"), ShapeMetric(y, "diffusion")


def test_dense_maps_give_both_relaxed_maps_their_inverse_rounds(monkeypatch, torus_densities):
    """``DENSE_INVERSE = R`` makes the dense maps :func:`consistent_maps` of the two relaxed
    maps after R rounds; on one surface at two densities the rounds change a map."""
    import gromov.dense as dense

    x, y, sx, sy = torus_densities
    monkeypatch.setattr(dense, "DENSE_ALIGN", 0)
    monkeypatch.setattr(dense, "DENSE_INVERSE", 0)
    r0 = gromov.match(sx, sy, dense=True)
    monkeypatch.setattr(dense, "DENSE_INVERSE", 2)
    r2 = gromov.match(sx, sy, dense=True)
    t, s = dense.consistent_maps(x, y, r0.x_to_y_dense_vertex, r0.y_to_x_dense_vertex, rounds=2)
    np.testing.assert_array_equal(r2.x_to_y_dense_vertex, t)
    np.testing.assert_array_equal(r2.y_to_x_dense_vertex, s)
    assert not (np.array_equal(t, r0.x_to_y_dense_vertex) and np.array_equal(s, r0.y_to_x_dense_vertex))


def test_align_keeps_a_similarity_and_brings_back_shaken_images():
    """The identity onto a rotated, moved copy twice as large is a fixed point of the local
    rigid alignment; a map whose every image was moved to a random neighbour comes home."""
    from gromov.dense import align_locally, ring_neighbourhoods

    x = bumpy_torus()
    rng = np.random.default_rng(0)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    y = Mesh(2.0 * x.vertices @ rot.T + 1.0, x.faces)
    ids = np.arange(x.n_vertices)
    np.testing.assert_array_equal(align_locally(x, y, ids), ids)
    ptr, nbr = ring_neighbourhoods(x, 1)
    shaken = nbr[ptr[:-1] + rng.integers(0, np.diff(ptr))]
    assert np.mean(shaken == ids) < 0.2
    np.testing.assert_array_equal(align_locally(x, y, shaken), ids)
    np.testing.assert_array_equal(align_locally(x, y, shaken, rounds=0), shaken)
    for bad, match in (({"rounds": -1}, "rounds must be"), ({"rings": 0}, "rings must be"),
                       ({"cap": 0.0}, "cap must be"), ({"edges": 0}, "edges must be")):
        with pytest.raises(ValueError, match=match):
            align_locally(x, y, ids, **bad)


def test_align_rounds_are_the_plain_procrustes_rule():
    """The compiled rounds move every image as the plain rule does: each vertex's neighbours
    (itself left out) carried onto their images by the orthogonal Procrustes motion (scipy's),
    refitted once with Huber's weights, and the image moved to the vertex nearest where that
    motion puts the vertex, among those within the rings of its image; all at once."""
    from scipy.linalg import orthogonal_procrustes

    from gromov.dense import _align, ring_neighbourhoods

    x = bumpy_torus()
    y = Mesh(1.3 * x.vertices + 0.02 * np.sin(7 * x.vertices[:, ::-1]), x.faces)   # not a similarity
    nptr, nids = ring_neighbourhoods(x, 2)
    yptr, yids = ring_neighbourhoods(y, 2)
    rng = np.random.default_rng(3)
    p1, n1 = ring_neighbourhoods(y, 1)
    T0 = n1[p1[:-1] + rng.integers(0, np.diff(p1))]
    px = 1.3 * x.vertices
    cap = 0.5 * y.mean_edge_length

    def fit(P, Q, w):
        cp, cq = np.average(P, axis=0, weights=w), np.average(Q, axis=0, weights=w)
        R = orthogonal_procrustes(np.sqrt(w)[:, None] * (P - cp), np.sqrt(w)[:, None] * (Q - cq))[0]
        return lambda p: (p - cp) @ R + cq

    def plain(T, rounds):
        for _ in range(rounds):
            new = T.copy()
            for v in range(len(T)):
                nb = nids[nptr[v]:nptr[v + 1]]
                nb = nb[nb != v]
                P, Q = px[nb], y.vertices[T[nb]]
                motion = fit(P, Q, np.ones(len(nb)))
                r = np.linalg.norm(motion(P) - Q, axis=1)
                at = fit(P, Q, np.minimum(1.0, cap / np.maximum(r, 1e-300)))(px[v])
                cand = yids[yptr[T[v]]:yptr[T[v] + 1]]
                d = ((y.vertices[cand] - at) ** 2).sum(axis=1)
                new[v] = cand[np.argmin(d)]
            T = new
        return T

    for rounds in (1, 2):
        out = _align(nptr, nids, np.ascontiguousarray(px), np.ascontiguousarray(y.vertices), yptr, yids,
                     T0.astype(np.int64), cap, rounds, np.ones(len(T0), dtype=bool))
        expected = plain(T0.copy(), rounds)
        assert np.mean(expected != T0) > 0.3   # the rounds move many images
        np.testing.assert_array_equal(out, expected)


def test_align_reads_no_vertex_order():
    """On a permuted copy of X, the aligned map of the permuted map is the permuted aligned map."""
    from gromov.dense import align_locally, ring_neighbourhoods

    x = bumpy_torus()
    xp, perm = permutation_of(x, 6)   # vertex j of xp is vertex perm[j] of x
    y = Mesh(1.3 * x.vertices + 0.02 * np.sin(7 * x.vertices[:, ::-1]), x.faces)
    ptr, nbr = ring_neighbourhoods(y, 1)
    shaken = nbr[ptr[:-1] + np.random.default_rng(7).integers(0, np.diff(ptr))]
    out = align_locally(x, y, shaken)
    assert not np.array_equal(out, shaken)
    np.testing.assert_array_equal(align_locally(xp, y, shaken[perm]), out[perm])


def test_align_rounds_a_finer_copy_to_the_nearest_vertex_better_than_the_local_stress():
    """One bumpy torus simplified to 2,800 and to 700 vertices (two triangulations of nearly one
    surface), the map fine -> coarse each vertex's nearest coarse vertex, every image then moved
    to a random neighbour: the local rigid alignment brings more images back to the nearest
    vertex than the local isometry step does (the local stress is flat below an edge, the
    neighbourhood's motion is not). Both with neighbourhoods of ``RELAX_EDGES`` edges and no
    ``reach`` (on these coarse meshes the default reach is about 3 edges, and the averaging
    that this states is over the neighbourhood)."""
    from scipy.spatial import cKDTree

    from gromov.dense import align_locally, relax_isometric, ring_neighbourhoods
    from gromov.shapes import torus

    t = torus(80, 40)
    v = t.vertices.copy()
    ang = np.arctan2(v[:, 1], v[:, 0])
    v *= (1 + 0.15 * np.exp(-((ang - 1.0) ** 2) / 0.2) + 0.05 * np.sin(3 * ang + 0.4))[:, None]
    coarse, fine = (Mesh(m.vertices, m.faces) for m in (gromov.simplify(Mesh(v, t.faces), n).mesh
                                                        for n in (700, 2800)))
    near = cKDTree(coarse.vertices).query(fine.vertices)[1]
    ptr, nbr = ring_neighbourhoods(coarse, 1)
    shaken = nbr[ptr[near] + np.random.default_rng(0).integers(0, np.diff(ptr)[near])]
    assert np.mean(shaken == near) < 0.2
    aligned = np.mean(align_locally(fine, coarse, shaken, reach=None) == near)
    relaxed = np.mean(relax_isometric(fine, coarse, shaken, reach=None) == near)
    assert aligned > 0.8
    assert aligned > relaxed + 0.03


def test_dense_maps_end_with_the_local_rigid_alignment_of_both_maps(monkeypatch, torus_densities):
    """``DENSE_ALIGN = R`` (no inverse round) makes the dense maps :func:`align_locally` of
    the maps without it, each direction on its own; on one surface at two densities it changes
    them. With ``DENSE_INVERSE = 1`` the aligned maps take the inverse round
    (:func:`consistent_maps`) and are aligned again from there (``since``); there both the
    round and the second alignment change the map from the fine copy."""
    import gromov.dense as dense

    x, y, sx, sy = torus_densities
    monkeypatch.setattr(dense, "DENSE_ALIGN", 0)
    monkeypatch.setattr(dense, "DENSE_INVERSE", 0)
    r0 = gromov.match(sx, sy, dense=True)
    monkeypatch.setattr(dense, "DENSE_ALIGN", 3)
    r3 = gromov.match(sx, sy, dense=True)
    t = dense.align_locally(x, y, r0.x_to_y_dense_vertex, rounds=3)
    s = dense.align_locally(y, x, r0.y_to_x_dense_vertex, rounds=3)
    np.testing.assert_array_equal(r3.x_to_y_dense_vertex, t)
    np.testing.assert_array_equal(r3.y_to_x_dense_vertex, s)
    assert not (np.array_equal(t, r0.x_to_y_dense_vertex) and np.array_equal(s, r0.y_to_x_dense_vertex))

    monkeypatch.setattr(dense, "DENSE_INVERSE", 1)
    r = gromov.match(sx, sy, dense=True)
    ct, cs = dense.consistent_maps(x, y, t, s, rounds=1, sweeps=dense.INVERSE_SWEEPS)
    again = dense.align_locally(y, x, cs, rounds=3, since=s)
    assert not np.array_equal(cs, s) and not np.array_equal(again, cs)   # both steps change the map
    np.testing.assert_array_equal(r.x_to_y_dense_vertex, dense.align_locally(x, y, ct, rounds=3, since=t))
    np.testing.assert_array_equal(r.y_to_x_dense_vertex, again)


def test_align_since_fits_only_around_changed_images():
    """``since`` equal to the map fits no vertex (the map comes back as it is, however far from
    aligned); ``since`` that differs everywhere is the plain alignment; a wrong shape is refused."""
    from gromov.dense import align_locally, ring_neighbourhoods

    x = bumpy_torus()
    ptr, nbr = ring_neighbourhoods(x, 1)
    shaken = nbr[ptr[:-1] + np.random.default_rng(3).integers(0, np.diff(ptr))]
    plain = align_locally(x, x, shaken, rounds=2)
    assert np.mean(plain != shaken) > 0.3
    np.testing.assert_array_equal(align_locally(x, x, shaken, rounds=2, since=shaken), shaken)
    other = (shaken + 1) % x.n_vertices
    np.testing.assert_array_equal(align_locally(x, x, shaken, rounds=2, since=other), plain)
    with pytest.raises(ValueError, match="since must have"):
        align_locally(x, x, shaken, since=shaken[:-1])


def test_the_closed_form_orthogonal_factor_is_the_svds():
    """``_orthogonal_factor(H)`` is ``V U^T`` of the singular value decomposition ``H = U S V^T``:
    equal to numpy's where the singular values are distinct, and where H has rank 2 or 1 (a
    flat or a straight neighbourhood, where the factor is not unique) orthogonal and as good:
    it maximises tr(R H) as numpy's does."""
    from gromov.dense import _orthogonal_factor

    rng = np.random.default_rng(1)
    R = np.empty((3, 3))
    for i in range(400):
        H = rng.normal(size=(3, 3))
        if i % 4 == 1:
            H[:, 2] = 0.0
        elif i % 4 == 2:
            H = np.outer(rng.normal(size=3), rng.normal(size=3))
        elif i % 4 == 3:
            H = H @ np.diag([1.0, 1.0, 1e-9])
        _orthogonal_factor(H.copy(), R)
        U, _, Vt = np.linalg.svd(H)
        best = Vt.T @ U.T
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
        assert np.trace(R @ H) >= np.trace(best @ H) - 1e-9 * np.abs(H).max()
        if i % 4 == 0:
            np.testing.assert_allclose(R, best, atol=1e-8)
    _orthogonal_factor(np.zeros((3, 3)), R)
    np.testing.assert_array_equal(R, np.eye(3))
