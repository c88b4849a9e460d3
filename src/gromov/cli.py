"""Command-line interface: ``gromov info|distances|match|index|search|pairwise|perturb|reproduce|demo``.

Thin: parses arguments, calls the library, prints. User errors (unreadable file, bad
option values, a metric that cannot be computed) print one line ``gromov: error: ...``
and exit with status 2; no traceback.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ._version import __version__
from ._atomic import atomic_path, atomic_savez_compressed
from ._json import finite as _finite
from ._defaults import (DEFAULT_RESOLUTION, DEFAULT_UNITS, DIFFUSION_FILL_HOLES, GZIP_FLOOR, GZIP_RATIO,
                        HEAT_UNITS, LOCAL_SCALING_K, PROFILE_SLACK, RANK_RESIDUAL, RANK_RESIDUALS,
                        RANK_TAU_SCALE, TRIANGLE_SLACK, WELD_JOINS)
from .errors import GromovError

__all__ = ["main"]



class _UserError(Exception):
    pass


def _dumps(o) -> str:
    """One JSON object, standard JSON only (``allow_nan=False``)."""
    return json.dumps(_finite(o), allow_nan=False)


#: Dense (n, n) float64 distance matrices held while one is computed: the matrix and a
#: transient of its size (``gromov distances`` on TOSCA cat0, 2,000 -> 4,000 working vertices:
#: peak memory 0.36 -> 0.55 GB with the diffusion metric, 0.35 -> 0.45 GB geodesic; ``gromov
#: match`` at 1,500 -> 3,000: 0.37 -> 0.60 GB; ``/usr/bin/time -f %M``).
DENSE_COPIES = 2


def _check_memory(sizes: list[int], what: str) -> None:
    """Refuse, before any metric is computed, working sizes whose dense distance matrices
    (8 n^2 bytes each, :data:`DENSE_COPIES` while computed) need more memory than is available."""
    from .experiments.pairwise import _available_memory

    have = _available_memory()
    need = sum(DENSE_COPIES * 8 * n * n for n in sizes)
    if have is None or need <= have:
        return
    fit = int(np.sqrt(have / (DENSE_COPIES * 8 * len(sizes))) // 100 * 100)
    gb = lambda b: f"{b / 1e9:.1f} GB" if b >= 1e9 else f"{b / 1e6:.1f} MB"  # noqa: E731
    n = max(sizes)
    matrices = "matrices" if len(sizes) > 1 else "matrix"
    raise _UserError(f"{what}: {len(sizes)} dense distance {matrices} of up to {n:,} working "
                     f"vertices need about {gb(need)} (8 bytes x n^2 each, {DENSE_COPIES}x "
                     f"while computed) and {gb(have)} of memory are available; a --resolution of at "
                     f"most {fit:,} fits")


def _int_at_least(text: str, low: int, what: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if v < low:
        raise argparse.ArgumentTypeError(f"expected {what}, got {v}")
    return v


def _positive_int(text: str) -> int:
    return _int_at_least(text, 1, "a positive integer")


def _nonnegative_int(text: str) -> int:
    return _int_at_least(text, 0, "an integer >= 0")


def _nonnegative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not (np.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {v}")
    return v


_SIZE = re.compile(r"(\d+(?:\.\d+)?)\s*([kmgt]?)(?:i?b)?", re.ASCII | re.IGNORECASE)


def _size(text: str) -> int:
    """``--max-decompressed``: bytes, or a number with K, M, G or T (powers of 1024)."""
    m = _SIZE.fullmatch(text.strip())
    if m is None:
        raise argparse.ArgumentTypeError(f"expected a size such as 4G, 500M or 1000000 (bytes), "
                                         f"got {text[:40]!r}")
    v = int(float(m.group(1)) * 1024 ** " kmgt".index(m.group(2).lower() or " "))
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a size of at least 1 byte, got {text!r}")
    return v


def _add_input_args(p: argparse.ArgumentParser) -> None:

    p.add_argument("--max-decompressed", type=_size, default=None, metavar="SIZE",
                   help=f"largest size a .gz input (or a compressed MATLAB variable) may decompress to, "
                        f"e.g. 4G (default: {GZIP_RATIO} times the compressed size, at least "
                        f"{GZIP_FLOOR // 2**20}M; refuses gzip bombs)")


def _classes(text: str) -> dict:
    out = {}
    for item in text.split(","):
        name, sep, n = item.partition(":")
        if not sep or not name.strip():
            raise argparse.ArgumentTypeError(f"expected CLASS:N[,CLASS:N...], got {item!r}")
        out[name.strip()] = _positive_int(n)
    return out   # the rest is checked by reproduce (settings_for)


def _metric_options(args) -> dict:
    if args.metric != "diffusion" and getattr(args, "fill_holes", None) is not None:
        raise _UserError("--fill-holes applies to --metric diffusion")
    if args.metric != "diffusion" and getattr(args, "units", None) is not None:
        raise _UserError("--units applies to --metric diffusion")
    refine = getattr(args, "refine", None) or None  # 0: the default, as if not given
    if refine is not None and (args.metric != "geodesic" or args.geodesic_method not in (None, "fmm")):
        raise _UserError("--refine applies to --metric geodesic with the fast marching (fmm)")
    neighbors = getattr(args, "neighbors", None)
    if neighbors is not None and not (args.metric == "geodesic" and args.geodesic_method in (None, "dijkstra")
                                      or args.metric == "diffusion" and args.kernel in ("heat", "biharmonic")):
        raise _UserError("--neighbors applies to point clouds with --metric geodesic (Dijkstra) or "
                         "--metric diffusion with --kernel heat or biharmonic")
    if args.metric == "geodesic":
        opts = {"method": args.geodesic_method} if args.geodesic_method else {}
        if refine:
            opts["refine"] = refine
        if neighbors is not None:
            opts["k"] = neighbors
        return opts
    if args.metric == "diffusion":
        opts = _diffusion_options(args)
        if neighbors is not None:
            opts["neighbors"] = neighbors
        return opts
    return {}


def _diffusion_options(args) -> dict:
    """Options of the diffusion metric from ``--kernel``, ``--tau``, ``--steps``, ``--fill-holes``."""
    opts = {"kernel": args.kernel}
    if args.tau is not None:
        if args.kernel != "heat":
            raise _UserError("--tau is the heat kernel's diffusion time: use it with --kernel heat")
        opts["tau"] = args.tau
    units = getattr(args, "units", None)
    if units is not None:
        if args.kernel != "heat":
            raise _UserError("--units applies to the heat kernel: use it with --kernel heat")
        opts["units"] = units
    steps = getattr(args, "steps", None)
    if steps is not None:
        if args.kernel not in ("connectivity", "gaussian"):
            raise _UserError("--steps is the graph kernels' number of diffusion steps: use it with "
                             "--kernel connectivity or gaussian")
        opts["m"] = steps

    fill = getattr(args, "fill_holes", None)
    if fill is not None and not 0 <= fill < float("inf"):
        raise _UserError(f"--fill-holes must be a finite number >= 0 (0: leave holes open), got {fill}")
    # recorded as used: the library's default unless given, None when switched off
    opts["fill_holes"] = DIFFUSION_FILL_HOLES if fill is None else (fill or None)
    return opts


def _rank_tau_scale(text: str) -> float | None:
    """``--rank-tau-scale``: a positive number; 1 is the metric of the match itself (None)."""
    from .gh import check_rank_tau_scale

    try:
        v = check_rank_tau_scale(float(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    return None if v == 1.0 else v


def _add_rank_args(p: argparse.ArgumentParser) -> None:
    """``--rank-tau-scale``, ``--rank-residual`` (how recognition ranks) and ``--local-scaling``
    (the locally scaled EER beside it), for ``pairwise`` and ``reproduce``."""

    p.add_argument("--rank-tau-scale", type=_rank_tau_scale, default=RANK_TAU_SCALE, metavar="S",
                   help=f"heat-kernel diffusion: the trimmed ranking measures each correspondence "
                        f"with the heat distance at S times the diffusion time it was found at "
                        f"(default {RANK_TAU_SCALE:g}: a finer scale; 1: the same metric)")
    p.add_argument("--rank-residual", choices=RANK_RESIDUALS, default=RANK_RESIDUAL,
                   help=f"the trimmed ranking summarises the log ratios of corresponding distances "
                        f"(log: a multiplicative distortion) or their differences over the larger "
                        f"diameter (difference: the additive form; default {RANK_RESIDUAL})")
    p.add_argument("--local-scaling", type=_positive_int, default=None, metavar="K",
                   help=f"the EER is also reported after local scaling: each distance over the "
                        f"geometric mean of the two shapes' distances to their K-th nearest shape (a "
                        f"set-level normalisation, Zelnik-Manor & Perona 2004; keep K below the "
                        f"smallest class; capped at the number of shapes less one; default "
                        f"{LOCAL_SCALING_K}; pairwise: needs labels)")


def _add_heat_args(p: argparse.ArgumentParser, units_default: str | None = None) -> None:
    """``--tau``, ``--units`` and ``--fill-holes`` (the diffusion metric's), for ``match``,
    ``distances`` and ``reproduce``; ``units_default``: the help's words for the default."""

    p.add_argument("--tau", type=float, default=None,
                   help="heat-kernel diffusion time relative to the area (default 0.01 with "
                        "--units normalized, 0.005 with raw or length)")
    p.add_argument("--units", choices=HEAT_UNITS, default=None,
                   help="heat-kernel diffusion distance between normalised heat distributions "
                        "(normalized), in units of 1/length (raw) or scaled to the geodesic "
                        "distance below the diffusion radius (length); default "
                        + (units_default or DEFAULT_UNITS))
    p.add_argument("--fill-holes", type=float, default=None, metavar="F",
                   help="diffusion: close boundary loops shorter than F * sqrt(area of their "
                        "component) before computing the metric (default 0.5; 0 leaves holes open)")


def _add_metric_args(p: argparse.ArgumentParser, units_default: str | None = None) -> None:
    p.add_argument("--metric", choices=("geodesic", "diffusion", "euclidean"), default="diffusion",
                   help="distance on the surface (default: diffusion)")
    p.add_argument("--geodesic-method", choices=("fmm", "heat", "exact", "dijkstra"), default=None,
                   help="geodesic backend (default: fmm on meshes, dijkstra on point clouds)")
    p.add_argument("--refine", type=int, choices=range(4), default=None, metavar="{0,1,2,3}",
                   help="geodesic fast marching: split every triangle into 4 this many times "
                        "before marching (~4^N times the work; about halves the error per level)")
    p.add_argument("--kernel", choices=("heat", "connectivity", "gaussian", "biharmonic"), default="heat",
                   help="diffusion kernel: the resolution-independent Laplace-Beltrami heat kernel "
                        "(default), the paper's connectivity kernel, a Gaussian k-NN kernel, or the "
                        "biharmonic distance (heat-kernel distances integrated over all times)")
    p.add_argument("--steps", type=_positive_int, default=None,
                   help="diffusion steps m of the graph kernels (default 50)")
    p.add_argument("--neighbors", type=_positive_int, default=None, metavar="K",
                   help="point clouds: each point's nearest neighbours in the geodesic metric's graph "
                        "(default 10) or in the heat / biharmonic kernels' Laplacian (default 20)")
    _add_heat_args(p, units_default)


def _load(path: str, args=None):
    from .io import load

    return load(path, max_decompressed=getattr(args, "max_decompressed", None))


def _check_pieces(args, path: str, shape) -> None:
    """Matching needs finite distances: refuse a mesh in several pieces with a metric that is
    infinite between them (geodesic, biharmonic), before any metric is computed."""
    from .mesh import Mesh

    infinite = args.metric == "geodesic" or (args.metric == "diffusion" and args.kernel == "biharmonic")
    if infinite and isinstance(shape, Mesh) and shape.n_components > 1:
        what = "geodesic" if args.metric == "geodesic" else "biharmonic"
        raise _UserError(f"{path}: the working mesh has {shape.n_components} connected components; "
                         f"{what} distances between them are infinite and matching needs finite ones: "
                         "--metric diffusion --kernel heat measures across them (or match the largest "
                         "piece on its own)")


def _check_neighbors(args, shapes) -> None:
    """``--neighbors`` shapes a point cloud's graph or Laplacian: refused when every input is a
    mesh, whose metric is built on its faces and would ignore it."""
    from .mesh import Mesh

    if getattr(args, "neighbors", None) is not None and all(isinstance(s, Mesh) for s in shapes):
        raise _UserError("--neighbors applies to point clouds; every input here is a mesh, whose "
                         "metric is built on its faces")


def _progress(total: int, desc: str, quiet: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="row", disable=quiet or total < 512, leave=False,
                file=sys.stderr)


# ----------------------------------------------------------------------------- commands
def _status(args, text: str) -> None:
    """One status line on stderr for a step that can take seconds: on a terminal (like the
    progress bars, never mixed into a script's captured output), unless ``-q``."""
    if not getattr(args, "quiet", False) and sys.stderr.isatty():
        print(f"gromov: {text}", file=sys.stderr, flush=True)


def cmd_info(args) -> int:
    from .mesh import Mesh
    from .metrics import GeodesicSolver

    shape = _load(args.mesh, args)
    if not isinstance(shape, Mesh):
        lo, hi = shape.bbox
        info = {"file": args.mesh, "type": "point cloud", "vertices": shape.n_vertices,
                "bbox_min": lo.tolist(), "bbox_max": hi.tolist()}
    else:
        info = {"file": args.mesh, "type": "triangle mesh", **shape.summary()}
        _status(args, f"geodesic diameter of {shape.n_vertices} vertices (fast marching)")
        t = time.perf_counter()
        info["geodesic_diameter"] = GeodesicSolver(shape).diameter()
        info["diameter_seconds"] = round(time.perf_counter() - t, 3)
    if args.json:
        print(_dumps(info))
        return 0
    width = max(len(k) for k in info)
    for k, v in info.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        elif isinstance(v, list):
            v = "(" + ", ".join(f"{x:.6g}" for x in v) + ")"
        print(f"{k.replace('_', ' '):<{width}}  {v}")
    return 0


def cmd_distances(args) -> int:
    from .metrics import metric_solver
    from .resolution import working_shape
    from .sampling import farthest_point_sampling

    shape = _load(args.mesh, args)
    _check_neighbors(args, [shape])
    t0 = time.perf_counter()
    _status(args, f"working shape of {shape.n_vertices} vertices (--resolution {args.resolution})")
    work = working_shape(shape, args.resolution)   # a point cloud's: farthest points in space
    target, to_input = work.mesh, work.to_input_ids
    if args.samples is None:
        _check_memory([target.n_vertices], f"--resolution {args.resolution}")
    if args.samples is not None and args.samples > target.n_vertices:
        raise _UserError(f"--samples {args.samples} is more than the {target.n_vertices} vertices "
                         f"of the working mesh of {args.mesh}")
    solver = metric_solver(target, args.metric, **_metric_options(args))
    _status(args, f"{args.metric} metric on {target.n_vertices} working vertices")
    if args.samples is None:
        idx = np.arange(target.n_vertices)
        with _progress(target.n_vertices, f"{args.metric} distances", args.quiet) as bar:
            dist = solver.pairwise(progress=bar.update)
        radius = 0.0
    else:
        with _progress(args.samples, "farthest point sampling", args.quiet) as bar:
            fps = farthest_point_sampling(solver, args.samples, seed=args.seed)
            bar.update(args.samples)
        idx, radius = fps.indices, fps.radius
        dist = solver.submatrix(idx)
    seconds = time.perf_counter() - t0
    if np.isnan(dist).any():
        raise _UserError(f"{args.mesh}: the {args.metric} distances came out undefined (NaN) for "
                         f"{int(np.isnan(dist).sum())} pairs; nothing was written")
    if np.isinf(dist).any():
        warnings.warn(f"{args.mesh}: {int(np.isinf(dist).sum()) // 2} pairs are infinitely far apart in "
                      f"the {args.metric} metric (parts of the working shape that no path joins); "
                      "they are written as inf", stacklevel=1)
    out = Path(args.out)
    if out.parent and not out.parent.exists():
        raise _UserError(f"output folder {out.parent} does not exist")
    atomic_savez_compressed(
        out, distances=np.asarray(dist, dtype=np.float64), samples=to_input(idx).astype(np.int64),
        working_vertices=idx.astype(np.int64), metric=args.metric,
        options=json.dumps(_metric_options(args)), resolution=target.n_vertices,
        seed=args.seed, covering_radius=radius)
    if not args.quiet:
        print(f"{args.mesh}: {len(idx)} samples on a {target.n_vertices}-vertex working shape, "
              f"{args.metric} distances in [{np.min(dist[dist > 0]) if len(idx) > 1 else 0:.4g}, "
              f"{np.max(dist):.4g}], covering radius {radius:.4g}, {seconds:.2f} s -> {out}")
    return 0


def _norm_arg(text: str) -> str:
    from .gmds import parse_norm

    try:
        parse_norm(text)
    except (TypeError, ValueError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def cmd_match(args) -> int:
    from .gh import ShapeMetric, match
    from .search import SearchOptions
    from .metrics.diffusion import correspondence_options

    options = correspondence_options(args.metric, _metric_options(args))
    store, handler = _open_store(args)
    if store is None:
        inputs = [_load(path, args) for path in (args.x, args.y)]
        _check_neighbors(args, inputs)
        shapes = [ShapeMetric(shape, args.metric, resolution=args.resolution, metric_options=options)
                  for shape in inputs]
    else:   # each shape as match measures it: read from the store, or loaded, computed and added
        try:
            if getattr(args, "neighbors", None) is not None:   # (a user error found before any metric)
                _check_neighbors(args, [_load(path, args) for path in (args.x, args.y)])
            shapes = store.shapes([args.x, args.y], args.metric, resolution=args.resolution,
                                  metric_options=options, progress=not (args.quiet or args.json))
        finally:
            _close_store(store, handler)
    for path, s in zip((args.x, args.y), shapes):
        if args.samples > s.mesh.n_vertices:
            raise _UserError(f"--samples {args.samples} is more than the {s.mesh.n_vertices} "
                             f"vertices of the working {'mesh' if s.has_faces else 'point set'} of {path}")
        _check_pieces(args, path, s.mesh)
    if store is None:   # (a store's shapes have their metrics already)
        _check_memory([s.mesh.n_vertices for s in shapes], f"--resolution {args.resolution}")
    dense = bool(args.dense or args.map or args.html)
    if dense and args.dense in ("zoomout", "placed"):
        dense = args.dense
    if args.map:
        _check_folder(args.map, "--map")
    if args.html:
        _check_folder(args.html, "--html")
        for path, s in zip((args.x, args.y), shapes):
            if not s.has_faces:
                raise _UserError(f"--html shows triangle meshes; {path} is a point cloud")
        try:
            import plotly  # noqa: F401
        except ImportError:
            raise _UserError("--html needs plotly: pip install 'gromov[plot]'") from None
    if args.out:
        _check_folder(args.out, "--out")
    if args.plot:
        for path, s in zip((args.x, args.y), shapes):
            if not s.has_faces:
                raise _UserError(f"--plot draws the correspondence on triangle meshes; {path} is a point cloud")
        _check_png(args.plot, "--plot")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise _UserError("--plot needs matplotlib: pip install 'gromov[plot]'") from None
    for path, s in zip((args.x, args.y), shapes if store is None else ()):
        _status(args, f"{args.metric} metric of {path} ({s.mesh.n_vertices} working vertices)")
        s.distances
    for path, s in zip((args.x, args.y), shapes):
        if not s.finite:   # a point cloud whose neighbour graph falls apart
            raise _UserError(f"{path}: some of its points are infinitely far apart in the {args.metric} "
                             f"metric (the point cloud's neighbour graph falls apart) and matching needs "
                             f"finite distances: more neighbours (--neighbors K) join it, or --metric "
                             f"diffusion measures across the pieces")
    search = SearchOptions(search_vertices=args.search_vertices,
                           **({} if args.signature_weight is None else {"signature_weight": args.signature_weight}))
    _status(args, f"matching {args.samples} samples" + (", then the dense maps" if dense else ""))
    r = match(shapes[0], shapes[1], args.metric, n_samples=args.samples, norm=args.norm,
              solver=args.solver, seed=args.seed, orientation=args.orientation, dense=dense, search=search)
    if args.out:
        atomic_savez_compressed(Path(args.out), **r.arrays())
    if args.map:   # SHREC's exchange format: one 1-based vertex id of Y per vertex of X
        with atomic_path(args.map) as tmp:
            np.savetxt(tmp, r.x_to_y_dense_vertex + 1, fmt="%d")
    if args.plot:
        (_plot_dense if dense else _plot_match)(r, shapes, args)
    if args.html:
        from .experiments.view import write_match_html

        write_match_html(shapes[0].input, shapes[1].input, r, args.html,
                         titles=(Path(args.x).name, Path(args.y).name))
    stored = None if store is None else {"path": args.store, "shapes_read": store.reused,
                                         "shapes_computed": store.computed}
    if args.json:   # the metric's options too: the distance's units depend on them
        print(_dumps({**r.to_dict(), "metric_options": options, **({} if stored is None else {"store": stored})}))
    else:
        print(f"{args.x} vs {args.y}: Gromov-Hausdorff distance {r.distance:.6g} "
              f"({r.norm} norm, {r.relative_distance:.4%} of the diameter), {args.metric} metric, {r.solver}, "
              f"{r.n_samples} samples per shape")
        if all(s.has_faces for s in shapes):
            how = f"{r.n_iter} iterations, {'converged' if r.converged else 'not converged'}"
        else:
            how = "images at points (a point cloud: no GMDS refinement inside triangles)"
        print(f"  distortion: {r.norm} {r.distortion:.6g}, rms {r.distortion_l2:.6g}, "
              f"max {r.distortion_linf:.6g}, rms of the best-fitting 80% of pairs "
              f"{r.distortion_trimmed:.6g}; {how}, {r.seconds:.2f} s")
        lo, hi = r.gh_interval
        print(f"  the two sample sets as finite metric spaces: their GH distance with the max norm is "
              f"certified in [{lo:.6g}, {hi:.6g}]" + ("" if r.norm == "linf" else f" (the {r.norm} value above averages "
                                                       "the distortion: it can lie below)"))
        if np.isfinite(r.orientation):
            kind = ("keeps the orientation" if r.orientation > 0.5 else
                    "reverses the orientation (a mirror image)")
            print(f"  the map {kind}: {r.orientation:.0%} of small sample triangles keep their sense of rotation")
        if dense:
            print(f"  dense maps: {len(r.x_to_y_dense_vertex)} vertices of X on Y, "
                  f"{len(r.y_to_x_dense_vertex)} of Y on X")
        if stored is not None:
            print(f"  store {args.store}: {store.reused} of 2 shapes read from it, {store.computed} computed")
        for f in (args.out, args.map, args.plot, args.html):
            if f:
                print(f"  wrote {f}")
    return 0


def _stem(path) -> str:
    """File name without folders, ``.gz`` and a mesh format's extension (``cat0.off.gz`` ->
    ``cat0``; the formats of :data:`gromov.io.FORMATS`)."""
    from .io import FORMATS

    name = Path(path).name
    if name.lower().endswith(".gz") and len(name) > 3:
        name = name[:-3]
    base, dot, ext = name.rpartition(".")
    return base if dot and base and ext.lower() in FORMATS else name


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


def _check_png(path: str, option: str) -> None:
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise _UserError(f"{option} writes a PNG image: give a file name ending in .png, got {path!r}")
    if p.is_dir():
        raise _UserError(f"{option} {path} is a folder")
    if p.parent and not p.parent.exists():
        raise _UserError(f"output folder {p.parent} does not exist")


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


class _StoreWarnings(logging.Handler):
    """Prints the store's warnings (an invalid entry, a changed file) as one line each,
    ``gromov: warning: ...``; passes its other records on to the root logger."""

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:   # on its own line under a progress bar
            from tqdm import tqdm

            tqdm.write(f"gromov: warning: {record.getMessage()}", file=sys.stderr)
        else:
            logging.getLogger().handle(record)


def _open_store(args):
    """``(store, handler)``: the ``--store`` of ``index`` and ``pairwise``, whose warnings the
    handler prints (:func:`_close_store` removes it); ``(None, None)`` without ``--store``."""
    if getattr(args, "store", None) is None:
        return None, None
    from .store import ShapeStore

    log = logging.getLogger("gromov.store")
    handler = _StoreWarnings()
    log.addHandler(handler)
    log.propagate = False
    try:
        return ShapeStore(args.store, load=lambda path: _load(path, args)), handler
    except BaseException:
        _close_store(None, handler)
        raise


def _close_store(store, handler) -> None:
    if store is not None:
        store.close()
    if handler is not None:
        log = logging.getLogger("gromov.store")
        log.removeHandler(handler)
        log.propagate = True


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
    store, handler = _open_store(args)
    try:
        _stored_shapes(store, args, options, progress=not args.quiet)
        size = sum(e.bytes for e in store.entries())
    finally:
        _close_store(store, handler)
    if not args.quiet:
        n = len(args.files)
        print(f"{n} file{'s' if n != 1 else ''} in {args.store}: {store.computed} computed, {store.reused} "
              f"read back; {time.perf_counter() - t:.1f} s; {size / 1e6:.1f} MB of entries")
    return 0


def cmd_search(args) -> int:
    from .retrieval import nearest

    if not (Path(args.store) / "catalogue.sqlite").is_file():
        raise _UserError(f"no shape store in {args.store}: gromov index FILES --store {args.store} makes one")
    options = _metric_options(args)
    t = time.perf_counter()
    store, handler = _open_store(args)
    try:
        r = nearest(args.query, store, args.k, args.metric, n_samples=args.samples, seed=args.seed,
                    resolution=args.resolution, metric_options=options, rank_by=args.rank_by,
                    rank_tau_scale=args.rank_tau_scale, rank_residual=args.rank_residual, prune=args.prune,
                    slack=args.slack, triangle_slack=args.triangle_slack,
                    progress=not (args.quiet or args.json))
    finally:
        _close_store(store, handler)
    seconds = time.perf_counter() - t
    if args.json:
        print(_dumps({"query": args.query, "store": args.store, "k": args.k, **r.to_dict(),
                      "seconds": seconds}))
        return 0
    n = r.full_matches + r.skipped
    what = "trimmed distortion" if args.rank_by == "trimmed" else "GH distance"
    how = ("exact" if r.exact else "by the profile gap" + (f" and {r.known_pairs:,} recorded distances between "
                                                          "them" if r.known_pairs else "") + ": not exact")
    print(f"{len(r.neighbors)} nearest of {n} shapes by {what}; {r.full_matches} matched, {r.skipped} "
          f"skipped ({how}), {seconds:.1f} s")
    width = max(len(x.name) for x in r.neighbors)
    for i, x in enumerate(r.neighbors, 1):
        print(f"  {i:>2}. {x.name:<{width}}  {x.distance:.4%}")
    return 0


def cmd_pairwise(args) -> int:
    from .experiments.recognition import LOCAL_SCALING_K, errors_at, local_roc, mds_map, roc

    n = len(args.files)
    if n < 2:
        raise _UserError("pairwise needs at least two meshes")
    import os

    real = [os.path.realpath(f) for f in args.files]
    if len(set(real)) < n:
        dup = sorted({f for f, r in zip(args.files, real) if real.count(r) > 1})
        raise _UserError(f"a file is given twice: {', '.join(dup)}")
    labels = _pairwise_labels(args, n)
    if args.local_scaling is not None and labels is None:
        raise _UserError("--local-scaling sets the neighbour of the locally scaled EER: give "
                         "--labels or --labels-from-names")
    k_local = LOCAL_SCALING_K if args.local_scaling is None else args.local_scaling
    outs = [Path(f) for f in (args.out, args.mds) if f]
    if args.out:
        if not args.out.endswith((".npz", ".csv")):
            raise _UserError(f"--out must end in .npz or .csv, got {args.out!r}")
        if Path(args.out).is_dir():
            raise _UserError(f"--out {args.out} is a folder")
        if Path(args.out).parent and not Path(args.out).parent.exists():
            raise _UserError(f"output folder {Path(args.out).parent} does not exist")
    if args.k is not None and args.mds:
        raise _UserError("--mds needs every pair; -k matches only each shape's nearest")
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
    if dask:
        import importlib.util

        if importlib.util.find_spec("distributed") is None:
            raise _UserError(f"{'--dask' if args.dask is not None else '--scheduler'} needs dask.distributed: "
                             "pip install 'gromov[dask]'")
    t = time.perf_counter()
    # a shape that cannot be used is left out, with its reason; the others go on
    loaded, unusable = _usable_shapes(args)
    files = [f for f in args.files if f not in unusable]
    _check_usable(files, n, unusable)
    _check_neighbors(args, list(loaded.values()))
    options = _metric_options(args)
    store, handler = _open_store(args)
    try:
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
            _check_usable(files, n, unusable)
            r = _pairwise_matrix(args, files, loaded, store, options, dask)
    finally:
        _close_store(store, handler)
    seconds = time.perf_counter() - t
    for f, why in unusable.items():
        print(f"gromov: skipped {f}: {why}", file=sys.stderr)
    if unusable:
        keep = [i for i, f in enumerate(args.files) if f not in unusable]
        labels = None if labels is None else [labels[i] for i in keep]
        n = len(files)
    D = r.trimmed if args.rank_by == "trimmed" else r.relative
    what = "trimmed distortion" if args.rank_by == "trimmed" else "GH distance"
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
    if args.k is not None:
        result.update(k=args.k, pairs_matched=n * (n - 1) // 2 - r.skipped, pairs_skipped=r.skipped)
    if store is not None:
        result["store"] = {"path": args.store, "shapes_read": store.reused, "pairs_read": store.pairs_reused}
    if labels is not None:
        lab = np.array(labels)
        result["nn_accuracy"] = float(np.mean(lab[nearest] == lab))
        same = (lab[:, None] == lab[None, :])[np.triu_indices(n, 1)]
        result.update(eer=None, eer_gh=None, eer_trimmed=None, errors_at_eer=None, eer_local=None,
                      local_scaling_k=None, errors_at_eer_local=None)
        if same.any() and not same.all() and args.k is None:   # else all one class, or every shape its
            # own, or not every pair matched: no EER
            curves = {k: roc(m, lab) for k, m in (("trimmed", r.trimmed), ("gh", r.relative))}
            local, scaled, k_used = local_roc(D, lab, k_local)   # warns if k >= the smallest class
            result.update(eer=curves[args.rank_by].eer, eer_gh=curves["gh"].eer,
                          eer_trimmed=curves["trimmed"].eer,
                          errors_at_eer=errors_at(D, lab, curves[args.rank_by].eer_threshold),
                          eer_local=local.eer, local_scaling_k=k_used,
                          errors_at_eer_local=errors_at(scaled, lab, local.eer_threshold))
    if args.out:
        out = Path(args.out)
        if out.suffix == ".csv":   # the matrix the results rank by, named in the corner cell
            _write_csv(out, names, D, "relative_trimmed_distance" if args.rank_by == "trimmed"
                       else "relative_distance")
        else:
            nan = float("nan")
            atomic_savez_compressed(out, files=np.array(names), distance=r.distance,
                                    relative_distance=r.relative, relative_trimmed_distance=r.trimmed,
                                    labels=np.array(labels if labels is not None else [], dtype=str),
                                    ranked_by=args.rank_by, nearest=np.array(result["nearest"]),
                                    eer=nan if result.get("eer") is None else result["eer"],
                                    eer_local=nan if result.get("eer_local") is None else result["eer_local"],
                                    local_scaling_k=result.get("local_scaling_k") or 0,
                                    metric=args.metric, options=json.dumps(options),
                                    rank_tau_scale=nan if r.rank_tau_scale is None else r.rank_tau_scale,
                                    rank_residual=r.rank_residual,
                                    n_samples=args.samples, resolution=args.resolution, seed=args.seed)
    if args.mds:
        from .experiments.recognition import plot_mds

        plot_mds(mds_map(D, 2, seed=args.seed), labels if labels is not None else ["shapes"] * n,
                 args.mds, names=_short_names(names),
                 title=f"MDS of {n} shapes, {args.metric}, {what}")
    status = 1 if unusable and args.strict else 0
    if args.json:
        print(_dumps(result))
        return status
    pairs = (f"{n * (n - 1) // 2} pairs" if args.k is None else
             f"{n * (n - 1) // 2 - r.skipped} of {n * (n - 1) // 2} pairs matched (each shape's {args.k} nearest)")
    left_out = f" ({len(unusable)} left out: see above)" if unusable else ""
    print(f"{n} shapes{left_out}, {pairs}, {args.metric} metric, {args.samples} samples per "
          f"shape, {seconds:.1f} s; relative GH distance (÷ the larger diameter); nearest by {what}")
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
            why = ("needs every pair; -k matched only each shape's nearest" if args.k is not None else
                   "needs two shapes of a class and two classes")
            print(f"  labels: no equal error rate ({why}); "
                  f"nearest-neighbour accuracy {result['nn_accuracy']:.1%}")
        else:
            other = result["eer_gh"] if args.rank_by == "trimmed" else result["eer_trimmed"]
            print(f"  equal error rate {result['eer']:.2%} (ranked by the other: {other:.2%}; "
                  f"locally scaled, k = {result['local_scaling_k']}: {result['eer_local']:.2%}), "
                  f"nearest-neighbour accuracy {result['nn_accuracy']:.1%}")
            from .experiments.report import errors_text

            print(f"  at its threshold: {errors_text(result['errors_at_eer'])}")
    for f in outs:
        print(f"  wrote {f}")
    return status


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
    from .experiments.pairwise import available_cpus, gh_matrix

    if store is None and not dask:
        shapes = [loaded[f] for f in files]
    elif dask:   # each worker reads its shapes from the store, or computes and adds them
        shapes = list(files)
    else:   # read from the store; loaded and computed only when not stored yet
        shapes = _stored_shapes(store, args, options, progress=not (args.quiet or args.json), files=files)
    if dask:
        from ._dask import client_for

        cluster = client_for(scheduler=args.scheduler, n_workers=args.dask)
    else:
        import contextlib

        cluster = contextlib.nullcontext()
    with cluster as client:
        return gh_matrix(shapes, args.metric, n_samples=args.samples, resolution=args.resolution,
                         metric_options=options, seed=args.seed, jobs=args.jobs or available_cpus(),
                         progress=not (args.quiet or args.json), rank_tau_scale=args.rank_tau_scale,
                         rank_residual=args.rank_residual, store=store, client=client, k=args.k)


def _failing_shapes(args, files: list, loaded: dict, options: dict) -> dict:
    """``{file: why}`` for the files whose metric cannot be computed, each tried on its own."""
    from .experiments.pairwise import prepare

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


def _plot_match(r, shapes, args) -> None:
    """``gromov match --plot``: the cells of X's samples and, in the same colours, the cells
    around their images on Y (each by the match's metric on the working meshes), as in the
    correspondence figures of Bronstein et al. (IJCV 2010, §5)."""
    from .experiments.report import plot_correspondence, voronoi_labels

    sx, sy = shapes

    def working(s, ids):   # input-file ids -> nearest working vertices
        return s.working.from_source(s.working.source.from_input_ids(ids))

    x_labels = voronoi_labels(sx.distances[working(sx, r.x_samples)])
    y_labels = voronoi_labels(sy.distances[working(sy, r.x_to_y_vertex)])
    plot_correspondence(sx.mesh, sy.mesh, x_labels, y_labels, args.plot,
                        titles=(Path(args.x).name, Path(args.y).name),
                        title=f"{args.metric}: cells of the samples of {Path(args.x).name} carried "
                              f"to {Path(args.y).name} (relative GH {r.relative_distance:.2%})")


def _check_folder(path: str, option: str) -> None:
    folder = Path(path).parent
    if str(folder) and not folder.exists():
        raise _UserError(f"{option}: output folder {folder} does not exist")


def _plot_dense(r, shapes, args) -> None:
    """``gromov match --dense --plot``: X painted by its coordinates and Y by the same colours
    carried through the dense map; where the map is unreliable (the nearest sample's
    distortion above three times the median) Y's colours are greyed."""
    from .experiments.report import coordinate_colours, plot_transfer

    sx, sy = shapes
    x_rgb = coordinate_colours(sx.input)
    y_rgb = r.transfer(sx.input.per_file_vertex(x_rgb, fill=0.0), method="barycentric")[sy.input.input_ids]
    _, e_y = r.sample_distortion
    q = sy.working.from_source(sy.input.from_input_ids(r.y_samples))
    nearest = np.argmin(sy.distances[:, q], axis=1)[sy.working.source_nearest]
    shaky = e_y[nearest] > 3.0 * np.median(e_y)
    y_rgb[shaky] = 0.35 * y_rgb[shaky] + 0.65 * 0.8
    plot_transfer(sx.input, sy.input, x_rgb, y_rgb, args.plot,
                  titles=(Path(args.x).name, Path(args.y).name),
                  title=f"{args.metric}: colours of {Path(args.x).name} carried by the dense map\n"
                        f"(grey: high distortion, {shaky.mean():.0%} of the vertices)")


def _json_value(o):
    """numpy scalars and arrays (e.g. a weld's gaps) as JSON numbers and lists."""
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def cmd_perturb(args) -> int:
    from .io import save
    from .mesh import Mesh
    from .perturb import WELD_RESOLUTION, holes, weld

    shape = _load(args.input, args)
    if not isinstance(shape, Mesh):
        raise _UserError(f"{args.input}: perturbations need a triangle mesh, got a point cloud")
    fn = weld if args.kind == "weld" else holes
    weld_only = {"--join": args.join, "--min-geodesic-ratio": args.min_geodesic_ratio,
                 "--separation": args.separation, "--resolution": args.resolution}
    if args.kind != "weld":
        given = [k for k, v in weld_only.items() if v is not None]
        if given:
            raise _UserError(f"{', '.join(given)} applies to weld, not to holes")
        extra = {}
    else:
        extra = {k: v for k, v in (("join", args.join), ("min_geodesic_ratio", args.min_geodesic_ratio),
                                   ("separation", args.separation)) if v is not None}
        if args.resolution is not None:
            extra["resolution"] = None if args.resolution == 0 else args.resolution
    where = extra.get("resolution", WELD_RESOLUTION) if args.kind == "weld" else None
    copy = (f" (sites searched on a {where}-vertex copy)" if where is not None
            and shape.n_vertices > where else "")
    _status(args, f"{args.kind} x{args.count} on {shape.n_vertices} vertices{copy}")
    p = fn(shape, args.count, radius=args.radius, seed=args.seed, **extra)
    out = Path(args.output)
    if out.parent and not out.parent.exists():
        raise _UserError(f"output folder {out.parent} does not exist")
    save(p.mesh, out)
    # ground truth: output vertex i is input vertex vertex_map[i] (file numbering)
    sidecar = out.with_name(_stem(out) + ".map.npz")
    atomic_savez_compressed(sidecar, vertex_map=shape.input_ids[p.vertex_map].astype(np.int64),
                            sites=shape.input_ids[p.sites].astype(np.int64), kind=p.kind,
                            euler_before=p.euler_before, euler_after=p.euler_after,
                            params=json.dumps(p.params, default=_json_value))
    print(f"{args.input} -> {out}: {args.kind} x{args.count}, Euler characteristic "
          f"{p.euler_before} -> {p.euler_after}, boundary loops {p.boundary_loops_before} -> "
          f"{p.boundary_loops_after}; ground-truth vertex map in {sidecar}")
    return 0


def cmd_demo(args) -> int:
    from .metrics import metric_solver
    from .sampling import farthest_point_sampling
    from .shapes import torus

    np.set_printoptions(precision=3, suppress=True, linewidth=120)
    shape = torus(64, 32)
    print(f"gromov {__version__} demo: a built-in torus, {shape.n_vertices} vertices, "
          f"Euler characteristic {shape.euler_characteristic}, genus {shape.genus:g}\n")
    for metric, opts in (("geodesic", {}), ("diffusion", {"kernel": "heat"}),
                         ("diffusion", {"kernel": "connectivity"})):
        t = time.perf_counter()
        s = metric_solver(shape, metric, **opts)
        d = s.pairwise()
        fps = farthest_point_sampling(s, args.samples, seed=args.seed)
        label = metric + (f" ({opts['kernel']} kernel)" if opts else "")
        print(f"{label}: all {shape.n_vertices}^2 distances in {time.perf_counter() - t:.2f} s, "
              f"diameter {d.max():.4g}")
        print(f"  {args.samples} farthest point samples {fps.indices.tolist()}")
        print(f"  covering radius {fps.radius:.4g} (after each sample: "
              + ", ".join(f"{r:.3g}" for r in fps.radii) + ")")
        print("  distances between the first 6 samples:")
        print("  " + str(s.submatrix(fps.indices[:6])).replace("\n", "\n  ") + "\n")

    from .gh import match
    from .shapes import grid, rolled_grid

    print("Gromov-Hausdorff distances (GMDS, 40 samples, geodesic and diffusion), relative to the diameter:")
    sheet = grid(31, 16)
    others = {"the same sheet rolled into a half-cylinder (isometric)": rolled_grid(31, 16),
              "a sheet twice as long": grid(41, 11, width=2 * np.pi),
              "the torus": shape}
    for label, other in others.items():
        vals = []
        for metric in ("geodesic", "diffusion"):
            r = match(sheet, other, metric, n_samples=40, resolution=None, seed=args.seed)
            vals.append(f"{metric} {r.relative_distance:.4f}")
        print(f"  sheet vs {label}: " + ", ".join(vals))
    return 0


def cmd_reproduce(args) -> int:
    import os

    from .experiments.datasets import data_root
    from .experiments.report import PAPER, PAPER_CLASSES, other_classes
    from .experiments.reproduce import METRICS, RESULT_KEYS, check_dependencies, reproduce

    try:
        check_dependencies()
    except ImportError as exc:
        raise _UserError(str(exc)) from None
    data = None
    if args.data is not None:
        data = data_root(args.data or None)   # "--data" alone: $GROMOV_DATA or ../shared/data
    command = "gromov reproduce " + " ".join(sys.argv[2:]) if len(sys.argv) > 1 else "gromov reproduce"
    diffusion = _diffusion_options(args)
    if args.store is not None and Path(args.store).resolve().is_relative_to(Path(args.out).resolve()):
        raise _UserError(f"--store {args.store} is inside --out {args.out}, which is replaced as a whole "
                         "when the run is complete: keep the store outside it")
    store, handler = _open_store(args)
    try:
        r = reproduce(data, args.out, quick=args.quick, jobs=args.jobs, seed=args.seed, quiet=args.quiet,
                      command=command.strip(), diffusion=diffusion, weld_join=args.weld_join,
                      classes=args.classes, topkids=not args.no_topkids, rank_by=args.rank_by,
                      rank_tau_scale=args.rank_tau_scale, rank_residual=args.rank_residual,
                      pose_stretch=args.pose_stretch,
                      local_scaling=LOCAL_SCALING_K if args.local_scaling is None else args.local_scaling,
                      store=store)
    finally:
        _close_store(store, handler)
    def paper(key):   # the paper's number for a results key (report.PAPER is the one source)
        a, b, c = key.split(".")
        return PAPER["eer"][b][c] if a == "eer" else PAPER["correspondence"][b][
            "clean" if c == "clean" else "topology"]

    print(f"{r['dataset']}{' (quick)' if r['quick'] else ''}: {r['seconds_total']:.0f} s; "
          f"report {os.path.join(args.out, 'index.html')}")
    opts = r["params"]["metric_options"]["diffusion"]
    copts = r["params"]["correspondence_options"]["diffusion"]
    words = lambda o: ", ".join(f"{k}={v}" for k, v in o.items())  # noqa: E731
    print("  diffusion metric: " + words(opts)
          + ("" if copts == opts else f" (recognition); {words(copts)} (correspondence)")
          + f"; welds: {r['params']['weld_join']}")
    if r["store"] is not None:
        st = r["store"]
        print(f"  store {args.store}: {st['shapes_read']} shapes read from it, {st['shapes_computed']} "
              f"computed; {st['pairs_read']} pairs read")
    other = other_classes(r)
    if other:
        print(f"  classes {', '.join(other)}: the paper's numbers are for {', '.join(PAPER_CLASSES)}")
    params = r["params"]
    rank = ("the trimmed distortion" if params.get("rank_by") == "trimmed" else "the GH estimate") + " (--rank-by)"
    if params.get("rank_by") == "trimmed":
        rank += (" of the log distance ratios" if params.get("rank_residual") == "log"
                 else " of the distance differences") + " (--rank-residual)"
        if params.get("rank_tau_scale") is not None:
            rank += (f", for diffusion measured at {params['rank_tau_scale']:g} x the diffusion time "
                     f"(--rank-tau-scale)")
    ks = sorted({r["recognition"][e][m]["local_scaling_k"] for e in r["recognition"] for m in METRICS})
    print(f"  EERs rank pairs by {rank}; in brackets the other's EER, and the EER after local "
          f"scaling (k = {', '.join(map(str, ks))}, --local-scaling)")
    print(f"  {'result':<34}{'ours':>9}{'paper (TOSCA)':>15}")
    for key in RESULT_KEYS:
        v = r[key]
        alt = ""
        if key.startswith("eer."):
            _, exp, m = key.split(".")
            rec = r["recognition"][exp][m]
            other = rec["eer_gh"] if rec["ranked_by"] == "trimmed" else rec["eer_trimmed"]
            alt = f"  ({other:.4f}; local {rec['eer_local']:.4f})"
        print(f"  {key:<34}{'-' if v is None else format(v, '.4f'):>9}{paper(key):>15.4f}{alt}")
    if r["topkids"] is not None:
        for m in ("geodesic", "diffusion"):
            print(f"  {'topkids.' + m + '.correspondence':<34}{r['topkids'][m]['correspondence']:>9.4f}")
    return 0


# ----------------------------------------------------------------------------- parser
def _info_parser(sub) -> None:
    q = sub.add_parser("info", help="counts, topology, diameter and bounding box of a mesh")
    q.add_argument("mesh", help="OFF, OBJ, PLY, STL, MAT, TOSCA .vert/.tri, XYZ point clouds (optionally "
                                ".gz); VTK, VTU, Gmsh, Medit with gromov[formats]")
    q.add_argument("-q", "--quiet", action="store_true", help="no status line")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    _add_input_args(q)
    q.set_defaults(func=cmd_info)


def _distances_parser(sub) -> None:
    q = sub.add_parser("distances", help="distance matrix between farthest point samples")
    q.add_argument("mesh")
    _add_metric_args(q)
    q.add_argument("--resolution", type=_positive_int, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION}; meshes "
                        "with fewer vertices are used as they are)")
    q.add_argument("--samples", type=_positive_int, default=None,
                   help="number of farthest point samples (default: all working vertices)")
    q.add_argument("--seed", type=int, default=0, help="seed of the first sample (default 0)")
    q.add_argument("--out", required=True, help="output .npz with 'distances' (K,K) and 'samples' (K,)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    _add_input_args(q)
    q.set_defaults(func=cmd_distances)


def _match_parser(sub) -> None:
    q = sub.add_parser("match", help="Gromov-Hausdorff distance and correspondence of two shapes")
    q.add_argument("x", help="first mesh (or point cloud: a file without faces; its images are points, "
                             "face -1 in --out)")
    q.add_argument("y", help="second mesh (or point cloud)")
    _add_metric_args(q, "normalized (the correspondence's; raw when --tau is given)")
    q.add_argument("--samples", type=_positive_int, default=100, help="samples per shape (default 100)")
    q.add_argument("--norm", type=_norm_arg, default="l2", help="l2 (default), linf or p:VALUE")
    q.add_argument("--solver", choices=("gmds", "gw"), default="gmds",
                   help="symmetric GMDS (default) or Gromov-Wasserstein (POT) on the same samples")
    q.add_argument("--resolution", type=_positive_int, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION})")
    q.add_argument("--search-vertices", type=_positive_int, default=None, metavar="K",
                   help="faster, less reliable on welded shapes: run GMDS's initial search on K "
                        "farthest point samples of each shape (e.g. 500; default: all vertices)")
    q.add_argument("--orientation", choices=("prefer", "ignore"), default="prefer",
                   help="prefer (default): among near-optimal maps, one that keeps the surfaces' "
                        "orientation rather than a mirror image, and their bending rather than a half "
                        "turn; ignore: the lowest distortion found")
    q.add_argument("--signature-weight", type=_nonnegative_float, default=None, metavar="W",
                   help="weight of the distance signatures in the extra coarse stages of GMDS's "
                        "initial search (default: gromov.match's; 0: distances only)")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.add_argument("--out", default=None, help="write the correspondences to this .npz")
    q.add_argument("--dense", nargs="?", const="input", choices=("input", "zoomout", "placed"), default=None,
                   help="also map every vertex: an image on Y for each vertex of X and on X for "
                        "each vertex of Y (x_to_y_dense_vertex/face/bary and y_to_x_dense_* in --out), "
                        "placed by its distances to the samples and refined by ZoomOut on the input "
                        "meshes; '--dense zoomout': refined on the working meshes instead; "
                        "'--dense placed': without a refinement")
    q.add_argument("--map", default=None, metavar="FILE.txt",
                   help="write the dense X -> Y vertex map: one 1-based vertex id of Y per vertex "
                        "of X, one per line (SHREC's format; implies --dense)")
    q.add_argument("--plot", default=None, metavar="FILE.png",
                   help="draw the correspondence: the cells of X's samples and, in the same "
                        "colours, the cells around their images on Y; with --dense, X's "
                        "colours carried to Y by the dense map")
    q.add_argument("--html", default=None, metavar="FILE.html",
                   help="write one self-contained page showing both shapes side by side, to turn "
                        "and zoom: X's colours carried to Y by the dense map, and the sample "
                        "correspondences (implies --dense; needs plotly)")
    q.add_argument("--store", default=None, metavar="DIR",
                   help="shape store (gromov index): read each shape's working mesh and metric, "
                        "in the correspondence's metric options, from it or add them (created if "
                        "missing); the same match as without it")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_input_args(q)
    q.set_defaults(func=cmd_match)


def _index_parser(sub) -> None:
    q = sub.add_parser("index", help="compute each shape's working mesh and metric once and keep "
                                     "them in a shape store, for pairwise --store")
    q.add_argument("files", nargs="+", metavar="FILE", help="meshes or point clouds")
    q.add_argument("--store", required=True, metavar="DIR",
                   help="the store's folder (created if missing): catalogue.sqlite and one .npz "
                        "per shape and set of options")
    _add_metric_args(q)
    q.add_argument("--resolution", type=_positive_int, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION})")

    q.add_argument("--rank-tau-scale", type=_rank_tau_scale, default=RANK_TAU_SCALE, metavar="S",
                   help=f"heat-kernel diffusion: also keep the heat distance at S times the diffusion "
                        f"time that pairwise ranks by (default {RANK_TAU_SCALE:g}, as pairwise)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    _add_input_args(q)
    q.set_defaults(func=cmd_index)


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {v}")
    return v


def _search_parser(sub) -> None:
    q = sub.add_parser("search", help="the shapes of a shape store nearest to a query, skipping the "
                                      "pairs a per-shape bound rules out")
    q.add_argument("query", help="a mesh or point cloud (left out of its own results if it is in the store)")
    q.add_argument("--store", required=True, metavar="DIR", help="a shape store made by gromov index")
    q.add_argument("-k", type=_positive_int, default=5, help="neighbours to return (default 5)")
    _add_metric_args(q)
    q.add_argument("--resolution", type=_positive_int, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count the store was indexed with (default {DEFAULT_RESOLUTION})")
    q.add_argument("--samples", type=_positive_int, default=100, help="samples per shape (default 100)")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--rank-by", choices=("trimmed", "gh"), default="trimmed",
                   help="rank by the trimmed distortion of each pair's correspondence (default, as "
                        "pairwise) or by the GH estimate")
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
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_input_args(q)
    q.set_defaults(func=cmd_search)


def _pairwise_parser(sub) -> None:
    q = sub.add_parser("pairwise", help="Gromov-Hausdorff distances between all pairs of a set of "
                                        "shapes; nearest neighbours, EER and an MDS map")
    q.add_argument("files", nargs="+", metavar="FILE", help="meshes (two or more)")
    _add_metric_args(q)
    q.add_argument("--samples", type=_positive_int, default=100, help="samples per shape (default 100)")
    q.add_argument("--resolution", type=_positive_int, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION})")
    q.add_argument("--seed", type=int, default=0)
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
    q.add_argument("--rank-by", choices=("trimmed", "gh"), default="trimmed",
                   help="nearest neighbours, EER and MDS by the trimmed distortion of each pair's "
                        "correspondence (default, as gromov reproduce) or by the GH estimate")
    _add_rank_args(q)
    q.add_argument("--out", default=None, metavar="FILE",
                   help=".npz with all matrices, or .csv with the matrix the results rank by "
                        "(named in its first cell)")
    q.add_argument("--mds", default=None, metavar="FILE.png", help="draw a 2-D MDS map of the shapes")
    q.add_argument("-k", "--nearest", dest="k", type=_positive_int, default=None, metavar="K",
                   help="match only the pairs that can be among some shape's K nearest (the pruning "
                        "of gromov search: recall 1.0 on the validation sets, not guaranteed); the "
                        "others are empty (NaN) in the matrices and not counted; no equal error rate "
                        "or MDS map (they need every pair); refused with --dask or --scheduler")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.add_argument("--store", default=None, metavar="DIR",
                   help="shape store (gromov index): read each shape's metric from it or add it, "
                        "and record each pair as it finishes; a run stopped at any point continues "
                        "where it stopped")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_input_args(q)
    q.set_defaults(func=cmd_pairwise)


def _perturb_parser(sub) -> None:
    q = sub.add_parser("perturb", help="topological noise: weld close parts, or punch holes")
    q.add_argument("kind", choices=("weld", "holes"))
    q.add_argument("input")
    q.add_argument("output")
    q.add_argument("--count", type=_positive_int, required=True, help="number of welds or holes")
    q.add_argument("--radius", type=float, default=None,
                   help="weld: search radius for close pairs; holes: geodesic radius (defaults in the docs)")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--join", choices=WELD_JOINS, default=None,
                   help="weld: join the two places by a short handle (tube, default: the mesh "
                        "stays manifold, like SHREC'16 TOPKIDS' merged contacts) or merge their "
                        "vertices (pinch: the paper's welded vertices, what `gromov reproduce` "
                        "uses; a non-manifold vertex that some tools reject)")
    q.add_argument("--min-geodesic-ratio", type=float, default=None, metavar="R",
                   help="weld: the path along the surface must be R times the gap (default 4)")
    q.add_argument("--separation", type=float, default=None,
                   help="weld: least distance along the surface between two welds "
                        "(default: half the radius)")
    q.add_argument("--resolution", type=_nonnegative_int, default=None, metavar="N",
                   help="weld: search the sites on a copy simplified to N vertices (default "
                        "3000; 0: on the mesh itself) and glue them on the mesh")
    q.add_argument("-q", "--quiet", action="store_true", help="no status line")
    _add_input_args(q)
    q.set_defaults(func=cmd_perturb)


def _reproduce_parser(sub) -> None:
    q = sub.add_parser("reproduce", help="the paper's experiments, results.json and an HTML report")
    q.add_argument("--data", nargs="?", const="", default=None, metavar="DIR",
                   help="directory with tosca/ (and topkids/); '--data' alone: $GROMOV_DATA. "
                        "Without it: the built-in synthetic set")
    q.add_argument("--out", default="gromov-reproduce", help="output directory (default gromov-reproduce)")
    q.add_argument("--quick", action="store_true", help="a smaller run (fewer shapes and samples)")
    q.add_argument("--jobs", type=_positive_int, default=None,
                   help="worker processes (default: the CPUs available)")
    q.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    q.add_argument("--kernel", choices=("heat", "connectivity", "gaussian", "biharmonic"), default="heat",
                   help="diffusion metric: heat kernel (default), the paper's connectivity-kernel graph "
                        "diffusion (m = 50), Gaussian k-NN graph diffusion, or the biharmonic distance")
    _add_heat_args(q, "raw for recognition (the EERs), normalized for the correspondence (d(C,C0), "
                      "TOPKIDS); --units or --tau given: the same metric for both")
    q.add_argument("--weld-join", choices=WELD_JOINS, default="pinch",
                   help="Experiment 1 welds: merge two vertices (pinch, the paper's welded vertices; "
                        "default) or join their 1-rings by a short handle (tube)")
    q.add_argument("--classes", type=_classes, default=None, metavar="C:N,...",
                   help="TOSCA classes instead of the paper's, each with its number of deformations "
                        "in Experiment 1, e.g. wolf:2,horse:4,centaur:5,michael:6 (Experiment 2: "
                        "up to 2 each)")
    q.add_argument("--no-topkids", action="store_true", help="skip the TOPKIDS part")
    q.add_argument("--rank-by", choices=("trimmed", "gh"), default="trimmed",
                   help="recognition ranks pairs by the trimmed distortion of their GH correspondence "
                        "(RMS of its best-fitting 80%% of pairs; default) or by the GH estimate; "
                        "results.json has both EERs")
    _add_rank_args(q)
    q.add_argument("--pose-stretch", type=float, default=0.0, metavar="S",
                   help="synthetic set only: stretch its poses so that they are not isometric, as "
                        "TOSCA's are not (0.1: geodesic distances change by 2.4-6.5%%; default 0)")
    q.add_argument("--store", default=None, metavar="DIR",
                   help="shape store (created if missing; not inside --out): read every shape's "
                        "metrics, the recognition's pairs and the correspondence error's geodesic "
                        "rows from it or add them, so that a second run computes no metric again; "
                        "the same results as without it")
    q.set_defaults(func=cmd_reproduce)


def _demo_parser(sub) -> None:
    q = sub.add_parser("demo", help="distances and samples on a built-in shape")
    q.add_argument("--samples", type=_positive_int, default=12)
    q.add_argument("--seed", type=int, default=0)
    q.set_defaults(func=cmd_demo)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gromov", description=(
        "Non-rigid shape matching in the Gromov-Hausdorff framework with diffusion geometry."))
    p.add_argument("--version", action="version", version=f"gromov {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0, help="log progress (-vv: debug)")
    sub = p.add_subparsers(dest="command", required=True)
    _info_parser(sub)
    _distances_parser(sub)
    _match_parser(sub)
    _index_parser(sub)
    _search_parser(sub)
    _pairwise_parser(sub)
    _perturb_parser(sub)
    _reproduce_parser(sub)
    _demo_parser(sub)
    return p


def _announce_compilation():
    """Say once on stderr when numba starts compiling a kernel: the first run after an
    install compiles for tens of seconds, later runs load the compiled code from the cache.
    Returns the listener, for ``numba.core.event.unregister("numba:compile", ...)``."""
    from numba.core import event

    class _Note(event.Listener):
        said = False

        def on_start(self, ev):
            if not self.said:
                self.said = True
                print("gromov: compiling kernels, first run only", file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    note = _Note()
    event.register("numba:compile", note)
    return note


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
                        format="%(levelname)s %(name)s: %(message)s")
    warnings.simplefilter("default")
    warnings.formatwarning = lambda msg, cat, *a, **k: f"gromov: warning: {msg}\n"
    note = None
    if args.func is not cmd_demo and not getattr(args, "quiet", False) and sys.stderr.isatty():
        note = _announce_compilation()   # on a terminal, like the progress bars
    try:
        return args.func(args)
    except (GromovError, _UserError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        print(f"gromov: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # invalid parameter values that reached the library
        print(f"gromov: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # pragma: no cover
        print("gromov: interrupted", file=sys.stderr)
        return 130
    finally:
        if note is not None:
            from numba.core import event

            event.unregister("numba:compile", note)
