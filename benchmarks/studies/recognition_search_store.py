"""One query's ten nearest in two stages against a store, measured end to end and read against brute force.

Run:  .venv/bin/python benchmarks/studies/recognition_search_store.py --cache DIR --store STORE
          [--collection watertight] [--queries-per-class 2] [--candidates 20] [--top 10] [--jobs 2]
          [--json benchmarks/studies/recognition_search_store.json]

after ``benchmarks/bench_recognition.py --collections watertight --methods combined --per-class 0
--combined-per-class 0 --cache DIR`` (the complete matrix, ``combined-<collection>-pc0-s50-c0-seed0.npz``).

The queries are each class's first ``--queries-per-class`` shapes in file order; the store holds
every other shape of the collection. As a user would: the store's shapes matched by
``gh_matrix(candidates=C, k=K, store=STORE, rank_by="combined")`` (``gromov pairwise FILES --store
STORE --units area --samples 50 --rank-by combined --candidates C -k K``, which records each pair
in the store), then each query searched by ``nearest(query, STORE, k=K, candidates=C,
rank_by="combined")`` (``gromov search QUERY --store STORE ... --candidates C -k K``). For each
query: the shapes matched, the time, and whether its K nearest are those of the complete matrix
(over the store's shapes); with ``--brute``, also those of the same query matched with every
stored shape (``nearest(..., prune="none")``), the reference: a match runs with the query as X,
while the complete matrix matched each pair in file order, and GMDS's search is not symmetric in
X and Y. The store keeps one entry per file content (two files of the watertight collection are
the same mesh), so the neighbours are compared as contents. ``STORE`` is a scratch folder (it is
filled, and reused when run again: its pairs are read, not matched again).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import write_results  # noqa: E402
from bench_recognition import GROMOV_METRIC, collection  # noqa: E402

SAMPLES = 50


def _distinct(keys: list, top: int) -> list:
    """The first ``top`` distinct of ``keys``, in order."""
    return list(dict.fromkeys(keys))[:top]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True, type=Path)
    ap.add_argument("--store", required=True, type=Path, help="a scratch folder for the shape store")
    ap.add_argument("--data", default=None)
    ap.add_argument("--collection", default="watertight")
    ap.add_argument("--queries-per-class", type=int, default=2)
    ap.add_argument("--candidates", type=int, default=20)
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--brute", action="store_true", help="also each query against every stored shape (the reference)")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "recognition_search_store.json"))
    args = ap.parse_args(argv)
    from gromov.errors import GromovWarning
    from gromov.experiments.pairwise import gh_matrix
    from gromov.retrieval import nearest
    from gromov.store import file_sha256

    data = args.data or os.environ.get("GROMOV_DATA") or str(ROOT.parent / "shared" / "data")
    files, labels = collection(data, args.collection)
    z = np.load(args.cache / f"combined-{args.collection}-pc0-s50-c0-seed0.npz")
    if [str(x) for x in z["files"]] != [f.name for f in files]:
        raise SystemExit("the cached matrix is not of this collection's files, in this order")
    D = np.asarray(z["combined"], dtype=np.float64)
    labels = np.asarray(labels)
    queries = [int(i) for c in dict.fromkeys(labels.tolist())
               for i in np.flatnonzero(labels == c)[:args.queries_per_class]]
    rest = [i for i in range(len(files)) if i not in queries]
    shape = dict(metric_options={**GROMOV_METRIC, "units": "area"}, n_samples=SAMPLES, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        filled = (args.store / "catalogue.sqlite").is_file()
        t = time.perf_counter()
        g = gh_matrix([str(files[i]) for i in rest], "diffusion", jobs=args.jobs, candidates=args.candidates,
                      k=args.top, rank_by="combined", store=str(args.store), **shape)
        store_seconds = time.perf_counter() - t
        n = len(rest)
        rows = []
        digest = {i: file_sha256(str(files[i])) for i in rest}   # the store keeps one entry per content
        at = {files[i].name: i for i in rest}

        def content(neighbors) -> list:
            return [digest[at[Path(nb.name).name]] for nb in neighbors]

        for q in queries:
            t = time.perf_counter()
            r = nearest(str(files[q]), str(args.store), k=args.top, candidates=args.candidates,
                        rank_by="combined", **shape)
            seconds = time.perf_counter() - t
            ours = content(r.neighbors)
            matrix = _distinct([digest[rest[j]] for j in np.argsort(D[q, rest], kind="stable")], args.top)
            row = {"query": files[q].name, "matched": r.full_matches, "candidates_in_store": r.full_matches + r.skipped,
                   "known_pairs": r.known_pairs, "seconds": seconds, "top_equal_matrix": ours == matrix,
                   "neighbours": [[Path(nb.name).name, nb.distance, float(D[q, at[Path(nb.name).name]])]
                                  for nb in r.neighbors]}
            if args.brute:   # the same query against every stored shape, matched in the same order
                t = time.perf_counter()
                b = nearest(str(files[q]), str(args.store), k=args.top, rank_by="combined", prune="none", **shape)
                row["brute_seconds"] = time.perf_counter() - t
                row["top_equal_brute_force"] = ours == content(b.neighbors)
                row["values_equal_brute_force"] = all(v == b.values[j] for j, v in r.values.items())
            rows.append(row)
            print(f"{files[q].name:<22} {r.full_matches:>3} matched in {seconds:5.1f} s, top {args.top} "
                  f"{'as' if row['top_equal_matrix'] else 'not as'} the matrix's"
                  + (f", {'as' if row['top_equal_brute_force'] else 'not as'} brute force's "
                     f"({row['brute_seconds']:.0f} s), values {'equal' if row['values_equal_brute_force'] else 'differ'}"
                     if args.brute else ""), flush=True)
    out = {"command": "python benchmarks/studies/recognition_search_store.py --cache CACHE --store STORE "
                      f"--collection {args.collection} --queries-per-class {args.queries_per_class} "
                      f"--candidates {args.candidates} --top {args.top} --jobs {args.jobs}"
                      + (" --brute" if args.brute else ""),
           "collection": args.collection, "store_shapes": n, "queries": len(queries),
           "store_filled_before": filled, "store_pairs": int(np.isfinite(g.trimmed[np.triu_indices(n, 1)]).sum()),
           "store_seconds": store_seconds,
           "top_equal_matrix": float(np.mean([r["top_equal_matrix"] for r in rows])),
           **({"top_equal_brute_force": float(np.mean([r["top_equal_brute_force"] for r in rows])),
               "values_equal_brute_force": all(r["values_equal_brute_force"] for r in rows),
               "brute_seconds_per_query": float(np.mean([r["brute_seconds"] for r in rows]))} if args.brute else {}),
           "matched_per_query": float(np.mean([r["matched"] for r in rows])),
           "seconds_per_query": float(np.mean([r["seconds"] for r in rows])), "rows": rows}
    write_results(args.json, out)
    print(f"store: {n} shapes, {out['store_pairs']} pairs in {store_seconds / 60:.1f} min"
          f"{' (read, filled before)' if filled else ''}; queries: "
          f"{out['top_equal_matrix']:.3f} with the matrix's {args.top} nearest"
          + (f", {out['top_equal_brute_force']:.3f} with brute force's" if args.brute else "")
          + f"; {out['matched_per_query']:.1f} matched and {out['seconds_per_query']:.1f} s a query")
    return 0


if __name__ == "__main__":
    sys.exit(main())
