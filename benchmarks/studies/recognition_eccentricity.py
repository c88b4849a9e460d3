"""Eccentricity and distance distributions of gromov's own metric as per-shape signatures.

Run:  .venv/bin/python benchmarks/studies/recognition_eccentricity.py [--data DIR] [--per-class 6]
          [--jobs 2] [--json benchmarks/studies/recognition_eccentricity.json]

On the subsets of ``recognition_defaults.py`` (``class_subset(labels, 6, seed=0)``: 60 watertight
shapes, 49 TOSCA shapes), each collection's matrices as ``gromov pairwise FILES --units area
--samples 50 --rank-by combined`` makes them (:func:`gromov.experiments.gh_matrix`: S the
Shape-DNA distance of the working meshes, G the trimmed distortion, the GH estimate, the combined
S^0.35 G^0.65), and from each prepared shape (:class:`gromov.ShapeMetric`: its working mesh and the
unit-area heat diffusion distances between all its vertices, the metric the match uses) two
signatures of Mémoli ("Gromov-Wasserstein distances and the metric approach to object matching",
Found. Comput. Math. 11, 2011, §6), compared by the 1-D Wasserstein distance (the mean absolute
difference of 25 quantiles, 2% to 98%):

- ``E``: the distribution of the eccentricities e(x) = sum_y a_y d(x, y) over the vertices,
  weighted by their areas a (exact: every vertex; the first lower bound's distribution);
- ``Dd``: the distribution of the distances between 600 area-weighted random vertices (seeded;
  the second lower bound's);

and, per pair, ``LB``: :func:`gromov.bounds.gh_lower_bound` of the 50 samples' distance matrices.
Scores (``bench_recognition.py``): NN, first tier, EER per collection and J = mean(1 - NN, 1 - FT,
EER) over both (``pooled_scores``); the weighted geometric means S^a X^b G^c (X one signature,
a in 0 / 0.15 / 0.25 / 0.35, b in 0 ... 0.5, each matrix over the median of its off-diagonal
values); and as the first stage of a two-stage search, the fraction of queries whose ten nearest
by the combined ranking lie within the signature's K nearest (K = 10, 15, 20, 30), and the
Spearman correlation of each signature with G over the pairs.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_recognition as BR  # noqa: E402
from _common import add_data_argument, write_results  # noqa: E402

from gromov.bounds import gh_lower_bound  # noqa: E402
from gromov.errors import GromovWarning  # noqa: E402
from gromov.experiments.pairwise import gh_matrix, prepare  # noqa: E402
from gromov.gh import RANK_TAU_SCALE  # noqa: E402

QUANTILES = np.linspace(0.02, 0.98, 25)
SAMPLES, PAIR_POINTS = 50, 600
OPTIONS = {**BR.GROMOV_METRIC, "units": "area"}
FIRST_STAGES = {"S": {"S": 1}, "E": {"E": 1}, "Dd": {"Dd": 1}, "S^0.5 E^0.5": {"S": 0.5, "E": 0.5},
                "S^0.5 Dd^0.5": {"S": 0.5, "Dd": 0.5}, "S^0.35 E^0.65": {"S": 0.35, "E": 0.65}}


def weighted_quantiles(values: np.ndarray, weights: np.ndarray, q: np.ndarray = QUANTILES) -> np.ndarray:
    """Quantiles ``q`` of ``values`` weighted by ``weights`` (linear in the cumulative weight)."""
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return np.interp(q, cum / cum[-1], values[order])


def eccentricity_quantiles(s) -> np.ndarray:
    """``E`` of a prepared shape: the quantiles of e(x) = sum_y a_y d(x, y) over its working
    vertices under the area measure a."""
    a = s.mesh.vertex_areas / s.mesh.vertex_areas.sum()
    return weighted_quantiles(s.distances @ a, a)


def signatures(s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(E quantiles, Dd quantiles, samples' distance matrix)`` of a prepared shape."""
    D = s.distances
    a = s.mesh.vertex_areas / s.mesh.vertex_areas.sum()
    ecc = eccentricity_quantiles(s)
    pick = np.random.default_rng(0).choice(len(a), min(PAIR_POINTS, len(a)), replace=False, p=a)
    dd = np.quantile(D[np.ix_(pick, pick)][np.triu_indices(len(pick), 1)], QUANTILES)
    samples = np.asarray(s.samples(SAMPLES, 0))
    return ecc, dd, D[np.ix_(samples, samples)]


def matrices(data: Path, name: str, per_class: int, jobs: int) -> dict:
    files, labels = BR.collection(data, name)
    keep = BR.class_subset(labels, per_class, 0)
    files, labels = [str(files[i]) for i in keep], labels[keep]
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        shapes = prepare(files, "diffusion", n_samples=SAMPLES, resolution=3000, metric_options=OPTIONS,
                         rank_tau_scale=RANK_TAU_SCALE, jobs=jobs, spectral=True)
        g = gh_matrix(shapes, "diffusion", n_samples=SAMPLES, resolution=3000, metric_options=OPTIONS, seed=0,
                      jobs=jobs, spectral=True)
    seconds = time.perf_counter() - t
    t = time.perf_counter()
    sig = [signatures(s) for s in shapes]
    n = len(sig)
    E, Dd, LB = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    for i, j in itertools.combinations(range(n), 2):
        E[i, j] = E[j, i] = np.abs(sig[i][0] - sig[j][0]).mean()
        Dd[i, j] = Dd[j, i] = np.abs(sig[i][1] - sig[j][1]).mean()
        LB[i, j] = LB[j, i] = gh_lower_bound(sig[i][2], sig[j][2])
    print(f"{name}: {n} shapes, matrix {seconds:.0f} s, signatures {time.perf_counter() - t:.1f} s", flush=True)
    return {"labels": labels, "S": g.spectral, "G": g.trimmed, "GH": g.relative, "C": g.combined,
            "E": E, "Dd": Dd, "LB": LB, "seconds_matrix": seconds}


def geometric(mats: dict, weights: dict) -> np.ndarray:
    """prod_k (M_k / median of its off-diagonal values)^w_k, zero diagonal."""
    out = np.ones_like(mats[next(iter(weights))], dtype=float)
    off = ~np.eye(len(out), dtype=bool)
    for k, w in weights.items():
        if w:
            m = np.asarray(mats[k], dtype=float)
            out = out * np.maximum(m / np.median(m[off]), 1e-12) ** w
    np.fill_diagonal(out, 0.0)
    return out


def scored(cols: dict, weights: dict, then=None) -> dict:
    """Scores of the weighted geometric mean of each collection's matrices (``then``: a function
    applied to each collection's matrix before scoring, e.g. a set-level re-ranking)."""
    mats = {c: geometric(m, weights) for c, m in cols.items()}
    if then is not None:
        mats = {c: then(M) for c, M in mats.items()}
    labels = {c: m["labels"] for c, m in cols.items()}
    pooled = BR.pooled_scores(mats, labels)
    out = {c: BR.scores(mats[c], labels[c]) for c in cols}
    out["J"] = float(np.mean([1 - pooled["nn"], 1 - pooled["ft"], pooled["eer"]]))
    return out


def line(name: str, r: dict) -> str:
    """One row of a study's table: a ranking's NN / FT / EER (%) on each collection, and J."""
    return (f"  {name:<26} TOSCA {100 * r['tosca']['nn']:.1f} / {100 * r['tosca']['ft']:.1f} / "
            f"{100 * r['tosca']['eer']:.1f}   watertight {100 * r['watertight']['nn']:.1f} / "
            f"{100 * r['watertight']['ft']:.1f} / {100 * r['watertight']['eer']:.1f}   J {r['J']:.4f}")


def table(title: str, rows) -> None:
    """Print a study's table: its title, then a :func:`line` per ``(name, scores)`` of ``rows``."""
    print(title)
    for name, r in rows:
        print(line(name, r))


def first_stage(m: dict, weights: dict, ks=(10, 15, 20, 30)) -> dict:
    """Fraction of queries whose 10 nearest by the combined ranking lie within the K nearest by
    the first-stage matrix."""
    C, P = m["C"], geometric(m, weights)
    n = len(C)

    def nearest(M, i, k):
        return set(np.argsort(np.where(np.arange(n) == i, np.inf, M[i]), kind="stable")[:k])

    top = [nearest(C, i, 10) for i in range(n)]
    return {f"K{k}": float(np.mean([top[i] <= nearest(P, i, k) for i in range(n)])) for k in ks}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "recognition_eccentricity.json"))
    args = ap.parse_args(argv)
    cols = {c: matrices(Path(args.data), c, args.per_class, args.jobs) for c in ("watertight", "tosca")}
    rows = {k: scored(cols, {k: 1}) for k in ("S", "G", "GH", "C", "E", "Dd", "LB")}
    combos = {}
    for x in ("E", "Dd", "LB"):
        for a, b in itertools.product((0, 0.15, 0.25, 0.35), (0, 0.15, 0.25, 0.35, 0.5)):
            c = round(1 - a - b, 2)
            if c >= 0 and b > 0:
                combos[f"S^{a} {x}^{b} G^{c}"] = scored(cols, {"S": a, x: b, "G": c})
    for a in (0.15, 0.25, 0.35):
        combos[f"S^{a} G^{round(1 - a, 2)}"] = scored(cols, {"S": a, "G": 1 - a})
    stages = {c: {name: first_stage(m, w) for name, w in FIRST_STAGES.items()} for c, m in cols.items()}
    iu = {c: np.triu_indices(len(m["G"]), 1) for c, m in cols.items()}
    spearman = {c: {k: float(spearmanr(m[k][iu[c]], m["G"][iu[c]])[0]) for k in ("S", "E", "Dd", "LB", "GH")}
                for c, m in cols.items()}

    table("alone (NN / FT / EER %):", rows.items())
    table("combinations, best J first:", sorted(combos.items(), key=lambda kv: kv[1]["J"])[:10])
    print("first stage (queries whose combined ten nearest lie within the K nearest):")
    for c, st in stages.items():
        for name, r in st.items():
            print(f"  {c:<10} {name:<14} " + "  ".join(f"{k} {100 * v:.0f}%" for k, v in r.items()))
        print(f"  {c:<10} Spearman with G: " + "  ".join(f"{k} {v:.3f}" for k, v in spearman[c].items()))
    write_results(args.json, {"per_class": args.per_class, "samples": SAMPLES, "quantiles": len(QUANTILES),
                              "pair_points": PAIR_POINTS,
                              "seconds_matrix": {c: m["seconds_matrix"] for c, m in cols.items()},
                              "shapes": {c: len(m["labels"]) for c, m in cols.items()},
                              "alone": rows, "combinations": combos, "first_stage": stages, "spearman": spearman})
    return 0


if __name__ == "__main__":
    sys.exit(main())
