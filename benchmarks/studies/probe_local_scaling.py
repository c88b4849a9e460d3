"""Which neighbour should local scaling use? EER and margin of the locally scaled rankings.

Run:  .venv/bin/python benchmarks/studies/probe_local_scaling.py [--ks 2,3,4] [--no-close] [--paper]
                                                          [--json benchmarks/studies/local_scaling.json]

:func:`gromov.experiments.recognition.local_scaling` divides each pair's distance by the
geometric mean of the two shapes' distances to their k-th nearest shape (Zelnik-Manor &
Perona, NIPS 2004). A weld moves a welded shape's diffusion distances to *every* other shape
(``weld_rows.py``), so a per-shape scale is what such noise changes. Nothing is
matched again for the sets that ``gromov reproduce`` has results files of: the ranking matrices
(``recognition.<experiment>.<metric>.trimmed``) are read from them, and ranked as they are and
after local scaling with each k. Printed per ranking: the EER and the *margin* (smallest
different-class over largest same-class distance; above 1 when one threshold separates every
pair).

The validation sets, never the paper's classes (cat, dog, david, victoria):

- ``synthetic``: ``make demo``'s set (``benchmarks/results/synthetic/``);
- ``stretched``: ``gromov reproduce --pose-stretch 0.1`` (``benchmarks/results/synthetic-stretch/``);
- ``heldout``: TOSCA classes the paper did not use (``benchmarks/results/reproduce-heldout/``);
- ``close1``, ``close0.5``: the stretched synthetic people, victoria's body the fraction 1 or
  0.5 of the way from david's (``bench_close_humanoids.py``'s set: 50 samples, reference + 4
  poses, clean and welded) -- matched here (about a minute on 2 cores; ``--no-close`` skips).

k is chosen by the geometric mean of the diffusion margins over the eight readings (the rule
every ranking choice of docs/design/recognition.md follows). The smallest class of every set's Experiment 1 has 5
shapes (``smallest`` in the output): from k = 5 on, scales come from other classes. ``--paper`` adds the paper's classes from their results
file, printed apart, for information only.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from gromov.experiments.recognition import equal_error_rate, local_roc, smallest_class

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import HERE, margin, write_results  # noqa: E402

SETS = {"synthetic": "synthetic", "stretched": "synthetic-stretch", "heldout": "reproduce-heldout"}
PAPER = "reproduce-tosca"


def from_results(folder: str, metrics) -> dict:
    """``{"<set>/<experiment>/<metric>": (trimmed matrix, labels)}`` of a committed run."""
    r = json.loads((HERE / "results" / folder / "results.json").read_text())
    out = {}
    for exp, rec in r["recognition"].items():
        for m in metrics:
            out[f"{exp}/{m}"] = (np.array(rec[m]["trimmed"]), np.array(rec["labels"]))
    return out


def close_people(blends=(1.0, 0.5), jobs: int = 2) -> dict:
    """The close-people matrices (diffusion), as ``bench_close_humanoids.py`` makes them."""
    from bench_close_humanoids import close_people as items_of

    from gromov.experiments.pairwise import gh_matrix

    out = {}
    for blend in blends:
        items = items_of(blend)
        r = gh_matrix([s.mesh for s in items], "diffusion", n_samples=50, resolution=None,
                      metric_options={"units": "raw"}, jobs=jobs)
        out[f"close{blend:g}/weld/diffusion"] = (np.asarray(r.trimmed), np.array([s.cls for s in items]))
    return out


def readings(D: np.ndarray, labels: np.ndarray, ks) -> dict:
    row = {"as is": {"eer": equal_error_rate(D, labels), "margin": margin(D, labels)},
           "smallest": smallest_class(labels)}
    for k in ks:
        curve, Dk, _ = local_roc(D, labels, k, warn=False)
        row[f"k={k}"] = {"eer": curve.eer, "margin": margin(Dk, labels)}
    return row


def show(name: str, row: dict) -> None:
    print(f"  {name:<28}smallest class {row['smallest']}  "
          + "  ".join(f"{k} {v['eer']:6.2%} / {v['margin']:.3f}" for k, v in row.items() if k != "smallest"),
          flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ks", default="2,3,4", help="the neighbours to try (default 2,3,4)")
    ap.add_argument("--metrics", default="diffusion,geodesic")
    ap.add_argument("--no-close", action="store_true", help="skip the close people (no matching)")
    ap.add_argument("--paper", action="store_true",
                    help="also the paper's classes (their committed results), apart, for information")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    ks = [int(k) for k in a.ks.split(",")]
    metrics = a.metrics.split(",")
    t0 = time.perf_counter()
    mats = {f"{s}/{k}": v for s, folder in SETS.items() for k, v in from_results(folder, metrics).items()}
    if not a.no_close:
        mats.update(close_people(jobs=a.jobs))
    out = {"ks": ks, "validation": {}, "choice": {}, "paper": {}}
    print("EER / margin, as ranked and after local scaling with k (capped at n - 1)")
    for name, (D, labels) in mats.items():
        out["validation"][name] = readings(D, labels, ks)
        show(name, out["validation"][name])
    for m in metrics:
        rows = [v for n, v in out["validation"].items() if n.endswith("/" + m)]
        gm = {key: float(np.exp(np.mean([np.log(r[key]["margin"]) for r in rows])))
              for key in rows[0] if key != "smallest"}
        out["choice"][m] = {"geometric_mean_margin": gm, "readings": len(rows),
                            "best": max(gm, key=gm.get)}
        print(f"{m}: geometric mean of the margins over {len(rows)} readings: "
              + ", ".join(f"{k} {v:.3f}" for k, v in gm.items()) + f" -> {out['choice'][m]['best']}")
    if a.paper:
        print("the paper's classes (information only; not used for the choice)")
        for name, (D, labels) in from_results(PAPER, metrics).items():
            out["paper"][name] = readings(D, labels, ks)
            show("paper/" + name, out["paper"][name])
    out["seconds"] = round(time.perf_counter() - t0, 1)
    print(f"({out['seconds']:.0f} s)")
    write_results(a.json, out)


if __name__ == "__main__":
    main()
