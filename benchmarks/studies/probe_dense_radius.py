"""The neighbourhoods of the steps after the refinement: a number of mean edges, or a part of
the shape too.

Run:  .venv/bin/python benchmarks/studies/probe_dense_radius.py --remeshed R [--data DIR]
          [--sets topkids,remeshed,perturbed] [--json benchmarks/studies/probe_dense_radius.json]

R is the folder ``benchmarks/remesh.py --out R`` fills. The local isometry step, the local rigid
alignment and the inverse round fit each vertex's neighbourhood within ``RELAX_EDGES`` mean edges
of the coarser mesh. On a coarse mesh that is a large part of the shape: 4 edges of a
1,500-vertex mesh reach about 0.11 √area, of a 28,000-vertex one 0.026 √area (a mean edge is
about 1.07 √(area / n) on a closed mesh of n vertices), and a rigid fit over a bent joint moves
right images. Each variant caps the radius at ``rho`` √area of Y (the steps' ``reach``: the radius
``min(RELAX_EDGES h, rho √A_Y)``, h the coarser mean edge at Y's scale, as
:func:`gromov.dense.relax_isometric` measures it), for all three steps, in the default order
(:func:`gromov.dense.dense_maps`: relax, align, inverse round, align since). The default cap,
``RELAX_REACH``, was chosen from this study.

On the pairs of ``bench_dense.py`` (TOPKIDS kidXX -> kid00; TOSCA poses remeshed on their own and
pose 0 at two densities; pose 0 against itself with 20 holes and with 3 welds, both ways) each
pair is matched once with ``gromov.dense.DENSE_RELAX`` off and ``DENSE_ALIGN = 0``, which gives
both refined maps; each variant takes both through the steps and T is scored on the same
``--points`` random vertices of X (seeded): error x 100 / sqrt(area) by
:func:`gromov.evaluate.dense_error` (the better of direct and mirrored), the mean per map; per
set the mean of the maps' means, and how many maps each variant makes better or worse (by 0.001)
than the default. No pyFM run: the anchor is in ``bench_dense.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_dense as B  # noqa: E402

import gromov.dense as D  # noqa: E402

#: name -> the cap rho (None: RELAX_EDGES mean edges alone); gromov.dense.RELAX_REACH is 0.06
VARIANTS = {"4 edges, no cap": None, "at most 0.06 sqrt(area)": 0.06, "at most 0.05 sqrt(area)": 0.05,
            "at most 0.04 sqrt(area)": 0.04}
BASE = "4 edges, no cap"


def capped_edges(x, y, rho: float | None) -> float:
    """The steps' ``edges`` for the pair (X, Y) with the cap: ``RELAX_EDGES``, or fewer where
    that reaches beyond ``rho`` √area of Y (the radius ``reach=rho`` gives)."""
    x, y = (getattr(s, "input", s) for s in (x, y))
    if rho is None:
        return float(D.RELAX_EDGES)
    h = max(x.mean_edge_length * np.sqrt(y.area / x.area), y.mean_edge_length)
    return float(min(D.RELAX_EDGES, rho * np.sqrt(y.area) / h))


def steps(x, y, T, S, rho):
    """T after the default steps with each direction's neighbourhoods capped at ``rho``
    (their ``reach``)."""
    t = D.align_locally(x, y, D.relax_isometric(x, y, T, sweeps=D.RELAX_SWEEPS, reach=rho), reach=rho)
    s = D.align_locally(y, x, D.relax_isometric(y, x, S, sweeps=D.RELAX_SWEEPS, reach=rho), reach=rho)
    t2 = D._better_start(x, y, t, s, D.INVERSE_SWEEPS, reach=rho)   # the inverse round's starts
    return D.align_locally(x, y, t2, since=t, reach=rho)


#: each pair's maps through the steps with each cap, scored (:func:`bench_dense.variant_scorer`),
#: with the edges each cap gives the pair
scorer = B.variant_scorer(VARIANTS, steps,
                          lambda x, y: {"edges": {v: capped_edges(x, y, rho) for v, rho in VARIANTS.items()}})


def main(argv=None) -> int:
    return B.variant_study(argv, __doc__, "probe_dense_radius.json", scorer, VARIANTS, BASE,
                           {"variants": dict(VARIANTS), "relax_edges": D.RELAX_EDGES})


if __name__ == "__main__":
    sys.exit(main())
