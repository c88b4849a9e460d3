"""``gromov perturb``: topological noise on a mesh (welds or holes), with its ground-truth
vertex map beside it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._atomic import atomic_savez_compressed
from .._defaults import WELD_JOINS
from ._args import _add_input_args, _nonnegative_int, _positive_int
from ._common import _UserError, _load, _status, _stem


def cmd_perturb(args) -> int:
    from ..io import save
    from ..mesh import Mesh
    from ..perturb import WELD_RESOLUTION, holes, weld

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


def _json_value(o):
    """numpy scalars and arrays (e.g. a weld's gaps) as JSON numbers and lists."""
    if hasattr(o, "tolist"):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


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
