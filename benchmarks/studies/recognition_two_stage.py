"""The two-stage search against brute force, read off one complete matrix of a collection.

Run:  .venv/bin/python benchmarks/studies/recognition_two_stage.py --cache DIR --bench JSON
          [--collection watertight] [--with tosca] [--candidates 10,20,30,40,60,80] [--top 10]
          [--first-stages] [--descent] [--measured NPZ,JSON]
          [--json benchmarks/studies/recognition_two_stage.json]

after ``benchmarks/bench_recognition.py --collections watertight --methods shapedna,hks,combined
--per-class 0 --combined-per-class 0 --cache DIR --json JSON``, which matches *every* pair of the
collection (brute force) and keeps the matrices in ``DIR`` (``combined-<collection>-pc0-s50-c0-seed0.npz``:
the spectral distance S, the trimmed distortion G, the GH estimate and the combined ranking
S^w G^(1-w); ``descriptors/<collection>/``: the input-mesh Shape-DNA and pooled HKS).

**Two stages, exactly.** ``gh_matrix(candidates=C)`` matches the pairs in which one shape is among
the other's C nearest by S (``gromov.experiments.pairwise._candidate_pairs``), and a matched pair's
values are the full matrix's (tested in tests/test_spectrum.py), so the two-stage result for any C
is the brute-force matrix with the other pairs removed. For each C: the pairs matched, and per
query whether its ``--top`` nearest (by the combined ranking; unmatched pairs after every matched
one, as ``bench_recognition.py`` ranks them) are brute force's, as a list (same order) and as a set;
the time a two-stage run would take at the brute-force run's measured cost per pair and per shape.
Also a rule that stops per query (:func:`adaptive`), simulated the same way.

**First stages.** With ``--first-stages``, the same reading for other per-shape distances in
place of S (:data:`FIRST_STAGES`): the eccentricity distributions E of each shape's working
distances (``recognition_eccentricity.py``: the 1-D Wasserstein distance of 25 quantiles, in the
metric of the matrix, unit-area heat distances; computed here, 10 shapes at a time, and kept in
``DIR/eccentricity-<collection>.npz``), weighted geometric means of S and E, and the input
meshes' Shape-DNA and pooled HKS of the benchmark. Their time adds the signatures' measured
cost to the brute-force run's preparation. E then also joins the pair-local rankings.

**Neighbour descent.** With ``--descent``, ``gh_matrix(candidates=C, k=K)``'s search (the first
stage, then rounds of ``gromov.experiments.pairwise._descent_pairs`` until one adds no pair)
read off each collection's complete matrix of each ranking, for K = 5, 10, 20, m = K, 1.5 K, 2 K
and C = K, 2 K (:data:`DESCENTS`); and ``nearest(query, store, k=K, candidates=C)``'s, each
shape the query of a store of the others (:func:`query_descent`, :data:`QUERY_DESCENTS`). With ``--measured NPZ,JSON`` (a two-stage run of
``bench_recognition.py --candidates C [--k K] --cache DIR`` and its results file): which
queries of that run have brute force's ten nearest, and whether its matched values are the
complete matrix's.

**Rankings of the complete matrix.** Nearest neighbour, first and second tier, EER (one threshold
over all pairs; after local scaling beside it) and nearest neighbour per class, for the combined
ranking, its two factors, the GH estimate and the two per-shape descriptors of the benchmark.
With ``--with tosca`` (the same benchmark run on TOSCA into the same cache), every weighted
geometric mean S^w G^(1-w) of a per-shape distance S and a GMDS statistic G is scored on both
collections together, J = mean(1 - NN, 1 - first tier, EER) as in recognition_defaults.py.
With the signature distortion in the cache, also the grid S^a G^b GH^c H^d (:func:`signature_local`,
:func:`signature_split`) and the combined ranking times a size factor (:func:`size_factor`; the
input meshes' areas are read from ``descriptors/``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

from bench_recognition import collection, euclidean, retrieval_scores, scores  # noqa: E402
from recognition_defaults import objective, top_sets  # noqa: E402
from recognition_eccentricity import eccentricity_quantiles, geometric  # noqa: E402

from gromov.experiments.pairwise import _candidate_pairs  # noqa: E402


def ranked_after(D: np.ndarray, S: np.ndarray, matched: np.ndarray) -> np.ndarray:
    """``D`` where ``matched``, else after every matched value in the order of ``S``: how a two-stage
    matrix is ranked (``bench_recognition.combined_matrix``)."""
    out = np.where(matched, D, np.nanmax(D[matched]) + 1.0 + S / (S.max() + 1e-300))
    np.fill_diagonal(out, 0.0)
    return out


def matched_by_candidates(S: np.ndarray, c: int) -> np.ndarray:
    """``(n, n)`` bool: the pairs ``gh_matrix(candidates=c)`` matches (and the diagonal)."""
    matched = np.eye(len(S), dtype=bool)
    for i, j in _candidate_pairs(S, c):
        matched[i, j] = matched[j, i] = True
    return matched


def against_brute_force(D: np.ndarray, S: np.ndarray, matched: np.ndarray, top: int, labels) -> dict:
    """The search that matched ``matched`` (the diagonal included) against brute force's ``D``:
    the pairs matched, the queries whose ``top`` nearest are brute force's (in order; as sets; the
    mean overlap), and its nearest neighbour and first tier."""
    n = len(D)
    R = ranked_after(D, S, matched)
    brute, ours = top_sets(D, top), top_sets(R, top)
    same_list = np.array([np.array_equal(a, b) for a, b in zip(brute, ours)])
    same_set = np.array([set(a.tolist()) == set(b.tolist()) for a, b in zip(brute, ours)])
    overlap = np.array([len(set(a.tolist()) & set(b.tolist())) / top for a, b in zip(brute, ours)])
    r = retrieval_scores(R, labels)
    pairs = int(matched[np.triu_indices(n, 1)].sum())
    return {"pairs": pairs, "fraction_of_pairs": pairs / (n * (n - 1) // 2),
            "top_equal_list": float(same_list.mean()), "top_equal_set": float(same_set.mean()),
            "top_overlap": float(overlap.mean()), "queries_differing": int((~same_set).sum()),
            "nn": float(np.mean(r["nn"])), "ft": float(np.nanmean(r["ft"]))}


def two_stage(D: np.ndarray, S: np.ndarray, c: int, top: int, labels) -> dict:
    """The two-stage search with ``c`` candidates, read off the complete matrix ``D``."""
    return {"candidates": c, **against_brute_force(D, S, matched_by_candidates(S, c), top, labels)}


def eer_local(D: np.ndarray, labels) -> float:
    """The EER after local scaling (:func:`gromov.experiments.recognition.local_scaling`, its default
    k): reported beside the EER, never in its place (docs/design/recognition.md, section 4)."""
    from gromov.experiments.recognition import equal_error_rate, local_scaling

    return float(equal_error_rate(local_scaling(0.5 * (D + D.T)), labels))


def adaptive(D: np.ndarray, S: np.ndarray, G: np.ndarray, w: float, top: int, first: int, q: float,
             labels) -> dict:
    """A two-stage search that stops per query: each shape's ``first`` nearest by S matched, then,
    query by query, the next shape in the order of S while S^w g^(1-w) is below the query's
    ``top``-th value found, g the ``q``-quantile of G over the pairs of the first round (a lower
    estimate of G: the rule is exact where no unmatched pair has G below g)."""
    n = len(D)
    matched = matched_by_candidates(S, first)
    iu = np.triu_indices(n, 1)
    g = float(np.quantile(G[iu][matched[iu]], q))
    order = [np.r_[0:i, i + 1:n][np.argsort(S[i, np.r_[0:i, i + 1:n]], kind="stable")] for i in range(n)]
    for i in range(n):
        for j in order[i]:
            if matched[i, j]:
                continue
            row = D[i][matched[i] & (np.arange(n) != i)]
            tth = np.sort(row)[top - 1] if len(row) >= top else np.inf
            if S[i, j] ** w * g ** (1.0 - w) >= tth:
                break
            matched[i, j] = matched[j, i] = True
    return {"first": first, "quantile": q, "floor": g, **against_brute_force(D, S, matched, top, labels)}


#: First stages compared (``--first-stages``): weighted geometric means of per-shape distances.
FIRST_STAGES = {"S": {"spectral": 1.0}, "E": {"eccentricity": 1.0},
                "S^0.65 E^0.35": {"spectral": 0.65, "eccentricity": 0.35},
                "S^0.5 E^0.5": {"spectral": 0.5, "eccentricity": 0.5},
                "S^0.35 E^0.65": {"spectral": 0.35, "eccentricity": 0.65},
                "input Shape-DNA": {"dna_input": 1.0}, "input HKS": {"hks_input": 1.0},
                "input HKS^0.5 E^0.5": {"hks_input": 0.5, "eccentricity": 0.5}}


def eccentricity_matrix(cache: Path, data: str, name: str, jobs: int) -> tuple[np.ndarray, float]:
    """``(E, seconds)``: the eccentricity distances between a collection's shapes, prepared as the
    benchmark's combined run prepares them, and the seconds the signatures took past that
    preparation (kept in ``cache``)."""
    import time
    import warnings

    from bench_recognition import GROMOV_METRIC

    from gromov.errors import GromovWarning
    from gromov.experiments.pairwise import prepare

    files, _ = collection(data, name)
    path = cache / f"eccentricity-{name}.npz"
    if path.exists():
        z = np.load(path)
        if [str(x) for x in z["files"]] == [f.name for f in files]:
            sig, seconds = z["signatures"], float(z["seconds"])
            return np.abs(sig[:, None] - sig[None]).mean(axis=2), seconds
    seconds, sig = 0.0, []
    for start in range(0, len(files), 10):   # 10 shapes' dense distances in memory at a time
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", GromovWarning)
            shapes = prepare([str(f) for f in files[start:start + 10]], "diffusion", resolution=3000,
                             metric_options={**GROMOV_METRIC, "units": "area"}, jobs=jobs)
        t = time.perf_counter()   # the signatures only: the distances are the preparation's
        sig += [eccentricity_quantiles(s) for s in shapes]
        seconds += time.perf_counter() - t
    sig = np.array(sig)
    np.savez(path, files=np.array([f.name for f in files]), signatures=sig, seconds=seconds)
    return np.abs(sig[:, None] - sig[None]).mean(axis=2), seconds


def first_stages(M: dict, labels, candidates, top: int, row: dict | None = None,
                 signature_seconds: float = 0.0) -> dict:
    """Each of :data:`FIRST_STAGES` as the first stage, read off the complete matrix: per C, the
    pairs, the queries whose ``top`` nearest are brute force's and, given the brute-force run's
    ``row``, the estimated time (its preparation and cost per pair, plus ``signature_seconds``
    for E)."""
    out = {}
    for name, weights in FIRST_STAGES.items():
        P = geometric(M, weights)
        extra = signature_seconds if "eccentricity" in weights else 0.0
        out[name] = []
        for c in candidates:
            t = {"candidates": c, **against_brute_force(M["combined"], P, matched_by_candidates(P, c), top, labels)}
            if row is not None:
                per_pair = row["seconds_match"] / row["pairs_matched"]
                t["estimated_seconds"] = row["seconds_prepare"] + extra + t["pairs"] * per_pair
            out[name].append(t)
    return out


def descent(D: np.ndarray, S: np.ndarray, c: int, top: int, factor: float, labels) -> dict:
    """``gh_matrix(candidates=c, k=top)``'s search read off the complete matrix ``D`` (the
    ranking the descent follows): the first stage, then rounds of
    :func:`gromov.experiments.pairwise._descent_pairs` with ``m = ceil(factor * top)`` until
    one adds no pair."""
    m = min(int(np.ceil(factor * top)), len(D) - 1)
    matched, rounds = descent_closure(D, matched_by_candidates(S, c), m)
    return {"candidates": c, "top": top, "factor": factor, "m": m, "rounds": rounds,
            **against_brute_force(D, S, matched, top, labels)}


def query_descent(D: np.ndarray, S: np.ndarray, c: int, top: int, factor: float) -> dict:
    """``nearest(query, store, k=top, candidates=c)`` read off the complete matrix ``D``, each shape
    in turn the query and the others the store: the store's pairs those of :func:`descent` run on
    the others alone (``gromov pairwise --candidates c -k top``), the query's first stage its ``c``
    nearest by ``S``, then rounds of :func:`gromov.retrieval._descent_candidates` over the others'
    ``m = ceil(factor * top)`` nearest until one adds none (``factor`` 0: the first stage alone).
    Per query: the pairs matched and whether its ``top`` nearest are brute force's, in order."""
    from gromov.retrieval import _descent_candidates, _nearest_lists

    n, m = len(D), min(int(np.ceil(factor * top)), len(D) - 2)
    exact, pairs = [], []
    for q in range(n):
        rest = np.delete(np.arange(n), q)
        Dr = D[np.ix_(rest, rest)]
        closed, _ = descent_closure(Dr, matched_by_candidates(S[np.ix_(rest, rest)], c), m)
        graph = _nearest_lists(np.where(closed & ~np.eye(n - 1, dtype=bool), Dr, np.nan), m)
        d = D[q, rest]
        values = {int(j): float(d[j]) for j in np.argsort(S[q, rest], kind="stable")[:c]}
        while factor:
            new = _descent_candidates(values, graph, m)
            if not len(new):
                break
            values.update({int(j): float(d[j]) for j in new})
        ours = [j for _, j in sorted((v, j) for j, v in values.items())[:top]]
        exact.append(ours == np.argsort(d, kind="stable")[:top].tolist())
        pairs.append(len(values))
    return {"candidates": c, "top": top, "factor": factor, "m": m, "top_equal_list": float(np.mean(exact)),
            "queries_differing": int(n - np.sum(exact)), "pairs_per_query": float(np.mean(pairs)),
            "pairs_per_query_max": int(np.max(pairs)), "collection": n - 1}


def descent_closure(D: np.ndarray, matched: np.ndarray, m: int) -> tuple[np.ndarray, int]:
    """``(matched, rounds)``: ``matched`` (changed in place) with rounds of
    :func:`gromov.experiments.pairwise._descent_pairs` added until one adds none."""
    from gromov.experiments.pairwise import _descent_pairs

    rounds = 0
    while True:
        new = _descent_pairs(np.where(matched, D, np.nan), matched, m)
        if not new:
            return matched, rounds
        rounds += 1
        for i, j in new:
            matched[i, j] = matched[j, i] = True


#: The single-query descents read off each complete matrix (``--descent``): (top, factor, C).
QUERY_DESCENTS = [(10, 0.0, 20), (10, 0.0, 50), (10, 1.0, 20), (10, 1.5, 10), (10, 1.5, 20), (10, 2.0, 20), (5, 1.5, 10)]

#: The neighbour descents read off each complete matrix (``--descent``): (top, factor, C).
DESCENTS = [(top, f, c) for top in (5, 10, 20) for f in (1.0, 1.5, 2.0) for c in (top, 2 * top)]


def per_class_nn(D: np.ndarray, labels) -> dict:
    r = retrieval_scores(0.5 * (D + D.T), labels)
    labels = np.asarray(labels)
    return {c: float(r["nn"][labels == c].mean()) for c in sorted(set(labels.tolist()))}


def load(cache: Path, data: str, name: str) -> tuple[dict, np.ndarray]:
    """The complete matrices of one collection (``combined`` first), and its labels."""
    files, labels = collection(data, name)
    z = np.load(cache / f"combined-{name}-pc0-s50-c0-seed0.npz")
    if [str(x) for x in z["files"]] != [f.name for f in files]:
        raise SystemExit(f"the cached {name} matrix is not of this collection's files, in this order")
    D, S, G, GH = (np.asarray(z[k], dtype=np.float64) for k in ("combined", "spectral", "trimmed", "gh"))
    if np.isnan(D).any():
        raise SystemExit(f"the cached {name} matrix is not complete: run the benchmark without --candidates")
    folder = cache / "descriptors" / name
    desc = [np.load(folder / f.name.replace(".off.gz", ".npz")) for f in files]
    out = {"combined": D, "spectral": S, "trimmed": G, "gh": GH,
           "dna_input": euclidean(np.stack([d["shapedna"] for d in desc])),
           "hks_input": euclidean(np.stack([d["hks"] for d in desc]))}
    if "signature" in z.files and z["signature"].ndim == 2:   # the combined ranking's third factor
        out["signature"] = np.asarray(z["signature"], dtype=np.float64)
    area = np.log([float(d["area"]) for d in desc])
    out["size"] = np.exp(0.5 * np.abs(area[:, None] - area[None, :]))   # sqrt(max(A_x/A_y, A_y/A_x))
    return out, labels


#: The pair-local rankings compared on all collections together: S^w G^(1-w) for each per-shape
#: distance S and GMDS statistic G of the same matches (w = 0: G alone).
SIGNATURES = ("spectral", "dna_input", "hks_input")
STATISTICS = ("trimmed", "gh")
WEIGHTS = (0.0, 0.15, 0.25, 0.35, 0.5, 0.65)


def pair_local(mats: dict, labs: dict) -> list[dict]:
    """Every S^w G^(1-w) scored on the collections together (pooled NN, FT, EER) and on each."""
    rows = []
    present = [sig for sig in (*SIGNATURES, "eccentricity") if all(sig in m for m in mats.values())]
    for sig in present:
        for stat in STATISTICS:
            for w in WEIGHTS:
                if w == 0.0 and sig != SIGNATURES[0]:
                    continue
                ranked = {c: m[sig] ** w * m[stat] ** (1.0 - w) for c, m in mats.items()}
                rows.append({"signature": sig if w else None, "statistic": stat, "w": w, **_scored(ranked, labs)})
    return sorted(rows, key=lambda r: r["pooled"]["J"])


def _scored(ranked: dict, labs: dict) -> dict:
    """Rankings of several collections scored together (``pooled``: NN, FT, EER and J) and on each."""
    from bench_recognition import pooled_scores

    pooled = pooled_scores(ranked, labs)
    return {"pooled": {**pooled, "J": objective(pooled)}, **{c: scores(ranked[c], labs[c]) for c in ranked}}


#: The signature-weighted rankings: S^a G^b GH^c H^d, a + b + c + d = 1, d > 0, on this grid.
SIGNATURE_GRID = np.round(np.arange(0.0, 1.0, 0.1), 1)


def signature_weights() -> tuple[tuple, list[tuple]]:
    """``(product, grid)``: the weights (a, b, c, d) of ``gromov.spectrum.combined`` and those of
    :data:`SIGNATURE_GRID` (a + b + c + d = 1, d > 0)."""
    from gromov.spectrum import SIGNATURE_WEIGHT, SPECTRUM_WEIGHT

    h = SIGNATURE_WEIGHT
    product = (round((1 - h) * SPECTRUM_WEIGHT, 6), round((1 - h) * (1 - SPECTRUM_WEIGHT), 6), 0.0, h)
    grid = [(float(a), float(b), float(c), float(round(1.0 - a - b - c, 6))) for a in SIGNATURE_GRID
            for b in SIGNATURE_GRID for c in SIGNATURE_GRID if a + b + c < 1.0 - 1e-9]
    return product, grid


#: The matrices the weights (a, b, c, d) of the signature-weighted rankings apply to, in order.
WEIGHTED = ("spectral", "trimmed", "gh", "signature")


def _weighted(m: dict, w) -> np.ndarray:
    """S^a G^b GH^c H^d of one collection's matrices ``m``."""
    out = np.ones_like(m[WEIGHTED[0]])
    for name, x in zip(WEIGHTED, w):
        out = out * m[name] ** x
    return out


def _named(w) -> dict:
    return dict(zip(WEIGHTED, w))


def signature_local(mats: dict, labs: dict) -> list[dict]:
    """Every S^a G^b GH^c H^d (S the working mesh's Shape-DNA distance, G the trimmed distortion,
    GH the GH estimate, H the heat kernel signature's distortion, all of the same matches) on
    :data:`SIGNATURE_GRID`, scored on the collections together (pooled NN, FT, EER, J) and on
    each; ``product``: the weights of ``gromov.spectrum.combined``."""
    product, grid = signature_weights()
    rows = [{"weights": _named(w), "product": w == product,
             **_scored({n: _weighted(m, w) for n, m in mats.items()}, labs)} for w in [product, *grid]]
    return sorted(rows, key=lambda r: r["pooled"]["J"])


def signature_split(mats: dict, labs: dict, collection: str, trials: int = 6, seed: int = 0) -> list[dict]:
    """The grid of :func:`signature_local` judged on classes it was not chosen on: in each of
    ``trials`` seeded splits of ``collection``'s classes into halves, the weights of lowest J on
    the other collections and one half, scored on the other half beside the product's weights."""
    product, grid = signature_weights()
    out = []
    for train, fit, fit_labs, held, held_labels in class_splits(mats, labs, collection, trials, seed):
        best = min(grid, key=lambda w: _scored({c: _weighted(m, w) for c, m in fit.items()}, fit_labs)["pooled"]["J"])
        out.append({"chosen_on": train, "weights": _named(best),
                    "held_out": scores(_weighted(held, best), held_labels),
                    "product": scores(_weighted(held, product), held_labels)})
    return out


def _among(m: dict, idx: np.ndarray) -> dict:
    """One collection's matrices restricted to the shapes ``idx`` (other entries as they are)."""
    return {k: (v[np.ix_(idx, idx)] if np.ndim(v) == 2 else v) for k, v in m.items()}


def class_splits(mats: dict, labs: dict, collection: str, trials: int = 6, seed: int = 0):
    """``trials`` seeded splits of ``collection``'s classes into halves: for each,
    ``(chosen_on, fit, fit_labs, held, held_labels)``: the classes of the first half, the
    matrices and labels a choice is made on (the other collections and that half), and the other
    half's matrices and labels, on which the choice is judged."""
    labels = np.asarray(labs[collection])
    classes = sorted(set(labels.tolist()))
    rng = np.random.default_rng(seed)
    for _ in range(trials):
        train = sorted(rng.permutation(classes)[: len(classes) // 2].tolist())
        a, b = np.flatnonzero(np.isin(labels, train)), np.flatnonzero(~np.isin(labels, train))
        fit = {c: m for c, m in mats.items() if c != collection}
        fit_labs = {c: labs[c] for c in fit}
        fit[collection], fit_labs[collection] = _among(mats[collection], a), labels[a]
        yield train, fit, fit_labs, _among(mats[collection], b), labels[b]


#: The exponents d of the size factor R^d (:func:`size_factor`).
SIZE_EXPONENTS = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)


def size_factor(mats: dict, labs: dict, collection: str, trials: int = 6, seed: int = 0) -> dict:
    """The product ranking times R^d, R = sqrt(max(A_x / A_y, A_y / A_x)) of the input meshes'
    areas (each shape's size, which unit area removes from the matches): ``whole``, every d of
    :data:`SIZE_EXPONENTS` scored on the collections together; ``split``, the d of lowest J on the
    other collections and half of ``collection``'s classes, scored on the other half beside d = 0
    (the splits of :func:`signature_split`)."""
    product, _ = signature_weights()

    def ranked(m, d):
        return _weighted(m, product) * m["size"] ** d

    whole = [{"d": d, **_scored({c: ranked(m, d) for c, m in mats.items()}, labs)} for d in SIZE_EXPONENTS]
    split = []
    for train, fit, fit_labs, held, held_labels in class_splits(mats, labs, collection, trials, seed):
        best = min(SIZE_EXPONENTS, key=lambda d: _scored({c: ranked(m, d) for c, m in fit.items()},
                                                          fit_labs)["pooled"]["J"])
        split.append({"chosen_on": train, "d": best, "held_out": scores(ranked(held, best), held_labels),
                      "product": scores(ranked(held, 0.0), held_labels)})
    return {"whole": whole, "split": split}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True, type=Path)
    ap.add_argument("--bench", required=True, type=Path, help="the brute-force run's results file")
    ap.add_argument("--data", default=None)
    ap.add_argument("--collection", default="watertight", help="the two-stage search's collection")
    ap.add_argument("--with", dest="others", default="", help="comma-separated: more collections in the cache, "
                    "scored with it for the pair-local rankings")
    ap.add_argument("--candidates", default="10,20,30,40,60,80")
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--first-stages", action="store_true", help="also other per-shape first stages (E: "
                    "the shapes are prepared again)")
    ap.add_argument("--jobs", type=int, default=2, help="processes preparing the shapes for E")
    ap.add_argument("--descent", action="store_true", help="also the neighbour descent after the first stage, "
                    "for each ranking of each collection (DESCENTS)")
    ap.add_argument("--measured", default=None, type=Path, help="the cached matrix of a two-stage run of the "
                    "collection (bench_recognition.py --candidates C [--k K] --cache DIR) and its results "
                    "file, comma-separated: its queries' ten nearest against brute force's")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "recognition_two_stage.json"))
    args = ap.parse_args(argv)
    import os

    data = args.data or os.environ.get("GROMOV_DATA") or str(ROOT.parent / "shared" / "data")
    names = [args.collection] + [c for c in args.others.split(",") if c]
    loaded = {c: load(args.cache, data, c) for c in names}
    mats, labs = {c: m for c, (m, _) in loaded.items()}, {c: lab for c, (_, lab) in loaded.items()}
    M, labels = mats[args.collection], labs[args.collection]
    D, S = M["combined"], M["spectral"]
    bench = json.loads(args.bench.read_text())
    row = next(v for k, v in bench["collections"][args.collection]["rows"].items() if k.startswith("gromov --units"))
    per_pair = row["seconds_match"] / row["pairs_matched"]   # wall seconds per pair with the run's jobs
    n = len(D)
    res = {"command": "python benchmarks/studies/recognition_two_stage.py " + " ".join(argv if argv is not None
                                                                                          else sys.argv[1:]),
           "collection": args.collection, "shapes": n, "top": args.top,
           "brute_force": {"pairs": n * (n - 1) // 2, "seconds": row["seconds"],
                           "seconds_prepare": row["seconds_prepare"], "seconds_match": row["seconds_match"],
                           "jobs": row["jobs"], "wall_seconds_per_pair": per_pair},
           "rankings": {c: {k: {**scores(X, labs[c]), "eer_local": eer_local(X, labs[c]),
                                "nn_per_class": per_class_nn(X, labs[c])}
                            for k, X in m.items()} for c, m in mats.items()},
           "two_stage": []}
    for c in (int(x) for x in args.candidates.split(",")):
        t = two_stage(D, S, c, args.top, labels)
        t["estimated_seconds"] = row["seconds_prepare"] + t["pairs"] * per_pair
        res["two_stage"].append(t)
    from gromov.spectrum import SPECTRUM_WEIGHT

    if "signature" not in M:   # (its estimate bounds S^w G^(1-w); the signature distortion has no floor)
        res["adaptive"] = [adaptive(D, S, M["trimmed"], SPECTRUM_WEIGHT, args.top, first, q, labels)
                           for first in (args.top, 2 * args.top) for q in (0.0, 0.01, 0.05)]
    if args.first_stages:
        res["first_stages"], res["eccentricity_seconds"] = {}, {}
        for c in names:   # times only for the collection of the brute-force run given
            E, sec = eccentricity_matrix(args.cache, data, c, args.jobs)
            res["eccentricity_seconds"][c] = sec
            mats[c]["eccentricity"] = E
            res["rankings"][c]["eccentricity"] = {**scores(E, labs[c]), "eer_local": eer_local(E, labs[c]),
                                                  "nn_per_class": per_class_nn(E, labs[c])}
            res["first_stages"][c] = first_stages(mats[c], labs[c], [int(x) for x in args.candidates.split(",")],
                                                  args.top, row if c == args.collection else None, sec)
    res["pair_local"] = pair_local(mats, labs)
    if all("signature" in m for m in mats.values()):
        res["signature_local"] = signature_local(mats, labs)
        res["signature_split"] = signature_split(mats, labs, args.collection)
        res["size_factor"] = size_factor(mats, labs, args.collection)
    if args.descent:
        res["descent"] = {}
        for c in names:
            res["descent"][c] = {}
            for rank in ("combined", "trimmed", "gh"):
                rows = [descent(mats[c][rank], mats[c]["spectral"], cc, top, f, labs[c]) for top, f, cc in DESCENTS]
                if c == args.collection:
                    for t in rows:
                        t["estimated_seconds"] = row["seconds_prepare"] + t["pairs"] * per_pair
                res["descent"][c][rank] = rows
        res["query_descent"] = {c: [query_descent(mats[c]["combined"], mats[c]["spectral"], cc, top, f)
                                    for top, f, cc in QUERY_DESCENTS] for c in names}
    if args.measured is not None:
        npz, results = str(args.measured).split(",")
        z = np.load(npz)
        if [str(x) for x in z["files"]] != [str(x) for x in np.load(args.cache / f"combined-{args.collection}-pc0-s50-c0-seed0.npz")["files"]]:
            raise SystemExit("the measured run is not of the same files in the same order")
        two = np.asarray(z["combined"], dtype=np.float64)
        matched = np.isfinite(np.asarray(z["trimmed"], dtype=np.float64))
        run = json.loads(Path(results).read_text())
        mrow = next(v for k, v in run["collections"][args.collection]["rows"].items() if k.startswith("gromov --units"))
        same = bool(np.array_equal(two[matched], D[matched]))
        res["measured"] = {"file": Path(results).name, "seconds": mrow["seconds"], "pairs_matched": mrow["pairs_matched"],
                           "values_equal_brute_force": same,
                           **against_brute_force(D, S, matched, args.top, labels)}
    Path(args.json).write_text(json.dumps(res, indent=1) + "\n")
    for c, m in res["rankings"].items():
        for k, s in m.items():
            print(f"{c:<11} {k:<11} NN {s['nn']:.3f} FT {s['ft']:.3f} ST {s['st']:.3f} EER {s['eer']:.3f} "
                  f"(local scaling {s['eer_local']:.3f})")
    for t in res["two_stage"]:
        print(f"C = {t['candidates']:>3}: {t['pairs']:>5} pairs ({t['fraction_of_pairs']:.2f}), top-{args.top} "
              f"equal {t['top_equal_list']:.3f} (as sets {t['top_equal_set']:.3f}, overlap {t['top_overlap']:.3f}), "
              f"NN {t['nn']:.3f}, est. {t['estimated_seconds'] / 60:.1f} min")
    for t in res.get("adaptive", []):
        print(f"adaptive, first {t['first']}, floor q {t['quantile']}: {t['pairs']} pairs, top-{args.top} equal "
              f"{t['top_equal_list']:.3f}, NN {t['nn']:.3f}")
    for c, rows in res.get("query_descent", {}).items():
        for t in rows:
            print(f"{c} one query (combined) top {t['top']} m {t['m']} C {t['candidates']}: top equal "
                  f"{t['top_equal_list']:.3f} ({t['queries_differing']} differ), {t['pairs_per_query']:.1f} pairs a "
                  f"query (at most {t['pairs_per_query_max']}) of {t['collection']}")
    for c, ranks in res.get("descent", {}).items():
        for rank, rows in ranks.items():
            for t in rows:
                print(f"{c} descent ({rank}) top {t['top']} m {t['m']} C {t['candidates']}: {t['rounds']} rounds, "
                      f"{t['pairs']} pairs, top equal {t['top_equal_list']:.3f} ({t['queries_differing']} differ)"
                      + (f", est. {t['estimated_seconds'] / 60:.1f} min" if "estimated_seconds" in t else ""))
    if "measured" in res:
        t = res["measured"]
        print(f"measured {t['file']}: {t['pairs_matched']} pairs in {t['seconds'] / 60:.1f} min, top-{args.top} equal "
              f"{t['top_equal_list']:.3f} ({t['queries_differing']} differ), values as brute force's: "
              f"{t['values_equal_brute_force']}")
    for c, stages in res.get("first_stages", {}).items():
        for name, rows in stages.items():
            print(f"{c} first stage {name}: " + "  ".join(
                f"C {t['candidates']} {t['top_equal_list']:.3f}"
                + (f" ({t['estimated_seconds'] / 60:.1f} min)" if "estimated_seconds" in t else "") for t in rows))
    for r in [x for x in res.get("signature_local", []) if x["product"]] + res.get("signature_local", [])[:12]:
        w = r["weights"]
        per = "  ".join(f"{c} NN {r[c]['nn']:.3f} FT {r[c]['ft']:.3f} EER {r[c]['eer']:.3f}" for c in mats)
        print(f"J {r['pooled']['J']:.4f}  S^{w['spectral']:.3g} G^{w['trimmed']:.3g} GH^{w['gh']:.3g} "
              f"H^{w['signature']:.3g}{' (product)' if r['product'] else ''}  {per}")
    for r in res.get("signature_split", []):
        h, p = r["held_out"], r["product"]
        print(f"chosen on {','.join(r['chosen_on'])} (+ the others): {r['weights']}; held-out half NN {h['nn']:.3f} "
              f"FT {h['ft']:.3f} EER {h['eer']:.3f}, product NN {p['nn']:.3f} FT {p['ft']:.3f} EER {p['eer']:.3f}")
    for r in res.get("size_factor", {}).get("whole", []):
        per = "  ".join(f"{c} NN {r[c]['nn']:.3f} FT {r[c]['ft']:.3f} EER {r[c]['eer']:.3f}" for c in mats)
        print(f"J {r['pooled']['J']:.4f}  product x R^{r['d']:g}  {per}")
    for r in res.get("size_factor", {}).get("split", []):
        h, p = r["held_out"], r["product"]
        print(f"chosen on {','.join(r['chosen_on'])} (+ the others): d {r['d']:g}; held-out half NN {h['nn']:.3f} "
              f"FT {h['ft']:.3f} EER {h['eer']:.3f}, d 0 NN {p['nn']:.3f} FT {p['ft']:.3f} EER {p['eer']:.3f}")
    for r in res["pair_local"][:12]:
        per = "  ".join(f"{c} NN {r[c]['nn']:.3f} FT {r[c]['ft']:.3f} EER {r[c]['eer']:.3f}" for c in mats)
        print(f"J {r['pooled']['J']:.4f}  {r['signature'] or '-':<10} {r['statistic']:<8} w {r['w']:.2f}  {per}")


if __name__ == "__main__":
    main()
