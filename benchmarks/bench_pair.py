"""What one pair of a recognition matrix costs, against POT's Gromov-Wasserstein.

Run:  .venv/bin/python benchmarks/bench_pair.py [--data DIR] [--pairs cat0:cat1,...]
                                               [--metric diffusion|geodesic] [--repeat 7] [--json OUT]

The shapes are prepared once, as :func:`gromov.experiments.gh_matrix` prepares them
(:func:`gromov.experiments.pairwise.prepare`: working mesh of 3,000 vertices, dense metric,
samples, signatures, search subsets, the ranking's heat distance), and each pair is then matched
as ``gh_matrix`` matches it: one symmetric match of 100 samples per side
(``orientation="ignore"``, the shapes in their own units, the ranking measured). Beside it, on
the same two 100 x 100 sample distance matrices, POT's ``ot.gromov.gromov_wasserstein``
(square loss, uniform weights). Both run on one thread (threadpoolctl and
``numba.set_num_threads(1)``), interleaved, after a warm-up run (compilation, per-shape caches):
median and best of ``--repeat`` runs each, and their ratio. ``search`` is the initial search
alone (:func:`gromov.search.initial_pairs` with the default options), the part of a match that
decides its basin; the rest is GMDS, the distortion, the ranking and the images on the input
meshes.

Timings depend on the machine and on what else runs on it; the results file records the CPU.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from _common import add_data_argument, write_results

import gromov
from gromov.experiments.pairwise import prepare
from gromov.gh import RANK_RESIDUAL, RANK_TAU_SCALE, _match
from gromov.search import initial_pairs

PAIRS = "cat0:cat1,dog0:dog1,horse0:horse5,centaur0:centaur1,michael0:david0"


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def _runs(x, y, metric: str, n_samples: int, options: dict) -> dict:
    """What is timed for the pair ``(x, y)``: the match as ``gh_matrix`` runs it, its initial
    search alone, and POT's GW on the same two sample distance matrices."""
    import ot

    P, Q = x.samples(n_samples, 0), y.samples(n_samples, 0)
    dx, dy = x.distances[np.ix_(P, P)], y.distances[np.ix_(Q, Q)]
    w = np.full(n_samples, 1.0 / n_samples)
    return {"match": lambda: _match(x, y, metric, orientation="ignore", as_prepared=True, **options),
            "search": lambda: initial_pairs(x, y, P, Q),
            "pot": lambda: ot.gromov.gromov_wasserstein(dx, dy, w, w, loss_fun="square_loss")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--pairs", default=PAIRS, help="comma-separated X:Y pairs of TOSCA shape names")
    ap.add_argument("--metric", choices=("diffusion", "geodesic"), default="diffusion")
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--resolution", type=int, default=3000)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)

    import numba
    from threadpoolctl import threadpool_limits

    numba.set_num_threads(1)
    threadpool_limits(limits=1)
    tosca = Path(args.data) / "tosca"
    pairs = [tuple(p.split(":")) for p in args.pairs.split(",")]
    names = sorted({n for p in pairs for n in p})
    rank_tau_scale = RANK_TAU_SCALE if args.metric == "diffusion" else None
    t = time.perf_counter()
    shapes = dict(zip(names, prepare([gromov.load(tosca / f"{n}.off.gz") for n in names], args.metric,
                                     n_samples=args.samples, resolution=args.resolution,
                                     rank_tau_scale=rank_tau_scale)))
    print(f"{len(names)} shapes prepared ({args.metric}, {args.resolution} vertices): "
          f"{time.perf_counter() - t:.1f} s")
    options = {"n_samples": args.samples, "seed": 0, "rank_tau_scale": RANK_TAU_SCALE,
               "rank_residual": RANK_RESIDUAL}
    rows = []
    print(f"{'pair':<20}{'match':>9}{'search':>9}{'POT GW':>9}{'ratio':>8}   (median of {args.repeat}, s)")
    for a, b in pairs:
        runs = _runs(shapes[a], shapes[b], args.metric, args.samples, options)
        for fn in runs.values():   # warm-up: compilation, per-shape caches
            fn()
        times = {k: [] for k in runs}
        for _ in range(args.repeat):   # interleaved: other work on the machine slows all alike
            for k, fn in runs.items():
                times[k].append(_timed(fn))
        med = {k: statistics.median(v) for k, v in times.items()}
        row = {"pair": f"{a}-{b}", **{f"{k}_seconds": v for k, v in med.items()},
               **{f"{k}_best_seconds": min(v) for k, v in times.items()},
               "ratio": med["match"] / med["pot"]}
        rows.append(row)
        print(f"{a + '-' + b:<20}{med['match']:>9.4f}{med['search']:>9.4f}{med['pot']:>9.4f}{row['ratio']:>8.1f}")
    summary = {k: statistics.median(r[k] for r in rows)
               for k in ("match_seconds", "search_seconds", "pot_seconds", "ratio")}
    print(f"{'median':<20}{summary['match_seconds']:>9.4f}{summary['search_seconds']:>9.4f}"
          f"{summary['pot_seconds']:>9.4f}{summary['ratio']:>8.1f}")
    given = sys.argv[1:] if argv is None else list(argv)
    write_results(args.json, {"command": " ".join([".venv/bin/python benchmarks/bench_pair.py", *given]),
                              "params": {"metric": args.metric, "samples": args.samples,
                                         "resolution": args.resolution, "repeat": args.repeat,
                                         "threads": 1},
                              "pairs": rows, "summary": summary})
    return rows


if __name__ == "__main__":
    main()
