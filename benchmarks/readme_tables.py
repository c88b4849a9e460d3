"""Print the result tables of README.md and docs/benchmarks.md (Markdown) from the results files.

    .venv/bin/python benchmarks/readme_tables.py [RESULTS.json ...]

Without arguments: every table of the two pages, in order (the ``gromov reproduce`` runs on
the paper's classes + TOPKIDS, the held-out classes and the synthetic set, then the anchors
and each benchmark's table). With files: the tables of those ``gromov reproduce`` runs.
Every number is read from a file under ``benchmarks/results/``; the paper's are
:data:`gromov.experiments.report.PAPER`. Nothing is computed again, and tests/test_benchmarks.py
checks that the pages hold exactly these tables.
"""

from __future__ import annotations

import argparse
import json
import shlex
from pathlib import Path

import numpy as np

from gromov.experiments.report import PAPER, errors_text, other_classes

HERE = Path(__file__).resolve().parent / "results"
DEFAULT = [HERE / "reproduce-tosca" / "results.json", HERE / "reproduce-heldout" / "results.json",
           HERE / "synthetic" / "results.json"]
METRICS = ("geodesic", "diffusion")
EXPERIMENTS = (("weld", "Experiment 1 (welds)"), ("holes", "Experiment 2 (holes)"))
# the paper reports one correspondence number "with topology changes"; compared with both
# welds and holes, as the report does
PAPER_CONDITION = {"clean": "clean", "weld": "topology", "holes": "topology"}
#: bench_match.py's and bench_point_clouds.py's pairs, in their order
PAIRS = ("cat0-cat1", "dog0-dog1", "david0-david1", "victoria0-victoria1")


def load(name: str) -> dict:
    """A results file under benchmarks/results/ by its name (``"match.json"``)."""
    return json.loads((HERE / name).read_text())


def _pct(x) -> str:
    if x is None:
        return "–"
    return f"{100 * x:.1f}%" if 100 * x >= 10 or x == 0 else f"{100 * x:.2f}%"


def _num(x, digits: int = 3) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def _secs(x: float) -> str:
    return f"{x:.2f} s" if x < 10 else (f"{x:.1f} s" if x < 100 else f"{x:.0f} s")


def _paper(*keys):
    d = PAPER
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


# ----------------------------------------------------------------------- gromov reproduce
def command(r: dict) -> str:
    """The command a ``gromov reproduce`` run recorded, its output folder named by its last
    component only (the folder it was written to is not part of the result)."""
    words = shlex.split(r["command"])
    for i, w in enumerate(words[:-1]):
        if w == "--out":
            words[i + 1] = Path(words[i + 1]).name
    return shlex.join(words)


def caption(r: dict) -> str:
    """The command that made a ``gromov reproduce`` results file, with its time and date."""
    return f"`{command(r)}` — {r['seconds_total']:.0f} s on {r['jobs']} cores, {r['date']}"


def table(r: dict) -> str:
    """One Markdown table: rows of measures, columns geodesic / diffusion (ours, paper)."""
    rec, cor = r["recognition"], r["correspondence"]
    # the paper's columns only beside the paper's classes
    paper_cols = r.get("dataset") == "tosca" and not other_classes(r)
    head = "| | geodesic | diffusion |" + (" geodesic (paper) | diffusion (paper) |" if paper_cols else "")
    rule = "|---|---:|---:|" + ("---:|---:|" if paper_cols else "")
    rows = [head, rule]

    def row(label, ours, paper=None):
        cells = [label, *ours] + ([*(paper or ("–", "–"))] if paper_cols else [])
        rows.append("| " + " | ".join(cells) + " |")

    for exp, name in EXPERIMENTS:
        if exp not in rec:
            continue
        row(f"EER, {name}", [_pct(rec[exp][m]["eer"]) for m in METRICS],
            [_pct(_paper("eer", exp, m)) for m in METRICS])
    for exp, name in EXPERIMENTS:
        if exp in rec:
            row(f"EER by the GH estimate, {name}", [_pct(rec[exp][m]["eer_gh"]) for m in METRICS])
    for exp, name in EXPERIMENTS:   # a set-level normalisation: never beside the paper's numbers
        if exp in rec and "eer_local" in rec[exp]["diffusion"]:
            k = rec[exp]["diffusion"]["local_scaling_k"]
            row(f"EER after local scaling (k = {k}), {name}", [_pct(rec[exp][m]["eer_local"]) for m in METRICS])
    nn = [" / ".join(_pct(rec[e][m]["nn_accuracy"]) for e, _ in EXPERIMENTS if e in rec)
          for m in METRICS]
    row("nearest-neighbour accuracy, Exp. 1 / Exp. 2", nn)
    for cond in ("clean", "weld", "holes"):
        if cond not in cor["diffusion"]:
            continue
        ours = [f"{_num(cor[m][cond])} ({_num(cor[m].get(cond + '_direct'))})" for m in METRICS]
        row(f"d(C, C0) {'welds' if cond == 'weld' else cond}, best (direct)", ours,
            [_num(_paper("correspondence", m, PAPER_CONDITION[cond]), 4) for m in METRICS])
    t = r.get("topkids")
    if t:
        row("TOPKIDS d(C, C0), best (direct)",
            [f"{_num(t[m]['correspondence'])} ({_num(t[m]['correspondence_direct'])})" for m in METRICS])
        row("TOPKIDS GH ÷ diameter to kid00, mean; Spearman ρ with the handles",
            [f"{_num(t[m]['relative_distance_mean'])}; {_num(t[m]['spearman_distance_vs_handles'], 2)}"
             for m in METRICS])
    return "\n".join(rows)


def errors(r: dict) -> str:
    """Where the diffusion errors are at its EER threshold, per experiment (as the report says)."""
    out = []
    for exp, name in EXPERIMENTS:
        e = r["recognition"].get(exp, {}).get("diffusion", {}).get("errors_at_eer")
        if e:
            out.append(f"- {name}, diffusion, at its EER threshold: {errors_text(e)}.")
    return "\n".join(out)


# ----------------------------------------------------------------------------- benchmarks
def _match_mean(m: dict, metric: str, solver: str) -> float:
    return float(np.mean([m["accuracy"][f"{p}/{metric}/{solver}"]["best"] for p in PAIRS]))


def anchors_table() -> str:
    """gromov beside the tool a practitioner would otherwise use, one row per task."""
    f = load("foundation.json")["geodesic_all_pairs"]
    m, dense, fps = load("match.json"), load("dense.json"), load("cloud_sampling.json")
    e2e = load("speed.json")["end_to_end"]
    ours, heat = f["gromov fmm (ours)"], f["potpourri3d heat"]
    big = max(fps["rows"], key=lambda row: row["points"])
    tosca = load("dense_tosca.json")["tosca"]
    td, tt = dense["topkids"]["summary"], tosca["summary"]
    rem = dense["remeshed"]
    tr, tdn = rem["summary"], rem["density"]["summary"]
    pert = dense["perturbed"]
    two_stage = json.loads((HERE.parent / "studies" / "recognition_two_stage_signature.json").read_text())
    rows = [
        "| task | gromov | anchor |",
        "|---|---|---|",
        f"| geodesic distances, all pairs of a {f['n_vertices']:,}-vertex TOSCA cat: time; mean / max "
        f"error against exact geodesics | {_secs(ours['seconds'])}; {_pct(ours['mean_rel_err'])} / "
        f"{_pct(ours['max_rel_err'])} (fast marching) | {_secs(heat['seconds'])}; "
        f"{_pct(heat['mean_rel_err'])} / {_pct(heat['max_rel_err'])} (potpourri3d, heat method) |",
        f"| sample correspondence, {len(PAIRS)} TOSCA pairs, diffusion metric: mean error ÷ diameter "
        f"| {_num(_match_mean(m, 'diffusion', 'gmds'), 4)} (GMDS) | "
        f"{_num(_match_mean(m, 'diffusion', 'gw'), 4)} (POT, Gromov–Wasserstein) |",
        f"| time per match, cat0 → cat1, geodesic metrics prepared, one thread | {_secs(m['speed']['match_seconds'])} "
        f"| {m['speed']['pot_gw_seconds'] * 1000:.1f} ms (POT) |",
        f"| `gromov match cat0 cat1` end to end, a new process: time; sample error ÷ diameter | "
        f"{_secs(e2e['gromov_s'])}; {_num(e2e['gromov_error'], 4)} | {_secs(e2e['pipeline_s'])}; "
        f"{_num(e2e['pipeline_error'], 4)} (potpourri3d heat geodesics + POT) |",
        f"| dense map, {len(dense['topkids']['pairs'])} TOPKIDS pairs (real topological noise): mean "
        f"error × 100 / √area | {td['ours_dense']['mean']:.2f} | {td['pyfm_dense']['mean']:.2f} "
        "(pyFM, functional maps + ZoomOut) |",
        f"| dense map, {len(tosca['pairs'])} clean TOSCA pairs ({len(tosca['classes'])} classes): mean; median | "
        f"{tt['ours_dense']['mean']:.2f}; {tt['ours_dense']['median']:.2f} | {tt['pyfm_dense']['mean']:.2f}; "
        f"{tt['pyfm_dense']['median']:.2f} (pyFM) |",
        f"| dense map, {len(rem['pairs'])} TOSCA pairs each remeshed on its own ({len(rem['classes'])} classes): "
        f"mean; median | {tr['ours_dense']['mean']:.2f}; {tr['ours_dense']['median']:.2f} | "
        f"{tr['pyfm_dense']['mean']:.2f}; {tr['pyfm_dense']['median']:.2f} (pyFM) |",
        "| dense map, a shape against itself: remeshed at another density; with 20 holes; with 3 welds "
        "(both directions): mean; median | "
        + "; ".join(f"{d['ours_dense']['mean']:.2f}, {d['ours_dense']['median']:.2f}"
                    for d in (tdn, pert["holes"]["summary"], pert["weld"]["summary"])) + " | "
        + "; ".join(f"{d['pyfm_dense']['mean']:.2f}, {d['pyfm_dense']['median']:.2f}"
                    for d in (tdn, pert["holes"]["summary"], pert["weld"]["summary"])) + " (pyFM) |",
        f"| farthest point sampling, {big['points']:,} points → {big['samples']:,} | "
        f"{_secs(big['ours_s'])} | {_secs(big['fpsample_vanilla_s'])} / "
        f"{_secs(big['fpsample_quickfps_s'])} (fpsample, vanilla / QuickFPS) |",
        *collection_rows(load("collection_retrieval.json"), load("collection_resume.json"),
                         load("collection_dask.json")),
        partial_row(load("partial_refined.json"), load("partial.json")),
        recognition_row(load("recognition_full.json"), two_stage, load(two_stage["measured"]["file"])),
    ]
    return "\n".join(rows)


def partial_row(mode: dict, old: dict) -> str:
    """bench_partial.py: ``match(part, whole, partial=True)`` (``mode``) beside pyFM (``old``, the
    same seeded parts), as a row of the anchors table."""
    m, o = mode["summary"], old["summary"]
    n = sum(m[k]["pairs"] for k in ("plane", "holes"))
    ours = "; ".join(f"{m[k]['ours_partial']['mean']:.2f} / {m[k]['ours_partial']['median']:.2f}" for k in ("plane", "holes"))
    pyfm = "; ".join(f"{o[k]['pyfm']['mean']:.2f} / {o[k]['pyfm']['median']:.2f}" for k in ("plane", "holes"))
    gross = sum(m[k]["ours_partial"]["gross"] for k in ("plane", "holes"))
    gross_pyfm = sum(o[k]["pyfm"]["gross"] for k in ("plane", "holes"))
    return (f"| a part matched into another pose, {n} TOSCA parts (plane cuts; holes): dense error × 100 / √area, "
            f"mean / median; gross pairs | {ours}; {gross} of {n} (`partial=True`) | {pyfm}; {gross_pyfm} of {n} (pyFM) |")


def recognition_row(r: dict, study: dict | None = None, descent: dict | None = None) -> str:
    """bench_recognition.py on the whole watertight collection: gromov's combined ranking (every
    pair, or in two stages) beside Shape-DNA and the pooled HKS, as a row of the anchors table;
    with ``study`` (recognition_two_stage.py's JSON) and ``descent`` (the results file of its
    ``measured`` run), also the time of each shape's nearest by neighbour descent and for how
    many shapes they are brute force's."""
    c = r["collections"]["watertight"]
    rows = c["rows"]
    name, ours = next((k, v) for k, v in rows.items() if k.startswith("gromov --units area") and "(" not in k)
    dna, hks = rows["shapedna"], rows["hks"]
    pairs = c["shapes"] * (c["shapes"] - 1) // 2
    which = "all" if ours["pairs_matched"] == pairs else f"{ours['pairs_matched']:,} of"

    def eer(x):
        return "–" if x["eer"] is None else _pct(x["eer"])

    return (f"| recognition, SHREC'07 watertight, {c['shapes']} shapes of {len(c['classes'])} classes: "
            f"nearest neighbour; first tier; EER; time on 2 cores | {_pct(ours['nn'])}; {_pct(ours['ft'])}; "
            f"{eer(ours)}; {_minutes(ours['seconds'])} (`{name[len('gromov '):]}`: {which} {pairs:,} pairs)"
            f"{_descent_cell(study, descent)} | "
            f"{_pct(dna['nn'])}; {_pct(dna['ft'])}; {eer(dna)}; {_minutes(dna['seconds'])} (Shape-DNA); "
            f"{_pct(hks['nn'])}; {_pct(hks['ft'])}; {eer(hks)}; {_minutes(hks['seconds'])} (pooled HKS) |")


def _descent_cell(study: dict | None, descent: dict | None) -> str:
    """``; each shape's 10 nearest: T (...)`` of a measured neighbour-descent run, or nothing."""
    m = (study or {}).get("measured")
    if not m or descent is None:
        return ""
    name = next(k for k in descent["collections"]["watertight"]["rows"] if "--candidates" in k and "(" not in k)
    flags = name[name.index("--candidates"):]
    return (f"; each shape's {study['top']} nearest: {_minutes(m['seconds'])} (`{flags}`: "
            f"{m['pairs_matched']:,} pairs; brute force's {study['top']} for {_pct(m['top_equal_list'])} of the shapes)")


def _minutes(s: float) -> str:
    return f"{s / 60:.1f} min" if s >= 120 else f"{s:.0f} s"


def collection_rows(r: dict, runs: dict, dask: dict) -> list[str]:
    """bench_collection.py, as rows of the anchors table: a collection (the runs of ``runs``), its
    retrieval (``r``) and the Dask comparison (``dask``, of ``--only dask``)."""
    sc, again, kill, d = runs["scratch"], runs["again"], runs["kill"], dask["dask"]
    ret, rec = r["retrieval"]["rows"], runs["recognition"]

    def same(x):
        return "same matrices" if x["identical"] else "**other matrices**"

    return [
        f"| {runs['shapes']} TOSCA shapes, all {runs['pairs']:,} pairs, 2 cores: from scratch; killed at 30% and 70% "
        f"and resumed ({same(kill)}); again on its store ({same(again)}); nearest-neighbour accuracy, EER | "
        f"{_minutes(sc['seconds'])}; {_minutes(kill['seconds'])}; {_minutes(again['seconds'])}; "
        f"{_pct(rec['nn_accuracy'])}, {_pct(rec['eer'])} | |",
        f"| the pairs of {d['shapes']} shapes on a Dask cluster of 2 workers: throughput (pairs alone; whole run), "
        f"median of {len(d['rounds'])} rounds | {d['throughput_ratio_match']:.2f}; {d['throughput_ratio_total']:.2f} "
        f"| 1 (`--jobs 2`, processes) |",
        f"| the {r['retrieval']['k']} nearest of each of {r['shapes']} shapes: full matches (recall), all at once; "
        f"one query at a time (`gromov search`, a store `gromov pairwise` filled) | "
        f"{ret['knn_pairs bound']['full_matches']:,} exact ({ret['knn_pairs bound']['recall']:.3f}); "
        f"{ret['knn_pairs profile']['full_matches']:,} default ({ret['knn_pairs profile']['recall']:.3f}); "
        f"{ret['nearest profile']['full_matches']:,} of {ret['nearest profile']['pairs']:,} "
        f"({ret['nearest profile']['recall']:.3f}) | {r['pairs']:,} (all pairs); {ret['nearest profile']['pairs']:,} |",
    ]


RETRIEVAL_LABELS = {
    "knn_pairs profile": "every shape at once (`gh_matrix(k=)`), default pruning",
    "knn_pairs profile, no triangle": "every shape at once, without the triangle estimates",
    "knn_pairs profile 0.4": "every shape at once, slack 0.4, without the triangle estimates",
    "knn_pairs bound": "every shape at once, exact pruning (`prune=\"bound\"`)",
    "nearest profile": "one query at a time (`gromov search`), default pruning, a store `gromov pairwise` filled",
    "nearest profile, k nearest known": "one query at a time, a store holding the pairs `gh_matrix(k=5)` matched",
    "nearest profile, none known": "one query at a time, a store only indexed (no triangle estimates)",
    "nearest profile 0.4": "one query at a time, slack 0.4, a store only indexed",
    "nearest bound": "one query at a time, exact pruning"}


def collection_runs(r: dict) -> str:
    """bench_collection.py: the runs alone (from scratch, again, killed and resumed) and recognition."""
    base = r["scratch"]["seconds"]
    sc, again, kill = r["scratch"], r["again"], r["kill"]
    rows = ["| run | seconds | × from scratch | notes |", "|---|---:|---:|---|",
            f"| all {r['pairs']:,} pairs from scratch (metrics and pairs) | {base:.0f} | 1.00 | "
            f"{r['pairs'] / base:.2f} pairs/s; a store of {sc['store_mb']:,.0f} MB |",
            f"| the same command again on its store | {again['seconds']:.0f} | {again['seconds'] / base:.2f} | "
            f"{again['shapes_read']} shapes and {again['pairs_read']:,} pairs read back; same matrices: "
            f"{'yes' if again['identical'] else 'no'} |",
            f"| killed (SIGKILL) at 30% and 70% of the pairs, run to the end | {kill['seconds']:.0f} | "
            f"{kill['seconds'] / base:.2f} | runs of " + " + ".join(f"{x['seconds']:.0f}" for x in kill["runs"])
            + f" s; same matrices: {'yes' if kill['identical'] else 'no'}; store problems: "
            f"{len(kill['store_problems'])} |"]
    rec = r["recognition"]
    rows += ["", f"Nearest-neighbour accuracy {_pct(rec['nn_accuracy'])}; EER {_pct(rec['eer'])} (by the GH "
             f"estimate {_pct(rec['eer_gh'])}, after local scaling with k = {rec['local_scaling_k']} "
             f"{_pct(rec['eer_local'])})."]
    return "\n".join(rows)


def retrieval_table(r: dict) -> str:
    """bench_collection.py --only retrieval: the retrieval rows."""
    rows = [f"| the {r['retrieval']['k']} nearest | recall | queries as brute force | full matches | fewer |",
            "|---|---:|---:|---:|---:|"]
    for name, row in r["retrieval"]["rows"].items():
        rows.append(f"| {RETRIEVAL_LABELS.get(name, name)} | {row['recall']:.3f} | {row['exact_queries']}/{row['queries']} | "
                    f"{row['full_matches']:,}/{row['pairs']:,} | {row['fewer']:.1f}× |")
    return "\n".join(rows)


def dask_table(r: dict) -> str:
    """bench_collection.py --only dask: each round, --jobs then a LocalCluster, and the medians."""
    d = r["dask"]
    rows = ["| round | `--jobs 2`: all, pairs (s) | LocalCluster of 2: all, start, pairs (s) | pairs | whole run |",
            "|---:|---:|---:|---:|---:|"]
    for i, x in enumerate(d["rounds"]):
        rows.append(f"| {i + 1} | {x['jobs']['seconds']:.1f}, {x['jobs']['match']:.1f} | {x['dask']['seconds']:.1f}, "
                    f"{x['dask']['cluster_start']:.1f}, {x['dask']['match']:.1f} | {x['throughput_ratio_match']:.2f}× | "
                    f"{x['throughput_ratio_total']:.2f}× |")
    rows.append(f"| median | | | {d['throughput_ratio_match']:.2f}× | {d['throughput_ratio_total']:.2f}× |")
    rows += ["", f"{d['shapes']} shapes, {d['pairs']} pairs; throughput of the cluster over that of the processes; "
             f"same matrices in every round: {'yes' if d['identical'] else 'no'}."]
    return "\n".join(rows)


FOUNDATION_LABELS = {
    "gromov fmm (ours)": "gromov fast marching (ours)",
    "gromov fmm refine=1": "ours, `refine=1` (every triangle split in four once)",
    "gromov fmm refine=2": "ours, `refine=2` (split twice)",
    "potpourri3d heat": "potpourri3d heat method",
    "potpourri3d fmm": "potpourri3d fast marching (geometry-central)",
}


def foundation_table(r: dict) -> str:
    """Geodesic distances between all pairs of vertices: time and error of each method."""
    g = r["geodesic_all_pairs"]
    ours = g["gromov fmm (ours)"]["seconds"]
    rows = ["| method | time | vs ours | mean rel. error | max rel. error |",
            "|---|---:|---:|---:|---:|"]
    for key, label in FOUNDATION_LABELS.items():
        e = g[key]
        rows.append(f"| {label} | {_secs(e['seconds'])} | {e['ratio_to_ours']:.2f}× | "
                    f"{_pct(e['mean_rel_err'])} | {_pct(e['max_rel_err'])} |")
    exact = g["exact_seconds_extrapolated"]
    rows.append(f"| exact MMP (pygeodesic), extrapolated from {g['sources']} sources | {_secs(exact)} | "
                f"{exact / ours:.2f}× | 0 | 0 |")
    return "\n".join(rows)


def foundation_steps(r: dict) -> str:
    """The other set-up steps of the foundation benchmark."""
    d, ls = r["diffusion"], r["load_simplify"]
    return "\n".join([
        "| step | gromov | reference |",
        "|---|---:|---:|",
        f"| graph diffusion distances, all pairs ({d['graph_eigenpairs']} eigenpairs; max rel. error "
        f"{d['graph_max_rel_err_vs_dense']:.1e}) | {_secs(d['graph_spectral_seconds'])} | "
        f"{_secs(d['graph_dense_seconds'])} (dense eigendecomposition) |",
        f"| heat-kernel diffusion distances, all pairs | {_secs(d['heat_seconds'])} | – |",
        f"| load a {ls['n_vertices']:,}-vertex OFF file | {_secs(ls['load_seconds'])} | "
        f"{_secs(ls['trimesh_load_seconds'])} (trimesh) |",
        f"| simplify it to {ls['working_vertices']:,} vertices | {_secs(ls['simplify_seconds'])} | – |",
    ])


def match_table(r: dict) -> str:
    """bench_match.py: error of each pair's sample images ÷ diameter (better reading)."""
    rows = ["| pair | geodesic, GMDS | geodesic, GW (POT) | diffusion, GMDS | diffusion, GW (POT) |",
            "|---|---:|---:|---:|---:|"]
    keys = [(m, s) for m in METRICS for s in ("gmds", "gw")]
    for p in PAIRS:
        cells = []
        for m, s in keys:
            a = r["accuracy"][f"{p}/{m}/{s}"]
            cells.append(_num(a["best"], 4) + (" (mirrored)" if a["branch"] == "mirrored" else ""))
        rows.append(f"| {p.replace('-', ' → ')} | " + " | ".join(cells) + " |")
    rows.append("| mean | " + " | ".join(_num(_match_mean(r, m, s), 4) for m, s in keys) + " |")
    return "\n".join(rows)


def match_speed(r: dict) -> str:
    """bench_match.py's timings."""
    s = r["speed"]
    return "\n".join([
        "| timing | seconds |",
        "|---|---:|",
        f"| `gromov.match`, cat0 → cat1, geodesic, metrics prepared, one thread | {s['match_seconds']:.3f} |",
        f"| the same with `search_vertices=500` | {s['match_search500_seconds']:.3f} |",
        f"| POT `gromov_wasserstein` on the same two sample matrices | {s['pot_gw_seconds']:.4f} |",
        f"| `gromov match cat0.off.gz cat1.off.gz` as a new process, diffusion (default) | "
        f"{s['end_to_end_diffusion_seconds']:.2f} |",
        f"| the same with `--metric geodesic` | {s['end_to_end_geodesic_seconds']:.2f} |",
    ])


def speed_table(r: dict) -> str:
    """bench_speed.py: first run, start-up, one pair, end to end, welds."""
    f, st, p, e = r["first_run"], r["startup"], r["one_pair"], r["end_to_end"]
    rows = ["| what | gromov | anchor | ratio |", "|---|---:|---:|---:|",
            f"| first `gromov match cat0 cat1` after install (empty numba cache) | {_secs(f['cold_s'])} | "
            f"{_secs(f['warm_s'])} (the same, warm) | {f['ratio']:.2f} |",
            f"| `import gromov`; `gromov --help` | {_secs(st['import_s'])}; {_secs(st['help_s'])} | "
            f"{_secs(st['python_s'])} (Python alone) | |",
            f"| one pair of a matrix, metrics computed, one thread | {_secs(p['ours'])} | "
            f"{p['pot'] * 1000:.1f} ms (POT Gromov–Wasserstein) | {p['ratio']:.0f} |",
            f"| `gromov match cat0 cat1` end to end | {_secs(e['gromov_s'])} | {_secs(e['pipeline_s'])} "
            f"(potpourri3d + POT) | {e['time_ratio']:.2f} |",
            f"| its sample error ÷ diameter | {_num(e['gromov_error'], 4)} | {_num(e['pipeline_error'], 4)} | "
            f"{e['error_ratio']:.2f} |",
            f"| the same with `--metric geodesic` | {_secs(e['gromov_geodesic_s'])} | | |"]
    for name, w in r["weld"].items():
        state = f"{w['seconds']:.1f} s, {w['peak_mb']:.0f} MB" if w["ok"] else "no weld sites"
        rows.append(f"| `gromov perturb weld {name} --count 3` | {state} | | |")
    return "\n".join(rows)


DENSE_LABELS = (("ours_samples", "ours, at our samples"), ("ours_dense", "**ours, dense**"),
                ("pyfm_samples", "pyFM, at our samples"), ("pyfm_dense", "pyFM, dense"))


def dense_table(summary: dict, placed: dict | None = None) -> str:
    """bench_dense.py's summary of one data set: the dense map beside pyFM's (and without a
    refinement, where ``placed``, the summary of a ``--dense placed`` run, is given)."""
    rows = ["| map | mean | median | mean, direct | gross | s / pair |", "|---|---|---|---|---|---|"]
    for key, label in DENSE_LABELS:
        r = summary[key]
        rows.append(f"| {label} | {r['mean']:.2f} | {r['median']:.2f} | {r['mean_direct']:.2f} | "
                    f"{r['gross']} | {r['seconds_per_pair']:.1f} |")
    if "ours_dense_at_samples" in summary:   # the dense map on the same points as our samples
        r = summary["ours_dense_at_samples"]
        rows.append(f"| ours, dense, read at our samples | {r['mean']:.2f} | {r['median']:.2f} | "
                    f"{r['mean_direct']:.2f} | {r['gross']} | |")
    if placed is not None:
        r = placed["ours_dense"]
        rows.append(f"| ours, dense, placed only (`--dense placed`) | {r['mean']:.2f} | {r['median']:.2f} | "
                    f"{r['mean_direct']:.2f} | {r['gross']} | |")
    return "\n".join(rows)


def perturbed_table(r: dict) -> str:
    """bench_dense.py --perturbed: a remeshed pose against itself with holes or welds, each way."""
    rows = ["| pairs | ours, dense: mean | median | pyFM, dense: mean | median | ours, at our samples: mean "
            "| gross (ours / pyFM) |", "|---|---|---|---|---|---|---|"]
    for kind in ("holes", "weld"):
        for part, label in (("to_clean", f"with {kind} → without"), ("to_noisy", f"without → with {kind}")):
            d = r[kind][part]
            rows.append(f"| {label} | {d['ours_dense']['mean']:.2f} | {d['ours_dense']['median']:.2f} | "
                        f"{d['pyfm_dense']['mean']:.2f} | {d['pyfm_dense']['median']:.2f} | "
                        f"{d['ours_samples']['mean']:.2f} | {d['ours_dense']['gross']} / {d['pyfm_dense']['gross']} |")
    return "\n".join(rows)


def cloud_sampling_table(r: dict) -> str:
    """bench_cloud_sampling.py: Euclidean farthest point sampling of large clouds."""
    rows = ["| random normal cloud → samples | ours | general loop | fpsample vanilla | fpsample QuickFPS "
            "| ours / vanilla | ours / QuickFPS |", "|---|---:|---:|---:|---:|---:|---:|"]
    for c in r["rows"]:
        rows.append(f"| {c['points']:,} points → {c['samples']:,} | {_secs(c['ours_s'])} | "
                    f"{_secs(c['ours_general_loop_s'])} | {_secs(c['fpsample_vanilla_s'])} | "
                    f"{_secs(c['fpsample_quickfps_s'])} | {c['ours_s'] / c['fpsample_vanilla_s']:.2f} | "
                    f"{c['ours_s'] / c['fpsample_quickfps_s']:.1f} |")
    return "\n".join(rows)


def point_clouds_table(r: dict) -> str:
    """bench_point_clouds.py: the same pairs matched as meshes, as clouds, as half clouds."""
    names = [p.split("-")[0].rstrip("0123456789") for p in PAIRS]
    rows = ["| best error | " + " | ".join(names) + " | mean | s per match |",
            "|---|" + "---:|" * (len(PAIRS) + 2)]
    for m in ("diffusion", "geodesic"):
        for kind, label in (("mesh", "meshes"), ("cloud", "clouds"), ("half cloud", "half clouds")):
            cells = [r["rows"][f"{p}/{m}/{kind}"] for p in PAIRS]
            secs = [c["seconds"] for c in cells]
            rows.append(f"| {m}, {label} | " + " | ".join(_num(c["best"], 4) for c in cells)
                        + f" | {_num(r['mean_best'][f'{m}/{kind}'], 4)} | {min(secs):.1f}–{max(secs):.1f} |")
    return "\n".join(rows)


def recognition_table(r: dict) -> str:
    """bench_recognition.py with every pair matched, on the watertight collection and on TOSCA:
    each method's retrieval scores and time; the rows that read the combined ranking's matches
    again (without the signature distortion, after the diffusion re-ranking) have no time."""
    rw, rt = r["collections"]["watertight"]["rows"], r["collections"]["tosca"]["rows"]
    names = {"shapedna": "Shape-DNA (input mesh, 50 eigenvalues)", "hks": "pooled heat kernel signature (input mesh)"}
    ours = next(k for k in rw if k.startswith("gromov --units area") and "(" not in k)
    names[ours] = f"gromov `{ours[len('gromov '):]}`, every pair"
    names[f"{ours} (without the signature distortion)"] = "the same matches, without the signature distortion"
    names[f"{ours} (after the diffusion re-ranking)"] = "the same, after the diffusion re-ranking (set-level)"
    out = ["| method (whole collection) | watertight NN | FT | ST | EER | time, 2 cores | TOSCA NN | FT | EER | time |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def time(x):
        return _minutes(x["seconds"]) if "seconds" in x else "–"

    for key, name in names.items():
        a, b = rw[key], rt[key]
        out.append(f"| {name} | {_pct(a['nn'])} | {_pct(a['ft'])} | {_pct(a['st'])} | {_pct(a['eer'])} | "
                   f"{time(a)} | {_pct(b['nn'])} | {_pct(b['ft'])} | {_pct(b['eer'])} | {time(b)} |")
    return "\n".join(out)


def two_stage_table(r: dict) -> str:
    """benchmarks/studies/recognition_two_stage.py: the two-stage search read off the complete
    matrix, for each number of candidates."""
    out = ["| C | pairs matched | queries whose 10 nearest are brute force's | NN | estimated time |",
           "|---:|---:|---:|---:|---:|"]
    for x in r["two_stage"]:
        out.append(f"| {x['candidates']} | {x['pairs']:,} | {_pct(x['top_equal_list'])} | {_pct(x['nn'])} | "
                   f"{_minutes(x['estimated_seconds'])} |")
    return "\n".join(out)


def benchmark_tables() -> list[tuple[str, str]]:
    """Every benchmark table of docs/benchmarks.md, each with the results file it reads."""
    f, m = load("foundation.json"), load("match.json")
    dense, placed = load("dense.json"), load("dense-placed.json")
    remeshed = dense["remeshed"]
    return [("foundation.json", foundation_table(f)), ("foundation.json", foundation_steps(f)),
            ("match.json", match_table(m)), ("match.json", match_speed(m)),
            ("dense.json, dense-placed.json", dense_table(dense["topkids"]["summary"], placed["topkids"]["summary"])),
            ("dense_tosca.json", dense_table(load("dense_tosca.json")["tosca"]["summary"])),
            ("dense.json", dense_table(remeshed["summary"])),
            ("dense.json", dense_table(remeshed["density"]["summary"])),
            ("dense.json", perturbed_table(dense["perturbed"])),
            ("cloud_sampling.json", cloud_sampling_table(load("cloud_sampling.json"))),
            ("point_clouds.json", point_clouds_table(load("point_clouds.json"))),
            ("speed.json", speed_table(load("speed.json"))),
            ("collection.json", collection_runs(load("collection.json"))),
            ("collection_retrieval.json", retrieval_table(load("collection_retrieval.json"))),
            ("collection_resume.json", collection_runs(load("collection_resume.json"))),
            ("collection_dask.json", dask_table(load("collection_dask.json"))),
            ("recognition_full.json", recognition_table(load("recognition_full.json"))),
            ("recognition_two_stage_signature.json", two_stage_table(
                json.loads((HERE.parent / "studies" / "recognition_two_stage_signature.json").read_text())))]


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="*", type=Path, default=None)
    a = p.parse_args(argv)
    for f in a.files or DEFAULT:
        r = json.loads(f.read_text())
        print(f"### {f.relative_to(HERE.parent.parent) if f.is_relative_to(HERE.parent.parent) else f}")
        print(caption(r) + "\n")
        print(table(r))
        print()
        print(errors(r))
        print()
    if a.files:
        return
    print("### anchors (foundation.json, match.json, speed.json, dense.json, cloud_sampling.json)\n")
    print(anchors_table() + "\n")
    for name, tab in benchmark_tables():
        print(f"### {name}\n")
        print(tab + "\n")


if __name__ == "__main__":
    main()
