"""Preliminary recognition run of the paper's Experiment 1 (welds) on TOSCA.

Run:  .venv/bin/python benchmarks/experiment1_quick.py [--data DIR] [--jobs 2]

Not yet `gromov reproduce` (issue 4): the 40 shapes of `experiments.datasets.experiment1`
(reference + deformations, each deformation also welded at 3 places by
`gromov.perturb.weld` on its 3,000-vertex working mesh), the pairwise GH matrix for each
metric, and the equal error rate over all pairs (positives: same class).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

import gromov
from gromov.experiments.datasets import TOSCA, experiment1
from gromov.experiments.pairwise import gh_matrix
from gromov.experiments.recognition import equal_error_rate

HERE = Path(__file__).resolve().parent


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[1] / "shared" / "data")))
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--samples", type=int, default=100)
    p.add_argument("--json", default=None, help="write labels, matrices and EERs to this file")
    args = p.parse_args(argv)
    tosca = TOSCA(Path(args.data) / "tosca")
    entries = experiment1(tosca)
    t = time.perf_counter()
    meshes, labels, welded = [], [], []
    for e in entries:
        work = gromov.simplify(tosca.load(e.cls, e.pose), 3000).mesh
        if e.perturbation is not None:
            # the default search radius is 5 mean edges; poses without close parts need more
            # and a pose whose parts never come close gets fewer welds (reported)
            edge = work.mean_edge_length
            done = None
            for ratio in (4.0, 2.0):
                for count in range(e.perturbation[1], 0, -1):
                    radius = 5 * edge
                    for _ in range(5):
                        try:
                            done = gromov.perturb.weld(work, count, radius=radius, seed=e.seed,
                                                       min_geodesic_ratio=ratio)
                            break
                        except ValueError:
                            radius *= 1.5
                    if done is not None:
                        break
                if done is not None:
                    break
            if done is None:
                raise RuntimeError(f"no weld sites on {e.label}")
            if count < e.perturbation[1] or radius > 5 * edge or ratio < 4:
                print(f"  {e.label}: {count} weld(s), search radius {radius / edge:.1f} mean edges, "
                      f"geodesic/euclidean ratio >= {ratio:g}")
            work = done.mesh
        meshes.append(work)
        labels.append(e.cls)
        welded.append(e.perturbation is not None)
    print(f"{len(meshes)} shapes ({sum(welded)} welded) prepared in {time.perf_counter() - t:.1f} s")
    labels = np.array(labels)
    out = {"entries": [e.label for e in entries], "labels": labels.tolist(), "welded": welded,
           "samples": args.samples, "date": time.strftime("%Y-%m-%d")}
    for metric in ("diffusion", "geodesic"):
        r = gh_matrix(meshes, metric, n_samples=args.samples, resolution=None, jobs=args.jobs, progress=True)
        eer = equal_error_rate(r.relative, labels)
        w = np.array(welded)
        mask = w[:, None] | w[None, :]
        eer_w = equal_error_rate(r.relative, labels, mask=mask)
        print(f"{metric}: EER {eer:.3f} over all pairs, {eer_w:.3f} over pairs with a welded shape "
              f"(metrics {r.seconds_prepare:.0f} s, pairs {r.seconds_match:.0f} s)")
        # nearest neighbour (leave one out): which classes are confused
        d = r.relative + np.diag(np.full(len(labels), np.inf))
        nn = labels[np.argmin(d, axis=1)]
        print(f"  nearest-neighbour class accuracy {np.mean(nn == labels):.3f}; confusions: "
              + ", ".join(f"{a}->{b}" for a, b in zip(labels, nn) if a != b))
        out[metric] = {"eer": eer, "eer_welded_pairs": eer_w, "relative": r.relative.tolist(),
                       "nn_accuracy": float(np.mean(nn == labels))}
    if args.json:
        import json

        Path(args.json).write_text(json.dumps(out))


if __name__ == "__main__":
    main()
