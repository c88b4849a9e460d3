"""The steps after the refinement: the inverse round before or after the local rigid alignment,
and how many sweeps of the local isometry step.

Run:  .venv/bin/python benchmarks/studies/probe_dense_order.py --remeshed R [--data DIR]
          [--sets topkids,remeshed,perturbed] [--json benchmarks/studies/probe_dense_order.json]

R is the folder ``benchmarks/remesh.py --out R`` fills. On the pairs of ``bench_dense.py`` (its
functions: TOPKIDS kidXX -> kid00; TOSCA poses remeshed on their own and pose 0 at two densities;
pose 0 against itself with 20 holes and with 3 welds, both ways) each pair is matched once with
``gromov.dense.DENSE_RELAX`` off and ``gromov.dense.DENSE_ALIGN = 0``, which gives both refined
maps, T: X -> Y and S: Y -> X. Each variant takes both through its steps
(:func:`gromov.dense.relax_isometric` with at most N sweeps, ``relax N``;
:func:`gromov.dense.align_locally` with R rounds, ``align R``;
:func:`gromov.dense.consistent_maps`, one round whose starts are relaxed by at most 3 sweeps,
``inverse``; an alignment after it starts from the vertices the round changed, ``since``) and
T is scored: error x 100 / sqrt(area) by :func:`gromov.evaluate.dense_error` (the better of
direct and mirrored) on the same ``--points`` random vertices of X (seeded) for every variant, the
mean per map; per set the mean of the maps' means, and how many maps each variant makes better or
worse (by 0.001) than ``relax 20, align 3`` (the steps before the inverse round was a default).
No pyFM run: the anchor is in ``bench_dense.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_dense as B  # noqa: E402

from gromov.dense import align_locally, consistent_maps, relax_isometric  # noqa: E402

#: name -> (relax sweeps, align rounds before the inverse round, inverse round, align rounds after)
VARIANTS = {"relax 20, align 3": (20, 3, False, 0),
            "relax 20, inverse, align 3": (20, 0, True, 3),
            "relax 20, align 3, inverse, align 3": (20, 3, True, 3),
            "relax 10, align 3, inverse, align 3": (10, 3, True, 3),
            "relax 10, align 3, inverse, align 1": (10, 3, True, 1)}
BASE = "relax 20, align 3"
INVERSE_SWEEPS = 3


def steps(x, y, T, S, sweeps, before, inverse, after):
    """T after one variant's steps (both maps go through them: the inverse round reads both)."""
    t, s = relax_isometric(x, y, T, sweeps=sweeps), relax_isometric(y, x, S, sweeps=sweeps)
    if before:
        t, s = align_locally(x, y, t, rounds=before), align_locally(y, x, s, rounds=before)
    if inverse:
        t2 = consistent_maps(x, y, t, s, rounds=1, sweeps=INVERSE_SWEEPS)[0]
        t = align_locally(x, y, t2, rounds=after, since=t) if before else align_locally(x, y, t2, rounds=after)
    return t


#: each pair's maps through each variant's steps, scored (:func:`bench_dense.variant_scorer`)
scorer = B.variant_scorer(VARIANTS, lambda x, y, T, S, spec: steps(x, y, T, S, *spec))


def main(argv=None) -> int:
    return B.variant_study(argv, __doc__, "probe_dense_order.json", scorer, VARIANTS, BASE,
                           {"variants": {k: list(v) for k, v in VARIANTS.items()},
                            "inverse_sweeps": INVERSE_SWEEPS})


if __name__ == "__main__":
    sys.exit(main())
