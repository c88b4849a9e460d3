"""The spectral signature (Shape-DNA), the combined ranking and the two-stage matrix."""

import json
import os

import numpy as np
import pytest

import gromov
from gromov import ShapeMetric
from gromov.cli import main
from gromov.experiments.pairwise import gh_matrix
from gromov.mesh import Mesh
from gromov.shapes import grid, icosphere, rolled_grid, torus
from gromov.spectrum import (SIGNATURE_TAUS, combined, heat_signature, shape_dna, signature_distortion,
                             spectral_distances, spectrum)


def test_the_sphere_spectrum_over_weyl():
    # unit sphere: lambda = l (l + 1) with multiplicity 2l + 1, area 4 pi, so DNA_i = lambda_i / i
    s = ShapeMetric(icosphere(4), "diffusion", resolution=None)
    dna = spectrum(s, 8)
    exact = np.array([2, 2, 2, 6, 6, 6, 6, 6]) / np.arange(1, 9)
    np.testing.assert_allclose(dna, exact, rtol=0.01)
    # a point cloud of the same vertices: the robust Laplacian's spectrum
    from gromov.mesh import PointCloud

    cloud = ShapeMetric(PointCloud(icosphere(4).vertices), "diffusion", resolution=None)
    np.testing.assert_allclose(spectrum(cloud, 8), exact, rtol=0.02)


def _moved(m: Mesh, seed: int, scale: float, shift: float = 0.0) -> tuple[Mesh, np.ndarray]:
    """``(copy, perm)``: ``m`` scaled, rotated, shifted and with its vertices in another order
    (copy vertex i is vertex ``perm[i]`` of ``m``)."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(m.n_vertices)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Mesh(scale * m.vertices[perm] @ q.T + shift, np.argsort(perm)[m.faces]), perm


def _bent_torus() -> Mesh:
    """A torus bent out of its symmetries (no eigenspace of several dimensions)."""
    t0 = torus(40, 20)
    x, y, z = t0.vertices.T
    return Mesh(np.c_[x * (1.0 + 0.2 * y), 0.7 * y + 0.1 * x**2, z * (1.0 + 0.1 * x)], t0.faces)


def test_the_signature_ignores_scale_rotation_and_vertex_order():
    m = torus(40, 20)
    moved, _ = _moved(m, 1, 3.0, 5.0)
    a = spectrum(ShapeMetric(m, "diffusion", resolution=None))
    b = spectrum(ShapeMetric(moved, "diffusion", resolution=None))
    np.testing.assert_allclose(b, a, rtol=1e-6)
    # an elongated torus is another shape
    c = spectrum(ShapeMetric(Mesh(m.vertices * [2.0, 1.0, 1.0], m.faces), "diffusion", resolution=None))
    assert np.linalg.norm(c - a) > 100 * np.linalg.norm(b - a)


def test_shape_dna_skips_one_zero_per_component_and_pads():
    lam = np.array([0.0, 0.0, 4 * np.pi, 8 * np.pi])   # two components, area 1
    np.testing.assert_allclose(shape_dna(lam, 1.0, 4), [1.0, 1.0, np.nan, np.nan])
    with pytest.raises(ValueError, match="area must be positive"):
        shape_dna(lam, 0.0)


def test_combined_is_a_weighted_geometric_mean_pair_by_pair():
    S = np.array([[0.0, 4.0, 1.0], [4.0, 0.0, 9.0], [1.0, 9.0, 0.0]])
    G = np.array([[0.0, 0.25, np.nan], [0.25, 0.0, 1.0], [np.nan, 1.0, 0.0]])
    C = combined(S, G, 0.5)
    np.testing.assert_allclose(C[0, 1], 1.0)
    np.testing.assert_allclose(C[1, 2], 3.0)
    assert np.isnan(C[0, 2]) and np.all(np.diag(C) == 0)
    # units of either factor scale every value alike: the order is kept
    off = ~np.eye(3, dtype=bool) & ~np.isnan(G)
    np.testing.assert_allclose(combined(7.0 * S, 0.1 * G, 0.3)[off], 7.0**0.3 * 0.1**0.7 * combined(S, G, 0.3)[off])
    np.testing.assert_array_equal(combined(S, G, 0.0)[off], G[off])
    with pytest.raises(ValueError, match="weight"):
        combined(S, G, 1.5)


def test_heat_signature_of_the_sphere_and_its_invariances():
    # unit sphere: k_t(x, x) = sum_l (2l + 1) e^{-l(l+1) t} / (4 pi) at every point (Sun et al.
    # 2009; the addition theorem of spherical harmonics), here truncated at the eigenpairs kept
    sphere = ShapeMetric(icosphere(4), "euclidean", resolution=None)
    h = heat_signature(sphere)
    area = sphere.mesh.area
    ell = np.arange(12)   # 144 eigenpairs: l = 0..11 (the 150 kept reach no further than l = 12)
    t = SIGNATURE_TAUS * area
    exact = np.log(area * ((2 * ell + 1)[:, None] * np.exp(-np.outer(ell * (ell + 1), t))).sum(0) / area)
    assert h.shape == (sphere.mesh.n_vertices, len(SIGNATURE_TAUS)) and not h.flags.writeable
    np.testing.assert_allclose(np.median(h, axis=0), exact, atol=0.03)
    assert np.ptp(h, axis=0).max() < 0.05   # the same at every point
    # scaling, a rotation and the vertex order change nothing, vertex by vertex (on a shape
    # without symmetries: no eigenspace of several dimensions for the truncation to cut through)
    m = _bent_torus()
    moved, perm = _moved(m, 2, 0.3, -2.0)
    a = heat_signature(ShapeMetric(m, "euclidean", resolution=None))
    b = heat_signature(ShapeMetric(moved, "euclidean", resolution=None))
    np.testing.assert_allclose(b, a[perm], atol=1e-6)
    assert np.ptp(a, axis=0).min() > 0.05   # while it tells its points apart


def test_signature_distortion_is_the_trimmed_rms_of_each_pair_rms():
    x = np.zeros((10, 2))
    y = np.repeat(np.arange(10.0)[:, None], 2, axis=1)   # pair i differs by i at both times
    y[3] = [3.0, -5.0]                                   # RMS over the times: sqrt(17)
    r = np.sort(np.r_[np.arange(10.0)[[0, 1, 2]], np.sqrt(17.0), np.arange(4.0, 10.0)])
    assert signature_distortion(x, y) == pytest.approx(np.sqrt(np.mean(r[:8] ** 2)), rel=1e-12)
    assert signature_distortion(x, y, keep=1.0) == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-12)
    assert signature_distortion(y, y) == 0.0
    with pytest.raises(ValueError, match="one shape"):
        signature_distortion(x, y[:5])


def test_combined_with_the_signature_distortion():
    S = np.array([[0.0, 4.0], [4.0, 0.0]])
    G = np.array([[0.0, 0.25], [0.25, 0.0]])
    H = np.array([[0.0, 9.0], [9.0, 0.0]])
    C = combined(S, G, 0.5, signature=H, signature_weight=0.5)
    assert C[0, 1] == pytest.approx(3.0) and C[0, 0] == 0.0    # (4^0.5 0.25^0.5)^0.5 9^0.5
    assert combined(S, G, 0.5, signature=H, signature_weight=0.0)[0, 1] == pytest.approx(1.0)
    assert np.isnan(combined(S, G, signature=np.array([[0.0, np.nan], [np.nan, 0.0]]))[0, 1])
    with pytest.raises(ValueError, match="signature_weight"):
        combined(S, G, signature=H, signature_weight=-0.1)


def test_the_signature_distortion_of_a_shape_against_its_moved_copy_is_near_zero():
    from gromov.gh import _match

    m = _bent_torus()
    moved, _ = _moved(m, 0, 2.0)
    opts = dict(n_samples=15, resolution=None, orientation="ignore")
    same = _match(m, moved, "diffusion", signature=True, **opts)
    other = _match(m, Mesh(m.vertices * [1.8, 1.0, 0.6], m.faces), "diffusion", signature=True, **opts)
    assert 0.0 <= same.signature_distortion < 1e-6 and other.signature_distortion > 0.05
    plain = _match(m, moved, "diffusion", **opts)
    assert np.isnan(plain.signature_distortion) and plain.distance == same.distance


def _sheets():
    return [grid(21, 11), rolled_grid(21, 11), grid(31, 11, width=2 * np.pi), torus(30, 12), grid(15, 15)]


def _sheet_files(folder) -> list[str]:
    """:func:`_sheets` saved as OFF files in ``folder``."""
    files = []
    for i, m in enumerate(_sheets()):
        files.append(str(folder / f"s{i}.off"))
        gromov.save(m, files[-1])
    return files


def test_two_stage_matrix_matches_only_the_candidates_and_agrees_with_the_full_one():
    shapes = [ShapeMetric(m, "geodesic", resolution=None) for m in _sheets()]
    opts = dict(n_samples=15, jobs=1)
    full = gh_matrix(shapes, "geodesic", spectral=True, **opts)
    assert full.skipped == 0 and np.allclose(full.spectral, full.spectral.T)
    S = spectral_distances(shapes)
    np.testing.assert_array_equal(full.spectral, S)
    n = len(shapes)
    expect = set()
    for i in range(n):
        others = [j for j in np.argsort(S[i], kind="stable") if j != i]
        expect.add(tuple(sorted((i, int(others[0])))))
    two = gh_matrix(shapes, "geodesic", candidates=1, **opts)
    matched = {(i, j) for i in range(n) for j in range(i + 1, n) if not np.isnan(two.trimmed[i, j])}
    assert matched == expect and two.skipped == n * (n - 1) // 2 - len(expect)
    for i, j in matched:
        assert two.trimmed[i, j] == full.trimmed[i, j] and two.relative[i, j] == full.relative[i, j]
    assert np.isnan(two.combined[[i for i, _ in matched][0], :]).sum() >= 1
    every = gh_matrix(shapes, "geodesic", candidates=n - 1, **opts)
    np.testing.assert_array_equal(every.trimmed, full.trimmed)
    with pytest.raises(ValueError, match="candidates"):
        gh_matrix(shapes, "geodesic", candidates=0, **opts)
    with pytest.raises(ValueError, match="at least k"):
        gh_matrix(shapes, "geodesic", candidates=1, k=2, **opts)


def test_pairwise_ranks_by_the_combined_distance(tmp_path, capsys):
    files = _sheet_files(tmp_path)[:4]
    base = ["pairwise", *files, "--metric", "geodesic", "--samples", "15", "--jobs", "1"]
    assert main([*base, "--rank-by", "combined", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    C, S, G, H = (np.array(res[k]) for k in ("combined_distance", "spectral_distance", "relative_trimmed_distance",
                                             "signature_distortion"))
    np.testing.assert_allclose(C, combined(S, G, signature=H))
    off = ~np.eye(len(C), dtype=bool)
    assert np.all(H[off] > 0) and not np.allclose(C, combined(S, G))
    assert res["ranked_by"] == "combined"
    assert main([*base, "--candidates", "1", "--json"]) == 0
    two = json.loads(capsys.readouterr().out)
    assert two["candidates"] == 1 and two["pairs_skipped"] >= 2
    assert main([*base, "--candidates", "1", "-k", "2"]) == 2
    assert "must be at least -k" in capsys.readouterr().err
    # labels: the EER needs every pair; a search whose candidates met every pair has them all
    lab = ["--labels", "a,a,b,b", "--json"]
    assert main([*base, *lab]) == 0
    whole = json.loads(capsys.readouterr().out)
    assert main([*base, *lab, "--candidates", "3"]) == 0
    met = json.loads(capsys.readouterr().out)
    assert met["pairs_skipped"] == 0 and whole["eer"] is not None and met["eer"] == whole["eer"]
    assert main([*base, *lab, "--candidates", "1"]) == 0
    assert json.loads(capsys.readouterr().out)["eer"] is None


def test_nearest_ranks_by_the_combined_distance_and_searches_in_two_stages():
    from gromov.retrieval import nearest

    shapes = [ShapeMetric(m, "geodesic", resolution=None) for m in _sheets()]
    full = gh_matrix(shapes, "geodesic", n_samples=15, jobs=1, spectral=True)
    r = nearest(shapes[0], shapes[1:], k=4, metric="geodesic", n_samples=15, rank_by="combined", prune="none")
    assert r.rank_by == "combined" and r.full_matches == 4
    for nb in r.neighbors:
        assert nb.distance == pytest.approx(full.combined[0, nb.index + 1], rel=1e-12)
    assert [nb.distance for nb in r.neighbors] == sorted(nb.distance for nb in r.neighbors)
    # exact pruning stays exact: the same neighbours as matching every candidate
    # (the signature distortion has no lower bound: nothing is pruned, the result is exact)
    b = nearest(shapes[0], shapes[1:], k=2, metric="geodesic", n_samples=15, rank_by="combined", prune="bound")
    assert [nb.index for nb in b.neighbors] == [nb.index for nb in r.neighbors[:2]]
    assert b.full_matches == 4 and b.exact and np.isnan(b.bounds).all()
    p = nearest(shapes[0], shapes[1:], k=2, metric="geodesic", n_samples=15, rank_by="combined")
    assert p.full_matches == 4 and p.exact and [nb.index for nb in p.neighbors] == [nb.index for nb in b.neighbors]
    two = nearest(shapes[0], shapes[1:], k=1, metric="geodesic", n_samples=15, candidates=2)
    first = np.argsort(full.spectral[0, 1:], kind="stable")[:2]
    assert two.full_matches == 2 and two.skipped == 2 and not two.exact
    assert set(two.values) == set(first.tolist())


def test_search_a_store_in_two_stages(tmp_path, capsys):
    from gromov.retrieval import SPECTRUM_NAME
    from gromov.spectrum import SPECTRUM_K
    from gromov.store import ShapeStore

    files = _sheet_files(tmp_path)
    store = tmp_path / "store"
    opts = ["--metric", "geodesic", "--resolution", "1000"]
    assert main(["index", *files, "--store", str(store), *opts, "-q"]) == 0
    capsys.readouterr()
    argv = ["search", files[0], "--store", str(store), *opts, "--samples", "15", "-k", "1", "--candidates", "2", "--rank-by",
            "combined", "--json", "-q"]
    assert main(argv) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["full_matches"] == 2 and res["skipped"] == 2 and res["ranked_by"] == "combined"
    st = ShapeStore(store)
    kept = [e for e in st.entries() if st.extra(e.key, f"{SPECTRUM_NAME}:k={SPECTRUM_K}") is not None]
    assert len(kept) == 4   # every candidate's signature kept for the next search
    # and no candidate's bound invariants: the first stage needs only the signatures
    assert not any(st.extra(e.key, name) is not None for e in st.entries()
                   for name in ("retrieval-bound-1:n_samples=15:seed=0",))
    # the heat kernel signatures of the query and of the candidates matched, kept too
    from gromov.retrieval import heat_signature_name
    from gromov.spectrum import SIGNATURE_EIGENPAIRS

    assert heat_signature_name().startswith(f"heat-signature-1:k={SIGNATURE_EIGENPAIRS}:tau=0.00473")
    heat = {e.path: st.extra(e.key, heat_signature_name()) for e in st.entries()}
    assert sum(h is not None for h in heat.values()) == 3 and heat[os.path.abspath(files[0])] is not None
    st.close()
    import gromov.spectrum as spectrum_module

    real = spectrum_module._eigenpairs
    def eigenpairs(shape, k, what):   # (the query's Shape-DNA is computed: it is not kept)
        if k == SIGNATURE_EIGENPAIRS:
            pytest.fail("a kept heat kernel signature was computed again")
        return real(shape, k, what)

    spectrum_module._eigenpairs = eigenpairs
    try:
        assert main(argv) == 0
    finally:
        spectrum_module._eigenpairs = real
    assert json.loads(capsys.readouterr().out)["neighbors"] == res["neighbors"]


def test_a_descent_round_adds_the_neighbours_of_the_neighbours():
    from gromov.experiments.pairwise import _descent_pairs

    # points on a line, ranked by their gaps; only neighbours along it matched
    x = np.array([0.0, 1.0, 2.1, 3.3, 4.6, 6.0])
    R = np.abs(x[:, None] - x[None])
    n = len(x)
    matched = np.eye(n, dtype=bool)
    for i in range(n - 1):
        matched[i, i + 1] = matched[i + 1, i] = True
    # m = 1: each point's nearest is the one before it (the gaps grow), and that one's nearest
    # the one before it again
    assert _descent_pairs(R, matched, 1) == [(0, 2), (1, 3), (2, 4), (3, 5)]
    # m = 2: every point two steps along, and nothing already matched
    got = _descent_pairs(R, matched, 2)
    assert got == [(0, 2), (1, 3), (2, 4), (3, 5)]
    matched[0, 2] = matched[2, 0] = True
    assert (0, 2) not in _descent_pairs(R, matched, 2)


def test_two_stage_matrix_with_k_adds_the_descent_and_keeps_the_values():
    shapes = [ShapeMetric(m, "geodesic", resolution=None) for m in _sheets()]
    opts = dict(n_samples=15, jobs=1)
    full = gh_matrix(shapes, "geodesic", spectral=True, **opts)
    first = gh_matrix(shapes, "geodesic", candidates=1, **opts)
    two = gh_matrix(shapes, "geodesic", candidates=1, k=1, rank_by="combined", **opts)
    n = len(shapes)
    was = ~np.isnan(first.trimmed)
    now = ~np.isnan(two.trimmed)
    assert (now >= was).all() and now.sum() > was.sum()   # the first stage, and more
    assert two.skipped == n * (n - 1) // 2 - (now.sum() - n) // 2
    np.testing.assert_array_equal(two.trimmed[now], full.trimmed[now])
    with pytest.raises(ValueError, match="rank_by"):
        gh_matrix(shapes, "geodesic", candidates=1, k=1, rank_by="distance", **opts)


def test_a_descent_run_again_from_its_store_matches_nothing(tmp_path, monkeypatch):
    from gromov.experiments import pairwise

    files = _sheet_files(tmp_path)
    opts = dict(n_samples=15, resolution=None, jobs=1, candidates=1, k=1, rank_by="combined")
    first = gh_matrix(files, "geodesic", store=tmp_path / "store", **opts)
    # the pairs it matched are closed under the descent: a second run reads them all and
    # matches none
    monkeypatch.setattr(pairwise, "_match", lambda *a, **k: pytest.fail("a pair was matched again"))
    again = gh_matrix(files, "geodesic", store=tmp_path / "store", **opts)
    np.testing.assert_array_equal(again.trimmed, first.trimmed)
    assert again.skipped == first.skipped


def test_a_query_descent_round_reaches_the_neighbours_of_its_nearest():
    from gromov.retrieval import _descent_candidates, _nearest_lists

    # a collection on a line, every value known; the query at 0.2 has found 0 and 4
    x = np.array([0.0, 1.0, 2.1, 3.3, 4.6, 6.0])
    graph = _nearest_lists(np.abs(x[:, None] - x[None]) + np.diag(np.full(len(x), np.nan)), 2)
    assert [g.tolist() for g in graph] == [[1, 2], [0, 2], [1, 3], [2, 4], [3, 5], [4, 3]]
    values = {0: 0.2, 4: 4.4}
    # the query's two nearest found are 0 and 4: their nearest, less those matched
    assert _descent_candidates(values, graph, 2).tolist() == [1, 2, 3, 5]
    assert _descent_candidates(values, graph, 1).tolist() == [1, 2]
    # unknown values give no neighbours
    R = np.full((3, 3), np.nan)
    R[0, 1] = R[1, 0] = 1.0
    assert [g.tolist() for g in _nearest_lists(R, 2)] == [[1], [0], []]


def test_a_two_stage_search_descends_over_the_known_values():
    from gromov.retrieval import nearest

    shapes = [ShapeMetric(m, "geodesic", resolution=None) for m in _sheets()]
    full = gh_matrix(shapes, "geodesic", n_samples=15, jobs=1, spectral=True)
    C = full.combined[1:, 1:]
    known = {(i, j): float(C[i, j]) for i in range(4) for j in range(i + 1, 4)}
    opts = dict(k=1, metric="geodesic", n_samples=15, rank_by="combined", candidates=1)
    first = nearest(shapes[0], shapes[1:], **opts)
    assert first.full_matches == 1 and first.known_pairs == 0   # nothing known: the first stage alone
    two = nearest(shapes[0], shapes[1:], known=known, **opts)
    assert two.known_pairs == 6 and two.full_matches > 1
    nearest_first = next(iter(first.values))
    for j in np.argsort(np.where(np.arange(4) == nearest_first, np.inf, C[nearest_first]), kind="stable")[:2]:
        assert j in two.values   # the first one's two nearest (m = ceil(1.5 k) = 2) matched
    for j, v in two.values.items():
        assert v == pytest.approx(full.combined[0, j + 1], rel=1e-12)
    assert two.neighbors[0].distance == min(two.values.values())
    assert two.skipped == 4 - two.full_matches


def test_search_a_store_descends_over_the_pairs_pairwise_recorded(tmp_path, capsys):
    files = _sheet_files(tmp_path)
    store = str(tmp_path / "store")
    opts = ["--metric", "geodesic", "--resolution", "1000", "--samples", "15", "--rank-by", "combined"]
    assert main(["pairwise", *files, "--store", store, *opts, "--candidates", "1", "-k", "1", "-q"]) == 0
    capsys.readouterr()
    assert main(["search", files[0], "--store", store, *opts, "-k", "1", "--candidates", "1", "--json", "-q"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["known_pairs"] > 0 and res["full_matches"] > 1 and res["ranked_by"] == "combined"
    assert res["full_matches"] + res["skipped"] == 4


def _plane_distances(rng) -> np.ndarray:
    """Distances between 14 random points of the plane (the first draws of ``rng``)."""
    x = rng.normal(size=(14, 2))
    return np.linalg.norm(x[:, None] - x[None], axis=-1)


def _descent_on_points(monkeypatch, known: dict, shared: bool = False) -> tuple[np.ndarray, list]:
    """:func:`_descent_runs` over 14 random points of the plane ranked by their distances, the first
    stage each point's nearest by a noisy copy of them, ``known`` pairs given before; ``shared``:
    the known pairs counted as searched too. Returns the pairs searched and the pairs run."""
    from gromov.experiments import pairwise

    rng = np.random.default_rng(3)
    D = _plane_distances(rng)
    noisy = D + rng.uniform(0.0, 1.5, size=D.shape)
    R = np.full(D.shape, np.nan)
    run = []

    def fake_run(prepared, todo, *args, **kwargs):
        run.extend(todo)
        return [(D[ij],) * 3 + (None,) for ij in todo]

    def put(ij, value):
        R[ij] = R[ij[::-1]] = value[2]

    monkeypatch.setattr(pairwise, "_run", fake_run)
    searched = np.eye(len(D), dtype=bool)
    done = np.eye(len(D), dtype=bool)
    for i, j in pairwise._candidate_pairs(noisy, 1):
        searched[i, j] = searched[j, i] = done[i, j] = done[j, i] = True
        R[i, j] = R[j, i] = D[i, j]
    for (i, j), v in known.items():
        done[i, j] = done[j, i] = True
        R[i, j] = R[j, i] = v
    if shared:
        searched = done.copy()
    pairwise._descent_runs(None, 1, searched, done, lambda: R, frozenset(), 1, False, "", {}, put)
    return searched, run


def test_a_descent_searches_the_same_pairs_whatever_else_is_known(monkeypatch):
    # a run resumed from a store that holds pairs of a later round (or any other pair) searches
    # what an uninterrupted run searches: the rounds follow the pairs they searched
    searched, run = _descent_on_points(monkeypatch, {})
    assert run and not searched.all()
    D = _plane_distances(np.random.default_rng(3))
    changed = 0
    for i, j in zip(*np.nonzero(np.triu(~np.eye(14, dtype=bool), 1))):
        known = {(int(i), int(j)): float(D[i, j])}
        again, run_again = _descent_on_points(monkeypatch, known)
        np.testing.assert_array_equal(again, searched)
        assert sorted(run_again) == sorted(ij for ij in run if ij != (i, j))
        # the known pair read as searched would steer the rounds elsewhere for some pairs
        steered, _ = _descent_on_points(monkeypatch, known, shared=True)
        plus = searched.copy()
        plus[i, j] = plus[j, i] = True
        changed += not np.array_equal(steered, plus)
    assert changed > 0


def test_search_says_whether_it_descended(tmp_path, capsys):
    files = _sheet_files(tmp_path)
    store = str(tmp_path / "store")
    opts = ["--metric", "geodesic", "--resolution", "1000", "--samples", "15", "--rank-by", "combined"]
    assert main(["index", *files, "--store", store, *opts[:4], "-q"]) == 0
    search = ["search", files[0], "--store", store, *opts, "-k", "1", "--candidates", "1", "-q"]
    capsys.readouterr()
    assert main(search) == 0
    assert "no distances between them recorded" in capsys.readouterr().out
    assert main(["pairwise", *files, "--store", store, *opts, "--candidates", "1", "-k", "1", "-q"]) == 0
    capsys.readouterr()
    assert main(search) == 0
    assert "then neighbour descent over" in capsys.readouterr().out


def test_point_clouds_have_a_signature_distortion_too():
    from gromov.mesh import PointCloud

    v = icosphere(3).vertices
    rng = np.random.default_rng(3)
    perm = rng.permutation(len(v))
    clouds = [PointCloud(v), PointCloud(2.0 * v[perm]), PointCloud(v * [1.0, 1.0, 2.5])]
    g = gh_matrix(clouds, "diffusion", n_samples=15, resolution=None, metric_options={"units": "area"},
                  spectral=True, jobs=1)
    assert g.signature[0, 1] < 0.2 * g.signature[0, 2] and g.signature[0, 1] == g.signature[1, 0]
    np.testing.assert_allclose(g.combined, combined(g.spectral, g.trimmed, signature=g.signature))
