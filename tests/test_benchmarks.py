"""The scripts under benchmarks/ (the comparisons) and benchmarks/studies/ (the studies behind
the design notes) compute what they say (no timings here), and the result tables of the README
and of docs/benchmarks.md are the committed results files'."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from gromov.experiments.recognition import equal_error_rate

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
STUDIES = BENCH / "studies"


def _module(name):
    """A benchmark script (a comparison under benchmarks/ or a study under benchmarks/studies/)
    as a module, with benchmarks/ on the path as when it is run (``python benchmarks/NAME.py``
    finds ``_common`` beside it; a study puts benchmarks/ on the path itself)."""
    if str(BENCH) not in sys.path:
        sys.path.insert(0, str(BENCH))
    path = BENCH / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path if path.is_file() else STUDIES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _results(D, labels, perturbed):
    return {"recognition": {"weld": {"labels": labels, "perturbed": perturbed,
                                     "geodesic": {"relative": D.tolist()},
                                     "diffusion": {"relative": D.tolist()}}}}


def _by_class(labels, within, between):
    """Distances ``within`` a class and ``between`` classes, zero diagonal."""
    lab = np.array(labels)
    D = np.where(lab[:, None] == lab[None], within, between)
    np.fill_diagonal(D, 0.0)
    return D, lab


def test_eer_breakdown_isolates_the_male_female_pairs():
    eb = _module("eer_breakdown")
    labels = ["cat", "cat", "david", "david", "victoria", "victoria"]
    perturbed = [False, True, False, True, False, True]
    # within a class 1, between classes 5, except david <-> victoria at 0.5: the only confusion
    D, lab = _by_class(labels, 1.0, 5.0)
    dv = np.isin(lab, ("david", "victoria"))
    D[dv[:, None] & dv[None] & (lab[:, None] != lab[None])] = 0.5
    out = eb.breakdown(_results(D, labels, perturbed))
    row = out["weld", "diffusion", "GH"]
    assert row["all"] == pytest.approx(equal_error_rate(D, lab)) and row["all"] > 0.1
    assert row["without david-victoria pairs"] == 0.0
    # clean shapes: one per class, so no positive pair among them
    assert row["clean only"] is None


def test_eer_breakdown_clean_subset_uses_only_clean_pairs():
    eb = _module("eer_breakdown")
    labels = ["cat", "cat", "cat", "dog", "dog", "dog"]
    perturbed = [False, False, True, False, False, True]
    D, _ = _by_class(labels, 1.0, 3.0)
    # the perturbed cat is far from its class: an error that the clean subset must not see
    D[2, :3] = D[:3, 2] = 10.0
    D[2, 2] = 0.0
    row = eb.breakdown(_results(D, labels, perturbed))["weld", "geodesic", "GH"]
    assert row["all"] > 0.0
    assert row["clean only"] == 0.0


def test_eer_breakdown_reads_the_trimmed_ranking_too():
    eb = _module("eer_breakdown")
    labels = ["cat", "cat", "dog", "dog"]
    D, _ = _by_class(labels, 1.0, 3.0)
    T, _ = _by_class(labels, 3.0, 1.0)   # a ranking that gets every pair wrong
    res = _results(D, labels, [False] * 4)
    res["recognition"]["weld"]["diffusion"]["trimmed"] = T.tolist()
    out = eb.breakdown(res)
    assert out["weld", "diffusion", "GH"]["all"] == 0.0
    assert out["weld", "diffusion", "trimmed"]["all"] == 1.0
    assert ("weld", "geodesic", "trimmed") not in out   # not recorded: not invented


def test_recognition_statistics_summarise_the_off_diagonal_residuals():
    rs = _module("recognition_statistics")
    e = np.full((21, 21), 0.1)
    e[0, 1:] = e[1:, 0] = 4.0          # one sample's pairs (2 x 20 of 420) fit badly
    np.fill_diagonal(e, 7.0)           # the diagonal is not a pair
    s = rs.statistics(e)
    assert s["linf"] == 4.0 and s["median"] == pytest.approx(0.1)
    assert s["gh"] == pytest.approx(np.sqrt((40 * 16 + 380 * 0.01) / 420))
    assert s["l1"] == pytest.approx((40 * 4 + 380 * 0.1) / 420)
    assert s["trim90"] == pytest.approx(0.1)   # 378 of 420 kept: the 40 bad ones are out
    assert s["trim95"] > 0.1                   # 399 kept: 19 bad ones are in
    # the sample-trimmed rankings (gromov.gmds.sample_trimmed_rms) drop the bad sample's row
    assert s["strim90"] == pytest.approx(0.1) and s["strim60"] == pytest.approx(0.1)


def test_margin_of_the_rankings():
    """The margin (benchmarks/_common.py, used by every ranking probe) is the smallest
    different-class distance over the largest same-class one."""
    common = _module("_common")
    D, lab = _by_class(["a", "a", "b", "b"], 1.0, 3.0)
    assert common.margin(D, lab) == 3.0
    D[0, 2] = D[2, 0] = 0.5            # one different-class pair closer than the classes
    assert common.margin(D, lab) == 0.5
    for name in ("recognition_statistics", "bench_close_humanoids", "bench_rank_residual",
                 "probe_local_scaling"):
        assert _module(name).margin(D, lab) == 0.5


def test_probe_local_scaling_readings():
    """A shape whose distances to every other shape are inflated breaks one threshold;
    local scaling restores it, and k is capped at n - 1."""
    pl = _module("probe_local_scaling")
    pos = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 2.0, 2.1, 2.2, 2.3, 2.4])
    lab = np.repeat(["a", "b"], 5)
    D = np.abs(pos[:, None] - pos[None, :])
    D[0, :] *= 4.0
    D[:, 0] *= 4.0
    row = pl.readings(D, lab, [2, 50])
    assert row["as is"]["eer"] > 0 and row["as is"]["margin"] <= 1   # a tie at 1.6
    assert row["k=2"]["eer"] == 0.0 and row["k=2"]["margin"] > 1
    assert row["k=50"] == pl.readings(D, lab, [9])["k=9"]


def test_weld_contact_pinch_merges_and_keeps_input_ids():
    wc = _module("bench_weld_contact")
    from gromov.shapes import torus

    m = torus()
    u, v = 0, m.n_vertices // 2
    w = wc._pinch(m, [(u, v)])
    assert w.n_vertices == m.n_vertices - 1
    assert w.n_faces == m.n_faces
    assert not np.isin(v, w.input_ids)
    assert wc._rows_of(w, [m.input_ids[v]])[0] == -1
    # v's faces now use u: the merged vertex has the degree of both
    iu = wc._rows_of(w, [m.input_ids[u]])[0]
    assert np.count_nonzero(w.faces == iu) == np.count_nonzero(m.faces == u) + np.count_nonzero(m.faces == v)
    # one vertex fewer, same edges and faces: the Euler characteristic drops by one
    assert w.euler_characteristic == m.euler_characteristic - 1


README = BENCH.parent / "README.md"
BENCHMARKS_PAGE = BENCH.parent / "docs" / "benchmarks.md"


def _json(name):
    import json

    return json.loads((BENCH / "results" / name).read_text())


def test_readme_tables_are_the_committed_results():
    """The result tables of the README and of docs/benchmarks.md are printed from the committed
    results files, not typed: each is on its page as printed, with the command that made it,
    and its cells are the files' values."""
    import json

    rt = _module("readme_tables")
    readme, page = README.read_text(), BENCHMARKS_PAGE.read_text()
    paper_run = rt.DEFAULT[0]
    assert paper_run.parent.name == "reproduce-tosca"
    for path in rt.DEFAULT:
        r = json.loads(path.read_text())
        tab = rt.table(r)
        pages = [page] + ([readme] if path == paper_run else [])
        for text in pages:
            assert tab in text, f"a page's table for {path.parent.name} is not what {path} gives"
            assert rt.caption(r) in text.replace("\n", " "), rt.caption(r)
        assert rt.errors(r) in page
        eer_row = next(line for line in tab.splitlines() if line.startswith("| EER, Experiment 1"))
        cells = [c.strip() for c in eer_row.strip("|").split("|")]
        assert cells[1] == rt._pct(r["eer.weld.geodesic"]) and cells[2] == rt._pct(r["eer.weld.diffusion"])
        # the recorded command, its output folder named by its last component only
        assert rt.command(r).startswith("gromov reproduce") and "/tmp" not in rt.command(r)
        assert f"{r['seconds_total']:.0f} s" in rt.caption(r)
    assert rt._pct(0.0675) == "6.75%" and rt._pct(0.2232) == "22.3%" and rt._pct(0.0) == "0.0%"
    assert rt.command({"command": "gromov reproduce --out /x/y/run -q"}) == "gromov reproduce --out run -q"


def test_readme_claims_about_the_paper_run_hold():
    """What the README says of its table against the paper, checked on the results file."""
    from gromov.experiments.report import PAPER

    r = _json("reproduce-tosca/results.json")
    rec, cor = r["recognition"], r["correspondence"]
    readme = " ".join(README.read_text().split())
    assert "are better than the paper's with and without topology changes" in readme
    for cond in ("clean", "weld", "holes"):
        paper = PAPER["correspondence"]["diffusion"]["clean" if cond == "clean" else "topology"]
        assert cor["diffusion"][cond] < paper and cor["diffusion"][cond + "_direct"] < paper, cond
    assert "diffusion beats geodesics in every EER and d(C, C0) row" in readme
    for exp in ("weld", "holes"):
        for key in ("eer", "eer_gh", "eer_local"):
            assert rec[exp]["diffusion"][key] < rec[exp]["geodesic"][key], (exp, key)
        for m in ("geodesic", "diffusion"):   # "its equal error rates are above the paper's"
            assert rec[exp][m]["eer"] > PAPER["eer"][exp][m], (exp, m)
        errors = rec[exp]["diffusion"]["errors_at_eer"]
        assert set(errors["false_accept"]) == {"david / victoria"}, errors
    for cond in ("clean", "weld", "holes"):
        for reading in (cond, cond + "_direct"):
            assert cor["diffusion"][reading] < cor["geodesic"][reading], reading
    t = r["topkids"]
    for key in ("correspondence", "correspondence_direct"):
        assert t["diffusion"][key] < t["geodesic"][key], key
    assert "every false acceptance at the diffusion threshold is a david ↔ victoria pair" in readme


def test_anchor_table_is_the_results_files():
    """The README's table against the anchors, row by row from the four results files."""
    import numpy as np

    rt = _module("readme_tables")
    tab = rt.anchors_table()
    assert tab in README.read_text() and tab in BENCHMARKS_PAGE.read_text()
    rows = tab.splitlines()[2:]
    g = _json("foundation.json")["geodesic_all_pairs"]
    ours, heat = g["gromov fmm (ours)"], g["potpourri3d heat"]
    assert f"| {ours['seconds']:.2f} s; {100 * ours['mean_rel_err']:.2f}% / {100 * ours['max_rel_err']:.2f}%" in rows[0]
    assert f"| {heat['seconds']:.2f} s; {100 * heat['mean_rel_err']:.2f}% / {100 * heat['max_rel_err']:.1f}%" in rows[0]
    acc = _json("match.json")["accuracy"]
    pairs = ("cat0-cat1", "dog0-dog1", "david0-david1", "victoria0-victoria1")
    gmds = np.mean([acc[f"{p}/diffusion/gmds"]["best"] for p in pairs])
    gw = np.mean([acc[f"{p}/diffusion/gw"]["best"] for p in pairs])
    assert f"| {gmds:.4f} (GMDS) | {gw:.4f} (POT" in rows[1] and gmds < gw
    speed = _json("match.json")["speed"]
    assert f"| {speed['match_seconds']:.2f} s | {1000 * speed['pot_gw_seconds']:.1f} ms (POT) |" in rows[2]
    e2e = _json("speed.json")["end_to_end"]
    assert (f"| {e2e['gromov_s']:.2f} s; {e2e['gromov_error']:.4f} | {e2e['pipeline_s']:.2f} s; "
            f"{e2e['pipeline_error']:.4f} (potpourri3d" in rows[3])
    dense = _json("dense.json")
    s = dense["topkids"]["summary"]
    assert f"| {s['ours_dense']['mean']:.2f} | {s['pyfm_dense']['mean']:.2f} " in rows[4], rows[4]
    assert len(dense["topkids"]["pairs"]) == 25 and "25 TOPKIDS pairs" in rows[4]
    tosca = _json("dense_tosca.json")["tosca"]
    s = tosca["summary"]
    assert (f"| {s['ours_dense']['mean']:.2f}; {s['ours_dense']['median']:.2f} | {s['pyfm_dense']['mean']:.2f}; "
            f"{s['pyfm_dense']['median']:.2f} (pyFM) |") in rows[5], rows[5]
    assert len(tosca["classes"]) == 8 and len(tosca["pairs"]) == 16 and "16 clean TOSCA pairs (8 classes)" in rows[5]
    rem = _json("dense.json")["remeshed"]
    s = rem["summary"]
    assert (f"| {s['ours_dense']['mean']:.2f}; {s['ours_dense']['median']:.2f} | {s['pyfm_dense']['mean']:.2f}; "
            f"{s['pyfm_dense']['median']:.2f} (pyFM) |") in rows[6], rows[6]
    assert len(rem["classes"]) == 8 and len(rem["pairs"]) == 16 and "16 TOSCA pairs each remeshed" in rows[6]
    holes = _json("dense.json")["perturbed"]["holes"]["summary"]["ours_dense"]
    density = rem["density"]["summary"]["ours_dense"]
    assert f"| {density['mean']:.2f}, {density['median']:.2f}; {holes['mean']:.2f}, {holes['median']:.2f};" in rows[7]
    big = _json("cloud_sampling.json")["rows"][-1]
    assert big["points"] == 1_000_000
    assert (f"| {big['ours_s']:.2f} s | {big['fpsample_vanilla_s']:.2f} s / {big['fpsample_quickfps_s']:.2f} s"
            in rows[8])
    # the watertight row's neighbour descent: the study's measured run of that results file
    m = _json("../studies/recognition_two_stage_signature.json")["measured"]
    run = _json(m["file"])["collections"]["watertight"]["rows"]
    descent = next(v for k, v in run.items() if k.endswith("--candidates 20 -k 10"))
    assert descent["pairs_matched"] == m["pairs_matched"] and descent["seconds"] == m["seconds"]
    assert (f"each shape's 10 nearest: {m['seconds'] / 60:.1f} min (`--candidates 20 -k 10`: "
            f"{m['pairs_matched']:,} pairs; brute force's 10 for {100 * m['top_equal_list']:.1f}% of the shapes)"
            in rows[-1])


def test_benchmark_page_tables_are_the_results_files():
    """Every table of docs/benchmarks.md is on the page as readme_tables prints it, and a cell
    of each is checked against its file independently of the printer."""
    import numpy as np

    rt = _module("readme_tables")
    page = BENCHMARKS_PAGE.read_text()
    tables = rt.benchmark_tables()
    assert len(tables) == 18
    for name, tab in tables:
        assert tab in page, f"docs/benchmarks.md's table from {name} is not what the file gives"
    (foundation, steps, match_acc, match_speed, _, _, _, _, _, sampling, clouds, speed, collection, retrieval,
     resume, dask, recognition, two_stage) = (t for _, t in tables)
    g = _json("foundation.json")["geodesic_all_pairs"]["gromov fmm refine=2"]
    assert f"| {g['seconds']:.1f} s | {g['ratio_to_ours']:.2f}× | {100 * g['mean_rel_err']:.2f}% |" in foundation
    d = _json("foundation.json")["diffusion"]
    assert f"| {d['graph_spectral_seconds']:.2f} s | {d['graph_dense_seconds']:.2f} s" in steps
    acc = _json("match.json")["accuracy"]
    pairs = ("cat0-cat1", "dog0-dog1", "david0-david1", "victoria0-victoria1")
    means = [np.mean([acc[f"{p}/{m}"]["best"] for p in pairs])
             for m in ("geodesic/gmds", "geodesic/gw", "diffusion/gmds", "diffusion/gw")]
    assert "| mean | " + " | ".join(f"{x:.4f}" for x in means) + " |" in match_acc
    assert f"| {_json('match.json')['speed']['end_to_end_geodesic_seconds']:.2f} |" in match_speed
    row = _json("cloud_sampling.json")["rows"][0]
    assert f"| {row['ours_s'] / row['fpsample_vanilla_s']:.2f} |" in sampling
    pc = _json("point_clouds.json")
    assert f"| {pc['mean_best']['diffusion/cloud']:.4f} |" in clouds
    assert f"| {pc['rows']['victoria0-victoria1/geodesic/half cloud']['best']:.4f} |" in clouds
    sp = _json("speed.json")
    assert f"| {sp['one_pair']['ours']:.2f} s | {1000 * sp['one_pair']['pot']:.1f} ms" in speed
    assert all(f"weld {name} --count 3` | {w['seconds']:.1f} s, {w['peak_mb']:.0f} MB |" in speed
               for name, w in sp["weld"].items())
    co = _json("collection.json")
    assert co["complete"] and co["shapes"] == 80 and co["pairs"] == 80 * 79 // 2
    assert f"| {co['scratch']['seconds']:.0f} | 1.00 |" in collection
    assert f"same matrices: {'yes' if co['kill']['identical'] else 'no'};" in collection
    ret = _json("collection_retrieval.json")
    assert ret["complete"] and ret["shapes"] == 80 and ret["pairs"] == 80 * 79 // 2
    for name in ("knn_pairs bound", "knn_pairs profile", "nearest profile", "nearest profile, none known"):
        row = ret["retrieval"]["rows"][name]
        assert f"| {row['recall']:.3f} | {row['exact_queries']}/80 | {row['full_matches']:,}/{row['pairs']:,} |" in retrieval
    re = _json("collection_resume.json")
    assert re["complete"] and re["shapes"] == 80
    assert f"same matrices: {'yes' if re['kill']['identical'] else 'no'};" in resume
    da = _json("collection_dask.json")["dask"]
    median = float(np.median([x["throughput_ratio_match"] for x in da["rounds"]]))
    assert f"| median | | | {median:.2f}× |" in dask and len(da["rounds"]) >= 3
    wt = _json("recognition_full.json")["collections"]["watertight"]
    ours = next(v for k, v in wt["rows"].items() if k.startswith("gromov --units area") and "(" not in k)
    assert ours["pairs_matched"] == 200 * 199 // 2 and wt["shapes"] == 200
    assert f"| {100 * ours['nn']:.1f}% | {100 * ours['ft']:.1f}% | {100 * ours['st']:.1f}% | {100 * ours['eer']:.1f}% |" in recognition
    study = _json("../studies/recognition_two_stage_signature.json")
    c40 = next(x for x in study["two_stage"] if x["candidates"] == 40)
    assert f"| 40 | {c40['pairs']:,} | {100 * c40['top_equal_list']:.1f}% |" in two_stage


def test_cloud_sampling_benchmark_compares_like_with_like():
    """The benchmark's general loop is the same sampling (identical samples and distances) and
    the anchor's covering radius is measured on the same cloud."""
    cs = _module("bench_cloud_sampling")
    r = cs.run(3000, 60)
    assert r["identical_to_general_loop"] and r["radius_ours"] > 0
    if "radius_fpsample_vanilla" in r:   # fpsample (bench extra): a covering radius near ours
        assert abs(r["radius_fpsample_vanilla"] / r["radius_ours"] - 1) < 0.2


def test_partial_benchmark_measures_coverage_and_the_cut():
    """bench_partial.py: the keeps spread over the stated ranges, a perfect map covers the true
    region (IoU 1), the distance to the cut is the edge-graph distance to the part's new boundary
    (0 on it), and a loop shorter than 0.5 sqrt(area) counts as closed by the metric."""
    from scipy.sparse.csgraph import dijkstra

    from gromov.perturb import cut
    from gromov.shapes import icosphere

    bp = _module("bench_partial")
    assert bp.keeps("plane", 4) == pytest.approx([0.45, 0.55, 0.65, 0.75])
    assert bp.keeps("holes", 2) == pytest.approx([0.65, 0.75])
    sphere = icosphere(4)
    p = cut(sphere, 0.5, seed=0)
    part, truth = p.mesh, p.vertex_map
    region = bp.grow(sphere, truth)
    assert region.sum() > len(truth) and bp.iou(bp.grow(sphere, truth), region) == 1.0
    assert bp.iou(bp.grow(sphere, truth[: len(truth) // 2]), region) < 1.0
    d = bp.cut_distance(part, truth, sphere)
    boundary = np.unique(part.boundary_edges.ravel())
    assert (d[boundary] == 0).all() and (np.delete(d, boundary) > 0).all()
    np.testing.assert_allclose(d, dijkstra(part.adjacency, directed=False, indices=boundary, min_only=True))
    assert bp.fill_closed(part, truth, sphere) == (0, 1)          # a hemisphere's rim: open
    small = cut(sphere, 0.99, seed=0)                              # a small cap cut off: closed
    assert bp.fill_closed(small.mesh, small.vertex_map, sphere) == (1, 1)


def test_dense_tables_are_the_results_files():
    """docs/benchmarks.md's dense-map tables hold bench_dense.py's numbers (both results files)."""
    page = BENCHMARKS_PAGE.read_text()
    ours, placed = _json("dense.json"), _json("dense-placed.json")
    for ds in ("topkids",):
        for key, label in (("ours_samples", "ours, at our samples"), ("ours_dense", "**ours, dense**"),
                           ("pyfm_samples", "pyFM, at our samples"), ("pyfm_dense", "pyFM, dense")):
            r = ours[ds]["summary"][key]
            row = (f"| {label} | {r['mean']:.2f} | {r['median']:.2f} | {r['mean_direct']:.2f} | "
                   f"{r['gross']} | {r['seconds_per_pair']:.1f} |")
            assert row in page, row
        r = ours[ds]["summary"]["ours_dense_at_samples"]
        assert f"| ours, dense, read at our samples | {r['mean']:.2f} | {r['median']:.2f} | {r['mean_direct']:.2f} |" in page
        r = placed[ds]["summary"]["ours_dense"]
        assert f"placed only (`--dense placed`) | {r['mean']:.2f} | {r['median']:.2f} |" in page
    r = _json("dense_tosca.json")["tosca"]["summary"]["pyfm_dense"]
    assert f"| pyFM, dense | {r['mean']:.2f} | {r['median']:.2f} | {r['mean_direct']:.2f} | {r['gross']} |" in page
    rem = _json("dense.json")["remeshed"]
    for summary in (rem["summary"], rem["density"]["summary"]):
        r = summary["ours_dense"]
        assert f"| **ours, dense** | {r['mean']:.2f} | {r['median']:.2f} | {r['mean_direct']:.2f} |" in page
    pert = _json("dense.json")["perturbed"]
    for kind in ("holes", "weld"):
        r, q = pert[kind]["to_clean"]["ours_dense"], pert[kind]["to_clean"]["pyfm_dense"]
        assert f"| with {kind} → without | {r['mean']:.2f} | {r['median']:.2f} | {q['mean']:.2f} |" in page
    cost = _json("dense_cost.json")
    flat = page.replace("\n", " ")
    assert f"it adds {cost['added_s']:.2f} s to a {cost['seconds']['sparse']:.2f} s match" in flat
    placed_s = cost["seconds"]["placed"] - cost["seconds"]["sparse"]
    assert f"({placed_s:.2f} s without ZoomOut)" in flat



def _alternatives(path: str) -> list[str]:
    """A path as the docs write it, spelled out: ``a/{b,c}.json`` -> ``a/b.json``, ``a/c.json``;
    ``a[-x].json`` -> ``a.json``, ``a-x.json``."""
    import re

    m = re.search(r"\{([^{}]*)\}|\[([^\[\]]*)\]", path)
    if m is None:
        return [path]
    alts = m.group(1).split(",") if m.group(1) is not None else ["", m.group(2)]
    return [x for alt in alts for x in _alternatives(path[:m.start()] + alt + path[m.end():])]


def test_the_paths_the_docs_name_under_benchmarks_exist():
    """Every ``benchmarks/...`` path that the README, the docs (design notes, guides) and
    benchmarks/README.md name is there -- a study moved to benchmarks/studies/ with its results
    keeps its notes' commands working -- every script benchmarks/README.md lists is there, and
    every study it lists is cited by a design note with its path."""
    import re

    root = BENCH.parent
    listing = (BENCH / "README.md").read_text()
    pages = [README, BENCH / "README.md", *sorted((root / "docs").rglob("*.md"))]
    named = set()
    for page in pages:
        for m in re.finditer(r"benchmarks/[\w./{},\[\]-]*[\w/}\]]", page.read_text()):
            named.update(_alternatives(m.group(0)))
    named = {p for p in named if not re.search(r"[A-Z]", p.removeprefix("benchmarks/"))}   # SET, OUT: placeholders
    assert len(named) > 50
    missing = sorted(p for p in named if not (root / p).exists())
    assert not missing, missing
    comparisons, studies = listing.split("## Studies")
    for name in re.findall(r"^\| `(\w+\.py)` \|", comparisons, flags=re.M):
        assert (BENCH / name).is_file(), name
    listed = re.findall(r"^\| `(\w+\.py)` \|", studies, flags=re.M)
    assert len(listed) >= 16
    notes = " ".join(p.read_text() for p in (root / "docs" / "design").glob("*.md"))
    for name in listed:
        assert (STUDIES / name).is_file(), name
        assert f"benchmarks/studies/{name}" in notes, f"no design note gives the path of {name}"


def test_two_stage_read_off_the_complete_matrix():
    """With every other shape a candidate the two-stage search is brute force; with fewer, a
    query whose true neighbours lie beyond its candidates differs, and unmatched pairs rank last."""
    st = _module("recognition_two_stage")
    rng = np.random.default_rng(0)
    n = 12
    labels = np.repeat(np.arange(3), 4)
    D = rng.random((n, n))
    D = D + D.T
    np.fill_diagonal(D, 0.0)
    S = D[::-1, ::-1].copy()   # a first stage that disagrees with D
    full = st.two_stage(D, S, n - 1, 3, labels)
    assert full["pairs"] == n * (n - 1) // 2 and full["top_equal_list"] == 1.0
    few = st.two_stage(D, S, 2, 3, labels)
    assert few["pairs"] < full["pairs"] and few["top_equal_list"] < 1.0
    matched = np.eye(n, dtype=bool)
    matched[0, 1] = matched[1, 0] = True
    R = st.ranked_after(D, S, matched)
    assert R[0, 1] == D[0, 1] and (R[0, 2:] > D[matched].max()).all()


def test_partial_benchmark_keeps_a_given_span():
    bp = _module("bench_partial")
    assert bp.keeps("holes", 3, (0.25, 0.4)) == pytest.approx([0.275, 0.325, 0.375])


def test_eccentricity_study_quantiles_and_first_stage():
    """The eccentricity study's weighted quantiles follow the weights, and a first stage equal to
    the combined ranking holds every query's ten nearest at K = 10; a reversed one at none."""
    st = _module("recognition_eccentricity")
    v = np.array([3.0, 1.0, 2.0, 4.0])
    q = st.weighted_quantiles(v, np.ones(4), np.array([0.25, 1.0]))
    np.testing.assert_allclose(q, [1.0, 4.0])
    even = st.weighted_quantiles(v, np.ones(4), np.array([0.5]))
    heavy = st.weighted_quantiles(v, np.array([1.0, 1.0, 1.0, 97.0]), np.array([0.5]))
    assert even[0] == 2.0 and 3.0 < heavy[0] < 4.0   # the median moves towards the heavy value
    rng = np.random.default_rng(0)
    x = rng.random((25, 3))
    C = np.linalg.norm(x[:, None] - x[None], axis=2)
    m = {"C": C, "S": C, "E": C.max() - C + np.eye(25)}
    assert st.first_stage(m, {"S": 1}, ks=(10,))["K10"] == 1.0
    assert st.first_stage(m, {"E": 1}, ks=(10,))["K10"] == 0.0


def test_rerank_study_diffusion_separates_clusters():
    """The re-ranking study's diffusion: symmetric, and on two far clusters every within-cluster
    value lies below every between-cluster one (no walk of the nearest-neighbour graph crosses);
    ``plain`` is the symmetrised matrix."""
    st = _module("recognition_rerank")
    rng = np.random.default_rng(3)
    x = np.r_[rng.normal(0.0, 0.1, (8, 2)), rng.normal(5.0, 0.1, (8, 2))]
    D = np.linalg.norm(x[:, None] - x[None], axis=-1)
    D[0, 1] *= 1.5   # not symmetric
    R = st.diffusion_rerank(D, 5, 3)
    np.testing.assert_allclose(R, R.T)
    lab = np.r_[np.zeros(8), np.ones(8)]
    same = (lab[:, None] == lab[None]) & ~np.eye(16, dtype=bool)
    assert R[same].max() < R[lab[:, None] != lab[None]].min()
    np.testing.assert_allclose(st.rules()["plain"](D), 0.5 * (D + D.T))


def test_radius_study_caps_the_edges_by_the_area():
    """The neighbourhood study's cap: RELAX_EDGES without one or where the cap reaches farther,
    and fewer edges, in proportion to the cap, where it does not."""
    from gromov.dense import RELAX_EDGES
    from gromov.shapes import icosphere

    st = _module("probe_dense_radius")
    m = icosphere(3)
    assert st.capped_edges(m, m, None) == RELAX_EDGES
    assert st.capped_edges(m, m, 10.0) == RELAX_EDGES
    small, smaller = st.capped_edges(m, m, 0.01), st.capped_edges(m, m, 0.005)
    assert small < RELAX_EDGES and smaller == pytest.approx(small / 2)
    h = m.mean_edge_length
    assert small * h == pytest.approx(0.01 * np.sqrt(m.area))


def test_one_query_descent_read_off_the_complete_matrix():
    """Each shape the query of a store of the others: with every other shape in its first stage
    the search is brute force; with the first stage alone (factor 0) it matches C shapes a query;
    the descent matches a superset of them, so a query that was exact stays exact."""
    st = _module("recognition_two_stage")
    rng = np.random.default_rng(1)
    n = 14
    x = rng.normal(size=(n, 2))
    D = np.linalg.norm(x[:, None] - x[None], axis=-1)
    S = D[::-1, ::-1].copy()   # a first stage that disagrees with D
    full = st.query_descent(D, S, n - 1, 3, 1.5)
    assert full["top_equal_list"] == 1.0 and full["pairs_per_query"] == n - 1 and full["collection"] == n - 1
    first = st.query_descent(D, S, 2, 3, 0.0)
    assert first["pairs_per_query"] == 2 and first["top_equal_list"] < 1.0
    down = st.query_descent(D, S, 2, 3, 1.5)
    assert down["pairs_per_query"] > 2 and down["top_equal_list"] >= first["top_equal_list"]


def _symmetric(x):
    """``x + x.T`` with a zero diagonal: a distance-like matrix for the studies' scorers."""
    x = x + x.T
    np.fill_diagonal(x, 0.0)
    return x


def test_signature_weighted_rankings_find_the_statistic_that_separates_the_classes():
    """The S^a G^b GH^c H^d grid: the weights sum to 1, one row is the product's, the rows are
    ordered by J, and where H alone separates the classes (the others are noise) H alone has
    J = 0, the lowest, and a small weight on H does not."""
    from gromov.spectrum import SIGNATURE_WEIGHT

    st = _module("recognition_two_stage")
    rng = np.random.default_rng(2)
    labels = np.repeat(np.arange(3), 4)
    same = labels[:, None] == labels[None]

    mats = {"a": {"spectral": _symmetric(rng.uniform(1, 1e3, (12, 12))), "trimmed": _symmetric(rng.uniform(1, 1e3, (12, 12))),
                  "gh": _symmetric(rng.uniform(1, 1e3, (12, 12))),
                  "signature": _symmetric(np.where(same, 0.5, 2.0) * rng.uniform(1, 1.2, (12, 12)))}}
    rows = st.signature_local(mats, {"a": labels})
    assert all(abs(sum(r["weights"].values()) - 1.0) < 1e-9 and r["weights"]["signature"] > 0 for r in rows)
    assert [r["weights"]["signature"] for r in rows if r["product"]] == [SIGNATURE_WEIGHT]
    J = [r["pooled"]["J"] for r in rows]
    alone = next(r for r in rows if r["weights"]["signature"] == 1.0)["pooled"]["J"]
    assert J == sorted(J) and J[0] == alone == 0.0
    assert all(r["pooled"]["J"] > 0 for r in rows if r["weights"]["signature"] == 0.1)


def test_signature_weights_are_judged_on_the_classes_they_were_not_chosen_on():
    """Each split chooses on half of the classes (and the other collections) and scores the
    other half only; where H alone separates every class, the held-out half is perfect."""
    st = _module("recognition_two_stage")
    rng = np.random.default_rng(3)
    labels = np.repeat(np.arange(4), 3)
    same = labels[:, None] == labels[None]

    def mats():
        return {"spectral": _symmetric(rng.uniform(1, 1e3, (12, 12))), "trimmed": _symmetric(rng.uniform(1, 1e3, (12, 12))),
                "gh": _symmetric(rng.uniform(1, 1e3, (12, 12))),
                "signature": _symmetric(np.where(same, 0.5, 2.0) * rng.uniform(1, 1.2, (12, 12)))}

    out = st.signature_split({"a": mats(), "b": mats()}, {"a": labels, "b": labels}, "a", trials=3)
    assert len(out) == 3
    for r in out:
        assert len(r["chosen_on"]) == 2 and set(r["chosen_on"]) < set(labels.tolist())
        assert r["held_out"]["nn"] == 1.0 and r["held_out"]["eer"] == 0.0 and r["weights"]["signature"] > 0.5


def test_size_factor_is_chosen_where_the_size_separates_the_classes():
    """The product ranking times R^d: d = 0 is the product itself; where the product is noise
    and each class has a size of its own, a larger d separates the classes (J falls to 0), and
    the splits choose d > 0 and score the held-out half perfectly."""
    st = _module("recognition_two_stage")
    rng = np.random.default_rng(4)
    labels = np.repeat(np.arange(4), 3)

    def mats():
        area = np.log(10.0 ** labels * rng.uniform(1.0, 1.05, 12))
        return {"spectral": _symmetric(rng.uniform(1, 2, (12, 12))), "trimmed": _symmetric(rng.uniform(1, 2, (12, 12))),
                "gh": _symmetric(rng.uniform(1, 2, (12, 12))), "signature": _symmetric(rng.uniform(1, 2, (12, 12))),
                "size": np.exp(0.5 * np.abs(area[:, None] - area[None, :]))}

    m = {"a": mats(), "b": mats()}
    labs = {"a": labels, "b": labels}
    out = st.size_factor(m, labs, "a", trials=3)
    whole = {r["d"]: r["pooled"]["J"] for r in out["whole"]}
    product, _ = st.signature_weights()
    plain = st._scored({c: st._weighted(x, product) for c, x in m.items()}, labs)["pooled"]["J"]
    assert whole[0.0] == plain > 0 and whole[max(whole)] == 0.0
    for r in out["split"]:
        assert r["d"] > 0 and r["held_out"]["nn"] == 1.0 and r["held_out"]["eer"] == 0.0
        assert r["product"]["eer"] > 0


def test_scales_study_scores_each_scale_and_judges_it_on_held_out_classes():
    """recognition_scales: the grid's weights are non-negative and sum to 1; the combined ranking
    with G measured at half the time is gromov's; where the distortion at twice the time alone
    separates the classes, the splits choose it and score the held-out half perfectly."""
    from gromov.spectrum import combined

    st = _module("recognition_scales")
    w = st.grid_weights()
    assert len(w) == 286 and all(min(x) >= 0 and abs(sum(x) - 1) < 1e-9 for x in w)
    rng = np.random.default_rng(5)
    labels = np.repeat(np.arange(4), 3)
    same = labels[:, None] == labels[None]

    def mats():
        m = {k: _symmetric(rng.uniform(1, 1e3, (12, 12))) for k in ("S", "G", "H", "L@1", "L@4")}
        m["L@0.5"] = m["G"]
        m["L@2"] = _symmetric(np.where(same, 0.5, 2.0) * rng.uniform(1, 1.2, (12, 12)))
        return m

    m = {"a": mats(), "b": mats()}
    labs = {"a": labels, "b": labels}
    np.testing.assert_array_equal(st.product(m["a"]), combined(m["a"]["S"], m["a"]["G"], signature=m["a"]["H"]))
    one = [(f"G at {s:g}", lambda x, s=s: st.product(x, s)) for s in st.SCALES]
    alone = one + [("L@2 alone", lambda x: x["L@2"])]
    for r in st.split(m, labs, "a", alone, trials=3):
        assert r["chosen"] == "L@2 alone" and r["held_out"]["nn"] == 1.0 and r["held_out"]["eer"] == 0.0
        assert r["as_it_is"]["eer"] > 0


def test_pointwise_study_distortion_reads_the_sample_pairs():
    """The signature distortion of the pointwise study: zero for a pair whose signatures agree at
    every sample pair, the RMS of the differences otherwise; trimming keeps the best-fitting
    sample pairs, so one bad sample pair moves the trimmed value less than the full one."""
    st = _module("recognition_pointwise")
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 100, 12))
    b = a.copy()
    b[1] += 0.5                      # pair (0, 2): every sample pair off by 0.5 at every time
    b[2, 0] += 10.0                  # pair (1, 2): one sample pair far off
    m = {"S": np.zeros((3, 3)), "pairs": np.array([(0, 1), (0, 2), (1, 2)]), "a": a, "b": b}
    full = st.distortion(m, slice(None), 1.0)
    trimmed = st.distortion(m, slice(None), 0.8)
    assert full[0, 1] == 0.0 and full[1, 0] == 0.0
    assert full[0, 2] == pytest.approx(0.5) and trimmed[0, 2] == pytest.approx(0.5)
    assert full[1, 2] == pytest.approx(1.0) and trimmed[1, 2] == 0.0
    band = st.distortion(m, slice(0, 6), 1.0)
    assert band[1, 2] == pytest.approx(1.0)


def test_pointwise_study_reads_each_side_at_its_own_samples_and_images():
    """``read_along``: X's signature at X's samples and at Y's samples' images, Y's at X's
    samples' images and at Y's samples, each looked up by input vertex id (ids need not be
    0..n-1: a loader may drop vertices)."""
    st = _module("recognition_pointwise")
    # shape k: input ids 10 * k + (0..4), signature row r = [100 k + r, -(100 k + r)]
    sig = [(10 * k + np.arange(5), np.c_[100 * k + np.arange(5.0), -(100 * k + np.arange(5.0))]) for k in range(3)]
    ids = np.array([[[20, 21], [24, 23], [11, 10], [12, 13]]])   # x_samples, y_to_x, x_to_y, y_samples
    a, b = st.read_along(sig, np.array([(2, 1)]), ids)
    assert a.shape == b.shape == (1, 4, 2)
    assert a[0, :, 0].tolist() == [200, 201, 204, 203]   # X = shape 2: its samples, then Y's images on X
    assert b[0, :, 0].tolist() == [101, 100, 102, 103]   # Y = shape 1: X's images on Y, then its samples
    assert np.array_equal(a[0, :, 1], -a[0, :, 0])
