"""The commands on a collection of shapes: ``gromov index`` (a shape store), ``gromov search``
(a query's nearest shapes in it) and ``gromov pairwise`` (all pairs: nearest neighbours, EER,
an MDS map)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from .._atomic import atomic_path, atomic_savez_compressed
from .._defaults import (DEFAULT_RESOLUTION, DIFFUSION_RERANK_K, DIFFUSION_RERANK_STEPS, PROFILE_SLACK, RANK_RESIDUAL,
                         RANK_RESIDUALS, RANK_TAU_SCALE, TRIANGLE_SLACK)
from ..errors import GromovError
from ._args import (_add_input_args, _add_metric_args, _add_rank_args, _metric_options, _nonnegative_float,
                    _nonnegative_int, _positive_float, _positive_int, _rank_tau_scale, _sample_count, _working_size)
from ._common import (_UserError, _check_folder, _check_memory, _check_neighbors, _check_pieces, _check_png, _count, _dumps,
                      _load, _stem, _store_of)


def class_from_name(path: str) -> str:
    """A shape's class read from its file name: the stem without trailing digits and
    separators (``cat0.off.gz`` -> ``cat``, ``kid_12.ply`` -> ``kid``); the whole stem when
    nothing is left."""
    stem = _stem(path)
    cls = stem.rstrip("0123456789").rstrip("-_., ")
    return cls or stem


def _short_names(paths: list[str]) -> list[str]:
    """Names to draw beside the shapes: the file stems, or, where two stems are equal, the
    shortest trailing parts of the paths that tell them apart."""
    parts = [Path(p).parts[:-1] + (_stem(p),) for p in paths]
    names = []
    for i, pp in enumerate(parts):
        for k in range(1, len(pp) + 1):
            tail = pp[-k:]
            if all(q[-k:] != tail for j, q in enumerate(parts) if j != i):
                break
        names.append("/".join(tail))
    return names


def _stored_shapes(store, args, options: dict, progress: bool, files: list | None = None) -> list:
    """Each file's ShapeMetric from the store (loaded and computed only when not stored yet),
    checked as ``pairwise`` checks loaded files. ``files``: these instead of ``args.files``."""
    files = list(args.files if files is None else files)
    if getattr(args, "neighbors", None) is not None:   # (a user error found before any metric)
        _check_neighbors(args, [_load(f, args) for f in files])
    shapes = store.shapes(files, args.metric, resolution=args.resolution, metric_options=options,
                          rank_tau_scale=args.rank_tau_scale, progress=progress)
    for path, s in zip(files, shapes):
        if getattr(args, "samples", 0) > s.mesh.n_vertices:
            raise _UserError(f"--samples {args.samples} is more than the {s.mesh.n_vertices} vertices "
                             f"of the working set of {path}")
    return shapes


def cmd_index(args) -> int:
    options = _metric_options(args)
    t = time.perf_counter()
    with _store_of(args) as store:
        _stored_shapes(store, args, options, progress=not args.quiet)
        size = sum(e.bytes for e in store.entries())
    if not args.quiet:
        n = len(args.files)
        print(f"{n} file{'s' if n != 1 else ''} in {args.store}: {store.computed} computed, {store.reused} "
              f"read back; {time.perf_counter() - t:.1f} s; {size / 1e6:.1f} MB of entries")
    return 0


def _index_parser(sub) -> None:
    q = sub.add_parser("index", help="compute each shape's working mesh and metric once and keep "
                                     "them in a shape store, for pairwise --store")
    q.add_argument("files", nargs="+", metavar="FILE", help="meshes or point clouds")
    q.add_argument("--store", required=True, metavar="DIR",
                   help="the store's folder (created if missing): catalogue.sqlite and one .npz "
                        "per shape and set of options")
    _add_metric_args(q)
    q.add_argument("--resolution", type=_working_size, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION})")

    q.add_argument("--rank-tau-scale", type=_rank_tau_scale, default=RANK_TAU_SCALE, metavar="S",
                   help=f"heat-kernel diffusion: also keep the heat distance at S times the diffusion "
                        f"time that pairwise ranks by (default {RANK_TAU_SCALE:g}, as pairwise)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    _add_input_args(q)
    q.set_defaults(func=cmd_index)


def cmd_search(args) -> int:
    from ..retrieval import nearest

    _metric_by_partial(args)
    if not (Path(args.store) / "catalogue.sqlite").is_file():
        raise _UserError(f"no shape store in {args.store}: gromov index FILES --store {args.store} makes one")
    if args.partial:
        return _search_partial(args)
    options = _metric_options(args)
    t = time.perf_counter()
    with _store_of(args) as store:
        r = nearest(args.query, store, args.k, args.metric, n_samples=args.samples, seed=args.seed,
                    resolution=args.resolution, metric_options=options, rank_by=args.rank_by,
                    rank_tau_scale=args.rank_tau_scale, rank_residual=args.rank_residual, prune=args.prune,
                    slack=args.slack, triangle_slack=args.triangle_slack, candidates=args.candidates,
                    progress=not (args.quiet or args.json))
    seconds = time.perf_counter() - t
    if args.json:
        print(_dumps({"query": args.query, "store": args.store, "k": args.k, **r.to_dict(),
                      "seconds": seconds}))
        return 0
    n = r.full_matches + r.skipped
    what = _RANKED_WORDS[args.rank_by]
    if args.candidates is not None:
        how = f"the {args.candidates} nearest by spectral distance matched" + (
            f", then neighbour descent over {r.known_pairs:,} recorded distances between them" if r.known_pairs else
            "; no distances between them recorded for a neighbour descent (gromov pairwise --store records them)") \
            + ": not exact"
    else:
        how = ("exact" if r.exact else "by the profile gap" + (f" and {r.known_pairs:,} recorded distances between "
                                                              "them" if r.known_pairs else "") + ": not exact")
    print(f"{len(r.neighbors)} nearest of {n} shapes by {what}; {r.full_matches} matched, {r.skipped} "
          f"skipped ({how}), {seconds:.1f} s")
    width = max(len(x.name) for x in r.neighbors)
    for i, x in enumerate(r.neighbors, 1):
        print(f"  {i:>2}. {x.name:<{width}}  {x.distance:.4%}")
    return 0


def _search_parser(sub) -> None:
    q = sub.add_parser("search", help="the shapes of a shape store nearest to a query, skipping the "
                                      "pairs a per-shape bound rules out")
    q.add_argument("query", help="a mesh or point cloud (left out of its own results if it is in the store)")
    q.add_argument("--store", required=True, metavar="DIR", help="a shape store made by gromov index")
    q.add_argument("-k", type=_positive_int, default=5, help="neighbours to return (default 5)")
    _add_metric_args(q)
    q.add_argument("--resolution", type=_working_size, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count the store was indexed with (default {DEFAULT_RESOLUTION})")
    q.add_argument("--samples", type=_sample_count, default=100, help="samples per shape (default 100)")
    q.add_argument("--seed", type=_nonnegative_int, default=0)
    q.add_argument("--rank-by", choices=("trimmed", "gh", "combined"), default="trimmed",
                   help="rank by the trimmed distortion of each pair's correspondence (default, as "
                        "pairwise), by the GH estimate, or by the trimmed distortion, the spectral "
                        "distance (Shape-DNA) and the heat kernel signature's distortion together "
                        "(every candidate matched, unless --candidates)")
    q.add_argument("--rank-tau-scale", type=_rank_tau_scale, default=RANK_TAU_SCALE, metavar="S",
                   help=f"heat-kernel diffusion: the trimmed ranking's heat distance at S times the "
                        f"diffusion time (default {RANK_TAU_SCALE:g}, as pairwise and index)")
    q.add_argument("--rank-residual", choices=RANK_RESIDUALS, default=RANK_RESIDUAL,
                   help=f"log ratios or differences of corresponding distances (default {RANK_RESIDUAL})")
    q.add_argument("--prune", choices=("profile", "bound", "none"), default="profile",
                   help="skip the shapes whose lower bound or profile gap rules them out (profile: "
                        "default; recall 1.0 on the validation sets, not guaranteed), only those "
                        "whose lower bound does (bound: the same neighbours as matching every "
                        "shape), or none")
    q.add_argument("--slack", type=_positive_float, default=PROFILE_SLACK, metavar="S",
                   help="--prune profile: skip a shape when S times its profile gap exceeds the "
                        f"k-th distance found (default {PROFILE_SLACK:g}; larger skips more)")
    q.add_argument("--triangle-slack", type=_nonnegative_float, default=TRIANGLE_SLACK, metavar="T",
                   help="--prune profile: skip a shape also when T times |d(query, m) - d(m, shape)| "
                        "exceeds the k-th distance found, for the shapes m matched so far whose "
                        "distance to it the store has recorded (gromov pairwise records them; "
                        f"default {TRIANGLE_SLACK:g}; 0: off)")
    q.add_argument("--candidates", type=_positive_int, default=None, metavar="C",
                   help="a two-stage search: match the C shapes nearest to the query by spectral "
                        "distance (Shape-DNA, kept in the store once computed), all of them; then, "
                        "where the store holds values between its shapes (gromov pairwise "
                        "--candidates C -k K records them), the 1.5 K nearest of the query's 1.5 K "
                        "nearest found, in rounds until none is new (neighbour descent); --prune "
                        "is not used")
    q.add_argument("--partial", action="store_true",
                   help="the query is a part (a cut or holed shape): match it as the part into every "
                        "stored shape (gromov match --partial) and rank them by the partial distance "
                        "relative to each one's diameter, divided by the share of its area the part "
                        "covers; every stored shape is matched "
                        "(no pruning: the bounds hold for full matches); metric geodesic by default")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_input_args(q)
    _partial_metric_default(q)
    q.set_defaults(func=cmd_search)


#: How the text output names what pairs are ranked by, and the .csv's corner cell.
_RANKED_WORDS = {"trimmed": "trimmed distortion", "gh": "GH distance", "combined": "combined distance"}
_MATRIX_NAME = {"trimmed": "relative_trimmed_distance", "gh": "relative_distance", "combined": "combined_distance"}


def cmd_pairwise(args) -> int:
    _metric_by_partial(args)
    if args.partial:
        return _pairwise_partial(args)
    n = len(args.files)
    labels, k_local, dask = _pairwise_arguments(args, n)
    # a shape that cannot be used is left out, with its reason; the others go on
    loaded, unusable = _usable_shapes(args)
    files = [f for f in args.files if f not in unusable]
    _check_usable(files, n, unusable)
    _check_neighbors(args, list(loaded.values()))
    options = _metric_options(args)
    r, files, store, seconds = _pairwise_run(args, files, loaded, unusable, options, dask)
    for f, why in unusable.items():
        print(f"gromov: skipped {f}: {why}", file=sys.stderr)
    if unusable:
        keep = [i for i, f in enumerate(args.files) if f not in unusable]
        labels = None if labels is None else [labels[i] for i in keep]
    D = r.ranked(args.rank_by)
    result, nearest = _pairwise_result(args, r, files, unusable, labels, options, store, seconds, D)
    if labels is not None:
        _add_recognition(result, args, r, D, nearest, k_local)
    _write_pairwise(args, r, result, D)
    status = 1 if unusable and args.strict else 0
    if args.json:
        print(_dumps(result))
        return status
    _print_pairwise(args, r, result, nearest, store)
    return status


def _pairwise_arguments(args, n: int) -> tuple[list[str] | None, int, bool]:
    """``(labels, k_local, dask)``: ``pairwise``'s arguments checked before any file is read
    (each file once, labels, ``--local-scaling``, ``--diffusion-rerank``, ``--out``, ``--mds``, ``-k``,
    Dask)."""
    from ..experiments.recognition import LOCAL_SCALING_K

    if n < 2:
        raise _UserError("pairwise needs at least two meshes")
    import os

    real = [os.path.realpath(f) for f in args.files]
    if len(set(real)) < n:
        dup = sorted({f for f, r in zip(args.files, real) if real.count(r) > 1})
        raise _UserError(f"a file is given twice: {', '.join(dup)}")
    labels = _pairwise_labels(args, n)
    for flag, value, sets in (("--local-scaling", args.local_scaling, "the neighbour of the locally scaled EER"),
                              ("--diffusion-rerank", args.diffusion_rerank, "the neighbours of the re-ranked EER")):
        if value is not None and labels is None:
            raise _UserError(f"{flag} sets {sets}: give --labels or --labels-from-names")
    k_local = LOCAL_SCALING_K if args.local_scaling is None else args.local_scaling
    if args.out:
        if not args.out.endswith((".npz", ".csv")):
            raise _UserError(f"--out must end in .npz or .csv, got {args.out!r}")
        if Path(args.out).is_dir():
            raise _UserError(f"--out {args.out} is a folder")
        _check_folder(args.out, "--out")
    if args.k is not None and args.mds:
        raise _UserError("--mds needs every pair; -k matches only each shape's nearest")
    if args.candidates is not None and args.mds:
        raise _UserError("--mds needs every pair; --candidates matches only each shape's candidates")
    if args.candidates is not None and args.k is not None and args.candidates < args.k:
        raise _UserError(f"--candidates ({args.candidates}) must be at least -k ({args.k})")
    if args.mds:
        _check_png(args.mds, "--mds")
        if n < 3:
            raise _UserError("--mds needs at least three shapes")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise _UserError("--mds needs matplotlib: pip install 'gromov[plot]'") from None
    dask = args.dask is not None or args.scheduler is not None
    if dask and args.k is not None:
        raise _UserError(f"-k is not available with {'--dask' if args.dask is not None else '--scheduler'}: "
                         "use --jobs")
    if dask and (args.candidates is not None or args.rank_by == "combined"):
        what = "--candidates" if args.candidates is not None else "--rank-by combined"
        raise _UserError(f"{what} is not available with {'--dask' if args.dask is not None else '--scheduler'}: "
                         "use --jobs")
    if dask:
        import importlib.util

        if importlib.util.find_spec("distributed") is None:
            raise _UserError(f"{'--dask' if args.dask is not None else '--scheduler'} needs dask.distributed: "
                             "pip install 'gromov[dask]'")
    return labels, k_local, dask


def _pairwise_run(args, files: list, loaded: dict, unusable: dict, options: dict, dask: bool):
    """``(PairwiseGH, files, store, seconds)``: the matrices of the usable files, the store open
    for the run. Where a shape's metric cannot be computed, that shape is added to ``unusable``
    with its reason and the others are matched without it."""
    with _store_of(args) as store:
        if store is None and not dask:   # (with Dask the matrices are on the workers)
            _check_memory([min(args.resolution, loaded[f].n_vertices) for f in files],
                          f"--resolution {args.resolution}")
        t = time.perf_counter()
        try:
            r = _pairwise_matrix(args, files, loaded, store, options, dask)
        except GromovError:   # a shape's metric cannot be computed: find which, go on without them
            failed = _failing_shapes(args, files, loaded, options)
            if not failed:
                raise
            unusable.update(failed)
            files = [f for f in files if f not in failed]
            _check_usable(files, len(args.files), unusable)
            r = _pairwise_matrix(args, files, loaded, store, options, dask)
    return r, files, store, time.perf_counter() - t


def _pairwise_result(args, r, files: list, unusable: dict, labels, options: dict, store, seconds: float,
                     D: np.ndarray) -> tuple[dict, np.ndarray]:
    """``(result, nearest)``: the JSON object of ``pairwise --json`` (without the recognition's
    fields) and each shape's nearest other by ``D``, the matrix the results rank by."""
    n = len(files)
    # (with -k the pairs not matched are NaN: never nearest)
    nearest = np.argmin(np.where(np.isnan(D), np.inf, D) + np.diag(np.full(n, np.inf)), axis=1)
    names = list(files)
    result = {"files": names, "skipped": unusable, "metric": args.metric, "metric_options": options,
              "n_samples": args.samples, "resolution": args.resolution, "seed": args.seed,
              "ranked_by": args.rank_by, "rank_tau_scale": r.rank_tau_scale,
              "rank_residual": r.rank_residual,
              "distance": r.distance.tolist(), "relative_distance": r.relative.tolist(),
              "relative_trimmed_distance": r.trimmed.tolist(),
              "nearest": [names[j] for j in nearest], "labels": labels,
              "seconds": seconds}
    if r.spectral is not None:
        result.update(spectral_distance=r.spectral.tolist(), signature_distortion=r.signature.tolist(),
                      combined_distance=r.combined.tolist())
    if args.k is not None or args.candidates is not None:
        result.update(k=args.k, candidates=args.candidates, pairs_matched=n * (n - 1) // 2 - r.skipped,
                      pairs_skipped=r.skipped)
    if store is not None:
        result["store"] = {"path": args.store, "shapes_read": store.reused, "pairs_read": store.pairs_reused}
    return result, nearest


def _add_recognition(result: dict, args, r, D: np.ndarray, nearest: np.ndarray, k_local: int) -> None:
    """With labels: the nearest-neighbour accuracy and, where every pair was matched and there
    are two shapes of a class and two classes, the equal error rates (ranked by ``D``, by the
    other matrix, after local scaling and after the diffusion re-ranking) and the errors at the
    threshold, into ``result``."""
    from ..experiments.recognition import diffusion_roc, errors_at, local_roc, roc

    lab = np.array(result["labels"])
    n = len(lab)
    result["nn_accuracy"] = float(np.mean(lab[nearest] == lab))
    same = (lab[:, None] == lab[None, :])[np.triu_indices(n, 1)]
    result.update(eer=None, eer_gh=None, eer_trimmed=None, errors_at_eer=None, eer_local=None,
                  local_scaling_k=None, errors_at_eer_local=None, eer_diffusion=None, diffusion_rerank_k=None)
    every_pair = args.k is None and args.candidates is None or not r.skipped
    if same.any() and not same.all() and every_pair:   # else all one class, or every shape its
        # own, or not every pair matched (a search that met every pair scores as the full matrix): no EER
        curves = {k: roc(r.ranked(k), lab) for k in ("trimmed", "gh", args.rank_by)}
        local, scaled, k_used = local_roc(D, lab, k_local)   # warns if k >= the smallest class
        result.update(eer=curves[args.rank_by].eer, eer_gh=curves["gh"].eer,
                      eer_trimmed=curves["trimmed"].eer,
                      errors_at_eer=errors_at(D, lab, curves[args.rank_by].eer_threshold),
                      eer_local=local.eer, local_scaling_k=k_used,
                      errors_at_eer_local=errors_at(scaled, lab, local.eer_threshold))
        k_diffusion = DIFFUSION_RERANK_K if args.diffusion_rerank is None else args.diffusion_rerank
        diffused, _, k_used = diffusion_roc(D, lab, k_diffusion)
        result.update(eer_diffusion=diffused.eer, diffusion_rerank_k=k_used)


def _write_pairwise(args, r, result: dict, D: np.ndarray) -> None:
    """``--out`` (.npz with every matrix, or .csv with ``D``, the one the results rank by) and
    ``--mds`` (a 2-D MDS map of ``D``)."""
    names, labels, n = result["files"], result["labels"], len(result["files"])
    if args.out:
        out = Path(args.out)
        if out.suffix == ".csv":   # the matrix the results rank by, named in the corner cell
            _write_csv(out, names, D, _MATRIX_NAME[args.rank_by])
        else:
            nan = float("nan")
            extra = {} if r.spectral is None else {"spectral_distance": r.spectral,
                                                   "signature_distortion": r.signature,
                                                   "combined_distance": r.combined}
            atomic_savez_compressed(out, files=np.array(names), distance=r.distance, **extra,
                                    relative_distance=r.relative, relative_trimmed_distance=r.trimmed,
                                    labels=np.array(labels if labels is not None else [], dtype=str),
                                    ranked_by=args.rank_by, nearest=np.array(result["nearest"]),
                                    eer=nan if result.get("eer") is None else result["eer"],
                                    eer_local=nan if result.get("eer_local") is None else result["eer_local"],
                                    local_scaling_k=result.get("local_scaling_k") or 0,
                                    eer_diffusion=nan if result.get("eer_diffusion") is None
                                    else result["eer_diffusion"],
                                    diffusion_rerank_k=result.get("diffusion_rerank_k") or 0,
                                    metric=args.metric, options=json.dumps(result["metric_options"]),
                                    rank_tau_scale=nan if r.rank_tau_scale is None else r.rank_tau_scale,
                                    rank_residual=r.rank_residual,
                                    n_samples=args.samples, resolution=args.resolution, seed=args.seed)
    if args.mds:
        from ..experiments.recognition import mds_map, plot_mds

        what = _RANKED_WORDS[args.rank_by]
        plot_mds(mds_map(D, 2, seed=args.seed), labels if labels is not None else ["shapes"] * n,
                 args.mds, names=_short_names(names),
                 title=f"MDS of {n} shapes, {args.metric}, {what}")


def _print_pairwise(args, r, result: dict, nearest: np.ndarray, store) -> None:
    """``pairwise``'s text output: the run, each shape's nearest, the recognition's scores and
    the files written."""
    names, labels, unusable = result["files"], result["labels"], result["skipped"]
    n = len(names)
    what = _RANKED_WORDS[args.rank_by]
    if args.candidates is not None:
        pairs = (f"{n * (n - 1) // 2 - r.skipped} of {n * (n - 1) // 2} pairs matched (each shape's "
                 f"{args.candidates} candidates by spectral distance)")
    elif args.k is not None:
        pairs = f"{n * (n - 1) // 2 - r.skipped} of {n * (n - 1) // 2} pairs matched (each shape's {args.k} nearest)"
    else:
        pairs = _count(n * (n - 1) // 2, "pair")
    left_out = f" ({len(unusable)} left out: see above)" if unusable else ""
    print(f"{n} shapes{left_out}, {pairs}, {args.metric} metric, {args.samples} samples per "
          f"shape, {result['seconds']:.1f} s; relative GH distance (÷ the larger diameter); nearest by {what}")
    if store is not None:
        print(f"  store {args.store}: {store.reused} of {n} shapes and {store.pairs_reused} of "
              f"{n * (n - 1) // 2} pairs read from it")
    width = max(len(f) for f in names)
    for i, f in enumerate(names):
        j = nearest[i]
        mark = ""
        if labels is not None and labels[j] != labels[i]:
            mark = f"   <- another class ({labels[i]} vs {labels[j]})"
        print(f"  {f:<{width}}  nearest {names[j]} ({r.relative[i, j]:.4%}; trimmed "
              f"{r.trimmed[i, j]:.4%}){mark}")
    if labels is not None:
        if result["eer"] is None:
            why = ("needs every pair; --candidates matched only each shape's candidates"
                   if args.candidates is not None else
                   "needs every pair; -k matched only each shape's nearest" if args.k is not None else
                   "needs two shapes of a class and two classes")
            print(f"  labels: no equal error rate ({why}); "
                  f"nearest-neighbour accuracy {result['nn_accuracy']:.1%}")
        else:
            if args.rank_by == "combined":
                others = f"trimmed distortion: {result['eer_trimmed']:.2%}; GH distance: {result['eer_gh']:.2%}"
            else:
                other = result["eer_gh"] if args.rank_by == "trimmed" else result["eer_trimmed"]
                others = f"ranked by the other: {other:.2%}"
            print(f"  equal error rate {result['eer']:.2%} ({others}; "
                  f"locally scaled, k = {result['local_scaling_k']}: {result['eer_local']:.2%}; "
                  f"diffusion re-ranked, k = {result['diffusion_rerank_k']}: {result['eer_diffusion']:.2%}), "
                  f"nearest-neighbour accuracy {result['nn_accuracy']:.1%}")
            from ..experiments.report import errors_text

            print(f"  at its threshold: {errors_text(result['errors_at_eer'])}")
    for f in (args.out, args.mds):
        if f:
            print(f"  wrote {Path(f)}")


def _pairwise_labels(args, n: int) -> list[str] | None:
    if args.labels is not None and args.labels_from_names:
        raise _UserError("give either --labels or --labels-from-names, not both")
    if args.labels_from_names:
        return [class_from_name(f) for f in args.files]
    if args.labels is None:
        return None
    labels = [x.strip() for x in args.labels.split(",")]
    if len(labels) != n or not all(labels):
        raise _UserError(f"--labels needs one non-empty label per file ({n}), got {len(labels)}: "
                         f"{args.labels!r}")
    return labels


def _one_line(exc: BaseException) -> str:
    """An error's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _check_usable(files: list, n: int, unusable: dict) -> None:
    """A user error naming every left-out file when fewer than two of the ``n`` remain."""
    if len(files) < 2:
        raise _UserError(f"pairwise needs at least two usable shapes; {len(files)} of {n} can be used ("
                         + "; ".join(f"{f}: {why}" for f, why in unusable.items()) + ")")


def _usable_shapes(args) -> tuple[dict, dict]:
    """``({file: shape}, {file: why not})``: each file of a collection loaded and checked as
    ``pairwise`` needs it (read, enough working vertices for ``--samples``, finite distances
    between its pieces); a file that fails is named with its reason and the others go on."""
    loaded, unusable = {}, {}
    for path in args.files:   # meshes or point clouds (their images are then points)
        try:
            shape = _load(path, args)
            work = min(args.resolution, shape.n_vertices)
            if args.samples > work:
                raise _UserError(f"--samples {args.samples} is more than the {work} vertices of its "
                                 "working set")
            _check_pieces(args, path, shape)   # simplification keeps the components
        except (GromovError, _UserError, OSError) as exc:
            unusable[path] = _one_line(exc).removeprefix(f"{path}: ")
            continue
        loaded[path] = shape
    return loaded, unusable


def _pairwise_matrix(args, files: list, loaded: dict, store, options: dict, dask: bool):
    """:func:`gromov.experiments.gh_matrix` of the usable files, as ``pairwise``'s options say."""
    from ..experiments.pairwise import available_cpus, gh_matrix

    if store is None and not dask:
        shapes = [loaded[f] for f in files]
    elif dask:   # each worker reads its shapes from the store, or computes and adds them
        shapes = list(files)
    else:   # read from the store; loaded and computed only when not stored yet
        shapes = _stored_shapes(store, args, options, progress=not (args.quiet or args.json), files=files)
    if dask:
        from .._dask import client_for

        cluster = client_for(scheduler=args.scheduler, n_workers=args.dask)
    else:
        import contextlib

        cluster = contextlib.nullcontext()
    with cluster as client:
        return gh_matrix(shapes, args.metric, n_samples=args.samples, resolution=args.resolution,
                         metric_options=options, seed=args.seed, jobs=args.jobs or available_cpus(),
                         progress=not (args.quiet or args.json), rank_tau_scale=args.rank_tau_scale,
                         rank_residual=args.rank_residual, store=store, client=client, k=args.k,
                         candidates=args.candidates, spectral=args.rank_by == "combined", rank_by=args.rank_by)


def _failing_shapes(args, files: list, loaded: dict, options: dict) -> dict:
    """``{file: why}`` for the files whose metric cannot be computed, each tried on its own."""
    from ..experiments.pairwise import prepare

    failed = {}
    for f in files:
        try:
            prepare([loaded[f]], args.metric, n_samples=args.samples, seed=args.seed,
                    resolution=args.resolution, metric_options=options,
                    rank_tau_scale=args.rank_tau_scale)
        except GromovError as exc:
            failed[f] = _one_line(exc).removeprefix(f"{f}: ")
    return failed


def _write_csv(path: Path, names: list[str], matrix: np.ndarray, what: str) -> None:
    import csv

    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([what] + names)
        for name, row in zip(names, matrix):
            w.writerow([name] + [repr(float(v)) for v in row])


def _pairwise_parser(sub) -> None:
    q = sub.add_parser("pairwise", help="Gromov-Hausdorff distances between all pairs of a set of "
                                        "shapes; nearest neighbours, EER and an MDS map")
    q.add_argument("files", nargs="+", metavar="FILE", help="meshes (two or more)")
    _add_metric_args(q)
    q.add_argument("--samples", type=_sample_count, default=100, help="samples per shape (default 100)")
    q.add_argument("--resolution", type=_working_size, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION})")
    q.add_argument("--seed", type=_nonnegative_int, default=0)
    q.add_argument("--strict", action="store_true",
                   help="exit with status 1 when a shape cannot be used (by default it is named "
                        "with its reason, left out, and the others are matched)")
    workers = q.add_mutually_exclusive_group()
    workers.add_argument("--jobs", type=_positive_int, default=None,
                         help="worker processes for the pairs (default: the CPUs available); "
                              "refused with --dask or --scheduler")
    workers.add_argument("--dask", type=_positive_int, default=None, metavar="N",
                         help="run on a Dask cluster of N worker processes of one thread each, "
                              "started on this machine for this run: each worker computes (or reads "
                              "from --store) its share of the shapes and keeps them, and each pair "
                              "runs where its shapes are; the same results as --jobs "
                              "(pip install 'gromov[dask]')")
    workers.add_argument("--scheduler", default=None, metavar="ADDRESS",
                         help="run on the workers of the running Dask scheduler at ADDRESS (e.g. "
                              "tcp://host:8786), as --dask does; they must see the files and --store "
                              "at the same absolute paths")
    q.add_argument("--labels", default=None, metavar="L,L,...",
                   help="the class of each file, in order: adds the equal error rate and the "
                        "nearest-neighbour accuracy")
    q.add_argument("--labels-from-names", action="store_true",
                   help="classes from the file names without trailing digits (cat0.off -> cat)")
    q.add_argument("--rank-by", choices=("trimmed", "gh", "combined"), default="trimmed",
                   help="nearest neighbours, EER and MDS by the trimmed distortion of each pair's "
                        "correspondence (default, as gromov reproduce), by the GH estimate, or by "
                        "the trimmed distortion, the spectral distance (Shape-DNA) and the heat "
                        "kernel signature's distortion together")
    _add_rank_args(q)
    q.add_argument("--diffusion-rerank", type=_positive_int, default=None, metavar="K",
                   help=f"the EER is also reported after a diffusion on the shapes' K-nearest "
                        f"neighbour graph ({DIFFUSION_RERANK_STEPS} steps; Donoser & Bischof 2013): "
                        f"shapes that share near neighbours come closer (a set-level rule, beside the "
                        f"EER; capped at the number of shapes less one; default {DIFFUSION_RERANK_K}; "
                        f"needs labels)")
    q.add_argument("--out", default=None, metavar="FILE",
                   help=".npz with all matrices, or .csv with the matrix the results rank by "
                        "(named in its first cell)")
    q.add_argument("--mds", default=None, metavar="FILE.png", help="draw a 2-D MDS map of the shapes")
    q.add_argument("-k", "--nearest", dest="k", type=_positive_int, default=None, metavar="K",
                   help="match only the pairs that can be among some shape's K nearest (the pruning "
                        "of gromov search: recall 1.0 on the validation sets, not guaranteed); the "
                        "others are empty (NaN) in the matrices and not counted; no equal error rate "
                        "or MDS map (they need every pair); refused with --dask or --scheduler")
    q.add_argument("--candidates", type=_positive_int, default=None, metavar="C",
                   help="a two-stage search: match only the pairs in which one shape is among the "
                        "other's C nearest by spectral distance (Shape-DNA, one eigendecomposition "
                        "per shape); with -k K, then the pairs of each shape with the 1.5 K nearest "
                        "of its 1.5 K nearest found, in rounds until none is new (neighbour "
                        "descent; C = 2 K is a good choice); the others are empty (NaN); no equal "
                        "error rate or MDS map; refused with --dask or --scheduler")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.add_argument("--store", default=None, metavar="DIR",
                   help="shape store (gromov index): read each shape's metric from it or add it, "
                        "and record each pair as it finishes; a run stopped at any point continues "
                        "where it stopped")
    q.add_argument("--partial", action="store_true",
                   help="the shapes are parts (cut or holed) and wholes: match each shape as the part "
                        "into every other (gromov match --partial; n (n - 1) ordered pairs, one after "
                        "the other) and rank each part's wholes by the partial distance relative to "
                        "the whole's diameter, divided by the share of its area the part covers; "
                        "metric geodesic by default; refused "
                        "with -k, --candidates, --rank-by, --mds, --jobs and Dask")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_input_args(q)
    _partial_metric_default(q)
    q.set_defaults(func=cmd_pairwise)


def _partial_metric_default(q) -> None:
    """``--metric``'s default: diffusion, or with ``--partial`` the partial match's (geodesic)."""
    for action in q._actions:
        if action.dest == "metric":
            action.default, action.help = None, "distance on the surface (default: diffusion; with --partial geodesic)"


def _metric_by_partial(args) -> None:
    if args.metric is None:
        from ..partial import PARTIAL_METRIC

        args.metric = PARTIAL_METRIC if args.partial else "diffusion"


def _refuse_with_partial(refused: dict) -> None:
    """A user error for the first option that ``--partial`` does not take: ``refused`` is
    ``{option: (given, why not)}``."""
    for option, (given, why) in refused.items():
        if given:
            raise _UserError(f"{option} is not available with --partial: {why}")


def _pairwise_partial(args) -> int:
    """``pairwise --partial``: each shape matched as a part into every other
    (:func:`gromov.partial.partial_matrix`), each part's nearest whole by the partial distance."""
    from ..mesh import Mesh
    from ..metrics.diffusion import correspondence_options
    from ..partial import SMALL_PART, partial_matrix

    every = "every ordered pair is matched"
    refused = {"-k": (args.k is not None, every), "--candidates": (args.candidates is not None, every),
               "--rank-by": (args.rank_by != "trimmed", "the shapes are ranked by the partial distance"),
               "--rank-tau-scale": (args.rank_tau_scale != RANK_TAU_SCALE, "it sets the ranking of full matches"),
               "--rank-residual": (args.rank_residual != RANK_RESIDUAL, "it sets the ranking of full matches"),
               "--local-scaling": (args.local_scaling is not None, ("it scales the equal error rate, which a "
                                                                    "distance that is not symmetric does not have")),
               "--diffusion-rerank": (args.diffusion_rerank is not None,
                                      "it re-ranks a symmetric distance, which the partial one is not"),
               "--mds": (args.mds is not None, "the partial distance is not symmetric"),
               "--jobs": (args.jobs is not None, "the pairs run one after the other in this process"),
               "--dask": (args.dask is not None, "the pairs run one after the other in this process"),
               "--scheduler": (args.scheduler is not None, "the pairs run one after the other in this process")}
    _refuse_with_partial(refused)
    n = len(args.files)
    labels, _, _ = _pairwise_arguments(args, n)
    loaded, unusable = _usable_shapes(args)
    for f, shape in loaded.items():
        if not isinstance(shape, Mesh):
            unusable[f] = "a point cloud: --partial matches triangle meshes"
    files = [f for f in args.files if f not in unusable]
    _check_usable(files, n, unusable)
    options = _metric_options(args)
    progress = not (args.quiet or args.json)
    t = time.perf_counter()
    with _store_of(args) as store:
        if store is None:
            _check_memory([min(args.resolution, loaded[f].n_vertices) for f in files],
                          f"--resolution {args.resolution}")
            shapes = [loaded[f] for f in files]
        else:   # each shape's metric in the correspondence's options, as match --partial --store
            shapes = store.shapes(files, args.metric, resolution=args.resolution,
                                  metric_options=correspondence_options(args.metric, options), progress=progress)
        m = partial_matrix(shapes, None, args.metric, n_samples=args.samples, seed=args.seed,
                           resolution=args.resolution, metric_options=options, names=files, progress=progress)
    seconds = time.perf_counter() - t
    for f, why in unusable.items():
        print(f"gromov: skipped {f}: {why}", file=sys.stderr)
    if unusable and labels is not None:
        labels = [lab for f, lab in zip(args.files, labels) if f not in unusable]
    nearest = m.nearest
    result = {"files": files, "skipped": unusable, "partial": True, "metric": args.metric, "metric_options": options,
              "n_samples": args.samples, "resolution": args.resolution, "seed": args.seed,
              "ranked_by": "ranking_distance/covered_fraction", "score": m.score.tolist(), "distance": m.distance.tolist(),
              "relative_distance": m.relative_distance.tolist(), "ranking_distance": m.ranking_distance.tolist(),
              "covered_fraction": m.covered_fraction.tolist(),
              "area_ratio": m.area_ratio.tolist(), "small_part": SMALL_PART,
              "nearest": [files[j] for j in nearest], "labels": labels, "seconds": seconds}
    if labels is not None:
        lab = np.array(labels)
        result["nn_accuracy"] = float(np.mean(lab[nearest] == lab))
    if store is not None:
        result["store"] = {"path": args.store, "shapes_read": store.reused, "shapes_computed": store.computed}
    if args.out:
        out = Path(args.out)
        if out.suffix == ".csv":   # rows: the parts, columns: the wholes
            _write_csv(out, files, m.distance, "partial_distance")
        else:
            atomic_savez_compressed(out, files=np.array(files), partial=True, distance=m.distance,
                                    relative_distance=m.relative_distance, ranking_distance=m.ranking_distance,
                                    covered_fraction=m.covered_fraction,
                                    area_ratio=m.area_ratio, small_part=SMALL_PART,
                                    labels=np.array(labels if labels is not None else [], dtype=str),
                                    ranked_by="ranking_distance/covered_fraction", score=m.score, nearest=np.array(result["nearest"]),
                                    metric=args.metric, options=json.dumps(options), n_samples=args.samples,
                                    resolution=args.resolution, seed=args.seed)
    status = 1 if unusable and args.strict else 0
    if args.json:
        print(_dumps(result))
        return status
    left_out = f" ({len(unusable)} left out: see above)" if unusable else ""
    print(f"{len(files)} shapes{left_out}, {len(files) * (len(files) - 1)} ordered pairs (each shape as a part of "
          f"each other), {args.metric} metric, {args.samples} samples per part, {seconds:.1f} s; nearest whole "
          f"by the partial ranking distance (distortion and curvature, ÷ the whole's diameter) per share of the "
          f"whole covered")
    if store is not None:
        print(f"  store {args.store}: {store.reused} of {len(files)} shapes read from it, {store.computed} computed")
    width = max(len(f) for f in files)
    for i, f in enumerate(files):
        j = nearest[i]
        mark = ""
        if m.small[i, j]:
            mark = f"   <- keeps only {m.area_ratio[i, j]:.0%} of its area: placement unreliable"
        elif labels is not None and labels[j] != labels[i]:
            mark = f"   <- another class ({labels[i]} vs {labels[j]})"
        print(f"  {f:<{width}}  in {files[j]}: {m.score[i, j]:.4g} = {m.ranking_distance[i, j]:.4%} of its "
              f"diameter (distance {m.distance[i, j]:.6g}, {m.relative_distance[i, j]:.4%}) / "
              f"{m.covered_fraction[i, j]:.1%} of it covered{mark}")
    if labels is not None:
        print(f"  labels: nearest-whole accuracy {result['nn_accuracy']:.1%} (no equal error rate: the partial "
              "distance is not symmetric)")
    if args.out:
        print(f"  wrote {Path(args.out)}")
    return status


def _search_partial(args) -> int:
    """``search --partial``: the query matched as a part into every stored shape
    (:func:`gromov.retrieval.nearest_wholes`)."""
    from ..partial import SMALL_PART
    from ..retrieval import nearest_wholes

    why = "every stored shape is matched (the bounds and gaps hold for full matches)"
    refused = {"--candidates": (args.candidates is not None, why),
               "--prune": (args.prune != "profile", why), "--slack": (args.slack != PROFILE_SLACK, why),
               "--triangle-slack": (args.triangle_slack != TRIANGLE_SLACK, why),
               "--rank-by": (args.rank_by != "trimmed", "the shapes are ranked by the partial distance"),
               "--rank-tau-scale": (args.rank_tau_scale != RANK_TAU_SCALE, "it sets the ranking of full matches"),
               "--rank-residual": (args.rank_residual != RANK_RESIDUAL, "it sets the ranking of full matches")}
    _refuse_with_partial(refused)
    options = _metric_options(args)
    t = time.perf_counter()
    with _store_of(args) as store:
        r = nearest_wholes(args.query, store, args.k, args.metric, n_samples=args.samples, seed=args.seed,
                           resolution=args.resolution, metric_options=options,
                           progress=not (args.quiet or args.json))
    seconds = time.perf_counter() - t
    if args.json:
        print(_dumps({"query": args.query, "store": args.store, "k": args.k, **r.to_dict(),
                      "metric": args.metric, "metric_options": options, "small_part": SMALL_PART,
                      "seconds": seconds}))
        return 0
    n = r.full_matches + r.skipped
    clouds = f", {r.skipped} point clouds left out" if r.skipped else ""
    print(f"{len(r.neighbors)} nearest of {n} shapes by the partial ranking distance per share covered "
          f"({args.query} as a part of each, "
          f"{args.metric} metric); {r.full_matches} matched{clouds} (exact: no pruning), {seconds:.1f} s")
    m = r.partial
    width = max(len(x.name) for x in r.neighbors)
    for i, x in enumerate(r.neighbors, 1):
        j = x.index
        mark = (f"   <- the part keeps only {m.area_ratio[0, j]:.0%} of its area: placement unreliable"
                if m.small[0, j] else "")
        print(f"  {i:>2}. {x.name:<{width}}  {x.distance:.4g} = {m.ranking_distance[0, j]:.4%} of its diameter "
              f"(distance {m.distance[0, j]:.6g}, {m.relative_distance[0, j]:.4%}) / {m.covered_fraction[0, j]:.1%} "
              f"of it covered{mark}")
    return 0
