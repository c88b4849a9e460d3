"""``gromov match``: the Gromov-Hausdorff distance and correspondence of two shapes, with its
dense maps, pictures and files."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._atomic import atomic_path, atomic_savez_compressed
from .._defaults import DEFAULT_RESOLUTION
from ._args import (_add_input_args, _add_metric_args, _metric_options, _nonnegative_float,
                    _nonnegative_int, _norm_arg, _positive_int, _sample_count, _working_size)
from ._common import (_UserError, _check_folder, _check_memory, _check_neighbors, _check_npz, _check_pieces, _check_png,
                      _close_store, _count, _dumps, _load, _open_store, _status)


def cmd_match(args) -> int:
    from ..gh import match
    from ..metrics.diffusion import correspondence_options
    from ..search import SearchOptions
    from ..shape_metric import ShapeMetric

    if args.metric is None:
        from ..partial import PARTIAL_METRIC

        args.metric = PARTIAL_METRIC if args.partial else "diffusion"
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
        _check_npz(args.out, "--out")
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
    if args.partial and (args.norm != "l2" or args.solver != "gmds"):
        raise _UserError("--partial takes the l2 norm and the gmds solver")
    if args.partial and args.dense == "zoomout":
        raise _UserError("--partial refines the dense map on the input meshes: --dense, --dense input or "
                         "--dense placed")
    r = match(shapes[0], shapes[1], args.metric, n_samples=args.samples, norm=args.norm,
              solver=args.solver, seed=args.seed, orientation=args.orientation, dense=dense, search=search,
              partial=args.partial)
    if args.out:
        atomic_savez_compressed(args.out, **r.arrays())
    if args.map:   # SHREC's exchange format: one 1-based vertex id of Y per vertex of X
        with atomic_path(args.map) as tmp:
            np.savetxt(tmp, r.x_to_y_dense_vertex + 1, fmt="%d")
    if args.plot:
        (_plot_dense if dense else _plot_match)(r, shapes, args)
    if args.html:
        from ..experiments.view import write_match_html

        write_match_html(shapes[0].input, shapes[1].input, r, args.html,
                         titles=(Path(args.x).name, Path(args.y).name))
    stored = None if store is None else {"path": args.store, "shapes_read": store.reused,
                                         "shapes_computed": store.computed}
    if args.json:   # the metric's options too: the distance's units depend on them
        print(_dumps({**r.to_dict(), "metric_options": options, **({} if stored is None else {"store": stored})}))
    elif args.partial:
        _print_partial(r, args, dense, store, stored)
    else:
        print(f"{args.x} vs {args.y}: Gromov-Hausdorff distance {r.distance:.6g} "
              f"({r.norm} norm, {r.relative_distance:.4%} of the diameter), {args.metric} metric, {r.solver}, "
              f"{r.n_samples} samples per shape")
        if all(s.has_faces for s in shapes):
            how = f"{_count(r.n_iter, 'iteration')}, {'converged' if r.converged else 'not converged'}"
        else:
            how = "images at points (a point cloud: no GMDS refinement inside triangles)"
        rms = "" if r.norm == "l2" else f", rms {r.distortion_l2:.6g}"   # l2 is the rms
        print(f"  distortion: {r.norm} {r.distortion:.6g}{rms}, "
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


def _print_partial(r, args, dense, store, stored) -> None:
    print(f"{args.x} as a part of {args.y}: partial distance {r.distance:.6g} ({r.relative_distance:.4%} "
          f"of the diameter of {args.y}), {args.metric} metric, {r.n_samples} samples of the part")
    print(f"  covered region: {r.covered_fraction:.1%} of the area of {args.y} "
          f"({int(r.y_covered.sum())} of its vertices); weighted rms distortion {r.distortion_l2:.6g}, "
          f"max {r.distortion_linf:.6g}; {_count(r.n_iter, 'iteration')}, "
          f"{'converged' if r.converged else 'not converged'}, {r.seconds:.2f} s")
    if dense:
        print(f"  dense map: {len(r.x_to_y_dense_vertex)} vertices of the part on the whole")
    if stored is not None:
        print(f"  store {args.store}: {store.reused} of 2 shapes read from it, {store.computed} computed")
    for f in (args.out, args.map, args.plot, args.html):
        if f:
            print(f"  wrote {f}")


def _match_parser(sub) -> None:
    q = sub.add_parser("match", help="Gromov-Hausdorff distance and correspondence of two shapes")
    q.add_argument("x", help="first mesh (or point cloud: a file without faces; its images are points, "
                             "face -1 in --out)")
    q.add_argument("y", help="second mesh (or point cloud)")
    _add_metric_args(q, "normalized (the correspondence's; raw when --tau is given)")
    for action in q._actions:   # with --partial the metric defaults to geodesic
        if action.dest == "metric":
            action.default, action.help = None, "distance on the surface (default: diffusion; with --partial geodesic)"
    q.add_argument("--samples", type=_sample_count, default=100, help="samples per shape (default 100)")
    q.add_argument("--norm", type=_norm_arg, default="l2", help="l2 (default), linf or p:VALUE")
    q.add_argument("--solver", choices=("gmds", "gw"), default="gmds",
                   help="symmetric GMDS (default) or Gromov-Wasserstein (POT) on the same samples")
    q.add_argument("--resolution", type=_working_size, default=DEFAULT_RESOLUTION,
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
    q.add_argument("--seed", type=_nonnegative_int, default=0)
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.add_argument("--out", default=None, help="write the correspondences to this .npz")
    q.add_argument("--dense", nargs="?", const="input", choices=("input", "zoomout", "placed"), default=None,
                   help="also map every vertex: an image on Y for each vertex of X and on X for "
                        "each vertex of Y (x_to_y_dense_vertex/face/bary and y_to_x_dense_* in --out), "
                        "placed by its distances to the samples, refined by ZoomOut on the input "
                        "meshes and made locally isometric; '--dense zoomout': refined on the "
                        "working meshes instead; "
                        "'--dense placed': without a refinement")
    q.add_argument("--map", default=None, metavar="FILE.txt",
                   help="write the dense X -> Y vertex map: one 1-based vertex id of Y per vertex "
                        "of X, one per line (SHREC's format; 0 for a vertex without an image; "
                        "implies --dense)")
    q.add_argument("--plot", default=None, metavar="FILE.png",
                   help="draw the correspondence: the cells of X's samples and, in the same "
                        "colours, the cells around their images on Y; with --dense, X's "
                        "colours carried to Y by the dense map")
    q.add_argument("--html", default=None, metavar="FILE.html",
                   help="write one self-contained page showing both shapes side by side, to turn "
                        "and zoom: X's colours carried to Y by the dense map, and the sample "
                        "correspondences (implies --dense; needs plotly)")
    q.add_argument("--partial", action="store_true",
                   help="X is a part of Y (given, not detected): only X's samples are embedded "
                        "into Y, X measured in Y's metric, samples near X's boundary down-weighted; "
                        "reports the partial distance, the share of Y's area the part covers and "
                        "the covered region (y_covered in --out, grey outside it in --plot and --html)")
    q.add_argument("--store", default=None, metavar="DIR",
                   help="shape store (gromov index): read each shape's working mesh and metric, "
                        "in the correspondence's metric options, from it or add them (created if "
                        "missing); the same match as without it")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_input_args(q)
    q.set_defaults(func=cmd_match)


def _plot_match(r, shapes, args) -> None:
    """``gromov match --plot``: the cells of X's samples and, in the same colours, the cells
    around their images on Y (each by the match's metric on the working meshes), as in the
    correspondence figures of Bronstein et al. (IJCV 2010, §5)."""
    from ..experiments.report import plot_correspondence, voronoi_labels

    sx, sy = shapes

    def working(s, ids):   # input-file ids -> nearest working vertices
        return s.working.from_source(s.working.source.from_input_ids(ids))

    x_labels = voronoi_labels(sx.distances[working(sx, r.x_samples)])
    y_labels = voronoi_labels(sy.distances[working(sy, r.x_to_y_vertex)])
    plot_correspondence(sx.mesh, sy.mesh, x_labels, y_labels, args.plot,
                        titles=(Path(args.x).name, Path(args.y).name),
                        title=f"{args.metric}: cells of the samples of {Path(args.x).name} carried "
                              f"to {Path(args.y).name} (relative GH {r.relative_distance:.2%})")


def _plot_dense(r, shapes, args) -> None:
    """``gromov match --dense --plot``: X painted by its coordinates and Y by the same colours
    carried through the dense map; where the map is unreliable (the nearest sample's
    distortion above three times the median) Y's colours are greyed."""
    from ..experiments.report import coordinate_colours, plot_transfer

    sx, sy = shapes
    x_rgb = coordinate_colours(sx.input)
    y_rgb = r.transfer(sx.input.per_file_vertex(x_rgb, fill=0.0), method="barycentric")[sy.input.input_ids]
    if r.partial:   # outside the region the part covers: grey
        outside = ~r.y_covered[sy.input.input_ids] | ~np.isfinite(y_rgb).all(axis=1)
        y_rgb[outside] = 0.8
        plot_transfer(sx.input, sy.input, x_rgb, y_rgb, args.plot,
                      titles=(Path(args.x).name, Path(args.y).name),
                      title=f"{args.metric}: colours of the part {Path(args.x).name} carried by the dense map\n"
                            f"(grey: outside the covered region, {outside.mean():.0%} of the vertices)")
        return
    _, e_y = r.sample_distortion
    q = sy.working.from_source(sy.input.from_input_ids(r.y_samples))
    nearest = np.argmin(sy.distances[:, q], axis=1)[sy.working.source_nearest]
    shaky = e_y[nearest] > 3.0 * np.median(e_y)
    y_rgb[shaky] = 0.35 * y_rgb[shaky] + 0.65 * 0.8
    plot_transfer(sx.input, sy.input, x_rgb, y_rgb, args.plot,
                  titles=(Path(args.x).name, Path(args.y).name),
                  title=f"{args.metric}: colours of {Path(args.x).name} carried by the dense map\n"
                        f"(grey: high distortion, {shaky.mean():.0%} of the vertices)")
