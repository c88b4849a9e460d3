"""Recognition on TOSCA and the SHREC'07 watertight collection: gromov against two per-shape descriptors.

Run:  nice -n 10 .venv/bin/python benchmarks/bench_recognition.py [--data DIR]
          [--collections tosca,watertight] [--per-class 6] [--shapes N] [--methods shapedna,hks,gromov,combined]
          [--jobs 2] [--seed 0] [--samples 100] [--resolution 3000] [--cache DIR]
          [--combined-per-class N] [--combined-samples 50] [--candidates C [--k K]]
          [--json benchmarks/results/recognition.json]

The collections (labels from the file names, ``cat10.off.gz`` -> ``cat``, ``chair07.off.gz`` ->
``chair``; data README): ``tosca``, TOSCA high-resolution, 80 meshes of 9 classes; ``watertight``,
10 classes x 20 meshes of the SHREC'07 Watertight Models track (Giorgi, Biasotti & Paraboschi
2007). Each mesh is read with :func:`gromov.load` (which repairs it). Three methods, side by side
in one run:

- **Shape-DNA** (Reuter, Wolter & Peinecke, "Laplace-Beltrami spectra as 'Shape-DNA' of surfaces
  and solids", Computer-Aided Design 38, 2006): the first 50 non-zero eigenvalues of the
  Laplace-Beltrami operator of the input mesh (robust Laplacian of Sharp & Crane, SGP 2020,
  ``robust_laplacian.mesh_laplacian``; ``scipy.sparse.linalg.eigsh`` in shift-invert mode),
  times the area (scale invariance, their §4) and over Weyl's asymptote 4 pi i / area
  (``DNA_i = lambda_i A / (4 pi i)``, i = 1..50), compared by the Euclidean distance.
- **Pooled HKS**: the heat kernel signature ``k_t(x, x) = sum_i exp(-lambda_i t) phi_i(x)^2`` (Sun,
  Ovsjanikov & Guibas, "A concise and provably informative multi-scale signature based on heat
  diffusion", SGP 2009) from the first 100 non-zero eigenpairs of the same Laplacian, scale-
  normalised (``t = tau A``, the signature times A: unchanged by scaling the shape) at 8
  log-spaced ``tau`` from 0.01 to 0.3 (Sun et al.'s range, ``4 ln 10 / lambda_K`` to ``4 ln 10 /
  lambda_1``, for K = 100 and a typical ``lambda_1 A``), pooled over the surface as the
  area-weighted 5/25/50/75/95% quantiles of its logarithm at each time (a 40-vector; pooling
  point signatures into one per shape as in Ovsjanikov et al., "Shape Google", 2009), compared by
  the Euclidean distance.
- **gromov**: :func:`gromov.experiments.gh_matrix` with the defaults of ``gromov pairwise`` (heat
  diffusion metric, holes filled below 0.5 sqrt(area), ``--resolution`` working vertices,
  ``--samples`` samples, ranked by the trimmed distortion -- and, as a second row, by the GH
  estimate, ``--rank-by gh``), on at most ``--per-class`` shapes of each class, drawn with
  ``--seed`` (:func:`class_subset`); the two descriptors are scored on that subset too (rows
  "on the gromov subset"), so that the three are compared on the same shapes.

- **gromov combined** (``--methods combined``): :func:`gromov.experiments.gh_matrix` as ``gromov
  pairwise FILES --units area --samples 50 --rank-by combined`` runs it (each shape measured at
  unit area; each pair ranked by (S^0.35 G^0.65)^0.5 H^0.5, S the Shape-DNA distance of the
  working meshes, G the trimmed distortion, H the heat kernel signature's distortion along the
  correspondence; docs/design/recognition.md, "Across collections"; two more rows read the same
  matches: without H, S^0.35 G^0.65, and after the set-level diffusion re-ranking that ``gromov
  pairwise`` reports beside the EER), on
  ``--combined-per-class`` shapes of each class (0: all); with ``--candidates C`` as a two-stage
  search (``--candidates C``): only each shape's C nearest by S are matched, with ``--k K``
  then each shape's K nearest searched by neighbour descent (``gromov pairwise --candidates C
  -k K``), the other pairs ranked after them by S, and no EER (not every pair is matched).

``--shapes N`` keeps at most N shapes of each collection for every method (spread over the
classes as :func:`class_subset` spreads them), for a quick check.

Scores (:func:`scores`), per collection and method: nearest-neighbour accuracy (NN), first and
second tier (FT, ST: of the c - 1 other shapes of a query's class of c, the fraction among its c - 1
and 2 (c - 1) nearest; Shilane et al., "The Princeton Shape Benchmark", SMI 2004) and the equal
error rate (:func:`gromov.experiments.recognition.equal_error_rate`: every pair a trial, one
global threshold). Times: each method over the collection in ``--jobs`` processes (gromov: the wall clock of
:func:`~gromov.experiments.gh_matrix`, metrics and pairs in ``--jobs`` workers; the descriptors:
their single-process times summed over the shapes, over ``--jobs``, and the wall clock of both
together as ``seconds_both_wall``) and the single-process time per shape (descriptors) or per
shape and per pair (gromov: its metrics' and its pairs' wall times times ``--jobs``).

``--cache DIR`` writes each shape's descriptors (``DIR/descriptors/COLLECTION/NAME.npz``) and each
gromov matrix (``DIR/gromov-*.npz``, ``DIR/combined-*.npz``) there, for ``benchmarks/studies/recognition_defaults.py``;
nothing is read back here: every run measures its own times.

Resources, measured on 2 cores shared with other jobs (load average 2-9): the descriptors of all 280
shapes 16 minutes (TOSCA's 50,000-vertex meshes dominate); gromov 6 per class (49 TOSCA and 60
watertight shapes, 2,946 pairs) 29 minutes; about 5 GB of memory.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from _common import HERE, add_data_argument, write_results

COLLECTIONS = ("tosca", "watertight")
METHODS = ("shapedna", "hks", "gromov", "combined")
#: Shape-DNA's length (Reuter et al. 2006 compare the first 50 or so).
DNA_K = 50
#: Eigenpairs of the pooled HKS.
HKS_K = 100
#: The HKS times relative to the area.
HKS_TAUS = np.geomspace(0.01, 0.3, 8)
#: The area-weighted quantiles pooled at each time.
HKS_QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
#: gromov pairwise's metric options (the library's defaults, spelled out).
GROMOV_METRIC = {"kernel": "heat", "fill_holes": 0.5}


# ----------------------------------------------------------------------------- data
def collection(data: str | Path, name: str) -> tuple[list[Path], np.ndarray]:
    """``(files, labels)`` of a collection, sorted by class and then by number."""
    folder = Path(data) / name
    files = list(folder.glob("*.off.gz"))
    if not files:
        raise SystemExit(f"no *.off.gz files in {folder}")

    def key(f: Path):
        m = re.fullmatch(r"(.*?)(\d+)\.off\.gz", f.name)
        return m.group(1), int(m.group(2))

    files.sort(key=key)
    return files, np.array([key(f)[0] for f in files])


def class_subset(labels, per_class: int | None, seed: int = 0) -> np.ndarray:
    """Indices of at most ``per_class`` members of each class (all where it has fewer; all with
    None or 0), drawn without replacement by one ``numpy.random.default_rng(seed)`` over the
    classes in sorted order, kept in the collection's order."""
    labels = np.asarray(labels)
    if not per_class:
        return np.arange(len(labels))
    rng = np.random.default_rng(seed)
    keep = []
    for c in sorted(set(labels.tolist())):
        idx = np.flatnonzero(labels == c)
        keep.extend(idx if len(idx) <= per_class else rng.choice(idx, per_class, replace=False))
    return np.sort(np.asarray(keep, dtype=np.int64))


def spread(labels, n_shapes: int | None) -> np.ndarray:
    """Indices of at most ``n_shapes`` shapes, the same number from each class (as many as
    ``n_shapes`` allows, the first of each class), in the collection's order."""
    labels = np.asarray(labels)
    if not n_shapes or n_shapes >= len(labels):
        return np.arange(len(labels))
    classes = sorted(set(labels.tolist()))
    per = max(1, n_shapes // len(classes))
    return np.sort(np.concatenate([np.flatnonzero(labels == c)[:per] for c in classes]))


# ----------------------------------------------------------------------------- descriptors
def _one_thread() -> None:
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1)


def laplacian(mesh):
    """``(L, M, area)``: the robust Laplacian (Sharp & Crane 2020) of a :class:`gromov.Mesh`,
    its lumped mass matrix and the area (the mass's sum)."""
    import robust_laplacian

    L, M = robust_laplacian.mesh_laplacian(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    return L.tocsc(), M.tocsc(), float(M.diagonal().sum())


def eigenpairs(L, M, k: int, seed: int = 0):
    """The ``k`` smallest eigenpairs of ``L phi = lambda M phi`` (shift-invert about a tiny
    negative shift, so that the singular L is no problem; a seeded start vector), ascending,
    ``phi`` M-orthonormal."""
    from scipy.sparse.linalg import eigsh

    n = L.shape[0]
    v0 = np.random.default_rng(seed).standard_normal(n)
    area = float(M.diagonal().sum())
    lam, phi = eigsh(L, k=min(k, n - 1), M=M, sigma=-1e-8 / area, which="LM", v0=v0)
    order = np.argsort(lam)
    return np.maximum(lam[order], 0.0), phi[:, order]


def nonzero(lam: np.ndarray, area: float) -> int:
    """The number of (numerically) zero eigenvalues at the start of ``lam``: one per connected
    component."""
    return int(np.count_nonzero(lam * area < 1e-6))


def shape_dna(lam: np.ndarray, area: float, k: int = DNA_K) -> np.ndarray:
    """``lambda_i A / (4 pi i)``, i = 1..k, of the ascending eigenvalues past the zero ones."""
    z = nonzero(lam, area)
    lam = lam[z:z + k]
    return lam * area / (4.0 * np.pi * np.arange(1, len(lam) + 1))


def pooled_hks(lam: np.ndarray, phi: np.ndarray, mass: np.ndarray, taus=HKS_TAUS, quantiles=HKS_QUANTILES):
    """``(len(taus) * len(quantiles),)``: at each ``t = tau A`` the mass-weighted quantiles of
    ``log(A k_t(x, x))`` over the vertices (Sun et al. 2009; the product with A and t in units
    of A make it scale-invariant)."""
    area = float(mass.sum())
    out = []
    order_cache = None
    for tau in taus:
        h = np.log(area * ((phi**2) @ np.exp(-lam * tau * area)))
        order_cache = np.argsort(h)
        cw = np.cumsum(mass[order_cache]) / area
        out.append(np.interp(quantiles, cw, h[order_cache]))
    return np.concatenate(out)


def descriptors_of(path: str, seed: int = 0) -> dict:
    """Shape-DNA and the pooled HKS of one mesh file, each with its own eigendecomposition and
    its single-process seconds (load and Laplacian counted in both)."""
    import gromov
    from gromov.errors import GromovWarning

    _one_thread()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        mesh = gromov.load(path)
    L, M, area = laplacian(mesh)
    t_base = time.perf_counter() - t0
    t = time.perf_counter()
    lam, _ = eigenpairs(L, M, DNA_K + mesh.n_components, seed)
    dna = shape_dna(lam, area)
    t_dna = time.perf_counter() - t
    t = time.perf_counter()
    lam, phi = eigenpairs(L, M, HKS_K + mesh.n_components, seed)
    hks = pooled_hks(lam, phi, M.diagonal())
    t_hks = time.perf_counter() - t
    return {"shapedna": dna, "hks": hks, "seconds_shapedna": t_base + t_dna, "seconds_hks": t_base + t_hks,
            "n_vertices": mesh.n_vertices, "area": area, "components": mesh.n_components}


def all_descriptors(files, jobs: int, seed: int = 0) -> tuple[list[dict], float]:
    """:func:`descriptors_of` of every file in ``jobs`` processes, and the wall time."""
    t = time.perf_counter()
    if jobs > 1:
        import multiprocessing as mp

        with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as pool:
            out = list(pool.map(descriptors_of, [str(f) for f in files], [seed] * len(files)))
    else:
        out = [descriptors_of(str(f), seed) for f in files]
    return out, time.perf_counter() - t


def euclidean(x: np.ndarray) -> np.ndarray:
    """``(n, n)`` Euclidean distances between the rows of ``x`` (exactly symmetric, 0 diagonal)."""
    from scipy.spatial.distance import pdist, squareform

    return squareform(pdist(np.asarray(x, dtype=np.float64)))


# ----------------------------------------------------------------------------- scores
def retrieval_scores(D: np.ndarray, labels) -> dict:
    """Nearest-neighbour accuracy, first and second tier of a distance matrix (each shape the
    query against all others; ties in index order), and the per-query arrays."""
    labels = np.asarray(labels)
    n = len(labels)
    nn, ft, st = np.zeros(n), np.zeros(n), np.zeros(n)
    for i in range(n):
        others = np.r_[0:i, i + 1:n]
        order = others[np.argsort(D[i, others], kind="stable")]
        hit = labels[order] == labels[i]
        c = int(hit.sum())
        nn[i] = hit[0]
        ft[i] = hit[:c].sum() / c if c else np.nan
        st[i] = hit[:2 * c].sum() / c if c else np.nan
    return {"nn": nn, "ft": ft, "st": st}


def scores(D, labels) -> dict:
    """``{nn, ft, st, eer, shapes}`` of a symmetric distance matrix and the shapes' classes."""
    from gromov.experiments.recognition import equal_error_rate

    D = np.asarray(D, dtype=np.float64)
    D = 0.5 * (D + D.T)
    r = retrieval_scores(D, labels)
    return {"nn": float(np.mean(r["nn"])), "ft": float(np.nanmean(r["ft"])), "st": float(np.nanmean(r["st"])),
            "eer": float(equal_error_rate(D, labels)), "shapes": len(labels)}


def pooled_scores(mats: dict, labs: dict) -> dict:
    """The scores of several collections together: NN, FT and ST averaged over all queries, each
    searching its own collection; the EER over all within-collection pairs with one threshold
    (:func:`gromov.experiments.recognition.roc` with a block-diagonal mask)."""
    from gromov.experiments.recognition import equal_error_rate

    per = {c: retrieval_scores(0.5 * (D + D.T), labs[c]) for c, D in mats.items()}
    n = sum(len(labs[c]) for c in mats)
    big = np.zeros((n, n))
    mask = np.zeros((n, n), dtype=bool)
    lab = []
    k = 0
    for c, D in mats.items():
        m = len(D)
        big[k:k + m, k:k + m] = 0.5 * (D + D.T)
        mask[k:k + m, k:k + m] = True
        lab.extend(f"{c}:{x}" for x in labs[c])
        k += m
    cat = {key: np.concatenate([per[c][key] for c in mats]) for key in ("nn", "ft", "st")}
    return {"nn": float(np.mean(cat["nn"])), "ft": float(np.nanmean(cat["ft"])),
            "st": float(np.nanmean(cat["st"])), "eer": float(equal_error_rate(big, np.array(lab), mask=mask)),
            "shapes": int(n)}


# ----------------------------------------------------------------------------- gromov
def gromov_matrix(files, args) -> dict:
    """:func:`gromov.experiments.gh_matrix` as ``gromov pairwise FILES`` runs it, with the times."""
    from gromov.errors import GromovWarning
    from gromov.experiments.pairwise import gh_matrix

    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        g = gh_matrix([str(f) for f in files], "diffusion", n_samples=args.samples, resolution=args.resolution,
                      metric_options=dict(GROMOV_METRIC), seed=args.seed, jobs=args.jobs)
    wall = time.perf_counter() - t
    return {"trimmed": g.trimmed, "gh": g.relative, "seconds": wall, "seconds_prepare": g.seconds_prepare,
            "seconds_match": g.seconds_match}


def combined_matrix(files, args) -> dict:
    """:func:`gromov.experiments.gh_matrix` as ``gromov pairwise FILES --units area --samples
    S --rank-by combined [-k 10 --candidates C]`` runs it: the heat distances of each shape at
    unit area, ranked by the spectral distance and the trimmed distortion together
    (:func:`gromov.spectrum.combined`); with ``--candidates``, only each shape's C nearest by
    the spectral distance are matched. Unmatched pairs are ranked after the matched ones, by
    their spectral distance."""
    from gromov.errors import GromovWarning
    from gromov.experiments.pairwise import gh_matrix

    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        g = gh_matrix([str(f) for f in files], "diffusion", n_samples=args.combined_samples,
                      resolution=args.resolution, metric_options={**GROMOV_METRIC, "units": "area"},
                      seed=args.seed, jobs=args.jobs, spectral=True, candidates=args.candidates, k=args.k,
                      rank_by="combined")
    wall = time.perf_counter() - t
    from gromov.spectrum import combined

    S = g.spectral
    miss = np.isnan(g.combined)

    def ranked(D):   # unmatched pairs after the matched ones, by their spectral distance
        D = D.copy()
        D[miss] = np.nanmax(D) + 1.0 + S[miss] / (S.max() + 1e-300)
        return D

    return {"combined": ranked(g.combined), "without_signature": ranked(combined(S, g.trimmed)), "spectral": S,
            "trimmed": g.trimmed, "gh": g.relative, "signature": g.signature, "complete": not miss.any(),
            "matched": int(len(files) * (len(files) - 1) // 2 - g.skipped),
            "seconds": wall, "seconds_prepare": g.seconds_prepare, "seconds_match": g.seconds_match}


# ----------------------------------------------------------------------------- main
def gromov_source() -> dict:
    """Where the gromov that ran comes from: its folder and, in a git checkout, the commit and
    whether its source differs from it."""
    import subprocess

    import gromov

    folder = Path(gromov.__file__).resolve().parent
    out = {"path": str(folder), "version": getattr(gromov, "__version__", None)}
    try:
        git = lambda *a: subprocess.run(["git", *a], cwd=folder, capture_output=True, text=True,
                                        check=True).stdout.strip()
        out["commit"] = git("rev-parse", "HEAD")
        out["modified"] = bool(git("status", "--porcelain", "--", "."))
    except (OSError, subprocess.CalledProcessError):
        pass
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--collections", default=",".join(COLLECTIONS), help="comma-separated: tosca, watertight")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated: shapedna, hks, gromov")
    ap.add_argument("--per-class", type=int, default=6,
                    help="gromov: at most this many shapes of each class, drawn with --seed (0: all; default 6)")
    ap.add_argument("--shapes", type=int, default=None,
                    help="every method: at most N shapes of each collection, the same number per class")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0, help="the subset's draw, gromov's samples, ARPACK's start")
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--resolution", type=int, default=3000)
    ap.add_argument("--cache", default=None, metavar="DIR",
                    help="write the descriptors and gromov matrices there (for the defaults study)")
    ap.add_argument("--combined-per-class", type=int, default=None, metavar="N",
                    help="method combined: at most N shapes of each class (default --per-class; 0: all)")
    ap.add_argument("--combined-samples", type=int, default=50, help="method combined: samples per shape")
    ap.add_argument("--candidates", type=int, default=None, metavar="C",
                    help="method combined: match only each shape's C nearest by spectral distance")
    ap.add_argument("--k", type=int, default=None, metavar="K",
                    help="method combined, with --candidates: then each shape's K nearest by neighbour descent")
    ap.add_argument("--json", default=str(HERE / "results" / "recognition.json"))
    args = ap.parse_args(argv)
    colls = [c.strip() for c in args.collections.split(",") if c.strip()]
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if set(colls) - set(COLLECTIONS) or not colls:
        ap.error(f"--collections takes {', '.join(COLLECTIONS)}, got {args.collections!r}")
    if set(methods) - set(METHODS) or not methods:
        ap.error(f"--methods takes {', '.join(METHODS)}, got {args.methods!r}")
    res: dict = {"command": "python benchmarks/bench_recognition.py " + shlex.join(
                     argv if argv is not None else sys.argv[1:]),
                 "jobs": args.jobs, "seed": args.seed, "per_class": args.per_class, "shapes_cap": args.shapes,
                 "gromov": {"metric": "diffusion", "metric_options": GROMOV_METRIC, "n_samples": args.samples,
                            "resolution": args.resolution, "rank_tau_scale": 0.5, "rank_residual": "log"},
                 "shapedna": {"eigenvalues": DNA_K, "laplacian": "robust_laplacian.mesh_laplacian (input mesh)",
                              "normalisation": "lambda_i * area / (4 pi i)", "distance": "euclidean"},
                 "hks": {"eigenpairs": HKS_K, "taus": HKS_TAUS.tolist(), "quantiles": list(HKS_QUANTILES),
                         "signature": "log(area * k_{tau area}(x, x))", "distance": "euclidean"},
                 "gromov_source": gromov_source(), "load_average_start": os.getloadavg(),
                 "collections": {}}
    cache = Path(args.cache) if args.cache else None
    for name in colls:
        files, labels = collection(args.data, name)
        keep = spread(labels, args.shapes)
        files, labels = [files[i] for i in keep], labels[keep]
        sub = class_subset(labels, args.per_class, args.seed)
        n, m = len(files), len(sub)
        out = {"shapes": n, "classes": sorted(set(labels.tolist())), "files": [f.name for f in files],
               "gromov_subset": [files[i].name for i in sub], "rows": {}}
        print(f"{name}: {n} shapes of {len(out['classes'])} classes; gromov on {m} "
              f"({m * (m - 1) // 2} pairs)", flush=True)
        if {"shapedna", "hks"} & set(methods):
            desc, wall = all_descriptors(files, args.jobs, args.seed)
            if cache is not None:
                folder = cache / "descriptors" / name
                folder.mkdir(parents=True, exist_ok=True)
                for f, d in zip(files, desc):
                    np.savez(folder / f.name.replace(".off.gz", ".npz"), **d)
            for meth in ("shapedna", "hks"):
                if meth not in methods:
                    continue
                X = np.array([d[meth] for d in desc])
                D = euclidean(X)
                per_shape = [d[f"seconds_{meth}"] for d in desc]
                # the method alone in --jobs processes: its single-process times over --jobs
                out["rows"][meth] = {**scores(D, labels), "seconds": float(np.sum(per_shape)) / args.jobs,
                                     "seconds_both_wall": wall, "jobs": args.jobs,
                                     "seconds_per_shape": float(np.mean(per_shape)),
                                     "seconds_per_shape_median": float(np.median(per_shape))}
                out["rows"][f"{meth} (gromov subset)"] = {
                    **scores(D[np.ix_(sub, sub)], labels[sub]),
                    "seconds_per_shape": float(np.mean([per_shape[i] for i in sub])),
                    "seconds": float(np.sum([per_shape[i] for i in sub])) / args.jobs}
                print(f"  {meth:<10} NN {out['rows'][meth]['nn']:.3f}  EER {out['rows'][meth]['eer']:.3f}  "
                      f"{wall:.1f} s", flush=True)
        if "gromov" in methods:
            g = gromov_matrix([files[i] for i in sub], args)
            if cache is not None:
                np.savez(cache / f"gromov-{name}-pc{args.per_class}-s{args.samples}-r{args.resolution}"
                                 f"-seed{args.seed}.npz", files=np.array([files[i].name for i in sub]),
                         trimmed=g["trimmed"], gh=g["gh"], seconds=g["seconds"])
            P = m * (m - 1) // 2
            timing = {"seconds": g["seconds"], "seconds_prepare": g["seconds_prepare"],
                      "seconds_match": g["seconds_match"], "jobs": args.jobs,
                      "seconds_per_shape": g["seconds_prepare"] * args.jobs / m,
                      "seconds_per_pair": g["seconds_match"] * args.jobs / P}
            for key, row in (("trimmed", "gromov"), ("gh", "gromov --rank-by gh")):
                out["rows"][row] = {**scores(g[key], labels[sub]), **timing}
            print(f"  gromov     NN {out['rows']['gromov']['nn']:.3f}  EER {out['rows']['gromov']['eer']:.3f}  "
                  f"{g['seconds']:.1f} s", flush=True)
        if "combined" in methods:
            per = args.per_class if args.combined_per_class is None else args.combined_per_class
            csub = class_subset(labels, per, args.seed)
            mc = len(csub)
            g = combined_matrix([files[i] for i in csub], args)
            if cache is not None:
                np.savez(cache / (f"combined-{name}-pc{per}-s{args.combined_samples}-c{args.candidates or 0}"
                                  + (f"-k{args.k}" if args.k else "") + f"-seed{args.seed}.npz"), files=np.array([files[i].name for i in csub]),
                         combined=g["combined"], spectral=g["spectral"], trimmed=g["trimmed"], gh=g["gh"],
                         signature=g["signature"])
            row = (f"gromov --units area --samples {args.combined_samples} --rank-by combined"
                   + (f" --candidates {args.candidates}" if args.candidates else "")
                   + (f" -k {args.k}" if args.k else ""))
            sc = scores(g["combined"], labels[csub])
            if not g["complete"]:
                sc["eer"] = None   # not every pair was matched: no EER
            out["rows"][row] = {**sc, "seconds": g["seconds"], "seconds_prepare": g["seconds_prepare"],
                                "seconds_match": g["seconds_match"], "jobs": args.jobs, "pairs_matched": g["matched"],
                                "files": [files[i].name for i in csub],
                                "seconds_per_shape": g["seconds_prepare"] * args.jobs / mc,
                                "seconds_per_pair": g["seconds_match"] * args.jobs / max(g["matched"], 1)}
            print(f"  combined   NN {sc['nn']:.3f}  FT {sc['ft']:.3f}  EER {sc['eer']}  {g['seconds']:.1f} s "
                  f"({g['matched']} pairs)", flush=True)
            if g["complete"]:   # the same matches ranked without the signature, and re-ranked
                from gromov.experiments.recognition import diffusion_rerank

                out["rows"][row + " (without the signature distortion)"] = {
                    **scores(g["without_signature"], labels[csub]), "same_matches_as": row}
                out["rows"][row + " (after the diffusion re-ranking)"] = {
                    **scores(diffusion_rerank(g["combined"]), labels[csub]), "same_matches_as": row}
        res["collections"][name] = out
        write_results(args.json, {**res, "complete": False})
    res["ratios"] = ratios(res)
    res["load_average_end"] = os.getloadavg()   # other work on the machine slows every time above
    print_table(res)
    write_results(args.json, {**res, "complete": True})


def ratios(res: dict) -> dict:
    """gromov against the descriptors on the same subset: time per shape (gromov's metrics and
    its pairs spread over the shapes, ``(prepare + match) / shapes``) and the score differences."""
    out = {}
    for name, c in res["collections"].items():
        r = c["rows"]
        if "gromov" not in r:
            continue
        m = len(c["gromov_subset"])
        g_total = (r["gromov"]["seconds_prepare"] + r["gromov"]["seconds_match"]) * r["gromov"]["jobs"]
        for meth in ("shapedna", "hks"):
            key = f"{meth} (gromov subset)"
            if key not in r:
                continue
            d_total = r[key]["seconds_per_shape"] * m
            out[f"{name}: gromov / {meth}"] = {
                "time": g_total / d_total,
                **{f"{s}_difference": r["gromov"][s] - r[key][s] for s in ("nn", "ft", "st", "eer")}}
    return out


def print_table(res: dict) -> None:
    print(f"\n{'collection':<11}{'method':<28}{'shapes':>7}{'NN':>7}{'FT':>7}{'ST':>7}{'EER':>7}"
          f"{'wall s':>9}{'s/shape':>9}{'s/pair':>8}")
    for name, c in res["collections"].items():
        for meth, r in c["rows"].items():
            pair = f"{r['seconds_per_pair']:8.3f}" if "seconds_per_pair" in r else f"{'':>8}"
            # (a row that re-reads another's matches has no time of its own)
            times = f"{r['seconds']:>9.1f}{r['seconds_per_shape']:>9.2f}" if "seconds" in r else f"{'':>18}"
            print(f"{name:<11}{meth:<28}{r['shapes']:>7}{r['nn']:>7.3f}{r['ft']:>7.3f}{r['st']:>7.3f}"
                  f"{r['eer'] if r['eer'] is not None else float('nan'):>7.3f}{times}{pair}")
    for key, r in res.get("ratios", {}).items():
        print(f"{key}: {r['time']:.1f}x the single-process time; NN {r['nn_difference']:+.3f}, "
              f"FT {r['ft_difference']:+.3f}, EER {r['eer_difference']:+.3f}")


if __name__ == "__main__":
    main()
