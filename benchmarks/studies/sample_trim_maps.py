"""Do the wrong GMDS maps still beat the ground truth when whole samples are set aside?

Run:  .venv/bin/python benchmarks/studies/sample_trim_maps.py [--data DIR] [--classes horse,centaur,wolf,michael]
                                                      [--json OUT]

Held-out TOSCA classes, reference pose 0 against deformations 1 and 2, clean and with 3
merged-vertex welds, built as ``gromov reproduce`` builds them; default diffusion metric,
100 samples, ``gromov.match``. For X's samples, the one-sided residual matrix ``d_X(p_i, p_j)
- d_Y(q_i, q_j)`` of the map GMDS found and of the ground-truth map (same input vertex), each
summarised as RMS, as the RMS of the best-fitting 80% of pairs (``trimmed_rms``) and as the
RMS over the pairs of the best-fitting 70% / 50% of *samples*. Where the found map is wrong
(d(C, C0) > 0.05, as in ``bench_heldout.py``) and its distortion is below the truth's, that
summary prefers the wrong map: the metric (seen through that summary) is at fault. A weld
moves whole rows of the diffusion distances (``weld_rows.py``), so setting samples aside is
the summary that matches the mechanism.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from gromov.experiments.datasets import TOSCA, experiment1
from gromov.experiments.reproduce import _pair_quality, _Shapes
from gromov.gh import ShapeMetric, match

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import HEAT as OPTIONS, add_data_argument, residual_summaries, write_results  # noqa: E402

WRONG = 0.05


def summaries(e: np.ndarray, diam: float) -> dict:
    return residual_summaries(e, diam, sample_keeps=(0.7, 0.5))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default="horse,centaur,wolf,michael")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    tosca = TOSCA(Path(args.data) / "tosca")
    shapes = _Shapes(tosca, 3000, "pinch")
    rows, t0 = [], time.perf_counter()
    for cls in args.classes.split(","):
        entries = [shapes.entry(e) for e in experiment1(tosca, {cls: 2})]
        ref = entries[0]
        sx = ShapeMetric(ref.mesh, "diffusion", resolution=None, metric_options=OPTIONS)
        for y in entries[1:]:
            sy = ShapeMetric(y.mesh, "diffusion", resolution=None, metric_options=OPTIONS)
            r = match(sx, sy, "diffusion", n_samples=100)
            quality = _pair_quality(r, shapes, ref, y)
            P = sx.mesh.from_input_ids(r.x_samples)
            found = sy.mesh.from_input_ids(r.x_to_y_vertex)
            pos = {int(v): i for i, v in enumerate(y.mesh.input_ids)}
            truth = np.array([pos.get(int(v), -1) for v in r.x_samples])
            ok = truth >= 0
            dx = sx.distances[np.ix_(P[ok], P[ok])]
            diam = max(sx.diameter, sy.diameter)
            row = {"shape": y.label, "d_c_c0": quality["best"],
                   "found": summaries(dx - sy.distances[np.ix_(found[ok], found[ok])], diam),
                   "truth": summaries(dx - sy.distances[np.ix_(truth[ok], truth[ok])], diam)}
            rows.append(row)
            mark = "WRONG" if row["d_c_c0"] > WRONG else "     "
            print(f"{y.label:>15} d(C,C0) {row['d_c_c0']:.3f} {mark}  found / truth: " + "  ".join(
                f"{k} {row['found'][k]:.4f} / {row['truth'][k]:.4f}" for k in row["found"]), flush=True)
    wrong = [r for r in rows if r["d_c_c0"] > WRONG]
    for k in ("rms", "trim80", "strim70", "strim50"):
        n = sum(r["found"][k] < r["truth"][k] for r in wrong)
        print(f"{k:>8}: {n} of {len(wrong)} wrong maps have lower distortion than the truth")
    print(f"({time.perf_counter() - t0:.0f} s)")
    write_results(args.json, {"options": OPTIONS, "rows": rows})
    return rows


if __name__ == "__main__":
    main()
