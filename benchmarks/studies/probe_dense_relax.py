"""The local isometry step after the dense refinement: which neighbourhood, which cap.

Run:  .venv/bin/python benchmarks/studies/probe_dense_relax.py --remeshed R [--data DIR]
          [--sets topkids,remeshed,perturbed] [--schedules "4:4;8:8,4:4"] [--max-rings N]
          [--json benchmarks/studies/probe_dense_relax.json]

R is the folder ``benchmarks/remesh.py --out R`` fills. On the pairs of ``bench_dense.py`` (its
functions: TOPKIDS kidXX -> kid00; TOSCA poses remeshed on their own and pose 0 at two densities;
pose 0 against itself with 20 holes and with 3 welds, both ways) each pair is matched once with
``gromov.match(X, Y, dense=True)`` with ``gromov.dense.DENSE_RELAX`` set off, and that input-vertex
map is scored as it is and after :func:`gromov.dense.relax_isometric` with each variant: the
neighbourhood's radius ``edges`` (mean edges of the coarser mesh) and the cap of a residual
(None: plain squares; else in the same unit). Error x 100 / sqrt(area) by
:func:`gromov.evaluate.dense_error` (the better of direct and mirrored) on the same ``--points``
random vertices of X (seeded) for every variant, the mean per map; per set the mean of the maps'
means, and how many maps each variant makes worse than the refined map. With ``--schedules`` each
variant is several steps run in turn (``edges:cap``, e.g. wider neighbourhoods first), with
``--max-rings`` raising :data:`gromov.dense.RELAX_MAX_RINGS` for them
(``probe_dense_relax_schedules.json``).
No pyFM run: the anchor is in ``bench_dense.py``.
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
import gromov.dense  # noqa: E402
from gromov.dense import relax_isometric  # noqa: E402

#: (edges, cap): the variants scored on every map.
VARIANTS = ((3, None), (4, None), (5, None), (3, 3), (4, 4), (5, 5))


def parse_schedules(text: str) -> list[tuple[tuple[float, float | None], ...]]:
    """``"8:8,4:4;12:12,8:8,4:4"`` -> variants of several steps, each ``(edges, cap)`` run on the
    result of the one before (``cap`` ``none``: plain squares)."""
    out = []
    for variant in filter(None, text.split(";")):
        steps = []
        for step in variant.split(","):
            edges, cap = step.split(":")
            steps.append((float(edges), None if cap == "none" else float(cap)))
        out.append(tuple(steps))
    return out


def scorer(points: int, variants=None):
    """A study's ``evaluate_pair`` (:func:`bench_dense.study_sets`) that scores our map and its
    relaxed variants on ``points`` random vertices of X with a truth, and returns the row."""
    def evaluate_pair(name, x, y, yref, truth, sym, fmm, pyfm_ref=None):
        relax, gromov.dense.DENSE_RELAX = gromov.dense.DENSE_RELAX, False   # the refined map
        try:
            r = gromov.match(x, yref, dense=True)
        finally:
            gromov.dense.DENSE_RELAX = relax
        T = y.from_input_ids(r.x_to_y_dense_vertex[x.input_ids])
        error = B.random_point_error(x, y, truth, sym, fmm, points)

        row = {"pair": name, "refined": error(T), "variants": {}, "seconds": {}}
        for steps in variants or [((e, c),) for e, c in VARIANTS]:
            key = " then ".join(f"edges {e:g}, cap {c if c is None else f'{c:g}'}" for e, c in steps)
            t = time.perf_counter()
            relaxed = T
            for edges, cap in steps:
                relaxed = relax_isometric(x, y, relaxed, edges=edges, cap=cap)
            row["seconds"][key] = time.perf_counter() - t
            row["variants"][key] = error(relaxed)
        B.print_variants(name, row, 28)
        return row
    return evaluate_pair


def summary(rows: list) -> dict:
    out = {"maps": len(rows), "refined": float(np.mean([r["refined"] for r in rows]))}
    for key in rows[0]["variants"]:
        vals = np.array([r["variants"][key] for r in rows])
        base = np.array([r["refined"] for r in rows])
        out[key] = {"mean": float(vals.mean()), "worse": int(np.sum(vals > base + 1e-9)),
                    "seconds_mean": float(np.mean([r["seconds"][key] for r in rows]))}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    B.add_study_arguments(ap)
    ap.add_argument("--schedules", default=None, help="variants of several steps instead of VARIANTS, e.g. "
                    "'4:4;8:8,4:4' (edges:cap of each step, run in turn; steps of a variant by ',', variants by ';')")
    ap.add_argument("--max-rings", type=int, default=None, help="gromov.dense.RELAX_MAX_RINGS for the run")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "probe_dense_relax.json"))
    args = ap.parse_args(argv)
    variants = parse_schedules(args.schedules) if args.schedules else None
    if args.max_rings is not None:
        gromov.dense.RELAX_MAX_RINGS = args.max_rings
    out = {"variants": [[list(step) for step in v] for v in variants] if variants else [list(v) for v in VARIANTS],
           "max_rings": gromov.dense.RELAX_MAX_RINGS, "points": args.points}
    def line(s):
        return f"refined {s['refined']:.3f}  " + "  ".join(
            f"{k}: {v['mean']:.3f} ({v['worse']} worse)" for k, v in s.items() if isinstance(v, dict))
    out["sets"] = B.study_parts(ap, args, scorer(args.points, variants), summary, line)
    write_results(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
