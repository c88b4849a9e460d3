"""`gromov reproduce`: end to end on the synthetic set, the results contract, helpers."""

import json

import numpy as np
import pytest

from gromov import Mesh
from gromov.cli import main
from gromov.experiments.recognition import LOCAL_SCALING_K, local_scaling, roc
from gromov.experiments.reproduce import RESULT_KEYS, reflection_map, settings_for
from gromov.shapes import grid


#: The quick run's contract is checked on a smaller synthetic set (two of its classes at 400
#: working vertices, 12 samples); the ``--quick``
#: settings themselves are checked by ``test_settings_and_user_errors``.
SMALL = {"resolution": 400, "n_samples": 12, "experiment1": {"cat": 1, "dog": 1}, "experiment2": {"cat": 1, "dog": 1}}


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    from dataclasses import replace

    from gromov.experiments import reproduce as rp

    out = tmp_path_factory.mktemp("reproduce")
    full = rp.settings_for
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rp, "settings_for", lambda *a, **k: replace(full(*a, **k), **SMALL))
        code = main(["reproduce", "--quick", "--out", str(out), "--jobs", "2", "--quiet"])
    return code, out


def test_quick_run_writes_the_contract(quick_run, capsys):
    code, out = quick_run
    assert code == 0
    r = json.loads((out / "results.json").read_text())
    assert r["dataset"] == "synthetic" and r["quick"] is True and r["topkids"] is None
    for key in RESULT_KEYS:
        a, b, c = key.split(".")
        flat, nested = r[key], r[a][b][c]
        assert flat == nested and 0.0 <= flat <= 1.0, key   # fractions, not percent
    for exp in ("weld", "holes"):
        rec = r["recognition"][exp]
        n = len(rec["entries"])
        assert any(rec["perturbed"]) and len(rec["classes"]) >= 2
        for m in ("geodesic", "diffusion"):
            d = np.array(rec[m]["relative"])
            assert d.shape == (n, n) and np.allclose(d, d.T) and np.all(np.diag(d) == 0)
            assert np.all(d[~np.eye(n, dtype=bool)] > 0)
            # recognition ranks by the trimmed distortion by default; both EERs are recorded
            t = np.array(rec[m]["trimmed"])
            assert t.shape == (n, n) and np.allclose(t, t.T) and np.all(t[~np.eye(n, dtype=bool)] > 0)
            # (of log distance ratios, rank_residual: dimensionless, not comparable with d)
            assert rec[m]["ranked_by"] == "trimmed" and r["params"]["rank_by"] == "trimmed"
            assert rec[m]["eer"] == rec[m]["eer_trimmed"] and 0.0 <= rec[m]["eer_gh"] <= 1.0
            # the locally scaled ranking's EER beside it (k capped at n - 1), recomputable
            assert rec[m]["local_scaling_k"] == min(r["params"]["local_scaling"], n - 1)
            local = roc(local_scaling(t, rec[m]["local_scaling_k"]), rec["labels"])
            assert rec["smallest_class"] == min(rec["labels"].count(c) for c in rec["classes"])
            assert rec[m]["eer_local"] == pytest.approx(local.eer, abs=1e-9)
            assert rec[m]["errors_at_eer_local"]["threshold"] == pytest.approx(local.eer_threshold, rel=1e-4)
    assert r["params"]["rank_tau_scale"] == 0.5 and r["params"]["rank_residual"] == "log"
    assert r["params"]["local_scaling"] == LOCAL_SCALING_K
    # the perturbations did what they say: welds lower the Euler characteristic, holes add loops
    shapes = r["recognition"]["weld"]["shapes"]
    welded = [s for label, s in shapes.items() if "+weld" in label]
    assert welded and all(s["euler_after"] < s["euler_before"] for s in welded)
    # the paper's welded vertices by default: one merged vertex per weld lowers chi by one
    assert r["params"]["weld_join"] == "pinch"
    assert all(s["join"] == "pinch" and s["euler_before"] - s["euler_after"] == s["welds"] for s in welded)
    holed = [s for label, s in r["recognition"]["holes"]["shapes"].items() if "+holes" in label]
    assert holed and all(s["boundary_loops_after"] >= 1 for s in holed)
    for key in ("timings", "versions", "seeds", "params"):
        assert r[key]
    assert r["versions"]["gromov"] and r["params"]["n_samples"] == SMALL["n_samples"]
    pages = [f for f in r["figures"].values() if f.endswith(".html")]
    for f in r["figures"].values():
        if f not in pages:
            assert (out / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # one interactive dense-map page per class of the correspondence pairs, linked from the report,
    # plotly.js once beside them
    classes = {label.split("+")[0].rstrip("0123456789") for exp in ("weld", "holes")
               for label in r["recognition"][exp]["shapes"]}
    assert sorted(pages) == sorted(f"dense_{c}.html" for c in classes)
    assert all('src="plotly.min.js"' in (out / f).read_text() for f in pages)
    assert (out / "plotly.min.js").stat().st_size > 1_000_000
    dense = r["correspondence"]["diffusion"]["dense"]
    assert {"clean", "weld", "holes"} <= set(dense) and all(0 <= dense[k] < 100 for k in ("clean", "weld", "holes"))
    html = (out / "index.html").read_text()
    assert all(f'href="{f}"' in html for f in pages) and "<h3>Dense maps</h3>" in html
    assert "data:image/png;base64," in html and "13.5" in html   # the paper's geodesic EER beside ours
    assert "trimmed distortion" in html and "EER, GH estimate" in html
    assert "heat distance at 0.5 × the diffusion time" in html   # what the diffusion ranking measures
    assert "log ratios of corresponding distances" in html       # and how it summarises residuals
    assert f"EER, locally scaled (k = {LOCAL_SCALING_K})" in html and "Zelnik-Manor" in html


def test_quick_run_correspondence_is_measured(quick_run):
    _, out = quick_run
    r = json.loads((out / "results.json").read_text())
    for m in ("geodesic", "diffusion"):
        c = r["correspondence"][m]
        for kind in ("clean", "weld", "holes"):
            assert c[f"{kind}_pairs"] >= 1
            # best counts the mirrored map as correct: never worse than the direct reading
            assert c[kind] <= c[f"{kind}_direct"] + 1e-12
        for p in c["pairs"]:
            assert p["best"] == min(p["direct"], p["mirrored"])


def test_correspondence_uses_its_own_diffusion_metric(quick_run):
    """Recognition ranks by the raw heat distances; the correspondence pairs are matched again
    with normalised heat distributions (correspondence_options); geodesic maps are shared."""
    _, out = quick_run
    r = json.loads((out / "results.json").read_text())
    rec_opts, corr_opts = r["params"]["metric_options"], r["params"]["correspondence_options"]
    assert "units" not in rec_opts["diffusion"] and corr_opts["diffusion"]["units"] == "normalized"
    assert corr_opts["geodesic"] == rec_opts["geodesic"]
    assert "recognition_metric" in r["correspondence"]["diffusion"]
    assert "recognition_metric" not in r["correspondence"]["geodesic"]
    for exp in ("weld", "holes"):
        assert f"{exp}.diffusion.correspondence_s" in r["timings"]
        assert f"{exp}.geodesic.correspondence_s" not in r["timings"]
    # geodesic pairs are the recognition's maps: their GH estimate is the matrix entry (unless
    # the orientation preference replaced the map); diffusion pairs are other maps, under
    # another metric
    same = {"geodesic": 0, "diffusion": 0}
    for m in same:
        for p in r["correspondence"][m]["pairs"]:
            for exp in ("weld", "holes"):
                rec = r["recognition"][exp]
                if p["x"] in rec["entries"] and p["y"] in rec["entries"]:
                    i, j = rec["entries"].index(p["x"]), rec["entries"].index(p["y"])
                    same[m] += abs(rec[m]["relative"][i][j] - p["relative_distance"]) < 1e-6
    n = len(r["correspondence"]["geodesic"]["pairs"])
    assert same["geodesic"] >= n / 2 and same["diffusion"] == 0


def test_correspondence_options():
    from gromov.metrics.diffusion import CORRESPONDENCE_UNITS, correspondence_options

    assert correspondence_options("diffusion", None) == {"units": CORRESPONDENCE_UNITS}
    given = {"kernel": "heat", "fill_holes": 0.5}
    assert correspondence_options("diffusion", given) == {**given, "units": CORRESPONDENCE_UNITS}
    assert given == {"kernel": "heat", "fill_holes": 0.5}   # not changed in place
    for opts in ({"units": "raw"}, {"tau": 0.01}, {"kernel": "connectivity"}, {"kernel": "biharmonic"}):
        assert correspondence_options("diffusion", opts) == opts
    assert correspondence_options("geodesic", {}) == {}


def test_cached_rows_are_the_solvers_rows():
    """A fast-marching row does not depend on the other sources of its call: cached rows are
    the same numbers, each computed once."""
    from gromov.experiments.reproduce import _CachedRows
    from gromov.metrics import metric_solver
    from gromov.shapes import icosphere

    solver = metric_solver(icosphere(2), "geodesic")
    calls = []

    class Counting:
        n_vertices = solver.n_vertices

        def from_sources(self, s):
            calls.append(len(s))
            return solver.from_sources(s)

    rows = _CachedRows(Counting())
    a = rows.from_sources([5, 3, 5, 40])
    b = rows.from_sources([40, 7, 3])
    np.testing.assert_array_equal(a, solver.from_sources([5, 3, 5, 40]))
    np.testing.assert_array_equal(b, solver.from_sources([40, 7, 3]))
    np.testing.assert_array_equal(b[0], solver.from_sources([40])[0])   # alone, the same row
    assert calls == [3, 1] and rows.from_sources([]).shape == (0, solver.n_vertices)


def test_cached_rows_between_are_the_rows_values():
    """Distances between given pairs, from cached rows or from marches stopped at their
    targets, are the rows' numbers bit for bit; no row is kept for the marched ones."""
    from gromov.experiments.reproduce import _CachedRows
    from gromov.metrics import metric_solver
    from gromov.shapes import icosphere

    solver = metric_solver(icosphere(3), "geodesic")
    rng = np.random.default_rng(1)
    src = rng.integers(0, solver.n_vertices, 300)
    tgt = rng.integers(0, solver.n_vertices, 300)
    full = solver.from_sources(np.arange(solver.n_vertices))
    rows = _CachedRows(solver)
    rows.from_sources(src[:20])                       # some sources have a row already
    got = rows.between(src, tgt)
    np.testing.assert_array_equal(got, full[src, tgt])
    assert sorted(rows.rows) == sorted(set(src[:20].tolist()))


def test_a_match_measures_both_sides_in_the_same_metric():
    """Without metric_options, the shape not prepared yet takes the correspondence options of
    the prepared one's (a ShapeMetric with default options against a mesh: normalised units
    on both sides, as for two meshes); with none prepared, the correspondence's defaults."""
    from gromov.gh import ShapeMetric, match, match_options_for
    from gromov.shapes import icosphere, rolled_grid

    x, y = grid(21, 11), rolled_grid(21, 11)
    for opts in ({}, {"units": "normalized"}, {"units": "raw"}):
        sx = ShapeMetric(x, "diffusion", resolution=None, metric_options=opts)
        assert match_options_for((sx, y), "diffusion", None) == (opts or {"units": "normalized"})
        a = match(sx, y, "diffusion", n_samples=20, resolution=None)
        b = match(sx, ShapeMetric(y, "diffusion", resolution=None, metric_options=opts), "diffusion",
                  n_samples=20, resolution=None)
        assert a.distance == b.distance
    assert match_options_for((x, icosphere(1)), "diffusion", None) == {"units": "normalized"}
    assert match_options_for((sx, y), "diffusion", {"units": "raw"}) == {"units": "raw"}


def test_reflection_map_of_a_symmetric_sheet():
    g = grid(9, 5)   # symmetric about the middle of its x range
    m = reflection_map(g)
    v = g.vertices
    np.testing.assert_allclose(v[m, 0], v[:, 0].max() + v[:, 0].min() - v[:, 0], atol=1e-12)
    np.testing.assert_allclose(v[m, 1:], v[:, 1:], atol=1e-12)
    assert np.array_equal(m[m], np.arange(g.n_vertices))
    # ids are input ids: a renumbered mesh maps its own ids
    sub = Mesh(g.vertices, g.faces, input_ids=np.arange(g.n_vertices) + 100)
    assert np.array_equal(reflection_map(sub)[100:], m + 100)


def test_reflection_map_keeps_each_piece_on_one_piece():
    """A nearly symmetric sheet and a small separate piece floating just where one sheet
    vertex's reflection lands: the sheet still maps onto the sheet, the piece onto one piece."""
    g = grid(9, 5)
    v = g.vertices.copy()
    y = v[:, 1] - v[:, 1].mean()
    v[:, 2] = 0.5 * y**3 / np.abs(y).max() ** 2   # symmetric in x only
    v[:, 0] += np.random.default_rng(0).uniform(-0.02, 0.02, len(v)) * (v[:, 0].max() - v[:, 0].min())
    lo, hi = v[:, 0].min(), v[:, 0].max()
    j = int(np.argmin(np.linalg.norm(v - [hi - 0.25 * (hi - lo), 0.5 * (v[:, 1].min() + v[:, 1].max()), 0], axis=1)))
    spot = v[j].copy()
    spot[0] = lo + hi - spot[0]   # where vertex j's reflection lands
    piece = spot + np.array([[0.0, 0.0, 1e-4], [0.01, 0.0, 1e-4], [0.0, 0.01, 1e-4]])
    m = Mesh(np.vstack([v, piece]), np.vstack([g.faces, [[0, 1, 2]] + np.int64(len(v))]))
    mirror = reflection_map(m)
    sheet = m.component_labels[:len(v)]
    assert np.all(m.component_labels[mirror[: len(v)]] == sheet[0])
    assert len(np.unique(m.component_labels[mirror[len(v):]])) == 1
    # what a plain nearest-vertex reflection did: vertex j onto the piece
    r = v.copy()
    r[:, 0] = m.vertices[:, 0].min() + m.vertices[:, 0].max() - r[:, 0]
    assert np.argmin(np.linalg.norm(m.vertices - r[j], axis=1)) >= len(v)
    np.testing.assert_allclose(m.vertices[mirror[j], 1:], v[j, 1:], atol=0.3 * m.mean_edge_length)


def test_settings_and_user_errors(tmp_path, capsys):
    with pytest.raises(ValueError, match="dataset must be"):
        settings_for("shrec")
    full = settings_for("tosca")
    assert full.experiment1 == {"cat": 2, "dog": 4, "david": 6, "victoria": 6}
    assert full.resolution == 3000 and full.n_samples == 100 and full.topkids == 25
    assert main(["reproduce", "--data", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "no tosca/ directory" in capsys.readouterr().err
    assert main(["reproduce", "--data", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2


def test_other_classes(tmp_path, capsys):
    st = settings_for("tosca", classes={"wolf": 2, "horse": 4, "michael": 6}, topkids=False)
    assert st.experiment1 == {"wolf": 2, "horse": 4, "michael": 6}
    assert st.experiment2 == {"wolf": 2, "horse": 2, "michael": 2} and st.topkids == 0
    quick = settings_for("tosca", True, classes={"wolf": 2, "horse": 4})
    assert quick.experiment1 == {"wolf": 2, "horse": 2} and quick.experiment2 == {"wolf": 1, "horse": 1}
    assert quick.topkids == 5
    for bad in ({"wolf": 2}, {"wolf": 0, "horse": 1}, {"wolf": True, "horse": 1}, {}):
        with pytest.raises(ValueError, match="classes"):
            settings_for("tosca", classes=bad)
    with pytest.raises(ValueError, match="TOSCA data only"):
        settings_for("synthetic", classes={"wolf": 2, "horse": 4})
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "--classes", "wolf2,horse:1", "--out", str(tmp_path / "o")])
    assert exc.value.code == 2 and "CLASS:N" in capsys.readouterr().err


def test_diffusion_kernel_option(quick_run, tmp_path, capsys):
    code, out = quick_run
    r = json.loads((out / "results.json").read_text())
    assert r["params"]["metric_options"]["diffusion"] == {"kernel": "heat", "fill_holes": 0.5}  # defaults
    assert main(["reproduce", "--quick", "--kernel", "biharmonic", "--tau", "0.01",
                 "--out", str(tmp_path / "o")]) == 2
    assert "--tau is the heat kernel's diffusion time" in capsys.readouterr().err
    from gromov.experiments.reproduce import reproduce

    with pytest.raises(ValueError, match="diffusion kernel must be one of"):
        reproduce(None, tmp_path / "o", quick=True, diffusion={"kernel": "cosine"})
    with pytest.raises(ValueError, match="tau must be positive"):
        reproduce(None, tmp_path / "o", quick=True, diffusion={"kernel": "heat", "tau": -1.0})
    with pytest.raises(ValueError, match="diffusion options"):
        reproduce(None, tmp_path / "o", quick=True, diffusion={"kernel": "biharmonic", "m": 50})
    assert not (tmp_path / "o").exists()  # refused before any work
    with pytest.raises(ValueError, match="rank_by must be one of"):
        reproduce(None, tmp_path / "o", quick=True, rank_by="median")
    for bad in (0, -0.5, float("nan"), "0.5"):
        with pytest.raises(ValueError, match="rank_tau_scale must be"):
            reproduce(None, tmp_path / "o", quick=True, rank_tau_scale=bad)
    with pytest.raises(ValueError, match="rank_residual must be one of"):
        reproduce(None, tmp_path / "o", quick=True, rank_residual="ratio")
    with pytest.raises(ValueError, match="pose_stretch must be a number"):
        reproduce(None, tmp_path / "o", quick=True, pose_stretch=0.5)
    (tmp_path / "data" / "tosca").mkdir(parents=True)
    with pytest.raises(ValueError, match="TOSCA's are as scanned"):
        reproduce(tmp_path / "data", tmp_path / "o", quick=True, pose_stretch=0.1)
    assert not (tmp_path / "o").exists()


def test_rank_by_option_reaches_reproduce(monkeypatch, tmp_path):
    import gromov.experiments.reproduce as rep

    seen = {}

    class Stop(Exception):
        pass

    def fake(*args, **kwargs):
        seen.update(kwargs)
        raise Stop

    monkeypatch.setattr(rep, "reproduce", fake)
    cases = [("rank_by", [], "trimmed"), ("rank_by", ["--rank-by", "gh"], "gh"),
             ("rank_tau_scale", [], 0.5), ("rank_tau_scale", ["--rank-tau-scale", "1"], None),
             ("rank_tau_scale", ["--rank-tau-scale", "0.25"], 0.25),
             ("rank_residual", [], "log"), ("rank_residual", ["--rank-residual", "difference"], "difference"),
             ("pose_stretch", [], 0.0), ("pose_stretch", ["--pose-stretch", "0.1"], 0.1),
             ("local_scaling", [], LOCAL_SCALING_K), ("local_scaling", ["--local-scaling", "2"], 2)]
    for key, argv, want in cases:
        with pytest.raises(Stop):
            main(["reproduce", "--quick", "--out", str(tmp_path / "o")] + argv)
        assert seen[key] == want, (key, argv)
    for bad in (["--rank-by", "median"], ["--rank-residual", "ratio"], ["--local-scaling", "0"],
                *(["--rank-tau-scale", v] for v in ("0", "-1", "x", "inf"))):
        with pytest.raises(SystemExit):
            main(["reproduce", *bad])


def test_weld_join_option(tmp_path, capsys):
    """Welds merge vertices (pinch, chi - 1) or add handles (tube, chi - 2); the same sites."""
    from gromov.experiments.datasets import experiment1
    from gromov.experiments.reproduce import _Shapes, reproduce
    from gromov.experiments.synthetic import Synthetic

    syn = Synthetic(n_vertices=800)
    entry = next(e for e in experiment1(syn, {"cat": 1}) if e.perturbation is not None)
    shapes = {j: _Shapes(syn, None, j).entry(entry) for j in ("pinch", "tube")}
    pinch, tube = shapes["pinch"].info, shapes["tube"].info
    assert pinch["welds"] == tube["welds"] >= 1 and pinch["euler_before"] == tube["euler_before"]
    assert pinch["euler_before"] - pinch["euler_after"] == pinch["welds"]
    assert tube["euler_before"] - tube["euler_after"] == 2 * tube["welds"]
    # a pinch merges one vertex of each site into the other; a tube removes both 1-rings' centres
    clean = _Shapes(syn, None).work(entry.cls, entry.pose).mesh
    assert shapes["pinch"].mesh.n_vertices == clean.n_vertices - pinch["welds"]
    assert shapes["tube"].mesh.n_vertices == clean.n_vertices - 2 * tube["welds"]
    with pytest.raises(ValueError, match="weld_join must be one of"):
        reproduce(None, tmp_path / "o", quick=True, weld_join="glue")
    assert not (tmp_path / "o").exists()  # refused before any work
    with pytest.raises(SystemExit):
        main(["reproduce", "--quick", "--weld-join", "glue", "--out", str(tmp_path / "o")])
    assert "invalid choice: 'glue'" in capsys.readouterr().err


def test_unknown_class_is_a_clear_error(data_dir, tmp_path, capsys):
    assert main(["reproduce", "--data", str(data_dir), "--classes", "unicorn:2,wolf:2", "--no-topkids",
                 "--out", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "no class 'unicorn'" in err and "wolf" in err and "Traceback" not in err
    assert main(["reproduce", "--data", str(data_dir), "--classes", "wolf:2", "--out", str(tmp_path / "o"),
                 "-q"]) == 2
    assert "recognition needs at least two classes" in capsys.readouterr().err
