"""Which recognition defaults? Candidates measured on TOSCA and the watertight collection together.

Run:  nice -n 10 .venv/bin/python benchmarks/studies/recognition_defaults.py [--data DIR] [--per-class 6]
          [--seed 0] [--jobs 2] [--configs default,area,normalized,samples50] [--partial area:tosca]
          [--cache DIR] [--json benchmarks/studies/recognition_defaults.json]

The results file was made with ``--configs default,area-samples50 --partial area:tosca --cache DIR``
after ``benchmarks/bench_recognition.py --cache DIR`` (which fills the input-mesh descriptors).

The shapes: TOSCA (80 meshes, 9 classes) and the watertight collection (10 classes x 20 SHREC'07
meshes), labels from the file names (``benchmarks/bench_recognition.py``'s :func:`collection`).
The per-pair (GMDS) candidates run on a fixed subset, the same for every candidate: at most
``--per-class`` shapes of each class (default 6: 49 TOSCA shapes -- wolf has 3, gorilla 4 -- and
60 watertight shapes), drawn by ``class_subset(labels, 6, seed=0)``. The per-shape candidates run
on every shape and are scored both on all shapes and on that subset. Nothing is tuned per class.

**Candidates.**

1. *Per-pair, GMDS* (:func:`gromov.experiments.gh_matrix`, the matrix ``gromov pairwise`` makes),
   one matrix run per *configuration* (``--configs``): ``default`` (``gromov pairwise``'s: raw heat
   diffusion distance, tau = 0.005 of the area, 100 samples, 3,000 working vertices); ``area``
   (each mesh scaled to unit area before anything else: the raw heat distance, whose unit is
   1/length, becomes dimensionless); ``normalized`` (``metric_options units="normalized"``: the
   distance between normalised heat distributions, scale-free); ``samples50`` (50 samples);
   ``area-samples50``; ``resolution2000`` (2,000 working vertices). Each pair's correspondence is
   summarised several ways (the rankings of one run, with no second match): ``trimmed`` (the
   default ranking: trimmed log ratios at rank_tau_scale 0.5), ``gh`` (``--rank-by gh``), and
   for rank_tau_scale s in 0.25 / 0.5 / 1 the trimmed log ratios (``log@s``) and differences over
   the larger diameter (``diff@s``) of the same correspondence, and the same after normalising
   each shape's distances by a scale of its own -- ``*_area@s``: times sqrt(area) (what the
   ``area`` configuration does to the distances, here without re-matching), ``*_mdiam@s``: over
   the shape's diameter in that metric, ``log_ediam@s``: times its Euclidean diameter -- and
   ``gh_area``, ``gh_mdiam``, the GH estimate after the same scalings. These extra summaries are
   read in the worker that matched the pair, by wrapping gromov's ``_ranking`` (found through
   ``gromov.experiments.pairwise._match``'s globals) for the duration of the run: the matched
   value and the correspondence are unchanged.
2. *Per-shape* (cheap: one eigendecomposition per shape, no pair matched): Shape-DNA and the
   pooled HKS of the input mesh (``bench_recognition.py``), and from gromov's own prepared
   shape (:class:`gromov.ShapeMetric`, its working mesh and heat-kernel eigenpairs,
   ``solver.at_tau``): ``dna_working`` (Shape-DNA of its eigenvalues), ``hks_working``
   (area-weighted quantiles of log(A k_2t(x, x)) at each time), and at diffusion times tau in
   ``DD_TAUS`` (relative to the area) the distribution of heat diffusion distances between 200
   area-weighted random points (``dd``; the distance distribution of Mémoli, "Gromov-Wasserstein
   distances and the metric approach to object matching", Found. Comput. Math. 11, 2011, §6, a
   lower bound of the Gromov-Wasserstein distance) and that of their eccentricities (mean distance
   to the others; ``ecc``, Mémoli's first lower bound), each compared by the 1-D Wasserstein
   distance (mean absolute difference of 256 or 64 quantiles), the distances made dimensionless
   by ``area`` (times sqrt(t) = sqrt(tau A): every time then saturates at about 1 / sqrt(4 pi))
   or by ``diam`` (over the diameter at that time); ``@all`` sums the times. And the profile gap
   of :func:`gromov.retrieval.profile_gap` (gromov's own per-shape estimate, used by
   ``gh_matrix(k=...)``), on the subset.
3. *Combinations* of each of the three best per-shape candidates with each of the three best GMDS
   candidates: ``ranksum`` (per query, the sum of the two ranks, symmetrised), ``zsum`` (the sum
   of the z-scores of the logarithms over the collection's pairs: a set-level normalisation) and
   ``geo w`` (the weighted geometric mean S^w G^(1-w), w = 0.25, 0.5, 0.75: needs nothing of the
   set).

**Scores and the choice.** Every candidate is scored per collection (NN, first tier, second tier,
EER) and on both together (NN, FT and ST over all queries, each searching its own collection;
the EER with one threshold over every within-collection pair), with
``bench_recognition.py``'s :func:`scores` and :func:`pooled_scores`. The procedure: the best
candidate is the one with the lowest J = mean(1 - NN, 1 - FT, EER) on both together; ties go to
the cheaper. The best per-shape candidate, the best single GMDS matrix and the best combination
are reported as well.

**Two-stage search.** For the best per-shape candidate S (and every other per-shape candidate,
in the JSON): recall of brute force's top 10 by the final ranking F (the best overall, and the
best single GMDS matrix) within S's top K, K = 10, 20, 30, 50 (of the subset's 48 / 59 others, so
K = 50 is nearly all; the same fractions of a 200-shape collection, K' = K (n - 1) / 199, are
given too; and of the top 5, a subset class's other members), NN and FT of the two-stage search
itself (each query's K candidates re-ranked by F, the others after them), and the pairs a
two-stage top-10 search of the whole 200-shape collection would match, with its time at the
measured seconds per pair.

``--cache DIR`` (default ``/tmp/recognition-defaults``) keeps each shape's signatures and each
configuration's matrices, so that a stopped run continues; ``bench_recognition.py --cache DIR``
fills the input-mesh descriptors (computed here where missing).

Resources, measured on 2 cores shared with other jobs (load average 2-9): the signatures of all 280
shapes 12 minutes; ``default`` on the 6-per-class subset (2,946 pairs) 28 minutes, ``area-samples50``
21, ``area`` on TOSCA's 49 shapes alone 14; the scoring from the cache a few seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(BENCH))

from _common import write_results
from bench_recognition import (
    COLLECTIONS,
    GROMOV_METRIC,
    class_subset,
    collection,
    descriptors_of,
    euclidean,
    gromov_source,
    pooled_scores,
    retrieval_scores,
    scores,
    shape_dna,
)

HERE = Path(__file__).resolve().parent
#: Diffusion times (relative to the area) of the distance and eccentricity distributions.
DD_TAUS = (0.0025, 0.005, 0.01, 0.02, 0.04, 0.08)
#: Area-weighted random points per shape for the distributions.
DD_POINTS = 200
DD_QUANTILES = 256
ECC_QUANTILES = 64
HKS_QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
RANK_SCALES = (0.25, 0.5, 1.0)
CONFIGS = {
    "default": {"scale": None, "units": None, "n_samples": 100, "resolution": 3000},
    "area": {"scale": "area", "units": None, "n_samples": 100, "resolution": 3000},
    "normalized": {"scale": None, "units": "normalized", "n_samples": 100, "resolution": 3000},
    "samples50": {"scale": None, "units": None, "n_samples": 50, "resolution": 3000},
    "area-samples50": {"scale": "area", "units": None, "n_samples": 50, "resolution": 3000},
    "resolution2000": {"scale": None, "units": None, "n_samples": 100, "resolution": 2000},
}
KS = (10, 20, 30, 50)
TOP = 10
COLLECTION_SIZE = 200   # the target collection: each shape's 10 nearest among 199 others


# ----------------------------------------------------------------------------- per-shape signatures
def _quiet_load(path):
    import gromov
    from gromov.errors import GromovWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        return gromov.load(path)


def _inner(solver):
    return getattr(solver, "inner", solver)


def _diameter(psi: np.ndarray) -> float:
    sq = (psi**2).sum(1)
    top = 0.0
    for i in range(0, len(psi), 1024):
        top = max(top, float((sq[i:i + 1024, None] + sq[None, :] - 2.0 * psi[i:i + 1024] @ psi.T).max()))
    return float(np.sqrt(max(top, 0.0)))


def _weighted_quantiles(values, weights, qs):
    order = np.argsort(values)
    cw = np.cumsum(weights[order]) / weights.sum()
    return np.interp(qs, cw, values[order])


def signatures_of(path: str, seed: int = 0, resolution: int = 3000) -> dict:
    """The per-shape candidates of one mesh from gromov's prepared shape (working mesh and heat
    eigenpairs; no dense distance matrix), with the single-process seconds."""
    from scipy.spatial.distance import pdist
    from threadpoolctl import threadpool_limits

    from gromov import ShapeMetric

    threadpool_limits(limits=1)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        from gromov.errors import GromovWarning

        warnings.simplefilter("ignore", GromovWarning)
        s = ShapeMetric(_quiet_load(path), "diffusion", resolution=resolution, metric_options=dict(GROMOV_METRIC))
        s.solver.embedding   # noqa: B018 - the eigendecomposition
    inner = _inner(s.solver)
    area = float(inner.area)
    t_eig = time.perf_counter() - t0
    out = {"dna_working": shape_dna(np.asarray(inner.eigenvalues), area), "n_eigenpairs": len(inner.eigenvalues)}
    w = np.asarray(s.mesh.vertex_areas, dtype=np.float64)
    rng = np.random.default_rng(seed)
    pts = np.sort(rng.choice(len(w), size=min(DD_POINTS, len(w)), replace=False, p=w / w.sum()))
    qd = (np.arange(DD_QUANTILES) + 0.5) / DD_QUANTILES
    qe = (np.arange(ECC_QUANTILES) + 0.5) / ECC_QUANTILES
    hks = []
    for tau in DD_TAUS:
        psi = np.asarray(s.solver.at_tau(tau).embedding)
        t = tau * area
        diam = _diameter(psi)
        d = pdist(psi[pts])
        sq = np.zeros((len(pts), len(pts)))
        iu = np.triu_indices(len(pts), 1)
        sq[iu] = d
        sq += sq.T
        ecc = sq.sum(1) / (len(pts) - 1)
        for norm, f in (("area", np.sqrt(t)), ("diam", 1.0 / diam)):
            out[f"dd_{norm}@{tau:g}"] = np.quantile(d * f, qd)
            out[f"ecc_{norm}@{tau:g}"] = np.quantile(ecc * f, qe)
        hks.append(_weighted_quantiles(np.log(area * (psi**2).sum(1)), w, HKS_QUANTILES))
    out["hks_working"] = np.concatenate(hks)
    out["seconds"] = time.perf_counter() - t0
    out["seconds_eigen"] = t_eig
    return out


def _cached(compute, files, folder: Path, jobs: int, seed: int) -> list[dict]:
    """``compute(path, seed)`` of each file in ``jobs`` processes, each kept as
    ``folder/NAME.npz`` and read from there where computed before."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f.name.replace(".off.gz", ".npz") for f in files]
    todo = [i for i, p in enumerate(paths) if not p.exists()]
    if todo:
        import multiprocessing as mp

        with ProcessPoolExecutor(max(1, jobs), mp_context=mp.get_context("fork")) as pool:
            for i, out in zip(todo, pool.map(compute, [str(files[i]) for i in todo], [seed] * len(todo))):
                np.savez(paths[i], **out)
    return [dict(np.load(p)) for p in paths]


def all_signatures(files, folder: Path, jobs: int, seed: int) -> list[dict]:
    """:func:`signatures_of` of each file, read from ``folder`` where computed before."""
    return _cached(signatures_of, files, folder, jobs, seed)


def input_descriptors(files, folder: Path, jobs: int, seed: int) -> list[dict]:
    """``bench_recognition.py``'s descriptors of each file, from its cache where there."""
    return _cached(descriptors_of, files, folder, jobs, seed)


def w1(X: np.ndarray) -> np.ndarray:
    """1-D Wasserstein distances between the rows of ``X`` (each a distribution's quantiles at
    evenly spaced levels): the mean absolute difference."""
    from scipy.spatial.distance import pdist, squareform

    return squareform(pdist(np.asarray(X, dtype=np.float64), "cityblock")) / X.shape[1]


def cheap_matrices(sigs: list[dict], desc: list[dict]) -> tuple[dict, dict]:
    """``({name: (n, n) matrix}, {name: single-process seconds per shape})`` of the per-shape candidates."""
    mats, cost = {}, {}
    sec = float(np.mean([s["seconds"] for s in sigs]))
    for key in ("shapedna", "hks"):
        mats[key] = euclidean(np.array([d[key] for d in desc]))
        cost[key] = float(np.mean([d[f"seconds_{key}"] for d in desc]))
    for key in ("dna_working", "hks_working"):
        mats[key] = euclidean(np.array([s[key] for s in sigs]))
        cost[key] = sec
    for kind in ("dd", "ecc"):
        for norm in ("area", "diam"):
            total = 0.0
            for tau in DD_TAUS:
                name = f"{kind}_{norm}@{tau:g}"
                mats[name] = w1(np.array([s[name] for s in sigs]))
                cost[name] = sec
                total = total + mats[name]
            mats[f"{kind}_{norm}@all"] = total
            cost[f"{kind}_{norm}@all"] = sec
    return mats, cost


# ----------------------------------------------------------------------------- GMDS configurations
_INDEX: dict = {}      # id(prepared shape) -> its index, set before the workers fork
_SCALES: dict = {}     # id(prepared shape) -> {"area": ..., "ediam": ...}
_EXTRA_DIR: str | None = None
_WRAPPED = False


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2)))


def _extras(sx, sy, P, Q, fit, dx, dy, diam, discrete) -> dict:
    """The other summaries of one correspondence (module notes), in its worker."""
    import gromov.experiments.pairwise as pw

    g = pw._match.__globals__
    ranking_value, gmds_cls = g["ranking_value"], g["SymmetricGMDS"]
    ax, ay = np.sqrt(_SCALES[id(sx)]["area"]), np.sqrt(_SCALES[id(sy)]["area"])
    ex_, ey_ = _SCALES[id(sx)]["ediam"], _SCALES[id(sy)]["ediam"]
    out = {}
    off = ~np.eye(len(dx), dtype=bool)
    dxs, dys = sx.diameter, sy.diameter
    out["gh_area"] = 0.5 * _rms((dx * ax - dy * ay)[off]) / max(dxs * ax, dys * ay)
    out["gh_mdiam"] = 0.5 * _rms((dx / dxs - dy / dys)[off])
    for scale in RANK_SCALES:
        mx, my = sx.ranking_surface(scale), sy.ranking_surface(scale)
        if mx is None or my is None or discrete:
            continue
        ex, ey = gmds_cls(mx[0], my[0], P, Q).blocks(fit.img_p, fit.img_q)
        Dx, Dy = mx[1], my[1]
        s = f"@{scale:g}"
        out["log" + s] = ranking_value(ex, ey, max(Dx, Dy), "log")
        out["diff" + s] = ranking_value(ex, ey, max(Dx, Dy), "difference")
        out["log_area" + s] = ranking_value(ex * ax, ey * ay, max(Dx * ax, Dy * ay), "log")
        out["diff_area" + s] = ranking_value(ex * ax, ey * ay, max(Dx * ax, Dy * ay), "difference")
        out["log_mdiam" + s] = ranking_value(ex / Dx, ey / Dy, 1.0, "log")
        out["diff_mdiam" + s] = ranking_value(ex / Dx, ey / Dy, 1.0, "difference")
        out["log_ediam" + s] = ranking_value(ex * ex_, ey * ey_, max(Dx * ex_, Dy * ey_), "log")
    return out


def _wrap_ranking() -> None:
    """Wrap the ``_ranking`` that :func:`gromov.experiments.pairwise._match` calls so that each
    pair's other summaries are written, as JSON lines, to ``_EXTRA_DIR/PID.jsonl``."""
    global _WRAPPED
    if _WRAPPED:
        return
    import gromov.experiments.pairwise as pw

    g = pw._match.__globals__
    if "_ranking" not in g:
        raise SystemExit("gromov's _match calls no _ranking any more: update the study's wrapper")
    original = g["_ranking"]

    def ranking(sx, sy, P, Q, fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual):
        value = original(sx, sy, P, Q, fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual)
        if _EXTRA_DIR is not None and id(sx) in _INDEX and id(sy) in _INDEX:
            row = {"i": _INDEX[id(sx)], "j": _INDEX[id(sy)], "ranked": float(value),
                   **{k: float(v) for k, v in _extras(sx, sy, P, Q, fit, dx, dy, diam, discrete).items()}}
            with open(os.path.join(_EXTRA_DIR, f"{os.getpid()}.jsonl"), "a") as fh:
                fh.write(json.dumps(row) + "\n")
        return value

    g["_ranking"] = ranking
    _WRAPPED = True


def _euclidean_diameter(v: np.ndarray) -> float:
    from scipy.spatial import ConvexHull
    from scipy.spatial.distance import pdist

    hull = v[ConvexHull(v).vertices]
    return float(pdist(hull).max())


def config_meshes(files, config: dict) -> list:
    """The meshes a configuration matches: as loaded, or scaled to unit area."""
    from gromov import Mesh

    out = []
    for f in files:
        m = _quiet_load(str(f))
        if config["scale"] == "area":
            m = Mesh(np.asarray(m.vertices) / np.sqrt(m.area), m.faces)
        out.append(m)
    return out


def run_config(name: str, files, config: dict, seed: int, jobs: int, cache: Path, tag: str) -> dict:
    """The matrices of one configuration on ``files`` (read from the cache where there)."""
    global _EXTRA_DIR, _INDEX, _SCALES
    path = cache / f"gmds-{tag}-{name}.npz"
    if path.exists():
        z = np.load(path, allow_pickle=False)
        return {k: z[k] for k in z.files}
    from gromov.errors import GromovWarning
    from gromov.experiments.pairwise import gh_matrix, prepare
    from gromov.retrieval import profile_gap, shape_bound

    metric_options = dict(GROMOV_METRIC)
    if config["units"]:
        metric_options["units"] = config["units"]
    n_samples, resolution = config["n_samples"], config["resolution"]
    extra_dir = cache / f"extras-{tag}-{name}"
    extra_dir.mkdir(parents=True, exist_ok=True)
    for f in extra_dir.glob("*.jsonl"):
        f.unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        t0 = time.perf_counter()
        meshes = config_meshes(files, config)
        prepared = prepare(meshes, "diffusion", n_samples=n_samples, seed=seed, resolution=resolution,
                           metric_options=metric_options, rank_tau_scale=0.5, jobs=jobs)
        t_prepare = time.perf_counter() - t0
        for s in prepared:   # the other ranking scales, once here rather than in every worker
            for scale in RANK_SCALES:
                s.ranking_surface(scale)
        _INDEX = {id(s): k for k, s in enumerate(prepared)}
        _SCALES = {id(s): {"area": float(_inner(s.solver).area),
                           "ediam": _euclidean_diameter(np.asarray(s.mesh.vertices))} for s in prepared}
        t = time.perf_counter()
        bounds = [shape_bound(s, n_samples, seed, 0.5) for s in prepared]
        n = len(prepared)
        gap = np.zeros((n, n))
        for i in range(n):
            for j in range(i + 1, n):
                gap[i, j] = gap[j, i] = profile_gap(bounds[i], bounds[j])
        t_gap = time.perf_counter() - t
        _wrap_ranking()
        _EXTRA_DIR = str(extra_dir)
        try:
            g = gh_matrix(prepared, "diffusion", n_samples=n_samples, resolution=resolution,
                          metric_options=metric_options, seed=seed, jobs=jobs)
        finally:
            _EXTRA_DIR = None
    out = {"trimmed": g.trimmed, "gh": g.relative, "profile_gap": gap,
           "seconds_prepare": np.float64(t_prepare + g.seconds_prepare), "seconds_match": np.float64(g.seconds_match),
           "seconds_profile_gap": np.float64(t_gap), "jobs": np.int64(jobs), "files": np.array([f.name for f in files])}
    rows = [json.loads(line) for f in sorted(extra_dir.glob("*.jsonl")) for line in f.read_text().splitlines()]
    keys = sorted({k for r in rows for k in r} - {"i", "j", "ranked"})
    for k in keys:
        out[k] = np.zeros((n, n))
    seen = np.zeros((n, n), dtype=bool)
    for r in rows:
        i, j = r["i"], r["j"]
        seen[i, j] = seen[j, i] = True
        for k in keys:
            out[k][i, j] = out[k][j, i] = r[k]
    if not seen[~np.eye(n, dtype=bool)].all():
        raise RuntimeError(f"{name}: extra summaries missing for {int((~seen).sum() - n) // 2} pairs")
    np.savez(path, **out)
    del prepared
    return out


# ----------------------------------------------------------------------------- combinations
def _ranks(D: np.ndarray) -> np.ndarray:
    n = len(D)
    R = np.zeros_like(D)
    for i in range(n):
        d = D[i].copy()
        d[i] = -np.inf
        R[i, np.argsort(d, kind="stable")] = np.arange(n)
    return 0.5 * (R + R.T)


def _zlog(D: np.ndarray) -> np.ndarray:
    off = ~np.eye(len(D), dtype=bool)
    L = np.log(np.maximum(D, 1e-12))
    z = (L - L[off].mean()) / L[off].std()
    z[~off] = 0.0
    return z


def combine(S: np.ndarray, G: np.ndarray, rule: str) -> np.ndarray:
    """A per-shape matrix ``S`` and a GMDS matrix ``G`` combined by ``rule``."""
    if rule == "ranksum":
        out = _ranks(S) + _ranks(G)
    elif rule == "zsum":
        out = _zlog(S) + _zlog(G)
    elif rule.startswith("geo"):
        w = float(rule.split()[1])
        out = np.exp(w * np.log(np.maximum(S, 1e-12)) + (1 - w) * np.log(np.maximum(G, 1e-12)))
    else:
        raise ValueError(rule)
    out = 0.5 * (out + out.T)
    np.fill_diagonal(out, out.min() - 1.0 if rule == "zsum" else 0.0)
    return out


RULES = ("ranksum", "zsum", "geo 0.25", "geo 0.5", "geo 0.75")
#: The library's rule: a value per pair, needing nothing of the rest of the collection (stored
#: pairs are reused, one threshold serves every pair), with a signature gromov computes from
#: its working mesh: S^w G^(1 - w) for these w (w = 0: the GMDS value alone).
GEO_WEIGHTS = (0.0, 0.15, 0.25, 0.35, 0.5)
PAIR_LOCAL_SIGNATURES = ("dna_working", "hks_working")
#: J differences up to this count as ties (one nearest neighbour of 109 changes J by 0.003).
J_TIE = 0.005


def _pair_local(cands: dict, labs: dict, gmds_names: list) -> dict:
    """The pair-local candidates S^w G^(1 - w) (:data:`GEO_WEIGHTS`) of each working-mesh
    signature and each of the best GMDS matrices, scored; ``chosen``: the lowest J; ``ties``:
    those within :data:`J_TIE` of it (not told apart by these sets)."""
    rows = {}
    for s in PAIR_LOCAL_SIGNATURES:
        for g in gmds_names:
            for w in GEO_WEIGHTS:
                mats = {c: combine(cands[s][c], cands[g][c], f"geo {w}") for c in COLLECTIONS}
                rows[f"geo {w:g}({s}, {g})"] = {**score_candidate(mats, labs), "signature": s, "gmds": g, "weight": w}
    best = min(r["J"] for r in rows.values())
    ties = [k for k, r in rows.items() if r["J"] <= best + J_TIE]
    chosen = min(rows, key=lambda k: rows[k]["J"])
    r = rows[chosen]
    cands[chosen] = {c: combine(cands[r["signature"]][c], cands[r["gmds"]][c], f"geo {r['weight']}") for c in COLLECTIONS}
    return {"procedure": f"lowest J among S^w G^(1-w), w in {list(GEO_WEIGHTS)}, S in {list(PAIR_LOCAL_SIGNATURES)}, "
                         f"G the best 3 GMDS matrices; ties: within {J_TIE} of the lowest J",
            "candidates": dict(sorted(rows.items(), key=lambda kv: kv[1]["J"])), "ties": ties,
            "chosen": {"name": chosen, **rows[chosen]}}


# ----------------------------------------------------------------------------- scoring
def objective(s: dict) -> float:
    """J = mean(1 - NN, 1 - FT, EER): the selection criterion, lower is better."""
    return float(np.mean([1.0 - s["nn"], 1.0 - s["ft"], s["eer"]]))


def score_candidate(mats: dict, labs: dict) -> dict:
    out = {c: scores(D, labs[c]) for c, D in mats.items()}
    out["together"] = pooled_scores(mats, labs)
    out["J"] = objective(out["together"])
    return out


def top_sets(D: np.ndarray, k: int) -> list[np.ndarray]:
    n = len(D)
    out = []
    for i in range(n):
        others = np.r_[0:i, i + 1:n]
        out.append(others[np.argsort(D[i, others], kind="stable")[:k]])
    return out


def recall_at(S: np.ndarray, F: np.ndarray, K: int, top: int = TOP) -> float:
    """Mean over queries of the fraction of F's ``top`` nearest among S's ``K`` nearest."""
    truth, cand = top_sets(F, min(top, len(F) - 1)), top_sets(S, min(K, len(S) - 1))
    return float(np.mean([len(set(t.tolist()) & set(c.tolist())) / len(t) for t, c in zip(truth, cand)]))


def two_stage_pairs(S: np.ndarray, K: int) -> int:
    """Unordered pairs matched when each shape's ``K`` nearest by ``S`` are matched."""
    pairs = set()
    for i, c in enumerate(top_sets(S, min(K, len(S) - 1))):
        pairs.update((min(i, j), max(i, j)) for j in c.tolist())
    return len(pairs)


def two_stage_nn(S: np.ndarray, F: np.ndarray, K: int, labels) -> dict:
    """NN and FT of a two-stage search: each query's K candidates by S re-ranked by F, the others
    after them in S's order."""
    n = len(S)
    big = float(np.nanmax(F)) + 1.0 + np.asarray(S) / (float(np.max(S)) + 1e-300)
    D = big.copy()
    for i, c in enumerate(top_sets(S, min(K, n - 1))):
        D[i, c] = F[i, c]
    np.fill_diagonal(D, 0.0)
    r = retrieval_scores(D, labels)
    return {"nn": float(np.mean(r["nn"])), "ft": float(np.nanmean(r["ft"]))}


# ----------------------------------------------------------------------------- main
def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(BENCH.parent.parent / "shared" / "data")))
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--configs", default="default,area,normalized,samples50",
                    help=f"comma-separated GMDS configurations: {', '.join(CONFIGS)}")
    ap.add_argument("--partial", default="", metavar="CONFIG:COLLECTION,...",
                    help="also run these configurations on one collection only (e.g. area:tosca), scored per "
                         "collection as a diagnostic, not as candidates")
    ap.add_argument("--cache", default="/tmp/recognition-defaults", metavar="DIR")
    ap.add_argument("--json", default=str(HERE / "recognition_defaults.json"))
    ap.add_argument("--notes", default=None, help="a note kept in the JSON (run_notes): e.g. where the cache came from")
    args = ap.parse_args(argv)
    configs = [c.strip() for c in args.configs.split(",") if c.strip()]
    if set(configs) - set(CONFIGS):
        ap.error(f"--configs takes {', '.join(CONFIGS)}, got {args.configs!r}")
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    res: dict = {"command": "python benchmarks/studies/recognition_defaults.py " + shlex.join(
                     argv if argv is not None else sys.argv[1:]),
                 "per_class": args.per_class, "seed": args.seed, "jobs": args.jobs,
                 "configs": {c: CONFIGS[c] for c in configs}, "dd_taus": list(DD_TAUS), "dd_points": DD_POINTS,
                 "procedure": "lowest J = mean(1 - NN, 1 - FT, EER) on both collections together "
                              "(NN, FT over all queries, each in its own collection; EER with one threshold "
                              "over all within-collection pairs); ties to the cheaper",
                 "gromov_source": gromov_source(), "load_average_start": os.getloadavg(), "run_notes": args.notes,
                 "collections": {}}
    labs_all, labs_sub, cheap_all, cheap_sub, cost, subs, gmds = {}, {}, {}, {}, {}, {}, {}
    for name in COLLECTIONS:
        files, labels = collection(args.data, name)
        sub = class_subset(labels, args.per_class, args.seed)
        subs[name] = sub
        labs_all[name], labs_sub[name] = labels, labels[sub]
        t = time.perf_counter()
        sigs = all_signatures(files, cache / "signatures" / name, args.jobs, args.seed)
        desc = input_descriptors(files, cache / "descriptors" / name, args.jobs, args.seed)
        mats, cost_c = cheap_matrices(sigs, desc)
        cost[name] = cost_c
        cheap_all[name] = mats
        cheap_sub[name] = {k: D[np.ix_(sub, sub)] for k, D in mats.items()}
        res["collections"][name] = {"shapes": len(files), "subset": [files[i].name for i in sub],
                                    "signature_seconds": time.perf_counter() - t}
        print(f"{name}: {len(files)} shapes, subset {len(sub)}; signatures {time.perf_counter() - t:.0f} s", flush=True)
        gmds[name] = {}
    for c in configs:   # configurations outside, so that a run stopped keeps whole configurations
        for name in COLLECTIONS:
            files, labels = collection(args.data, name)
            sub = subs[name]
            t = time.perf_counter()
            out = run_config(c, [files[i] for i in sub], CONFIGS[c], args.seed, args.jobs, cache,
                             f"{name}-pc{args.per_class}-seed{args.seed}")
            gmds[name][c] = out
            m = len(sub)
            print(f"  {name} {c}: prepare {float(out['seconds_prepare']):.0f} s, pairs "
                  f"{float(out['seconds_match']):.0f} s (this call {time.perf_counter() - t:.0f} s)", flush=True)
            res["collections"][name].setdefault("gmds_seconds", {})[c] = {
                "prepare": float(out["seconds_prepare"]), "match": float(out["seconds_match"]),
                "jobs": int(out["jobs"]),
                "per_shape": float(out["seconds_prepare"]) * int(out["jobs"]) / m,
                "per_pair": float(out["seconds_match"]) * int(out["jobs"]) / (m * (m - 1) // 2)}
            write_results(args.json, {**res, "complete": False})
    partial = {}
    for item in [x.strip() for x in args.partial.split(",") if x.strip()]:
        c, _, name = item.partition(":")
        if c not in CONFIGS or name not in COLLECTIONS:
            ap.error(f"--partial takes CONFIG:COLLECTION, got {item!r}")
        files, labels = collection(args.data, name)
        out = run_config(c, [files[i] for i in subs[name]], CONFIGS[c], args.seed, args.jobs, cache,
                         f"{name}-pc{args.per_class}-seed{args.seed}")
        keys = [k for k in ("trimmed", "gh", "log@0.25", "log@0.5", "log@1", "log_area@1", "gh_area", "diff@0.5")
                if k in out]
        partial[f"{c}:{name}"] = {"scores": {k: scores(out[k], labs_sub[name]) for k in keys},
                                  "seconds_prepare": float(out["seconds_prepare"]),
                                  "seconds_match": float(out["seconds_match"])}
    res["partial"] = partial
    # every candidate on the subset
    cands: dict = {}
    kinds: dict = {}
    for k in cheap_sub[COLLECTIONS[0]]:
        cands[k] = {c: cheap_sub[c][k] for c in COLLECTIONS}
        kinds[k] = "per-shape"
    gkeys = sorted(set.intersection(*[set(v.keys()) for c in COLLECTIONS for v in gmds[c].values()]) - {
        "seconds_prepare", "seconds_match", "seconds_profile_gap", "jobs", "files"})
    for c in configs:
        for k in gkeys:
            name = f"profile_gap[{c}]" if k == "profile_gap" else f"gmds[{c}] {k}"
            cands[name] = {col: gmds[col][c][k] for col in COLLECTIONS}
            kinds[name] = "per-shape" if k == "profile_gap" else "gmds"
    scored = {k: {**score_candidate(v, labs_sub), "kind": kinds[k]} for k, v in cands.items()}
    cheap_full = {k: score_candidate({c: cheap_all[c][k] for c in COLLECTIONS}, labs_all) for k in cheap_all[COLLECTIONS[0]]}
    by_j = lambda kind: sorted((k for k in scored if scored[k]["kind"] == kind), key=lambda k: scored[k]["J"])
    best_cheap, best_gmds = by_j("per-shape"), by_j("gmds")
    combos = {}
    for s in best_cheap[:3]:
        for g in best_gmds[:3]:
            for rule in RULES:
                name = f"{rule}({s}, {g})"
                mats = {c: combine(cands[s][c], cands[g][c], rule) for c in COLLECTIONS}
                cands[name] = mats
                combos[name] = {**score_candidate(mats, labs_sub), "kind": "combination", "parts": [s, g, rule]}
    scored.update(combos)
    pair_local = _pair_local(cands, labs_sub, best_gmds[:3])
    ranking = sorted(scored, key=lambda k: scored[k]["J"])
    best = ranking[0]
    best_combo = by_j("combination")[0] if combos else None
    # two-stage: recall of the final ranking's top 10 within a first stage's top K
    finals = {"best": best, "best_gmds": best_gmds[0], "default": "gmds[default] trimmed",
              "pair_local": pair_local["chosen"]["name"]}
    two = {}
    for label, F in finals.items():
        if F not in cands:
            continue
        rows = {}
        for s in best_cheap:
            row = {}
            for c in COLLECTIONS:
                n = len(subs[c])
                row[c] = {f"K={K}": recall_at(cands[s][c], cands[F][c], K) for K in KS}
                # the class's other members in a 6-per-class subset: 5 (the rest of a top 10 is other classes)
                row[c].update({f"top5 K={K}": recall_at(cands[s][c], cands[F][c], K, top=5) for K in KS})
                row[c].update({f"K'={max(1, round(K * (n - 1) / (COLLECTION_SIZE - 1)))} (K={K} of 199)":
                               recall_at(cands[s][c], cands[F][c], max(1, round(K * (n - 1) / (COLLECTION_SIZE - 1))))
                               for K in KS})
                row[c].update({f"two-stage K={K}": two_stage_nn(cands[s][c], cands[F][c], K, labs_sub[c])
                               for K in (10, 20)})
            rows[s] = row
        two[label] = {"final": F, "first_stages": rows}
    # the whole watertight collection: pairs a two-stage top-10 search would match
    full = {}
    for s in best_cheap[:5]:
        if s not in cheap_all["watertight"]:
            continue
        S = cheap_all["watertight"][s]
        full[s] = {f"K={K}": two_stage_pairs(S, K) for K in KS}
    per_pair = np.mean([res["collections"]["watertight"]["gmds_seconds"][c]["per_pair"] for c in configs[:1]])
    per_shape = np.mean([res["collections"]["watertight"]["gmds_seconds"][c]["per_shape"] for c in configs[:1]])
    res.update({
        "candidates": scored, "per_shape_full": cheap_full, "per_shape_seconds": cost,
        "ranking": ranking[:40], "best": {"name": best, **scored[best]},
        "best_gmds": {"name": best_gmds[0], **scored[best_gmds[0]]},
        "best_per_shape": {"name": best_cheap[0], **scored[best_cheap[0]]},
        "best_per_shape_full": {"name": min(cheap_full, key=lambda k: cheap_full[k]["J"]),
                                **cheap_full[min(cheap_full, key=lambda k: cheap_full[k]["J"])]},
        "best_combination": None if best_combo is None else {"name": best_combo, **scored[best_combo]},
        "two_stage": two, "pair_local": pair_local,
        "two_stage_watertight_200": {"pairs": full, "default_seconds_per_pair_one_core": float(per_pair),
                                     "default_seconds_per_shape_one_core": float(per_shape),
                                     "minutes_on_2_cores": {s: {k: (v * per_pair + 200 * per_shape) / 2 / 60
                                                                for k, v in row.items()} for s, row in full.items()}},
        "seconds": time.perf_counter() - t_start, "load_average_end": os.getloadavg()})
    write_results(args.json, {**res, "complete": True})
    print_summary(res, scored, ranking)


def _line(name, s):
    t = s["together"]
    per = "  ".join(f"{c[:5]} {s[c]['nn']:.3f}/{s[c]['ft']:.3f}/{s[c]['eer']:.3f}" for c in COLLECTIONS)
    return (f"{name[:70]:<70} J {s['J']:.3f}  both NN {t['nn']:.3f} FT {t['ft']:.3f} ST {t['st']:.3f} "
            f"EER {t['eer']:.3f}  {per}")


def print_summary(res, scored, ranking) -> None:
    print("\nbest 25 candidates (J; together; per collection NN/FT/EER):")
    for k in ranking[:25]:
        print(_line(k, scored[k]))
    for kind in ("per-shape", "gmds", "combination"):
        ks = [k for k in ranking if scored[k]["kind"] == kind][:10]
        print(f"\nbest {kind}:")
        for k in ks:
            print(_line(k, scored[k]))
    print("\nper-shape candidates on all shapes (80 + 200):")
    for k in sorted(res["per_shape_full"], key=lambda k: res["per_shape_full"][k]["J"])[:10]:
        print(_line(k, res["per_shape_full"][k]))
    pl = res["pair_local"]
    print(f"\npair-local (S^w G^(1-w)); chosen: {pl['chosen']['name']}")
    for k in list(pl["candidates"])[:10]:
        print(_line(k, pl["candidates"][k]))
    for label, t in res["two_stage"].items():
        print(f"\nrecall of the top {TOP} by {t['final']} ({label}):")
        for s, row in list(t["first_stages"].items())[:6]:
            print(f"  {s[:40]:<40} " + "  ".join(
                f"{c[:5]} " + " ".join(f"{v:.2f}" for k, v in row[c].items() if k.startswith("K="))
                for c in COLLECTIONS))


if __name__ == "__main__":
    main()
