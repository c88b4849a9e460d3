"""Two more per-pair rankings: the heat kernel signature's distortion along the match, and a second metric.

Run:  nice -n 10 .venv/bin/python benchmarks/studies/recognition_pointwise.py [--data DIR] [--per-class 6]
          [--jobs 2] [--no-geodesic] [--orientation prefer|ignore] [--working] [--weights W,W,...] [--cache DIR]
          [--json benchmarks/studies/recognition_pointwise.json]

The whole collections (``recognition_pointwise_full.json``): ``--per-class 0 --no-geodesic
--orientation ignore --working --weights 0.1,0.15,0.25,0.35,0.5,0.65,0.75``.

On the subsets of ``recognition_defaults.py`` (``class_subset(labels, 6, seed=0)``: 60 watertight
shapes, 49 TOSCA shapes), each collection's matrices as ``gromov pairwise FILES --units area
--samples 50 --rank-by combined`` makes them (:func:`gromov.experiments.gh_matrix`: ``S`` the
Shape-DNA distance of the working meshes, ``G`` the trimmed distortion, ``GH`` the GH estimate,
``C`` the combined S^0.35 G^0.65), every pair's correspondence kept, and two candidates that a
pair's value could also be made of:

- ``H``: the distortion of the heat kernel signature along the match. Each input mesh's
  signature h(x) = log(A k_t(x, x)) at the times t = tau A, ``TAUS`` (12 from 0.001 to 0.3;
  Sun, Ovsjanikov & Guibas, "A concise and provably informative multi-scale signature based on
  heat diffusion", SGP 2009), from 150 eigenpairs of its robust Laplacian (Sharp & Crane 2020;
  ``bench_recognition.py``'s ``laplacian`` and ``eigenpairs``): scale-invariant, and unchanged
  by an isometry, as the distances are. For each of the 2 x 50 sample pairs (x, T(x)) of the
  two-sided correspondence (each image read at its nearest input vertex), the RMS over a band of
  times of h_X(x) - h_Y(T(x)); the pair's value is the RMS of the best-fitting 80% (``_0.8``) or
  of all (``_1.0``) of them. Bands: ``all`` the 12 times, ``small`` the first 6, ``mid`` the 4th to
  9th, ``large`` the last 6. The distances compare each sample with the others; the signature
  compares each sample with its own image.
- ``W`` (with ``--working``): ``H`` with the signature of gromov's working mesh of each shape
  (3,000 vertices, 150 eigenpairs of its cotangent Laplacian with lumped masses), read at each
  input vertex's nearest working vertex, along the same matches: what the product could compute
  from the prepared shapes alone.
- ``GEO`` (without ``--no-geodesic``): the GH estimate (and ``GEO_T`` the trimmed distortion) of
  a second match of every pair with the geodesic metric, each mesh scaled to unit area, 50
  samples (``gh_matrix(meshes, "geodesic", n_samples=50)``).

Scores (``bench_recognition.py``): NN, first tier, EER per collection and J = mean(1 - NN, 1 - FT,
EER) over both (``pooled_scores``), each ranking alone and the weighted geometric means C^(1-w)
X^w (each matrix over the median of its off-diagonal values: ``recognition_eccentricity.py``'s
``scored``). One nearest neighbour of the 109 queries moves J by about 0.003 (of the 280, about
0.0012). Then C and the two best combinations of each candidate after the set-level diffusion
re-ranking that ``gromov pairwise`` reports beside the EER (``diffusion_rerank``, k = 8, three
steps; each collection on its own).

``--orientation ignore`` reads the signatures along the map whose distortion the matrices hold
(``gh_matrix(keep=..., orientation="ignore")``: a mirror image as good as any), which also saves
``"prefer"``'s second match of a pair whose map is mirrored.

``--cache DIR`` keeps each collection's matrices, the matched samples' input vertex ids and the
signatures read along them, so that a stopped run continues and ``--working`` is added without
matching again. Resources, 2 cores: the subsets' signatures 1.7 min (watertight) and 3.8 min
(TOSCA's 50,000-vertex meshes); their diffusion matrices with every correspondence kept 12 and 7
min; the geodesic matrices 9 and 5.5 min. The whole collections (``--orientation ignore``): the
signatures 6.3 and 7.2 min, the matrices 72 and 13.4 min, the working meshes' signatures 2.2 and
1.3 min, and 20 GB of memory (every prepared shape's distances and every correspondence held at
once).
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(Path(__file__).resolve().parent))   # the sibling study it scores with

import bench_recognition as BR  # noqa: E402
from _common import add_data_argument, write_results  # noqa: E402
from recognition_eccentricity import scored, table  # noqa: E402

from gromov.errors import GromovWarning  # noqa: E402

SAMPLES = 50
OPTIONS = {**BR.GROMOV_METRIC, "units": "area"}
#: The signature's times, relative to the area.
TAUS = np.geomspace(0.001, 0.3, 12)
#: Eigenpairs of each input mesh's signature.
EIGENPAIRS = 150
BANDS = {"all": slice(None), "small": slice(0, 6), "mid": slice(3, 9), "large": slice(6, None)}
KEEPS = (0.8, 1.0)
WEIGHTS = (0.1, 0.15, 0.25, 0.35, 0.5)


def vertex_signature(path: str) -> tuple[np.ndarray, np.ndarray]:
    """``(input ids, (n, len(TAUS)))``: log(A k_t(x, x)) at every vertex of the loaded mesh."""
    import gromov

    BR._one_thread()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        mesh = gromov.load(path)
    L, M, area = BR.laplacian(mesh)
    lam, phi = BR.eigenpairs(L, M, EIGENPAIRS + mesh.n_components)
    return np.asarray(mesh.input_ids), heat_signature(lam, phi, area)


def heat_signature(lam: np.ndarray, phi: np.ndarray, area: float) -> np.ndarray:
    """``(n, len(TAUS))``: log(A k_t(x, x)) at t = tau A from the eigenpairs ``(lam, phi)``."""
    return np.log(area * ((phi**2) @ np.exp(-np.outer(np.maximum(lam, 0.0), TAUS * area))))


def working_signature(path: str) -> tuple[np.ndarray, np.ndarray]:
    """``(input ids, (n, len(TAUS)))``: the signature of gromov's working mesh of the file (3,000
    vertices, ``EIGENPAIRS`` eigenpairs of its cotangent Laplacian with lumped masses, as
    :func:`gromov.spectrum.spectrum` decomposes it), read at each input vertex's nearest working
    vertex in space: what a pair worker holding only the prepared shapes could compute."""
    from scipy.spatial import cKDTree

    from gromov._eigen import shift_invert_eigsh
    from gromov.metrics.diffusion import _laplacian
    from gromov.shape_metric import ShapeMetric

    BR._one_thread()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        s = ShapeMetric(path, "diffusion", resolution=3000, metric_options=OPTIONS)
    work, inp = s.mesh, s.input
    _, L, M, area = _laplacian(work, "cotan", "a heat kernel signature")
    lam, phi = shift_invert_eigsh(L, M, min(work.n_vertices - 2, EIGENPAIRS + work.n_components),
                                   sigma=-1e-2 / area)
    h = heat_signature(lam, phi, area)
    _, near = cKDTree(np.asarray(work.vertices)).query(np.asarray(inp.vertices))
    return np.asarray(inp.input_ids), h[near]


def _signatures(files: list[str], jobs: int, of=vertex_signature) -> list:
    if jobs < 2:
        return [of(f) for f in files]
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as pool:
        return list(pool.map(of, files))


def read_along(sig: list, pairs: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(a, b)``: per pair, the signatures of X at its samples and at Y's samples' images, and
    of Y at X's samples' images and at its samples (``ids``: per pair x_samples, y_to_x_vertex,
    x_to_y_vertex, y_samples)."""
    a = [np.vstack([_at(sig[i], d[0]), _at(sig[i], d[1])]) for (i, _), d in zip(pairs, ids)]
    b = [np.vstack([_at(sig[j], d[2]), _at(sig[j], d[3])]) for (_, j), d in zip(pairs, ids)]
    return np.stack(a).astype(np.float32), np.stack(b).astype(np.float32)


def _at(sig, ids: np.ndarray) -> np.ndarray:
    """The signature rows of the input (file) vertex ids ``ids``."""
    inputs, h = sig
    pos = np.full(int(inputs.max()) + 1, -1)
    pos[inputs] = np.arange(len(inputs))
    return h[pos[np.asarray(ids)]]


def matched(files: list[str], jobs: int, orientation: str = "prefer") -> dict:
    """The combined ranking's matrices, and each pair's signatures at its 2 x 50 sample pairs of
    the map ``gh_matrix(keep=..., orientation=orientation)`` returns."""
    from gromov.experiments.pairwise import gh_matrix

    t = time.perf_counter()
    sig = _signatures(files, jobs)
    t_sig = time.perf_counter() - t
    n = len(files)
    pairs = list(itertools.combinations(range(n), 2))
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        g = gh_matrix(files, "diffusion", n_samples=SAMPLES, resolution=3000, metric_options=OPTIONS, seed=0,
                      jobs=jobs, spectral=True, rank_by="combined", keep=pairs, orientation=orientation)
    t_match = time.perf_counter() - t
    ids = np.asarray([[r.x_samples, r.y_to_x_vertex, r.x_to_y_vertex, r.y_samples]
                      for r in (g.results[ij] for ij in pairs)], dtype=np.int64)
    a, b = read_along(sig, np.array(pairs), ids)
    return {"S": g.spectral, "G": g.trimmed, "GH": g.relative, "C": g.combined, "pairs": np.array(pairs),
            "a": a, "b": b, "ids": ids, "seconds_signatures": t_sig, "seconds_matrix": t_match}


def geodesic(files: list[str], jobs: int) -> dict:
    """The GH estimate and trimmed distortion of every pair matched with the geodesic metric, each
    mesh at unit area."""
    import gromov
    from gromov.experiments.pairwise import gh_matrix

    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        meshes = []
        for f in files:
            m = gromov.load(f)
            meshes.append(gromov.Mesh(np.asarray(m.vertices) / np.sqrt(m.area), m.faces))
        g = gh_matrix(meshes, "geodesic", n_samples=SAMPLES, resolution=3000, seed=0, jobs=jobs)
    return {"GEO": g.relative, "GEO_T": g.trimmed, "seconds_geodesic": time.perf_counter() - t}


def distortion(m: dict, band: slice, keep: float, along: str = "") -> np.ndarray:
    """``H``: per pair, the RMS of the best-fitting ``keep`` of the sample pairs' signature RMS
    differences over ``band`` (of the signatures ``m["a" + along]``, ``m["b" + along]``)."""
    n = len(m["S"])
    out = np.zeros((n, n))
    for (i, j), a, b in zip(m["pairs"], m["a" + along], m["b" + along]):
        r = np.sort(np.sqrt(np.mean((a[:, band] - b[:, band]) ** 2, axis=1)))
        out[i, j] = out[j, i] = np.sqrt(np.mean(r[:max(1, int(round(keep * len(r))))] ** 2))
    return out


def collection_matrices(data: Path, name: str, per_class: int, jobs: int, cache: Path, geo: bool,
                        orientation: str = "prefer", working: bool = False) -> dict:
    files, labels = BR.collection(data, name)
    keep = BR.class_subset(labels, per_class, 0)
    files, labels = [str(files[i]) for i in keep], labels[keep]
    path = cache / f"pointwise-{name}-{per_class}{'' if orientation == 'prefer' else '-' + orientation}.npz"
    if path.exists():
        z = np.load(path)
        m = {k: z[k] for k in z.files}
    else:
        m = matched(files, jobs, orientation)
        np.savez(path, **m)
    gpath = cache / f"pointwise-geodesic-{name}-{per_class}.npz"
    if geo:
        if gpath.exists():
            z = np.load(gpath)
            m.update({k: z[k] for k in z.files})
        else:
            gm = geodesic(files, jobs)
            np.savez(gpath, **gm)
            m.update(gm)
    if working and "a_working" not in m:   # from the matches' sample ids, no new match
        t = time.perf_counter()
        m["a_working"], m["b_working"] = read_along(_signatures(files, jobs, working_signature), m["pairs"], m["ids"])
        m["seconds_working"] = time.perf_counter() - t
        np.savez(path, **m)
    for band, k in itertools.product(BANDS, KEEPS):
        m[f"H_{band}_{k}"] = distortion(m, BANDS[band], k)
        if working:
            m[f"W_{band}_{k}"] = distortion(m, BANDS[band], k, "_working")
    print(f"{name}: {len(files)} shapes, signatures {float(m['seconds_signatures']):.0f} s, matrix "
          f"{float(m['seconds_matrix']):.0f} s" + (f", geodesic {float(m['seconds_geodesic']):.0f} s" if geo else ""),
          flush=True)
    m["labels"] = labels
    return m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--no-geodesic", action="store_true", help="skip the second (geodesic) match of every pair")
    ap.add_argument("--orientation", choices=("prefer", "ignore"), default="prefer",
                    help="the map the signatures are read along: 'ignore' is the one the matrix's values measure "
                         "(a mirror image as good as any), and saves the second match of a mirrored pair")
    ap.add_argument("--working", action="store_true",
                    help="also W: the signature of gromov's working meshes (cotangent Laplacian), read along the same "
                         "matches")
    ap.add_argument("--weights", default=",".join(map(str, WEIGHTS)),
                    help="the weights w of the candidate in C^(1-w) X^w, comma-separated")
    ap.add_argument("--cache", default="/tmp/recognition-pointwise")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "studies" / "recognition_pointwise.json"))
    args = ap.parse_args(argv)
    weights = [float(w) for w in args.weights.split(",")]
    if not all(0.0 < w < 1.0 for w in weights):
        ap.error(f"--weights must lie in (0, 1), got {args.weights}")
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    geo = not args.no_geodesic
    cols = {c: collection_matrices(Path(args.data), c, args.per_class, args.jobs, cache, geo, args.orientation,
                                     args.working)
            for c in ("watertight", "tosca")}
    extra = [f"{x}_{b}_{k}" for x in ("HW" if args.working else "H") for b, k in itertools.product(BANDS, KEEPS)] \
        + (["GEO", "GEO_T"] if geo else [])
    alone = {k: scored(cols, {k: 1}) for k in ["S", "G", "GH", "C"] + extra}
    mixes = {f"C^{round(1 - w, 2)} {x}^{w}": (x.split("_")[0], {"C": 1 - w, x: w}) for x in extra for w in weights}
    combos = {k: scored(cols, mix) for k, (_, mix) in mixes.items()}

    ranked = sorted(combos, key=lambda k: combos[k]["J"])
    table("alone (NN / FT / EER %):", alone.items())
    table("with the combined ranking, best J first:", [(k, combos[k]) for k in ranked[:12]])
    # the set-level diffusion that `gromov pairwise` reports beside the EER, on the best of each
    from gromov.experiments.recognition import diffusion_rerank

    best = {"C": {"C": 1}}
    for family in dict.fromkeys(mixes[k][0] for k in ranked):
        best.update((k, mixes[k][1]) for k in [k for k in ranked if mixes[k][0] == family][:2])
    rerank = {k: scored(cols, mix, then=diffusion_rerank) for k, mix in best.items()}
    table("after the diffusion re-ranking (k = 8, three steps):", rerank.items())
    seconds = {c: {k: float(m[k]) for k in ("seconds_signatures", "seconds_matrix", "seconds_geodesic",
                                            "seconds_working") if k in m}
               for c, m in cols.items()}
    write_results(args.json, {"per_class": args.per_class, "orientation": args.orientation, "samples": SAMPLES,
                              "weights": weights, "taus": TAUS.tolist(),
                              "eigenpairs": EIGENPAIRS, "bands": {b: [s.start, s.stop] for b, s in BANDS.items()},
                              "shapes": {c: len(m["labels"]) for c, m in cols.items()}, "seconds": seconds,
                              "alone": alone, "combinations": combos, "diffusion_reranked": rerank})
    return 0


if __name__ == "__main__":
    sys.exit(main())
