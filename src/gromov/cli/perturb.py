"""``gromov perturb``: topological noise on a mesh (welds or holes), or a part of it (a plane cut
or large holes), with its ground-truth vertex map beside it."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from .._atomic import atomic_savez_compressed
from .._defaults import CUT_KINDS, CUT_PATCHES, WELD_JOINS
from ._args import _add_input_args, _nonnegative_int, _positive_int
from ._common import _UserError, _check_folder, _load, _status, _stem


def _check_options(args) -> None:
    """Each option applies to some of the perturbations: a wrong one is one clear line."""
    only = {"weld": {"--join": args.join, "--min-geodesic-ratio": args.min_geodesic_ratio,
                     "--separation": args.separation, "--resolution": args.resolution},
            "cut": {"--keep": args.keep, "--kind": args.cut_kind}}
    for kind, options in only.items():
        given = [k for k, v in options.items() if v is not None]
        if args.kind != kind and given:
            raise _UserError(f"{', '.join(given)} applies to {kind}, not to {args.kind}")
    if args.kind == "cut":
        if args.radius is not None:
            raise _UserError("--radius applies to weld and holes, not to cut")
        if args.keep is None:
            raise _UserError("cut needs --keep: the fraction of the area the part keeps, e.g. --keep 0.6")
        if args.count is not None and (args.cut_kind or "plane") != "holes":
            raise _UserError("--count applies to cut --kind holes (the number of patches), not to a plane cut")
    elif args.count is None:
        raise _UserError(f"{args.kind} needs --count: the number of {'welds' if args.kind == 'weld' else 'holes'}")


def cmd_perturb(args) -> int:
    from ..io import save
    from ..mesh import Mesh
    from ..perturb import WELD_RESOLUTION, cut, holes, weld

    _check_options(args)
    if Path(args.output).resolve() == Path(args.input).resolve():
        raise _UserError(f"{args.output} is the input mesh: give the perturbed copy another name")
    shape = _load(args.input, args)
    if not isinstance(shape, Mesh):
        raise _UserError(f"{args.input}: perturbations need a triangle mesh, got a point cloud")
    extra = {}
    if args.kind == "weld":
        extra = {k: v for k, v in (("join", args.join), ("min_geodesic_ratio", args.min_geodesic_ratio),
                                   ("separation", args.separation)) if v is not None}
        if args.resolution is not None:
            extra["resolution"] = None if args.resolution == 0 else args.resolution
    where = extra.get("resolution", WELD_RESOLUTION) if args.kind == "weld" else None
    copy = (f" (sites searched on a {where}-vertex copy)" if where is not None
            and shape.n_vertices > where else "")
    out = Path(args.output)
    _check_folder(out, "OUTPUT")
    if args.kind == "cut":
        kind = args.cut_kind or "plane"
        _status(args, f"cut ({kind}) keeping {args.keep:g} of the area of {shape.n_vertices} vertices")
        p = cut(shape, args.keep, kind=kind, count=args.count, seed=args.seed)
        what = (f"cut ({kind}), {p.params['kept']:.1%} of the area kept, {shape.n_vertices} -> "
                f"{p.mesh.n_vertices} vertices")
    else:
        _status(args, f"{args.kind} x{args.count} on {shape.n_vertices} vertices{copy}")
        fn = weld if args.kind == "weld" else holes
        p = fn(shape, args.count, radius=args.radius, seed=args.seed, **extra)
        what = f"{args.kind} x{args.count}"
    save(p.mesh, out)
    # ground truth: output vertex i is input vertex vertex_map[i] (file numbering)
    sidecar = out.with_name(_stem(out) + ".map.npz")
    atomic_savez_compressed(sidecar, vertex_map=shape.input_ids[p.vertex_map].astype(np.int64),
                            sites=shape.input_ids[p.sites].astype(np.int64), kind=p.kind,
                            euler_before=p.euler_before, euler_after=p.euler_after,
                            params=json.dumps(p.params, default=_json_value))
    print(f"{args.input} -> {out}: {what}, Euler characteristic "
          f"{p.euler_before} -> {p.euler_after}, boundary loops {p.boundary_loops_before} -> "
          f"{p.boundary_loops_after}; ground-truth vertex map in {sidecar}")
    return 0


def _json_value(o):
    """numpy scalars and arrays (e.g. a weld's gaps) as JSON numbers and lists."""
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _fraction(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction between 0 and 1, got {text!r}") from None
    if not 0.0 < v < 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction strictly between 0 and 1, got {v:g}")
    return v


def _perturb_parser(sub) -> None:
    q = sub.add_parser("perturb", help="topological noise: weld close parts, or punch holes; or "
                                       "cut a part off",
                       epilog="Beside the output, NAME.map.npz (NAME: the output's file name without its "
                              "extension) holds the ground truth: vertex_map[i] is the input file's "
                              "vertex (0-based) of output vertex i.")
    q.add_argument("kind", choices=("weld", "holes", "cut"))
    q.add_argument("input")
    q.add_argument("output")
    q.add_argument("--count", type=_positive_int, default=None,
                   help="number of welds or holes (required for weld and holes); cut --kind holes: "
                        f"number of patches (default {CUT_PATCHES})")
    q.add_argument("--radius", type=float, default=None,
                   help="weld: search radius for close pairs; holes: geodesic radius (defaults in the docs)")
    q.add_argument("--seed", type=_nonnegative_int, default=0,
                   help="seeds where the welds, the holes or the cut go (default 0)")
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
    q.add_argument("--keep", type=_fraction, default=None, metavar="F",
                   help="cut: the fraction of the area the part keeps, between 0 and 1 (required), "
                        "within 0.02; the largest connected piece is kept")
    q.add_argument("--kind", dest="cut_kind", choices=CUT_KINDS, default=None,
                   help="cut: one side of a plane of random direction (plane, default; SHREC'16 "
                        "Partial's cuts) or the surface outside patches of random centres grown "
                        "until the rest keeps F (holes)")
    q.add_argument("-q", "--quiet", action="store_true", help="no status line")
    _add_input_args(q)
    q.set_defaults(func=cmd_perturb)
