"""Each direction of a dense map offered the other's inverse: how many rounds, what they buy.

Run:  .venv/bin/python benchmarks/studies/probe_dense_inverse.py --remeshed R [--data DIR]
          [--sets topkids,remeshed,perturbed] [--rounds 3] [--sweeps 20]
          [--json benchmarks/studies/probe_dense_inverse.json]

R is the folder ``benchmarks/remesh.py --out R`` fills. On the pairs of ``bench_dense.py`` (its
functions: TOPKIDS kidXX -> kid00; with ``--sets tosca`` the TOSCA pairs as given (one
triangulation), both ways; TOSCA poses remeshed on their own and pose 0 at two densities;
pose 0 against itself with 20 holes and with 3 welds, both ways) each pair is matched once with
``gromov.match(X, Y, dense=True)`` as the default makes it (refined on the input meshes, then the
local isometry step, :data:`gromov.dense.DENSE_INVERSE` = 0), and its two input-vertex maps
T: X -> Y and S: Y -> X are given to :func:`gromov.dense.consistent_maps` one round at a time, up
to ``--rounds``. T is scored as it is and after each round: error x 100 / sqrt(area) by
:func:`gromov.evaluate.dense_error` (the better of direct and mirrored) on the same ``--points``
random vertices of X (seeded), the mean per map; per set the mean of the maps' means and how many
maps each round makes better and worse (by 0.001); the seconds of each round (both directions,
X's and Y's neighbourhoods built in the first). ``--sweeps`` caps each start's local isometry
step in the rounds (``consistent_maps(..., sweeps=)``, :data:`gromov.dense.INVERSE_SWEEPS`). No pyFM run: the anchor is in ``bench_dense.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_dense as B  # noqa: E402
from _common import add_data_argument, write_results  # noqa: E402

import gromov  # noqa: E402
from gromov.dense import INVERSE_SWEEPS, consistent_maps  # noqa: E402


def scorer(points: int, rounds: int, sweeps: int):
    """A study's ``evaluate_pair`` (:func:`bench_dense.study_sets`): the default map and the
    maps after each round, scored on ``points`` random vertices of X with a truth."""
    def evaluate_pair(name, x, y, yref, truth, sym, fmm, pyfm_ref=None):
        r = gromov.match(x, yref, dense=True)
        T = y.from_input_ids(r.x_to_y_dense_vertex[x.input_ids])
        S = x.from_input_ids(r.y_to_x_dense_vertex[y.input_ids])
        error = B.random_point_error(x, y, truth, sym, fmm, points)

        row = {"pair": name, "default": error(T), "rounds": [], "seconds": [], "changed": []}
        for _ in range(rounds):
            t0 = time.perf_counter()
            T1, S1 = consistent_maps(x, y, T, S, rounds=1, sweeps=sweeps)
            row["seconds"].append(time.perf_counter() - t0)
            row["changed"].append([bool(T1 is not T), bool(S1 is not S)])
            T, S = T1, S1
            row["rounds"].append(error(T))
        print(f"  {name:<30} default {row['default']:.3f}  "
              + "  ".join(f"round {i + 1}: {v:.3f}" for i, v in enumerate(row["rounds"]))
              + f"  ({sum(row['seconds']):.1f} s)", flush=True)
        return row
    return evaluate_pair


def summary(rows: list) -> dict:
    base = np.array([r["default"] for r in rows])
    out = {"maps": len(rows), "default": float(base.mean()), "rounds": []}
    for i in range(len(rows[0]["rounds"])):
        vals = np.array([r["rounds"][i] for r in rows])
        out["rounds"].append({"mean": float(vals.mean()), "median_of_means": float(np.median(vals)),
                              "better": int(np.sum(vals < base - 1e-3)),
                              "worse": int(np.sum(vals > base + 1e-3)),
                              "seconds_mean": float(np.mean([r["seconds"][i] for r in rows]))})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    B.add_study_arguments(ap)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--sweeps", type=int, default=INVERSE_SWEEPS, help="of each start's local isometry step")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "probe_dense_inverse.json"))
    args = ap.parse_args(argv)
    for name in args.sets.split(","):
        if name not in ("topkids", "tosca", "remeshed", "perturbed"):
            ap.error(f"unknown set {name!r}")
    out = {"rounds": args.rounds, "sweeps": args.sweeps, "points": args.points, "sets": {}}
    parts = B.study_sets(args.sets.split(","), Path(args.data), Path(args.remeshed),
                         scorer(args.points, args.rounds, args.sweeps))
    for part, part_rows in parts.items():
        out["sets"][part] = {"summary": summary(part_rows), "pairs": part_rows}
        s = out["sets"][part]["summary"]
        print(f"{part}: default {s['default']:.3f}  " + "  ".join(
            f"round {i + 1}: {v['mean']:.3f} (+{v['better']} -{v['worse']}, {v['seconds_mean']:.2f} s)"
            for i, v in enumerate(s["rounds"])), flush=True)
    write_results(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
