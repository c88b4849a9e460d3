"""The local rigid alignment after the local isometry step: how many rounds, after how many sweeps.

Run:  .venv/bin/python benchmarks/studies/probe_dense_align.py --remeshed R [--data DIR]
          [--sets topkids,remeshed,perturbed] [--json benchmarks/studies/probe_dense_align.json]

R is the folder ``benchmarks/remesh.py --out R`` fills. On the pairs of ``bench_dense.py`` (its
functions: TOPKIDS kidXX -> kid00; TOSCA poses remeshed on their own and pose 0 at two densities;
pose 0 against itself with 20 holes and with 3 welds, both ways) each pair is matched once with
``gromov.match(X, Y, dense=True)`` with ``gromov.dense.DENSE_RELAX`` off and
``gromov.dense.DENSE_ALIGN = 0`` (the refined map), and that input-vertex map is scored after each
variant: ``relax N`` is :func:`gromov.dense.relax_isometric` with at most N sweeps, ``align R``
:func:`gromov.dense.align_locally` with R rounds (``plain fits``: no refit with Huber's weights,
``edges E``: a neighbourhood of E mean edges). Error x 100 / sqrt(area) by
:func:`gromov.evaluate.dense_error` (the better of direct and mirrored) on the same ``--points``
random vertices of X (seeded) for every variant, the mean per map; per set the mean of the maps'
means, and how many maps each variant makes better or worse (by 0.001) than ``relax 20`` (the
local isometry step alone). No pyFM run: the anchor is in ``bench_dense.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_dense as B  # noqa: E402

from gromov.dense import align_locally, relax_isometric  # noqa: E402

#: name -> (relax sweeps, align rounds, align options)
VARIANTS = {"relax 20": (20, 0, {}), "align 3": (0, 3, {}),
            "relax 5, align 2": (5, 2, {}), "relax 5, align 3": (5, 3, {}),
            "relax 10, align 3": (10, 3, {}), "relax 20, align 1": (20, 1, {}),
            "relax 20, align 2": (20, 2, {}), "relax 20, align 3": (20, 3, {}),
            "relax 20, align 3, plain fits": (20, 3, {"cap": np.inf}),
            "relax 20, align 3, edges 3": (20, 3, {"edges": 3}),
            "relax 20, align 3, edges 6": (20, 3, {"edges": 6})}
BASE = "relax 20"


def scorer(points: int):
    """A study's ``evaluate_pair`` (:func:`bench_dense.study_sets`) that scores the refined map
    after each variant on ``points`` random vertices of X with a truth, and returns the row."""
    def evaluate_pair(name, x, y, yref, truth, sym, fmm, pyfm_ref=None):
        T = B.refined_maps(x, y, yref)[0]
        error = B.random_point_error(x, y, truth, sym, fmm, points)
        row = {"pair": name, "refined": error(T), "variants": {}, "seconds": {}}
        relaxed, relax_s = {0: T}, {0: 0.0}
        for name_v, (sweeps, rounds, options) in VARIANTS.items():
            if sweeps not in relaxed:
                t = time.perf_counter()
                relaxed[sweeps] = relax_isometric(x, y, T, sweeps=sweeps)
                relax_s[sweeps] = time.perf_counter() - t
            t = time.perf_counter()
            out = align_locally(x, y, relaxed[sweeps], rounds=rounds, **options)
            row["seconds"][name_v] = relax_s[sweeps] + time.perf_counter() - t
            row["variants"][name_v] = error(out)
        B.print_variants(name, row)
        return row
    return evaluate_pair


def main(argv=None) -> int:
    variants = {k: [s, r, {o: (float(v) if np.isfinite(v) else None) for o, v in opts.items()}]
                for k, (s, r, opts) in VARIANTS.items()}
    return B.variant_study(argv, __doc__, "probe_dense_align.json", scorer, VARIANTS, BASE,
                           {"variants": variants})


if __name__ == "__main__":
    sys.exit(main())
