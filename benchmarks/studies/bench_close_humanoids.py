"""A harder recognition pair for choosing on validation data: two synthetic people made closer.

Run:  .venv/bin/python benchmarks/studies/bench_close_humanoids.py [--blends 1,0.5,0.25] [--json OUT]

On the paper's TOSCA classes every false acceptance at the equal error rate is a david /
victoria pair, and neither validation set has a pair of classes that close (the held-out
classes and the synthetic set are at 0% / 0.7% EER; TOSCA's unused gorilla is far from
michael). Here the synthetic victoria's body is moved towards the synthetic david's
(``Synthetic(victoria_blend=b)``: her body parameters the fraction ``b`` of the way from his
to hers), and the two classes are built as ``gromov reproduce``'s Experiment 1 builds them
(reference pose, deformations 1-4 clean and welded; :func:`gromov.experiments.datasets.experiment1`,
the same welds). For each blend, the GH matrices of the heat-kernel diffusion metric with raw
heat distances and with normalised heat distributions are computed (``gh_matrix``), and
pairs are ranked by each and by their elementwise geometric mean (the trimmed distortions
measured at ``--rank-tau-scale`` times each metric's diffusion time, as ``gh_matrix`` does by
default; ``--rank-tau-scale 1`` for the match's own metric; of the log distance ratios, as
``gh_matrix`` does by default; ``--rank-residual difference`` for their differences).
``--stretch`` builds the people with non-isometric poses (``Synthetic(pose_stretch=...)``), as
TOSCA's are. Printed per ranking: the
equal error rate and the *margin* (smallest different-class over largest same-class distance;
above 1 when one threshold separates every pair), for the trimmed distortion (what
``gromov reproduce`` ranks by) and the GH estimate.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from gromov.experiments import datasets
from gromov.experiments.pairwise import gh_matrix
from gromov.experiments.recognition import equal_error_rate
from gromov.experiments.reproduce import _Shapes
from gromov.experiments.synthetic import Synthetic
from gromov.gh import RANK_RESIDUAL, RANK_RESIDUALS, RANK_TAU_SCALE

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import margin  # noqa: E402

OPTIONS = {"raw": {"units": "raw"}, "normalized": {"units": "normalized"}}


def close_people(blend: float, stretch: float = 0.1, deformations: int = 4) -> list:
    """The synthetic david and victoria (victoria's body the fraction ``blend`` of the way from
    david's), reference + ``deformations`` poses each, clean and welded, as ``gromov
    reproduce`` builds Experiment 1's shapes."""
    coll = Synthetic(victoria_blend=blend, pose_stretch=stretch)
    shapes = _Shapes(coll, None)
    entries = datasets.experiment1(coll, {"david": deformations, "victoria": deformations})
    return [shapes.entry(e) for e in entries]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blends", default="1,0.5,0.25")
    ap.add_argument("--deformations", type=int, default=4)
    ap.add_argument("--samples", type=int, default=50)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--raw-tau", type=float, default=None,
                    help="diffusion time of the raw heat distance (default the library's, 0.005)")
    ap.add_argument("--stretch", type=float, default=0.0,
                    help="Synthetic(pose_stretch=...): non-isometric poses, as TOSCA's (0.1: geodesic "
                         "distances change by 2.4-6.5%%, TOSCA's people 2.5-4.5%%)")
    ap.add_argument("--rank-residual", choices=RANK_RESIDUALS, default=RANK_RESIDUAL,
                    help="the trimmed ranking's residuals: log distance ratios (default) or differences")
    ap.add_argument("--rank-tau-scale", type=float, default=RANK_TAU_SCALE,
                    help="the trimmed ranking measures each correspondence at this times the "
                         "diffusion time (default the library's; 1: in the metric of the match)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    rank_scale = None if args.rank_tau_scale == 1.0 else args.rank_tau_scale
    options = {k: dict(v) for k, v in OPTIONS.items()}
    if args.raw_tau is not None:
        options["raw"]["tau"] = args.raw_tau
    out = {"date": time.strftime("%Y-%m-%d"), "samples": args.samples, "deformations": args.deformations,
           "pose_stretch": args.stretch, "rank_tau_scale": rank_scale,
           "rank_residual": args.rank_residual,
           "options": options, "blends": {}}
    t0 = time.perf_counter()
    for blend in (float(b) for b in args.blends.split(",")):
        items = close_people(blend, args.stretch, args.deformations)
        labels = np.array([s.cls for s in items])
        mats = {}
        for name, opts in options.items():
            r = gh_matrix([s.mesh for s in items], "diffusion", n_samples=args.samples, resolution=None,
                          metric_options=opts, jobs=args.jobs, rank_tau_scale=rank_scale,
                          rank_residual=args.rank_residual)
            mats[name] = {"trimmed": r.trimmed, "gh": r.relative}
        mats["geometric mean"] = {k: np.sqrt(mats["raw"][k] * mats["normalized"][k]) for k in ("trimmed", "gh")}
        row = {}
        for name, m in mats.items():
            row[name] = {k: {"eer": float(equal_error_rate(D, labels)), "margin": margin(D, labels)}
                         for k, D in m.items()}
            t, g = row[name]["trimmed"], row[name]["gh"]
            print(f"victoria_blend {blend:g} ({len(items)} shapes), {name:<15} trimmed: EER "
                  f"{t['eer']:.3f} margin {t['margin']:.3f} | GH: EER {g['eer']:.3f} margin {g['margin']:.3f}",
                  flush=True)
        out["blends"][f"{blend:g}"] = row
    print(f"({time.perf_counter() - t0:.0f} s)")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
