"""Set-level re-ranking of complete recognition matrices: what the collection around a pair adds.

Run:  .venv/bin/python benchmarks/studies/recognition_rerank.py --cache DIR [--data DIR]
          [--collections tosca,watertight] [--json benchmarks/studies/recognition_rerank.json]

after ``benchmarks/bench_recognition.py ... --per-class 0 --combined-per-class 0 --cache DIR`` on
each collection (the complete matrices, as ``recognition_two_stage.py`` reads them). Every value
``gromov pairwise`` ranks by is a pair's own; a set-level rule also reads the other shapes of the
collection, so each collection is re-ranked on its own, from its complete matrix, and a value
changes when shapes are added. Rules, for the combined ranking, the trimmed distortion and the GH
estimate of the same matches:

- ``plain``: the matrix itself (symmetrised).
- ``local k``: local scaling, :func:`gromov.experiments.recognition.local_scaling` (each distance
  over the geometric mean of the two shapes' distances to their k-th nearest; Zelnik-Manor &
  Perona, NIPS 2004), k in :data:`LOCAL_K`.
- ``diffusion k, t``: the affinity :math:`W_{ij} = \\exp(-d_{ij}^2 / (\\sigma_i \\sigma_j))`
  (:math:`\\sigma_i` the distance to the 4th nearest, as local scaling's default), its
  transition matrix restricted to each shape's k nearest and itself, :math:`P`, and the
  diffusion :math:`A \\leftarrow P A P^\\top` from :math:`A = P`, t - 1 times (Donoser & Bischof,
  "Diffusion processes for retrieval revisited", CVPR 2013); ranked by :math:`\\max A - A`
  (symmetrised; :func:`gromov.experiments.recognition.diffusion_rerank`). k in
  :data:`DIFFUSION_K`, t in :data:`DIFFUSION_T`.

Each rule scored per collection (nearest neighbour, first tier, EER) and on the collections
together, J = mean(1 - NN, 1 - first tier, EER) as in ``recognition_defaults.py`` (the EER with
one threshold over every within-collection pair); the rows sorted by J.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

LOCAL_K = (2, 4, 6, 8)
DIFFUSION_K = (5, 8, 10, 15)
DIFFUSION_T = (1, 2, 3)
SCALE_K = 4
RANKINGS = ("combined", "trimmed", "gh")


def diffusion_rerank(D: np.ndarray, k: int, t: int, scale_k: int = SCALE_K) -> np.ndarray:
    """:func:`gromov.experiments.recognition.diffusion_rerank` of the symmetrised ``D`` (the
    diffusion of the module's docstring on its ``k``-nearest neighbour graph, ``t`` steps)."""
    from gromov.experiments.recognition import diffusion_rerank as rerank

    D = np.asarray(D, dtype=np.float64)
    n = len(D)
    return rerank(0.5 * (D + D.T), min(k, n - 1), int(t), scale_k=min(scale_k, n - 1))


def rules() -> dict:
    """name -> function of a distance matrix, every rule of the study."""
    from gromov.experiments.recognition import local_scaling

    out = {"plain": lambda D: 0.5 * (D + D.T)}
    for k in LOCAL_K:
        out[f"local {k}"] = lambda D, k=k: local_scaling(0.5 * (D + D.T), k)
    for k in DIFFUSION_K:
        for t in DIFFUSION_T:
            out[f"diffusion {k}, {t}"] = lambda D, k=k, t=t: diffusion_rerank(D, k, t)
    return out


def main(argv=None) -> None:
    from bench_recognition import pooled_scores, scores
    from recognition_defaults import objective
    from recognition_two_stage import load

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True, type=Path)
    ap.add_argument("--data", default=None)
    ap.add_argument("--collections", default="tosca,watertight")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "recognition_rerank.json"))
    args = ap.parse_args(argv)
    data = args.data or os.environ.get("GROMOV_DATA") or str(ROOT.parent / "shared" / "data")
    names = [c for c in args.collections.split(",") if c]
    mats, labs = {}, {}
    for c in names:
        mats[c], labs[c] = load(args.cache, data, c)
    rows = []
    for ranking in RANKINGS:
        for name, rule in rules().items():
            ranked = {c: rule(mats[c][ranking]) for c in names}
            pooled = pooled_scores(ranked, labs)
            rows.append({"ranking": ranking, "rule": name, "J": objective(pooled), "pooled": pooled,
                         **{c: scores(ranked[c], labs[c]) for c in names}})
    rows.sort(key=lambda r: r["J"])
    res = {"command": "python benchmarks/studies/recognition_rerank.py " + " ".join(
               argv if argv is not None else sys.argv[1:]),
           "collections": {c: len(labs[c]) for c in names}, "scale_k": SCALE_K, "rows": rows}
    Path(args.json).write_text(json.dumps(res, indent=1) + "\n")
    for r in rows:
        print(f"J {r['J']:.4f}  {r['ranking']:<9} {r['rule']:<16} "
              + "  ".join(f"{c} NN {r[c]['nn']:.3f} FT {r[c]['ft']:.3f} EER {r[c]['eer']:.3f}" for c in names))


if __name__ == "__main__":
    main()
