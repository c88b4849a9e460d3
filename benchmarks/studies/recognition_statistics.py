"""What should recognition rank pairs of shapes by? The GH estimate or a robust distortion.

Run:  .venv/bin/python benchmarks/studies/recognition_statistics.py [--set synthetic|heldout|paper]
                                                            [--metrics geodesic,diffusion] [--json OUT]

The shapes are those of `gromov reproduce` (Experiment 1: clean and welded deformations;
Experiment 2: 10 and 20 holes): ``synthetic`` is the built-in set of ``make demo``,
``heldout`` the TOSCA classes the paper did not use (wolf:2, horse:4, centaur:5,
michael:6, as ``gromov reproduce --classes``), ``paper`` the paper's classes (cat, dog, david,
victoria: the test set -- choose on the other two). Every pair is matched once as in
:func:`gromov.experiments.gh_matrix` (``orientation="ignore"``, the lowest distortion found);
the same correspondence's pair residuals (:attr:`gromov.MatchResult.pair_distortion`) are
then summarised in several ways, each divided by the larger diameter, and the equal error
rate of each ranking is printed:

- ``gh``: RMS (the GH estimate, ``2 * relative_distance``), ``linf``: the maximum;
- ``l1``: mean absolute residual, ``median``: median absolute residual;
- ``trimK``: RMS of the best-fitting K% of the pairs (:func:`gromov.gmds.trimmed_rms`);
- ``strimK``: RMS over the pairs of the best-fitting K% of the *samples*
  (:func:`gromov.gmds.sample_trimmed_rms`: samples ranked by their own RMS residual, the rows of
  :attr:`gromov.MatchResult.sample_distortion`).

A weld changes the heat-kernel diffusion distance of a point near it to *every* other point:
between far points ``d_t^2 ~ k_2t(x, x) + k_2t(y, y)``, and the weld changes the return
probability ``k_2t(x, x)`` of the points within about ``sqrt(8t)`` of it. So whole rows of
the residual matrix move, not a few pairs -- what setting samples aside models.

Besides the EER (saturated at 0 on easy sets), each ranking's *margin*: the smallest distance
between shapes of different classes over the largest between shapes of the same class (above
1: one threshold separates all pairs; the larger, the wider the gap).

A weld changes the distances of the pairs whose paths run through it; a different shape
changes most pairs. Rankings that set aside the worst-fitting pairs should keep the first
and not the second.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from gromov.experiments import datasets
from gromov.experiments.pairwise import _one_thread_per_worker, prepare
from gromov.experiments.recognition import equal_error_rate
from gromov.experiments.reproduce import DIFFUSION_FILL_HOLES, _collection, _Shapes, settings_for
from gromov.gh import match
from gromov.gmds import norm_value, sample_trimmed_rms, trimmed_rms

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import margin  # noqa: E402

HERE = Path(__file__).resolve().parent
HELDOUT = {"wolf": 2, "horse": 4, "centaur": 5, "michael": 6}
KEEPS = (0.95, 0.9, 0.8, 0.7)
SAMPLE_KEEPS = (0.9, 0.8, 0.7, 0.6)

_SHAPES: list = []
_N = 0


def statistics(e: np.ndarray) -> dict:
    """Summaries of a residual matrix's off-diagonal entries (not yet divided by a diameter)."""
    r = e[~np.eye(len(e), dtype=bool)]
    out = {"gh": norm_value(r, 2.0), "linf": norm_value(r, np.inf), "l1": norm_value(r, 1.0),
           "median": float(np.median(np.abs(r)))}
    out.update({f"trim{round(100 * k)}": trimmed_rms(r, k) for k in KEEPS})
    out.update({f"strim{round(100 * k)}": sample_trimmed_rms(e, k) for k in SAMPLE_KEEPS})
    return out


def _pair(ij):
    i, j = ij
    x, y = _SHAPES[i], _SHAPES[j]
    r = match(x, y, x.metric, n_samples=_N, seed=0, orientation="ignore")
    diam = max(x.diameter, y.diameter)
    return {k: v / diam for k, v in statistics(r.pair_distortion).items()}


def main(argv=None):
    global _N
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[2] / "shared" / "data")))
    ap.add_argument("--set", choices=("synthetic", "heldout", "paper"), default="synthetic")
    ap.add_argument("--metrics", default="geodesic,diffusion")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--tau", type=float, default=None,
                    help="heat-kernel diffusion time relative to the area (default: the library's)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    if args.set == "synthetic":
        st, coll = settings_for("synthetic"), _collection("synthetic", None)
    else:
        st = settings_for("tosca", classes=HELDOUT if args.set == "heldout" else None, topkids=False)
        coll = _collection("tosca", Path(args.data))
    _N = st.n_samples
    shapes = _Shapes(coll, st.resolution)
    res = {"date": time.strftime("%Y-%m-%d"), "set": args.set, "n_samples": _N, "tau": args.tau, "eer": {}}
    print(f"EER by ranking, {args.set} set ({_N} samples per shape)")
    for metric in args.metrics.split(","):
        opts = dict(st.metric_options[metric])
        if metric == "diffusion":
            opts.setdefault("fill_holes", DIFFUSION_FILL_HOLES)
            if args.tau is not None:
                opts["tau"] = args.tau
        for exp, entries in (("weld", datasets.experiment1(coll, st.experiment1)),
                             ("holes", datasets.experiment2(coll, st.experiment2))):
            items = [shapes.entry(e) for e in entries]
            labels = np.array([s.cls for s in items])
            t = time.perf_counter()
            _SHAPES[:] = prepare([s.mesh for s in items], metric, n_samples=_N, seed=0, resolution=None,
                                 metric_options=opts)
            pairs = [(i, j) for i in range(len(items)) for j in range(i + 1, len(items))]
            with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("fork"),
                                     initializer=_one_thread_per_worker) as pool:
                rows = list(pool.map(_pair, pairs, chunksize=8))
            row, marg = {}, {}
            for k in rows[0]:
                D = np.zeros((len(items),) * 2)
                for (i, j), v in zip(pairs, rows):
                    D[i, j] = D[j, i] = v[k]
                row[k] = float(equal_error_rate(D, labels))
                marg[k] = margin(D, labels)
            res["eer"][f"{exp}/{metric}"] = row
            res.setdefault("margin", {})[f"{exp}/{metric}"] = marg
            print(f"  {exp:<6}{metric:<10}" + "  ".join(f"{k} {100 * v:5.1f}%" for k, v in row.items())
                  + f"   ({time.perf_counter() - t:.0f} s)", flush=True)
            print(f"  {'':<6}{'margin':<10}" + "  ".join(f"{k} {v:6.3f}" for k, v in marg.items()),
                  flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
