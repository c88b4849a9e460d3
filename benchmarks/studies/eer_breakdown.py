"""Where the equal error rate of a `gromov reproduce` run comes from.

Run:  .venv/bin/python benchmarks/studies/eer_breakdown.py [RESULTS.json ...]
      (default: benchmarks/results/reproduce-tosca*/results.json)

For each experiment, metric and ranking (the GH estimate; the trimmed distortion where the
run recorded it), the EER (``gromov.experiments.recognition.equal_error_rate``,
one global threshold, positives = pairs of the same class) over

- all pairs (the number in results.json),
- pairs of clean shapes only (no topological noise at all),
- all pairs except those of a male (david) and a female (victoria) shape -- the two classes
  that our Gromov-Hausdorff distances confuse most (nearest-neighbour errors) -- to show how
  much of the EER that one confusion is;

and, at the threshold of the EER over all pairs, the errors by pair of classes and by class
(``gromov.experiments.recognition.errors_at``, which ``gromov reproduce`` now records itself
as ``errors_at_eer``).

This is a diagnostic beside the paper's protocol, not a replacement for it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from gromov.experiments.recognition import equal_error_rate, errors_at, roc
from gromov.experiments.report import errors_text

HERE = Path(__file__).resolve().parent


def _eer(D, labels, mask):
    """EER of the selected pairs; None where they hold no positive or no negative pair."""
    sel = np.triu(np.ones(D.shape, bool) if mask is None else mask, 1)
    same = (labels[:, None] == labels[None])[sel]
    if same.all() or not same.any():   # e.g. Experiment 2's clean shapes: one per class
        return None
    return equal_error_rate(D, labels, mask=mask)


def breakdown(results: dict) -> dict:
    out = {}
    for exp, rec in results["recognition"].items():
        labels = np.array(rec["labels"])
        clean = ~np.array(rec["perturbed"])
        cross = np.isin(labels, ("david", "victoria"))
        not_mf = ~(cross[:, None] & cross[None] & (labels[:, None] != labels[None]))
        for m in ("geodesic", "diffusion"):
            # "relative": the GH estimates; "trimmed" (where recorded): the trimmed distortion
            for stat, key in (("GH", "relative"), ("trimmed", "trimmed")):
                if key not in rec[m]:
                    continue
                D = np.array(rec[m][key])
                out[exp, m, stat] = {
                    "all": _eer(D, labels, None),
                    "clean only": _eer(D, labels, clean[:, None] & clean[None]),
                    "without david-victoria pairs": _eer(D, labels, not_mf),
                    "errors": errors_at(D, labels, roc(D, labels).eer_threshold),
                }
    return out


def main(argv=None):
    paths = [Path(p) for p in (argv if argv is not None else sys.argv[1:])] or sorted(
        HERE.parent.glob("results/reproduce-tosca*/results.json"))
    for path in paths:
        r = json.loads(path.read_text())
        opts = r["params"]["metric_options"]["diffusion"]
        print(f"{path}  (diffusion {opts}, welds {r['params'].get('weld_join', 'tube')})")
        for (exp, m, stat), row in breakdown(r).items():
            errors = row.pop("errors")
            print(f"  {exp:<6}{m:<11}{stat:<9}" + "".join(f"{k} {'-' if v is None else format(v, '6.1%')}   "
                                          for k, v in row.items()))
            print(f"  {'':<26}at the EER threshold: {errors_text(errors)}")


if __name__ == "__main__":
    main()
