"""How many full matches do per-shape bounds save, and at what recall? (``gromov search``)

Run:  .venv/bin/python benchmarks/bench_retrieval.py --store DIR [--set heldout|synthetic]
                                                      [--data DIR] [--json benchmarks/results/retrieval_SET.json]

The shapes -- ``heldout``: TOSCA's held-out classes wolf 0-2, horse 0, 5, 6, 7, 10, centaur
0-3, michael 0-3, and the gorillas 1, 5, 8, 14 (20 shapes, none of the paper's classes);
``synthetic``: the stretched synthetic set, ``Synthetic(pose_stretch=0.1)``, poses 0-3 of its
four classes (16 shapes, written as OFF files beside the store) -- are matched in full once, as
``gromov pairwise --store DIR`` matches them (the pairs are recorded in the store, so a second
run reads them). Then, for every shape as the query and the others as the collection, the
search of :func:`gromov.retrieval.nearest` is replayed on the recorded values
(it matches a pair only when its bound allows, so the values decide which pairs it would match),
for k = 1, 3, 5, with the lower bound alone (``prune="bound"``, exact) and with the profile gap
at several slacks (``prune="profile"``, the triangle estimates off), and at the default slack with the triangle
estimates at several ``triangle_slack`` (a search knowing the values between the other shapes,
as a store does after ``gromov pairwise``): recall@k against brute force (the fraction of the
true k nearest found, averaged over the queries) and the fraction of the pairs skipped. The same for
every shape's k nearest at once (:func:`gromov.retrieval.knn_pairs`, ``gh_matrix(k=...)``).
Ranked by the trimmed distortion (the default) and by the GH estimate (``rank_by="gh"``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from _common import add_data_argument

from gromov.experiments.pairwise import gh_matrix
from gromov.retrieval import PROFILE_SLACK, _schedule, _Triangle, knn_pairs, pair_bound, profile_gap, shape_bound
from gromov.store import ShapeStore

SHAPES = ([f"wolf{i}" for i in range(3)] + [f"horse{i}" for i in (0, 5, 6, 7, 10)]
          + [f"centaur{i}" for i in range(4)] + [f"michael{i}" for i in range(4)]
          + [f"gorilla{i}" for i in (1, 5, 8, 14)])
SLACKS = (0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.75, 1.0)
TRIANGLE_SLACKS = (0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2)
KS = (1, 3, 5)


def synthetic_files(folder: Path) -> list[str]:
    """Poses 0-3 of the stretched synthetic set's classes, as OFF files in ``folder``."""
    import gromov
    from gromov.experiments.synthetic import Synthetic

    folder.mkdir(parents=True, exist_ok=True)
    data = Synthetic(pose_stretch=0.1)
    files = []
    for cls in sorted(data.classes):
        for pose in range(4):
            files.append(str(folder / f"{cls}{pose}.off"))
            if not Path(files[-1]).exists():
                gromov.save(data.load(cls, pose), files[-1])
    return files


def brute(values: np.ndarray, k: int) -> list[set]:
    n = len(values)
    return [{j for _, j in sorted((values[i, j], j) for j in range(n) if j != i)[:k]} for i in range(n)]


def replay_queries(V, B, G, k, prune, slack, triangle_slack=None):
    """recall@k and fraction skipped of a search from every shape over the others; with
    ``triangle_slack``, the values between the others known (a store after ``gromov pairwise``)."""
    n = len(V)
    truth = brute(V, k)
    found, skipped = [], 0
    for q in range(n):
        others = [j for j in range(n) if j != q]
        pairs = [(0, j) for j in others]
        key = np.array([B[q, j] for j in others])
        gap = np.array([G[q, j] for j in others])
        if prune == "profile":
            key = np.maximum(key, slack * gap)
        triangle = None
        if prune == "profile" and triangle_slack:
            triangle = _Triangle(triangle_slack)
            for a in others:
                for b in others:
                    if a < b:
                        triangle.add(a, b, V[a, b], estimates=False)
        _, rows, _, n_skip = _schedule(pairs, lambda ij: [(0, ij[1])], key, gap, k, 1,
                                       lambda take, q=q: [V[q, j] for _, j in take], known={},
                                       triangle=triangle, nodes=lambda ij, q=q: (q, ij[1]))
        found.append(len({j for _, j in rows.best[0]} & truth[q]) / k)
        skipped += n_skip
    return float(np.mean(found)), skipped / (n * (n - 1))


def replay_all(shapes, V, k, rank_by, prune, slack, triangle_slack=None):
    n = len(V)
    # knn_pairs reads the ranked value at 2 (trimmed) or 1 (gh) of what run returns
    out = knn_pairs(shapes, k, lambda take: [(None, V[i, j], V[i, j]) for i, j in take],
                    rank_by=rank_by, prune=prune, slack=slack, triangle_slack=triangle_slack)
    truth = brute(V, k)
    recall = np.mean([len(set(out.neighbors[i].tolist()) & truth[i]) / k for i in range(n)])
    return float(recall), out.skipped / (n * (n - 1) // 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--store", required=True, help="a shape store folder (created if missing)")
    ap.add_argument("--set", choices=("heldout", "synthetic"), default="heldout")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    if a.set == "heldout":
        files = [str(Path(a.data) / "tosca" / f"{s}.off.gz") for s in SHAPES]
    else:
        files = synthetic_files(Path(f"{a.store.rstrip('/')}-shapes"))
    store = ShapeStore(a.store)
    g = gh_matrix(files, "diffusion", n_samples=100, jobs=a.jobs, store=store)
    shapes = store.shapes(files, "diffusion", rank_tau_scale=0.5)
    inv = [shape_bound(s, 100, 0, 0.5) for s in shapes]
    n = len(files)
    out = {"set": a.set, "files": [Path(f).name for f in files], "rankings": {}}
    for rank_by, V in (("trimmed", g.trimmed), ("gh", g.relative)):
        B = np.array([[pair_bound(inv[i], inv[j], rank_by=rank_by) if i != j else 0.0 for j in range(n)]
                      for i in range(n)])
        G = np.array([[profile_gap(inv[i], inv[j], rank_by=rank_by) if i != j else 0.0 for j in range(n)]
                      for i in range(n)])
        off = ~np.eye(n, dtype=bool)
        assert np.all(B[off] <= V[off]), "a bound above the ranked value"
        rows = {"bound_positive": float(np.mean(B[off] > 0)),
                "bound_over_value_median": float(np.median(B[off] / V[off])),
                "gap_over_value": [float(q) for q in np.quantile(G[off] / V[off], [0.0, 0.05, 0.5, 0.95, 1.0])],
                "search": {}, "all": {}}
        for k in KS:
            runs = [("bound", 1.0, None, "bound")] + [("profile", s, None, f"profile {s:g}") for s in SLACKS]
            runs += [("profile", PROFILE_SLACK, t, f"profile {PROFILE_SLACK:g} triangle {t:g}") for t in TRIANGLE_SLACKS]
            for prune, s, t, name in runs:
                recall, skip = replay_queries(V, B, G, k, prune, s, t)
                rows["search"][f"k={k} {name}"] = {"recall": recall, "skipped": skip}
                recall, skip = replay_all(shapes, V, k, rank_by, prune, s, t)
                rows["all"][f"k={k} {name}"] = {"recall": recall, "skipped": skip}
        out["rankings"][rank_by] = rows
        print(f"ranked by {rank_by}: bound > 0 on {rows['bound_positive']:.1%} of the pairs; profile gap / "
              f"value quantiles 0/5/50/95/100%: {', '.join(f'{q:.2f}' for q in rows['gap_over_value'])}")
        for kind in ("search", "all"):
            for name, r in rows[kind].items():
                print(f"  {kind:<6} {name:<18} recall {r['recall']:.3f}  skipped {r['skipped']:.1%}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
