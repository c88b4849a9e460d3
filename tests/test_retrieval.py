"""Retrieval with per-shape lower bounds: the bound never exceeds the ranked value, pruning by it
returns brute force's neighbours, and ``gromov search`` prints them as one JSON object."""

import json

import numpy as np
import pytest

import gromov
from gromov import Mesh, ShapeMetric, retrieval
from gromov.cli import main
from gromov.experiments.pairwise import gh_matrix
from gromov.gh import _match, ranking_value
from gromov.gmds import EmbeddedDistance, SurfaceDistance, SurfacePoints, SymmetricGMDS
from gromov.retrieval import (KnnPairs, NearestResult, ShapeBound, knn_pairs, nearest, pair_bound, profile_gap,
                              shape_bound)
from gromov.shapes import grid, icosphere, rolled_grid
from gromov.store import ShapeStore

N = 15   # samples per shape: seconds for the whole file


def _shapes() -> dict:
    """A sphere and an ellipsoid, a sphere five times smaller, and two long thin strips (flat
    and rolled: isometric)."""
    s = icosphere(2)
    return {"sphere": s, "ellipsoid": Mesh(s.vertices * [1.0, 1.0, 1.3], s.faces),
            "small": Mesh(s.vertices * 0.2, s.faces),
            "strip": grid(61, 3, width=200.0, height=0.6), "rolled": rolled_grid(61, 3, width=200.0, height=0.6)}


@pytest.fixture(scope="module", params=["geodesic", "diffusion"])
def prepared(request):
    metric = request.param
    return metric, {k: ShapeMetric(m, metric, resolution=None) for k, m in _shapes().items()}


@pytest.fixture(scope="module")
def shape_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shapes")
    files = {}
    for name, m in _shapes().items():
        files[name] = str(folder / f"{name}.off")
        gromov.save(m, files[name])
    return files


def test_bound_is_below_the_ranked_value_of_every_pair(prepared):
    """Both rankings, both residuals, the heat kernel's ranking scale or the match's metric;
    the bound is symmetric and non-zero on the unalike pairs."""
    metric, shapes = prepared
    inv = {k: shape_bound(s, N, 0, 0.5) for k, s in shapes.items()}
    names = list(shapes)
    positive = 0
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            for residual in ("log", "difference"):
                r = _match(shapes[a], shapes[b], metric, n_samples=N, orientation="ignore", as_prepared=True,
                           rank_tau_scale=0.5, rank_residual=residual)
                lb = pair_bound(inv[a], inv[b], rank_residual=residual)
                assert lb == pair_bound(inv[b], inv[a], rank_residual=residual)
                assert 0.0 <= lb <= r.ranking_distance, (a, b, residual)
                assert 0.0 <= pair_bound(inv[a], inv[b], rank_by="gh") <= r.relative_distance, (a, b)
                positive += lb > 0
    assert positive >= 6   # every pair with the small sphere or a strip but the two strips


def test_bound_holds_for_any_correspondence():
    """The bound rests on the range of distances on each shape, not on the correspondence
    found: random images of the samples never give a ranked value below it."""
    rng = np.random.default_rng(0)
    x, y = ShapeMetric(icosphere(2), "diffusion", resolution=None), \
        ShapeMetric(Mesh(icosphere(2).vertices * 0.3, icosphere(2).faces), "diffusion", resolution=None)
    bx, by = shape_bound(x, N, 0, 0.5), shape_bound(y, N, 0, 0.5)
    P, Q = x.samples(N, 0), y.samples(N, 0)
    (ex, dx), (ey, dy) = x.ranking_surface(0.5), y.ranking_surface(0.5)
    assert isinstance(ex, EmbeddedDistance)
    sx, sy = SurfaceDistance(x.mesh, x.distances), SurfaceDistance(y.mesh, y.distances)
    lb, lb_gh = pair_bound(bx, by), pair_bound(bx, by, rank_by="gh")
    assert lb > 0 and lb_gh > 0

    def points(mesh, k):
        b = rng.dirichlet(np.ones(3), size=k)
        return SurfacePoints(rng.integers(0, len(mesh.faces), k), b)

    for _ in range(50):
        img_p, img_q = points(y.mesh, N), points(x.mesh, N)
        ax, ay = SymmetricGMDS(ex, ey, P, Q).blocks(img_p, img_q)
        assert ranking_value(ax, ay, max(dx, dy), "log") >= lb
        gx, gy = SymmetricGMDS(sx, sy, P, Q).blocks(img_p, img_q)
        r = (gx - gy)[~np.eye(len(gx), dtype=bool)]
        assert 0.5 * np.sqrt(np.mean(r**2)) / max(x.diameter, y.diameter) >= lb_gh


def test_the_diameter_bound_is_not_a_bound_of_the_trimmed_value():
    """½|diam X − diam Y| bounds the GH distance, not the trimmed distortion: Y is X with one
    point moved far off, whose pairs are among the 20% the trimmed RMS sets aside."""
    t = np.linspace(0.0, 1.0, 20)
    dx = np.abs(t[:, None] - t[None, :])
    u = t.copy()
    u[-1] = 5.0
    dy = np.abs(u[:, None] - u[None, :])
    diam = max(dx.max(), dy.max())
    assert ranking_value(dx, dy, diam, "difference") == 0.0
    assert 0.5 * abs(dx.max() - dy.max()) / diam > 0.3


def _brute(values: np.ndarray, k: int):
    """Each row's k smallest off-diagonal entries, ties by column."""
    n = len(values)
    out = []
    for i in range(n):
        order = sorted((values[i, j], j) for j in range(n) if j != i)[:k]
        out.append([j for _, j in order])
    return out


def test_the_schedule_equals_brute_force_on_random_values():
    """Any lower bounds (here random fractions of the values, ties included) give brute
    force's neighbours, however many pairs each batch holds."""
    rng = np.random.default_rng(1)
    for trial in range(30):
        n = int(rng.integers(3, 12))
        v = np.round(rng.random((n, n)), 1 if trial % 3 == 0 else 6)   # coarse rounding: ties
        v = np.triu(v, 1) + np.triu(v, 1).T
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        key = [v[i, j] * rng.random() for i, j in pairs]
        k = int(rng.integers(1, n))
        calls = []

        def run(take, v=v, calls=calls):
            calls.extend(take)
            return [v[i, j] for i, j in take]

        _, rows, n_run, n_skipped = retrieval._schedule(
            pairs, lambda ij: [(ij[0], ij[1]), (ij[1], ij[0])], key, np.zeros(len(pairs)), k, n, run,
            known={}, batch=int(rng.integers(1, 4)))
        assert [[j for _, j in r] for r in rows.best] == _brute(v, k)
        assert n_run == len(calls) == len(set(calls)) and n_run + n_skipped == len(pairs)


def test_nearest_equals_brute_force_and_skips_the_unalike(prepared):
    metric, shapes = prepared
    names = list(shapes)
    for q in ("sphere", "strip"):
        others = [shapes[n] for n in names if n != q]
        kw = {"n_samples": N, "resolution": None}
        got = nearest(shapes[q], others, 1, metric, prune="bound", **kw)
        full = nearest(shapes[q], others, len(others), metric, prune="none", **kw)
        assert isinstance(got, NearestResult) and got.exact and full.skipped == 0
        assert [(n.index, n.distance) for n in got.neighbors] == [(n.index, n.distance) for n in full.neighbors[:1]]
        assert got.full_matches + got.skipped == len(others)
        assert all(full.values[j] >= got.bounds[j] for j in full.values)
        if metric == "geodesic" and q == "sphere":   # the strips are 60 times longer
            assert got.skipped >= 2


def test_knn_pairs_equals_brute_force_and_skips_pairs(prepared):
    """gh_matrix's pairs, scheduled: every shape's k nearest as in the full matrix."""
    metric, shapes = prepared
    items = list(shapes.values())
    g = gh_matrix(items, metric, n_samples=N, resolution=None, jobs=1)
    asked = []

    def run(take):
        asked.extend(take)
        return [(g.distance[i, j], g.relative[i, j], g.trimmed[i, j], None) for i, j in take]

    for k in (1, 2):
        asked.clear()
        out = knn_pairs(items, k, run, n_samples=N, prune="bound")
        assert isinstance(out, KnnPairs)
        assert out.neighbors.tolist() == _brute(g.trimmed, k)
        np.testing.assert_array_equal(out.distances, np.take_along_axis(g.trimmed, out.neighbors, 1))
        assert out.full_matches == len(asked) and out.full_matches + out.skipped == 10
        assert set(out.results) == set(asked) and np.all(out.bounds <= g.trimmed)
        if metric == "geodesic" and k == 1:   # the round shapes and the strips: 6 pairs apart
            assert out.skipped >= 4
    # pairs known before are not run again; forced pairs are run whatever their bound
    asked.clear()
    known = {(0, 1): (g.distance[0, 1], g.relative[0, 1], g.trimmed[0, 1], None)}
    out = knn_pairs(items, 1, run, n_samples=N, known=known, force=[(3, 4)], batch=3, prune="bound")
    assert (0, 1) not in asked and (3, 4) in asked and out.neighbors.tolist() == _brute(g.trimmed, 1)
    gh = knn_pairs(items, 1, run, n_samples=N, rank_by="gh", prune="bound")
    assert gh.neighbors.tolist() == _brute(g.relative, 1)


def test_gh_matrix_k_matches_only_the_pairs_it_needs(prepared, capsys):
    """``gh_matrix(k=1)``: every shape's nearest as in the full matrix, the matched entries
    equal to the full run's, the skipped ones NaN and counted, on the progress bar too."""
    metric, shapes = prepared
    items = list(shapes.values())
    full = gh_matrix(items, metric, n_samples=N, resolution=None, jobs=1)
    capsys.readouterr()
    part = gh_matrix(items, metric, n_samples=N, resolution=None, jobs=1, k=1, progress=True)
    bar = capsys.readouterr().err
    assert "GH pairs (k = 1)" in bar and f"skipped={part.skipped}" in bar
    assert full.skipped == 0
    off = ~np.eye(len(items), dtype=bool)
    matched = ~np.isnan(part.trimmed) & off
    assert int(np.triu(~matched & off, 1).sum()) == part.skipped
    np.testing.assert_array_equal(part.trimmed[matched], full.trimmed[matched])
    np.testing.assert_array_equal(part.distance[matched], full.distance[matched])
    nearest = np.where(off, np.nan_to_num(part.trimmed, nan=np.inf), np.inf).argmin(axis=1)
    assert nearest.tolist() == [row[0] for row in _brute(full.trimmed, 1)]
    if metric == "geodesic":
        assert part.skipped >= 4


def test_profile_prune_is_flagged_as_not_exact(prepared):
    metric, shapes = prepared
    others = [shapes[n] for n in ("ellipsoid", "small", "strip")]
    r = nearest(shapes["sphere"], others, 1, metric, n_samples=N, resolution=None, prune="profile", slack=0.5)
    assert not r.exact and r.full_matches >= 1
    assert np.all(r.gaps >= 0) and r.gaps[0] == profile_gap(shape_bound(shapes["sphere"], N), shape_bound(others[0], N))


def test_errors(prepared):
    metric, shapes = prepared
    s = shapes["sphere"]
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="k must be"):
            nearest(s, [shapes["ellipsoid"]], bad, metric, n_samples=N)
    with pytest.raises(ValueError, match="prune"):
        nearest(s, [shapes["ellipsoid"]], 1, metric, n_samples=N, prune="fast")
    with pytest.raises(ValueError, match="slack"):
        nearest(s, [shapes["ellipsoid"]], 1, metric, n_samples=N, prune="profile", slack=0)
    with pytest.raises(ValueError, match="rank_by"):
        nearest(s, [shapes["ellipsoid"]], 1, metric, n_samples=N, rank_by="median")
    with pytest.raises(ValueError, match="empty"):
        nearest(s, [], 1, metric, n_samples=N)
    with pytest.raises(ValueError, match="n_samples"):
        shape_bound(s, 10_000)
    with pytest.raises(TypeError, match="ShapeMetric"):
        shape_bound(icosphere(1))
    with pytest.raises(ValueError, match="samples"):
        pair_bound(shape_bound(s, N), shape_bound(s, N + 1))


def test_store_keeps_the_invariants_and_reads_only_what_it_matches(tmp_path, shape_files, monkeypatch):
    files = list(shape_files.values())
    store = ShapeStore(tmp_path / "s")
    store.shapes(files, "geodesic", resolution=None)
    kw = {"n_samples": N, "resolution": None, "prune": "bound"}
    first = nearest(shape_files["sphere"], store, 1, "geodesic", **kw)
    name = f"{retrieval.BOUND_NAME}:n_samples={N}:seed=0"
    for e in store.entries():   # kept for every entry but the query's
        kept = store.extra(e.key, name)
        if e.path == shape_files["sphere"]:
            assert kept is None
            continue
        b = ShapeBound.from_arrays(kept)
        assert b.n_samples == N and len(b.distances) == N * (N - 1) // 2 and np.all(np.diff(b.distances) >= 0)
    reads = []
    real = retrieval._entry_shape
    monkeypatch.setattr(retrieval, "_entry_shape", lambda store, e, *a: reads.append(e.path) or real(store, e, *a))
    again = nearest(shape_files["sphere"], ShapeStore(tmp_path / "s"), 1, "geodesic", **kw)
    assert [(n.name, n.distance) for n in again.neighbors] == [(n.name, n.distance) for n in first.neighbors]
    # the query's own entry is read (not computed), the others only when matched
    assert len(reads) == 1 + again.full_matches and again.skipped >= 2
    assert first.neighbors[0].name.endswith("ellipsoid.off") and len(first.neighbors) == 1
    assert all(not n.name.endswith("sphere.off") for n in first.neighbors)


def _search(capsys, *args):
    rc = main(["search", *args])
    out, err = capsys.readouterr()
    return rc, out, err


def test_cli_search_json(tmp_path, shape_files, capsys):
    store = str(tmp_path / "s")
    files = list(shape_files.values())
    opts = ["--metric", "geodesic", "--resolution", "400"]
    assert main(["index", *files, "--store", store, "-q", *opts]) == 0
    opts += ["--samples", str(N)]
    capsys.readouterr()
    for k in (1, 3):
        rc, out, _ = _search(capsys, shape_files["sphere"], "--store", store, "-k", str(k), "--json", "--prune",
                             "bound", *opts)
        assert rc == 0
        got = json.loads(out)
        assert {"neighbors", "full_matches", "skipped"} <= set(got)
        assert [set(n) for n in got["neighbors"]] == [{"file", "distance"}] * k
        d = [n["distance"] for n in got["neighbors"]]
        assert d == sorted(d) and got["full_matches"] + got["skipped"] == 4
        assert got["neighbors"][0]["file"].endswith("ellipsoid.off") and got["exact"] is True
        assert got["skipped"] >= (2 if k == 1 else 0)   # the strips are 60 times longer than the sphere
        rc, out, _ = _search(capsys, shape_files["sphere"], "--store", store, "-k", str(k), "--json", "--prune",
                             "none", *opts)
        brute = json.loads(out)
        assert brute["neighbors"] == got["neighbors"] and brute["skipped"] == 0 and brute["full_matches"] == 4
    rc, out, _ = _search(capsys, shape_files["sphere"], "--store", store, "-k", "1", "--json", *opts)
    default = json.loads(out)   # the profile gap: not exact, the same nearest here
    assert default["exact"] is False and default["neighbors"] == brute["neighbors"][:1]
    rc, out, _ = _search(capsys, shape_files["sphere"], "--store", store, "-k", "1", "-q", *opts)
    assert rc == 0 and "ellipsoid.off" in out and "skipped" in out


def test_cli_search_errors(tmp_path, shape_files, capsys):
    q = shape_files["sphere"]
    rc, _, err = _search(capsys, q, "--store", str(tmp_path / "none"))
    assert rc == 2 and err.count("\n") == 1 and "no shape store" in err and not (tmp_path / "none").exists()
    ShapeStore(tmp_path / "empty")
    rc, _, err = _search(capsys, q, "--store", str(tmp_path / "empty"))
    assert rc == 2 and err.count("\n") == 1 and "has no shapes" in err
    store = str(tmp_path / "s")
    assert main(["index", shape_files["ellipsoid"], "--store", store, "-q", "--metric", "geodesic"]) == 0
    bad = tmp_path / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n")
    for query in (str(bad), str(tmp_path / "missing.off")):
        rc, _, err = _search(capsys, query, "--store", store, "--metric", "geodesic")
        assert rc == 2 and err.count("\n") == 1 and err.startswith("gromov: error:"), err
    with pytest.raises(SystemExit) as e:
        main(["search", q, "--store", store, "-k", "0"])
    assert e.value.code == 2 and "positive integer" in capsys.readouterr().err


def test_cli_slack_default_is_the_library_default():
    from gromov.cli import build_parser

    args = build_parser().parse_args(["search", "q.off", "--store", "s"])
    assert args.slack == retrieval.PROFILE_SLACK and args.prune == "profile" and args.k == 5
    assert args.triangle_slack == retrieval.TRIANGLE_SLACK


def test_store_extra_arrays_round_trip(tmp_path):
    store = ShapeStore(tmp_path)
    assert store.extra("key", "name") is None
    store.put_extra("key", "name", {"a": np.arange(3.0), "b": np.float64(2.0)})
    store.put_extra("key", "name", {"a": np.arange(4.0)})   # replaced
    got = ShapeStore(tmp_path).extra("key", "name")
    assert set(got) == {"a"} and got["a"].tolist() == [0.0, 1.0, 2.0, 3.0]


def test_kept_extra_is_read_back_or_computed_and_kept(tmp_path):
    """Nothing kept: computed and kept; kept: read back, not computed; kept otherwise (the
    reader raises): computed again and replaced."""
    store = ShapeStore(tmp_path)
    calls = []

    def compute():
        calls.append(1)
        return np.arange(3.0)

    def kept():
        return retrieval._kept_extra(store, "key", "name", lambda got: got["v"], compute, lambda v: {"v": v})

    np.testing.assert_array_equal(kept(), [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(kept(), [0.0, 1.0, 2.0])
    assert len(calls) == 1
    store.put_extra("key", "name", {"other": np.zeros(2)})   # written otherwise
    np.testing.assert_array_equal(kept(), [0.0, 1.0, 2.0])
    assert len(calls) == 2 and set(store.extra("key", "name")) == {"v"}


def test_triangle_estimates_are_the_largest_differences_through_known_pairs():
    """Points on a line: |d(a, m) - d(m, b)| is d(a, b) for m outside [a, b], less inside."""
    x = {"a": 0.0, "b": 1.0, "m": 3.0, "c": 0.5}
    t = retrieval._Triangle(0.5)
    assert t.estimate("a", "b") == 0.0   # nothing known
    t.add("a", "m", 3.0)
    t.add("b", "m", 2.0)   # a - m - b: |3 - 2| = d(a, b)
    assert t.estimate("a", "b") == 0.5 * abs(x["a"] - x["b"])
    t.add("c", "a", 0.5)   # pivots a (for c - m) and, later, m (for c - b)
    assert t.estimate("c", "m") == 0.5 * abs(0.5 - 3.0)
    t.add("c", "m", 2.5)
    assert t.estimate("b", "c") == 0.5 * abs(2.5 - 2.0) == 0.5 * abs(x["b"] - x["c"])
    t.add("a", "b", float("nan"))   # a NaN value tells nothing
    assert t.estimate("a", "b") == 0.5


def test_the_schedule_with_triangle_estimates_equals_brute_force_on_a_metric():
    """Where the values are a metric, the triangle estimate with slack 1 is a lower bound: every
    row's k nearest are brute force's; clustered points let it skip pairs."""
    rng = np.random.default_rng(3)
    skipped = 0
    for trial in range(20):
        n = int(rng.integers(6, 16))
        centres = rng.normal(size=(3, 2)) * 10
        pts = centres[rng.integers(0, 3, n)] + rng.normal(size=(n, 2))
        v = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
        k = int(rng.integers(1, 4))
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        _, rows, n_run, n_skip = retrieval._schedule(
            pairs, lambda ij: [(ij[0], ij[1]), (ij[1], ij[0])], np.zeros(len(pairs)), np.zeros(len(pairs)), k, n,
            lambda take, v=v: [v[i, j] for i, j in take], known={}, batch=int(rng.integers(1, 3)),
            triangle=retrieval._Triangle(1.0), nodes=lambda ij: ij)
        assert [[j for _, j in r] for r in rows.best] == _brute(v, k)
        assert n_run + n_skip == len(pairs)
        skipped += n_skip
        # one query at a time, the values between the others known
        q, others = 0, list(range(1, n))
        tri = retrieval._Triangle(1.0)
        for a in others:
            for b in others:
                if a < b:
                    tri.add(a, b, v[a, b])
        _, rows, n_run, n_skip = retrieval._schedule(
            [(0, j) for j in others], lambda ij: [(0, ij[1])], np.zeros(n - 1), np.zeros(n - 1), k, 1,
            lambda take, v=v: [v[0, j] for _, j in take], known={}, triangle=tri, nodes=lambda ij: (q, ij[1]))
        assert [j for _, j in rows.best[0]] == _brute(v, k)[0]
        skipped += n_skip
    assert skipped > 100


def test_nearest_reads_the_pairs_recorded_between_candidates(tmp_path, shape_files):
    """A store that holds the candidates' pairs (gh_matrix with it) gives the triangle estimates
    their pivots; the query's own recorded pairs are not read: it is matched."""
    files = list(shape_files.values())
    store = ShapeStore(tmp_path / "s")
    g = gh_matrix(files, "geodesic", n_samples=N, resolution=None, store=store)
    gh_matrix(files, "geodesic", n_samples=N, resolution=None, store=store, seed=1)   # other options: not read
    assert len(store.pairs()) == 20
    kw = {"n_samples": N, "resolution": None}
    q = shape_files["small"]   # a small sphere: the strips are ruled out through the spheres
    rest = [f for f in files if f != q]
    opts = retrieval._options(N, 0, retrieval.RANK_TAU_SCALE, retrieval.RANK_RESIDUAL, {}, "test")
    cands, _, recorded = retrieval._candidates(q, store, "geodesic",
                                               {"resolution": None, "metric_options": None}, N, 0,
                                               retrieval.RANK_TAU_SCALE)
    got = recorded(opts)
    at = [files.index(c.name) for c in cands]
    assert len(got) == len(rest) * (len(rest) - 1) // 2   # every pair between candidates, none with the query
    for (i, j), v in got.items():
        assert v[2] == g.trimmed[at[i], at[j]]
    with_tri = nearest(q, store, 1, "geodesic", triangle_slack=1.0, **kw)
    without = nearest(q, store, 1, "geodesic", triangle_slack=0, **kw)
    assert 1 <= with_tri.full_matches < without.full_matches
    assert with_tri.known_pairs == len(got) == 6 and without.known_pairs == 0
    assert with_tri.to_dict()["known_pairs"] == 6
    assert with_tri.neighbors[0].name == without.neighbors[0].name
    with pytest.raises(ValueError, match="known"):
        nearest(shape_files["sphere"], [shape_files["ellipsoid"]], 1, "geodesic", known={(0, 3): 1.0}, **kw)
    with pytest.raises(ValueError, match="triangle_slack"):
        nearest(shape_files["sphere"], [shape_files["ellipsoid"]], 1, "geodesic", triangle_slack=-1, **kw)


def test_cli_pairwise_k_matches_only_the_nearest_pairs(tmp_path, shape_files, capsys):
    """``gromov pairwise -k 1``: every shape's nearest as all pairs give it, the pairs not matched
    empty (null in the JSON) and not recorded in the store, which a search then reads."""
    files = list(shape_files.values())
    opts = ["--metric", "geodesic", "--resolution", "400", "--samples", str(N), "--json"]
    assert main(["pairwise", *files, *opts]) == 0
    full = json.loads(capsys.readouterr().out)
    store = str(tmp_path / "s")
    labels = ["round", "round", "round", "strip", "strip"]   # sphere, ellipsoid, small, strip, rolled
    assert main(["pairwise", *files, *opts, "-k", "1", "--store", store, "--labels", ",".join(labels)]) == 0
    part = json.loads(capsys.readouterr().out)
    assert part["nearest"] == full["nearest"] and part["k"] == 1
    assert part["pairs_matched"] + part["pairs_skipped"] == 10 and part["pairs_skipped"] >= 1
    t = np.array(part["relative_trimmed_distance"], dtype=float)   # null -> nan
    matched = ~np.isnan(t[np.triu_indices(5, 1)])
    assert int(matched.sum()) == part["pairs_matched"]
    np.testing.assert_array_equal(t[~np.isnan(t)], np.array(full["relative_trimmed_distance"])[~np.isnan(t)])
    assert part["eer"] is None and part["nn_accuracy"] == 1.0
    assert len(ShapeStore(store).pairs()) == part["pairs_matched"]
    assert main(["pairwise", *files, "--metric", "geodesic", "--resolution", "400", "--samples", str(N),
                 "-k", "1", "-q"]) == 0
    out = capsys.readouterr().out
    assert f"{part['pairs_matched']} of 10 pairs matched (each shape's 1 nearest)" in out
    for extra, message in ((["--mds", str(tmp_path / "m.png")], "--mds needs every pair"),
                           (["--dask", "2"], "-k is not available with --dask")):
        assert main(["pairwise", *files, "-k", "1", *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
