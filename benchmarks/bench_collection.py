"""A collection of shapes with a store: from scratch, read back, killed and resumed, searched, on Dask.

Run:  nice -n 10 .venv/bin/python benchmarks/bench_collection.py [--data DIR] [--classes cat,wolf,...]
          [--jobs 2] [--store DIR] [--json benchmarks/results/collection.json]
          [--skip rematch,kill,retrieval,dask] [--dask-classes centaur,horse] [--only dask|retrieval]
          [--retrieval-store DIR]

The shapes are TOSCA's (:class:`gromov.experiments.datasets.TOSCA`: 80 shapes of 9 classes;
``--classes`` a subset), matched with the defaults of ``gromov pairwise`` (diffusion metric, heat
kernel, 3,000-vertex working meshes, 100 samples, ranked by the trimmed distortion). Every run of
``gromov pairwise`` is a subprocess, timed by its wall clock (start-up included); the stores are
fresh folders under ``--store``.

1. scratch: ``gromov pairwise FILES --store S1 --jobs J --out scratch.npz --labels-from-names
   --json``: every metric computed, every pair matched and recorded.
2. again: the same command on S1: the shapes and the pairs read back (the JSON's ``store``
   counters say how many), the matrices compared with (1)'s bit for bit.
3. rematch: the same on S1 with ``--seed 1``: the metrics read back, every pair matched again
   (other samples, so other pair records): the time of the pairs alone.
4. recognition: the nearest-neighbour accuracy and the equal error rates (trimmed, GH, locally
   scaled) of (1), by the classes of the file names, as ``gromov pairwise`` reports them.
5. retrieval: every shape as the query of :func:`gromov.retrieval.nearest` over the others, and
   every shape's k nearest at once (:func:`gromov.retrieval.knn_pairs`), with the default pruning
   (``prune="profile"``: the profile gap and the triangle estimates), without the triangle
   estimates, with slack 0.4, and the exact one (``prune="bound"``), against brute force on (1)'s
   trimmed matrix (ties to the lower index): recall@k, the queries whose k nearest are brute
   force's in order, and the full matches against all pairs. A query knows the values between
   the other shapes that its store would hold: all (after ``gromov pairwise``), those
   ``knn_pairs`` matched (after ``gh_matrix(k=...)``), or none; never its own. The bounds come
   from the shapes read from S1; a full match is replaced by the value (1) found for the pair
   (the same match, same options: ``knn_pairs``'s ``run`` and, for ``nearest``, its
   ``_match``), so no pair is matched again. ``--only retrieval`` runs ``gromov pairwise`` on
   ``--retrieval-store DIR`` (reading back what it holds) and then this part alone.
6. dask: on ``--dask-classes`` (default centaur and horse, 14 shapes), what
   ``gromov pairwise --dask 2`` runs -- a ``LocalCluster`` of 2 one-thread workers
   (:func:`gromov._dask.client_for`) and :func:`gromov.experiments.gh_matrix` with ``client`` --
   against ``gh_matrix(jobs=2)``, both without a store, in this process, ``--dask-rounds`` times
   by turns (default 3): pairs per second of the matching alone and of the whole run (cluster
   start, metrics and pairs), each round's ratios and their medians, and whether the matrices
   are identical. ``--only dask`` runs this part alone and writes only it (a larger
   comparison: ``--only dask --dask-classes centaur,horse,david,gorilla --json
   benchmarks/results/collection_dask.json``, 25 shapes, 300 pairs).

7. kill: a fresh store S2; ``gromov pairwise`` killed (SIGKILL to its process group) once 30%
   of the pairs are recorded in S2's catalogue (read-only polling), started again and killed at
   70%, then run to the end: the total time, the pairs read back by the last run, and its
   matrices compared with (1)'s bit for bit.
Resources, for all 80 shapes: ``gh_matrix`` holds every prepared shape in memory (about 95 MB
each at 3,000 vertices), shared with its forked workers: the ``gromov pairwise`` process of
(1), (2), (3) and (7) with its two workers peaked at 9.1 GB (the sum of their proportional set
sizes, sampled every 5 s); step 5 holds the 80 shapes read back from S1 in this process (about
80 MB each, 6.5 GB). A store takes about 93 MB of disk per shape, 7.4 GB for all 80; S1 is removed
before S2 is made when ``--store`` is not given. On 2 cores all 3,160 pairs take about 24 minutes
from scratch (metrics included), and so do (3) and (7); the whole run about an hour with
``--skip rematch``. The results file is written after every part (``"complete": false`` until
the last); ``--classes wolf,centaur --dask-classes wolf,centaur`` (9 shapes) checks the script in about 5
minutes. Timings on a shared machine are noisy; the results file records the CPU.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import math
import os
import shlex
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from unittest import mock

import numpy as np
from _common import HERE, add_data_argument, write_results

from gromov import retrieval
from gromov.experiments.datasets import TOSCA
from gromov.gh import RANK_TAU_SCALE
from gromov.store import CATALOGUE, ShapeStore

PARTS = ("rematch", "kill", "retrieval", "dask")
MATRICES = ("distance", "relative_distance", "relative_trimmed_distance")
KILL_AT = (0.3, 0.7)
K = 5
#: A slack beside the default: the largest at which recall stays 1.0 on the validation sets.
LARGER_SLACK = 0.4


# ----------------------------------------------------------------------------- gromov pairwise
def pairwise_cmd(files, store, out, jobs, *extra) -> list[str]:
    return [sys.executable, "-m", "gromov", "pairwise", *map(str, files), "--store", str(store),
            "--jobs", str(jobs), "--out", str(out), "--labels-from-names", "--json", *extra]


def n_pairs(store: Path) -> int | None:
    """Pairs recorded in a store's catalogue (read-only), None while it cannot be read."""
    path = store / CATALOGUE
    if not path.exists():
        return 0
    try:
        with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=10)) as db:
            return db.execute("SELECT count(*) FROM pairs").fetchone()[0]
    except sqlite3.OperationalError:   # being created
        return None


def run_cli(cmd, log: Path, *, store: Path | None = None, kill_at: int | None = None, poll: float = 0.1):
    """Run ``cmd`` in its own process group, stderr to ``log``; with ``kill_at``, SIGKILL the
    group once ``store`` records that many pairs. ``(wall seconds, JSON result or None, killed,
    pairs recorded after)``."""
    with open(log, "ab") as err, tempfile.TemporaryFile() as out:
        t = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, start_new_session=True)
        killed = False
        try:
            while proc.poll() is None:
                if kill_at is not None and (n_pairs(store) or 0) >= kill_at:
                    os.killpg(proc.pid, signal.SIGKILL)
                    killed = True
                    break
                time.sleep(poll)
            proc.wait()
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        wall = time.perf_counter() - t
        out.seek(0)
        text = out.read().decode()
    if not killed and proc.returncode != 0:
        raise RuntimeError(f"{shlex.join(cmd[:4])} ... exited with {proc.returncode}; see {log}")
    result = json.loads(text) if not killed else None
    return wall, result, killed, (n_pairs(store) if store is not None else None)


def matrices(path: Path) -> dict:
    with np.load(path) as z:
        return {k: z[k] for k in MATRICES}


def same(a: dict, b: dict) -> bool:
    return all(np.array_equal(a[k], b[k]) for k in MATRICES)


# ----------------------------------------------------------------------------- retrieval
def brute(T: np.ndarray, k: int) -> list[list[int]]:
    """Each row's k nearest others by value, ties to the lower index."""
    n = len(T)
    return [[j for _, j in sorted((T[i, j], j) for j in range(n) if j != i)[:k]] for i in range(n)]


def retrieval_rows(shapes, D, R, T, k: int) -> dict:
    """recall@k, exact queries and full matches of ``nearest`` (per query) and ``knn_pairs``
    (all at once), with each pruning, the values looked up in (1)'s matrices.

    ``nearest`` with the default pruning is run three times, as the store it searches would
    give it the values between the other shapes (its triangle estimates' pivots): all of them
    (a store after ``gromov pairwise``), those ``knn_pairs`` matched with the default pruning (a
    store after ``gh_matrix(k=...)``), and none (a store after ``gromov index`` only). The
    query's own pairs are never known to it."""
    n = len(shapes)
    k = min(k, n - 1)
    truth = brute(T, k)
    at = {id(s): i for i, s in enumerate(shapes)}

    looked = []

    def looked_up(x, y, metric, **options):   # the match nearest() would run: its value from (1)
        i, j = at[id(x)], at[id(y)]
        looked.append((i, j))
        return SimpleNamespace(ranking_distance=T[i, j], relative_distance=R[i, j])

    ran = []

    def run(take):   # knn_pairs: gh_matrix's worker results (distance, relative, trimmed), from (1)
        ran.extend(take)
        return [(D[i, j], R[i, j], T[i, j]) for i, j in take]

    out = {}
    default_t = retrieval.TRIANGLE_SLACK
    matched_by_knn = set()
    for prune, slack, t, name in (("profile", retrieval.PROFILE_SLACK, default_t, "profile"),
                                  ("profile", retrieval.PROFILE_SLACK, 0, "profile, no triangle"),
                                  ("profile", LARGER_SLACK, 0, f"profile {LARGER_SLACK:g}"),
                                  ("bound", retrieval.PROFILE_SLACK, 0, "bound")):
        ran.clear()
        r = retrieval.knn_pairs(shapes, k, run, prune=prune, slack=slack, triangle_slack=t)
        got = [r.neighbors[i].tolist() for i in range(n)]
        out[f"knn_pairs {name}"] = {
            "recall": float(np.mean([len(set(got[i]) & set(truth[i])) / k for i in range(n)])),
            "exact_queries": int(sum(got[i] == truth[i] for i in range(n))), "queries": n,
            "full_matches": int(r.full_matches), "pairs": n * (n - 1) // 2}
        assert r.full_matches == len(ran)
        if name == "profile":
            matched_by_knn = set(r.results)
    everything = {(i, j) for i in range(n) for j in range(i + 1, n)}
    for prune, slack, t, known, name in (
            ("profile", retrieval.PROFILE_SLACK, default_t, everything, "profile"),
            ("profile", retrieval.PROFILE_SLACK, default_t, matched_by_knn, "profile, k nearest known"),
            ("profile", retrieval.PROFILE_SLACK, default_t, set(), "profile, none known"),
            ("profile", LARGER_SLACK, 0, set(), f"profile {LARGER_SLACK:g}"),
            ("bound", retrieval.PROFILE_SLACK, 0, set(), "bound")):
        found, exact, full = [], 0, 0
        looked.clear()
        with mock.patch.object(retrieval, "_match", looked_up):
            for q in range(n):
                others = [j for j in range(n) if j != q]
                pos = {j: c for c, j in enumerate(others)}
                kn = {(pos[i], pos[j]): T[i, j] for i, j in known if q not in (i, j)}
                r = retrieval.nearest(shapes[q], [shapes[j] for j in others], k, prune=prune, slack=slack,
                                      triangle_slack=t, known=kn)
                got = [others[nb.index] for nb in r.neighbors]
                found.append(len(set(got) & set(truth[q])) / k)
                exact += got == truth[q]
                full += r.full_matches
        assert full == len(looked)
        out[f"nearest {name}"] = {"recall": float(np.mean(found)), "exact_queries": int(exact), "queries": n,
                                   "full_matches": int(full), "pairs": n * (n - 1)}
    for row in out.values():
        row["fewer"] = row["pairs"] / max(row["full_matches"], 1)
    return out


# ----------------------------------------------------------------------------- dask
def dask_rows(files, jobs: int, rounds: int = 3) -> dict:
    """``gh_matrix`` on a LocalCluster of ``jobs`` one-thread workers and with ``jobs`` worker
    processes, ``rounds`` times by turns: seconds, the ratios of each round and their medians
    (the machine's noise moves one round's ratio by about 10%), identical matrices."""
    from gromov._dask import client_for
    from gromov.experiments.pairwise import gh_matrix

    n = len(files)
    pairs = n * (n - 1) // 2
    out = []
    identical = True
    for _ in range(rounds):
        t = time.perf_counter()
        ref = gh_matrix(files, "diffusion", jobs=jobs)
        t_jobs = time.perf_counter() - t
        gc.collect()
        t = time.perf_counter()
        with client_for(n_workers=jobs) as client:
            t_start = time.perf_counter() - t
            got = gh_matrix(files, "diffusion", client=client)
        t_dask = time.perf_counter() - t   # cluster start and close included
        gc.collect()
        identical &= bool(all(np.array_equal(a, b) for a, b in ((ref.distance, got.distance),
                                                                (ref.relative, got.relative),
                                                                (ref.trimmed, got.trimmed))))
        out.append({"jobs": {"seconds": t_jobs, "prepare": ref.seconds_prepare, "match": ref.seconds_match},
                    "dask": {"seconds": t_dask, "cluster_start": t_start, "prepare": got.seconds_prepare,
                             "match": got.seconds_match},
                    "throughput_ratio_match": ref.seconds_match / got.seconds_match,
                    "throughput_ratio_total": t_jobs / t_dask,
                    "throughput_ratio_without_start": ((ref.seconds_prepare + ref.seconds_match)
                                                       / (got.seconds_prepare + got.seconds_match))})
    rows = {"shapes": n, "pairs": pairs, "workers": jobs, "rounds": out, "identical": identical}
    for key in ("throughput_ratio_match", "throughput_ratio_total", "throughput_ratio_without_start"):
        rows[key] = float(np.median([r[key] for r in out]))
    return rows


def print_dask(d: dict) -> None:
    for i, r in enumerate(d["rounds"]):
        print(f"6 dask ({d['shapes']} shapes, {d['pairs']} pairs), round {i + 1}: --jobs {d['workers']} "
              f"{r['jobs']['seconds']:.1f} s (pairs {r['jobs']['match']:.1f} s), LocalCluster of {d['workers']} "
              f"{r['dask']['seconds']:.1f} s (start {r['dask']['cluster_start']:.1f} s, pairs "
              f"{r['dask']['match']:.1f} s); throughput dask / jobs: pairs {r['throughput_ratio_match']:.2f}, "
              f"metrics and pairs {r['throughput_ratio_without_start']:.2f}, whole run "
              f"{r['throughput_ratio_total']:.2f}")
    print(f"6 dask, medians: pairs {d['throughput_ratio_match']:.2f}, whole run {d['throughput_ratio_total']:.2f}; "
          f"identical matrices: {d['identical']}")


# ----------------------------------------------------------------------------- main
def retrieval_part(s1: Path, files, ref: dict, n: int) -> dict:
    """Part 5 on the shapes of store ``s1`` and the matrices ``ref`` of a pairwise run on it."""
    st = ShapeStore(s1)
    shapes = st.shapes([str(f) for f in files], "diffusion", rank_tau_scale=RANK_TAU_SCALE)
    t = time.perf_counter()
    rows = retrieval_rows(shapes, ref["distance"], ref["relative_distance"], ref["relative_trimmed_distance"], K)
    part = {"k": min(K, n - 1), "metrics_computed": st.computed, "seconds": time.perf_counter() - t,
            "triangle_slack": retrieval.TRIANGLE_SLACK, "slack": retrieval.PROFILE_SLACK, "rows": rows}
    st.close()
    del shapes, st
    gc.collect()
    print(f"5 retrieval, k = {part['k']} (metrics computed for it: {part['metrics_computed']}):")
    for name, row in rows.items():
        print(f"    {name:<36} recall {row['recall']:.3f}, {row['exact_queries']}/{row['queries']} as brute "
              f"force, {row['full_matches']}/{row['pairs']} full matches ({row['fewer']:.1f}x fewer)")
    return part


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default=None, help="comma-separated TOSCA classes (default: all)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes, and Dask workers (default 2)")
    ap.add_argument("--store", default=None, metavar="DIR",
                    help="an empty or new folder for the stores (kept); default a temporary folder beside "
                         "--json, removed at the end")
    ap.add_argument("--json", default=str(HERE / "results" / "collection.json"))
    ap.add_argument("--skip", default="", help=f"comma-separated parts to leave out: {', '.join(PARTS)}")
    ap.add_argument("--dask-classes", default="centaur,horse", help="the classes of the Dask comparison")
    ap.add_argument("--dask-rounds", type=int, default=3,
                    help="rounds of the Dask comparison, each --jobs then Dask (default 3; medians reported)")
    ap.add_argument("--only", choices=("dask", "retrieval"), default=None,
                    help="run only this part, with its own results file (e.g. --only dask --dask-classes "
                         "centaur,horse,david,gorilla --json benchmarks/results/collection_dask.json; "
                         "--only retrieval --json benchmarks/results/collection_retrieval.json)")
    ap.add_argument("--retrieval-store", default=None, metavar="DIR",
                    help="--only retrieval: the store gromov pairwise fills (or reads back, where it "
                         "holds the shapes and pairs already); default a fresh one under --store")
    args = ap.parse_args(argv)
    skip = {s for s in args.skip.split(",") if s}
    if skip - set(PARTS):
        ap.error(f"--skip takes {', '.join(PARTS)}, got {', '.join(sorted(skip - set(PARTS)))}")
    tosca = TOSCA(Path(args.data) / "tosca")

    def classes_of(text):
        classes = tosca.classes if text is None else [c.strip() for c in text.split(",") if c.strip()]
        bad = [c for c in classes if c not in tosca.classes]
        if bad or not classes:
            ap.error(f"TOSCA classes are {', '.join(tosca.classes)}; got {text!r}")
        return classes

    def files_of(classes):
        return [tosca.path(c, p) for c in classes for p in tosca.poses(c)]

    if args.only == "dask":
        d = dask_rows([str(f) for f in files_of(classes_of(args.dask_classes))], args.jobs, args.dask_rounds)
        print_dask(d)
        write_results(args.json, {"command": "python benchmarks/bench_collection.py " + shlex.join(
            argv if argv is not None else sys.argv[1:]), "jobs": args.jobs, "dask": d, "complete": True})
        return
    classes = classes_of(args.classes)
    files = files_of(classes)
    n = len(files)
    P = n * (n - 1) // 2
    if args.only == "retrieval":
        with tempfile.TemporaryDirectory(prefix="collection-retrieval-", dir=args.store) as tmp:
            s1 = Path(args.retrieval_store or Path(tmp) / "store")
            wall, out, _, _ = run_cli(pairwise_cmd(files, s1, Path(tmp) / "matrix.npz", args.jobs),
                                      Path(tmp) / "stderr.log", store=s1)
            ref = matrices(Path(tmp) / "matrix.npz")
            res = {"command": "python benchmarks/bench_collection.py " + shlex.join(
                       argv if argv is not None else sys.argv[1:]), "shapes": n, "pairs": P, "classes": classes,
                   "pairwise": {"seconds": wall, "shapes_read": out["store"]["shapes_read"],
                                "pairs_read": out["store"]["pairs_read"]},
                   "retrieval": retrieval_part(s1, files, ref, n)}
        write_results(args.json, {**res, "complete": True})
        return
    if args.store is None:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        root, keep = Path(tempfile.mkdtemp(prefix="collection-stores-", dir=Path(args.json).parent)), False
    else:
        root, keep = Path(args.store), True
        if root.exists() and any(root.iterdir()):
            ap.error(f"--store {root} is not empty: the runs start from fresh stores")
        root.mkdir(parents=True, exist_ok=True)
    s1, s2, log = root / "scratch", root / "resume", root / "stderr.log"
    res: dict = {"command": "python benchmarks/bench_collection.py " + shlex.join(argv if argv is not None
                                                                                  else sys.argv[1:]),
                 "shapes": n, "pairs": P, "classes": classes,
                 "jobs": args.jobs, "skipped": sorted(skip)}
    print(f"{n} TOSCA shapes, {P} pairs, --jobs {args.jobs}; stores in {root}")

    def save(complete: bool = False) -> None:   # after every part: a long run stopped keeps its parts
        write_results(args.json, {**res, "complete": complete})

    try:
        # 1. from scratch
        wall, out, _, _ = run_cli(pairwise_cmd(files, s1, root / "scratch.npz", args.jobs), log, store=s1)
        ref = matrices(root / "scratch.npz")
        with contextlib.closing(ShapeStore(s1)) as st:
            mb = sum(e.bytes for e in st.entries()) / 1e6
        res["scratch"] = {"seconds": wall, "cli_seconds": out["seconds"], "shapes_read": out["store"]["shapes_read"],
                          "pairs_read": out["store"]["pairs_read"], "store_mb": mb}
        print(f"1 scratch   {wall:8.1f} s  ({P / wall:.2f} pairs/s over the whole run)")
        # 2. again, same store
        wall, out2, _, _ = run_cli(pairwise_cmd(files, s1, root / "again.npz", args.jobs), log, store=s1)
        res["again"] = {"seconds": wall, "cli_seconds": out2["seconds"], "shapes_read": out2["store"]["shapes_read"],
                        "pairs_read": out2["store"]["pairs_read"], "identical": same(ref, matrices(root / "again.npz"))}
        r = res["again"]
        print(f"2 again     {wall:8.1f} s  ({wall / res['scratch']['seconds']:.1%} of 1): {r['shapes_read']}/{n} "
              f"shapes and {r['pairs_read']}/{P} pairs read back; identical matrices: {r['identical']}")
        # 3. pairs matched again, metrics read back
        if "rematch" not in skip:
            wall, out3, _, _ = run_cli(pairwise_cmd(files, s1, root / "rematch.npz", args.jobs, "--seed", "1"),
                                       log, store=s1)
            res["rematch"] = {"seconds": wall, "cli_seconds": out3["seconds"],
                              "shapes_read": out3["store"]["shapes_read"], "pairs_read": out3["store"]["pairs_read"]}
            print(f"3 rematch   {wall:8.1f} s  ({wall / res['scratch']['seconds']:.1%} of 1): "
                  f"{res['rematch']['shapes_read']}/{n} shapes read back, "
                  f"{P - res['rematch']['pairs_read']} pairs matched (--seed 1)")
        save()
        # 4. recognition, as gromov pairwise reports it
        res["recognition"] = {k: out[k] for k in ("nn_accuracy", "eer", "eer_gh", "eer_local", "local_scaling_k")}
        rec = res["recognition"]
        if rec["eer"] is not None:
            print(f"4 recognition: nearest-neighbour accuracy {rec['nn_accuracy']:.1%}, EER {rec['eer']:.2%} "
                  f"(GH {rec['eer_gh']:.2%}, locally scaled k={rec['local_scaling_k']} {rec['eer_local']:.2%})")
        else:
            print(f"4 recognition: nearest-neighbour accuracy {rec['nn_accuracy']:.1%}, no EER")
        save()
        # 5. retrieval
        if "retrieval" not in skip:
            res["retrieval"] = retrieval_part(s1, files, ref, n)
        save()
        if not keep:
            shutil.rmtree(s1)
        # 6. Dask
        if "dask" not in skip:
            dfiles = [str(f) for f in files_of(classes_of(args.dask_classes))]
            d = res["dask"] = dask_rows(dfiles, args.jobs, args.dask_rounds)
            print_dask(d)
            save()
        # 7. killed at 30% and 70%, resumed
        if "kill" not in skip:
            runs = []
            for frac in KILL_AT:
                at = max(1, math.ceil(frac * P))
                wall, _, killed, got = run_cli(pairwise_cmd(files, s2, root / "resume.npz", args.jobs), log,
                                               store=s2, kill_at=at)
                runs.append({"kill_at": at, "seconds": wall, "killed": killed, "pairs_recorded": got})
            with contextlib.closing(ShapeStore(s2)) as st:
                problems = st.verify()
            wall, out6, _, got = run_cli(pairwise_cmd(files, s2, root / "resume.npz", args.jobs), log, store=s2)
            runs.append({"seconds": wall, "killed": False, "pairs_recorded": got,
                         "pairs_read": out6["store"]["pairs_read"], "shapes_read": out6["store"]["shapes_read"]})
            total = sum(r["seconds"] for r in runs)
            res["kill"] = {"runs": runs, "seconds": total, "store_problems": problems,
                           "identical": same(ref, matrices(root / "resume.npz"))}
            print(f"7 killed    {total:8.1f} s  ({total / res['scratch']['seconds']:.2f}x 1) in "
                  + " + ".join(f"{r['seconds']:.1f}" for r in runs)
                  + " s; stopped at " + ", ".join(f"{r['pairs_recorded']}" + ("" if r["killed"] else " (finished)")
                                                  for r in runs[:-1])
                  + f" pairs; the last run "
                  f"read {runs[-1]['pairs_read']}; store problems: {len(problems)}; "
                  f"identical matrices: {res['kill']['identical']}")
    finally:
        if not keep:
            shutil.rmtree(root, ignore_errors=True)
    print_table(res)
    save(complete=True)


def print_table(res: dict) -> None:
    base = res["scratch"]["seconds"]
    rows = [("1 all pairs from scratch", base, f"{res['pairs'] / base:.2f} pairs/s")]
    r = res["again"]
    rows.append(("2 again, same store", r["seconds"],
                 f"{r['shapes_read']} shapes, {r['pairs_read']} pairs read; identical {r['identical']}"))
    if "rematch" in res:
        r = res["rematch"]
        rows.append(("3 pairs again (--seed 1)", r["seconds"], f"{r['shapes_read']} shapes read"))
    if "kill" in res:
        r = res["kill"]
        rows.append(("7 killed 30%, 70%, resumed", r["seconds"], f"identical {r['identical']}"))
    print(f"\n{'step':<30}{'seconds':>10}{'x step 1':>10}  notes")
    for name, s, note in rows:
        print(f"{name:<30}{s:>10.1f}{s / base:>10.2f}  {note}")
    rec = res["recognition"]
    print(f"recognition: nearest-neighbour accuracy {rec['nn_accuracy']:.3f}, EER "
          + ("-" if rec["eer"] is None else f"{rec['eer']:.4f}"))
    if "retrieval" in res:
        for name, row in res["retrieval"]["rows"].items():
            print(f"retrieval {name:<18} recall@{res['retrieval']['k']} {row['recall']:.3f}  exact "
                  f"{row['exact_queries']}/{row['queries']}  full matches {row['full_matches']}/{row['pairs']} "
                  f"({row['fewer']:.1f}x fewer)")
    if "dask" in res:
        d = res["dask"]
        print(f"dask / --jobs throughput: pairs {d['throughput_ratio_match']:.2f}, metrics and pairs "
              f"{d['throughput_ratio_without_start']:.2f}, whole run "
              f"{d['throughput_ratio_total']:.2f}; identical {d['identical']}")


if __name__ == "__main__":
    main()
