"""The input refinement's global steps: what they add, and where the dense map leaves the samples.

Run:  .venv/bin/python benchmarks/studies/probe_dense_global.py --remeshed R [--data DIR]
          [--sets topkids,remeshed] [--points 2000] [--json benchmarks/studies/probe_dense_global.json]

R is the folder ``benchmarks/remesh.py --out R`` fills. While the refinement on the input meshes
has at most ``gromov.dense.INPUT_GLOBAL`` (32) eigenfunctions, each vertex's image is also searched
among all of Y's working vertices, and the nearer of that and the local search is kept
(docs/design/dense.md, "Refinement on the input meshes"). On the pairs of ``bench_dense.py`` (its
functions: TOPKIDS kidXX -> kid00; TOSCA poses remeshed on their own, both ways, and pose 0 at two
densities) each pair is matched with ``gromov.match(X, Y, dense=True)`` as it is and with
``INPUT_GLOBAL = 0`` (no global step). Error x 100 / sqrt(area) by
:func:`gromov.evaluate.dense_error` (the better of direct and mirrored): of the dense map on the
same ``--points`` random vertices of X (seeded) for both; of the samples' images and of the dense
map read at the samples' vertices (the issue of "dense less precise than the samples on the same
points"). Per set: the means, how many maps each way is worse, and the pairs whose dense map at
the samples is above the samples. No pyFM run: the anchor is in ``bench_dense.py``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_dense as B  # noqa: E402
from _common import add_data_argument, write_results  # noqa: E402

import gromov  # noqa: E402
import gromov.dense  # noqa: E402

#: The ways each pair is matched: name -> INPUT_GLOBAL.
WAYS = {"default": gromov.dense.INPUT_GLOBAL, "no global steps": 0}


def scorer(points: int):
    """A study's ``evaluate_pair`` (:func:`bench_dense.study_sets`) that matches each pair both
    ways, scores them, and returns the row."""
    def evaluate_pair(name, x, y, yref, truth, sym, fmm, pyfm_ref=None):
        tr = truth[x.input_ids]
        ok = np.flatnonzero(tr >= 0)
        if len(ok) > points:
            ok = np.sort(np.random.default_rng(0).choice(ok, points, replace=False))

        def error(face, bary, true):
            return float(100 * B.dense_error(face, bary, y, true, sym, fmm=fmm).mean)

        row = {"pair": name}
        default = gromov.dense.INPUT_GLOBAL
        for way, global_k in WAYS.items():
            gromov.dense.INPUT_GLOBAL = global_k
            try:
                r = gromov.match(x, yref, dense=True)
            finally:
                gromov.dense.INPUT_GLOBAL = default
            s = r.x_samples[truth[r.x_samples] >= 0]
            face, bary = r.x_to_y_dense_face[x.input_ids], r.x_to_y_dense_bary[x.input_ids]
            row[way] = {"dense": error(face[ok], bary[ok], tr[ok]),
                        "dense_at_samples": error(r.x_to_y_dense_face[s], r.x_to_y_dense_bary[s], truth[s])}
            if way == "default":
                keep = truth[r.x_samples] >= 0
                row["samples"] = error(r.x_to_y_face[keep], r.x_to_y_bary[keep], truth[s])
        print(f"  {name:<32} samples {row['samples']:.2f}  " + "  ".join(
            f"{w}: {row[w]['dense']:.2f} (at samples {row[w]['dense_at_samples']:.2f})" for w in WAYS), flush=True)
        return row
    return evaluate_pair


def summary(rows: list) -> dict:
    out = {"maps": len(rows), "samples": float(np.mean([r["samples"] for r in rows]))}
    for way in WAYS:
        out[way] = {"dense": float(np.mean([r[way]["dense"] for r in rows])),
                    "dense_at_samples": float(np.mean([r[way]["dense_at_samples"] for r in rows])),
                    "above_samples": [r["pair"] for r in rows if r[way]["dense_at_samples"] > r["samples"]]}
    out["no global steps"]["worse"] = int(sum(r["no global steps"]["dense"] > r["default"]["dense"] + 1e-9
                                              for r in rows))
    out["no global steps"]["better"] = int(sum(r["no global steps"]["dense"] < r["default"]["dense"] - 1e-9
                                               for r in rows))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--remeshed", help="the folder benchmarks/remesh.py --out filled (set 'remeshed')")
    ap.add_argument("--sets", default="topkids,remeshed")
    ap.add_argument("--points", type=int, default=2000, help="vertices of X scored per map")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "probe_dense_global.json"))
    args = ap.parse_args(argv)
    data = Path(args.data)
    out = {"input_global": gromov.dense.INPUT_GLOBAL, "points": args.points, "sets": {}}
    sets = args.sets.split(",")
    for name in sets:
        if name not in ("topkids", "remeshed"):
            ap.error(f"unknown set {name!r}")
    if "remeshed" in sets and not args.remeshed:
        ap.error("the set 'remeshed' needs --remeshed R")
    parts = B.study_sets(sets, data, Path(args.remeshed) if args.remeshed else None, scorer(args.points))
    for part, part_rows in parts.items():
        out["sets"][part] = {"summary": summary(part_rows), "pairs": part_rows}
        s = out["sets"][part]["summary"]
        print(f"{part}: samples {s['samples']:.3f}  " + "  ".join(
            f"{w}: {s[w]['dense']:.3f} (at samples {s[w]['dense_at_samples']:.3f}, above the samples: "
            f"{s[w]['above_samples']})" for w in WAYS)
            + f"; without, {s['no global steps']['worse']} maps worse, {s['no global steps']['better']} better",
            flush=True)
    write_results(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
