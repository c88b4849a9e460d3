"""``gromov info`` (counts, topology, diameter of one shape) and ``gromov distances`` (its
distance matrix between farthest point samples)."""

from __future__ import annotations

import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from .._atomic import atomic_savez_compressed
from .._defaults import DEFAULT_RESOLUTION
from ._args import _add_input_args, _add_metric_args, _metric_options, _nonnegative_int, _positive_int, _working_size
from ._common import _UserError, _check_memory, _check_neighbors, _check_npz, _dumps, _load, _status


def _progress(total: int, desc: str, quiet: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="row", disable=quiet or total < 512, leave=False,
                file=sys.stderr)


def cmd_info(args) -> int:
    from ..mesh import Mesh
    from ..metrics import GeodesicSolver

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


def _info_parser(sub) -> None:
    q = sub.add_parser("info", help="counts, topology, diameter and bounding box of a mesh")
    q.add_argument("mesh", help="OFF, OBJ, PLY, STL, MAT, TOSCA .vert/.tri, XYZ point clouds (optionally "
                                ".gz); VTK, VTU, Gmsh, Medit with gromov[formats]")
    q.add_argument("-q", "--quiet", action="store_true", help="no status line")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    _add_input_args(q)
    q.set_defaults(func=cmd_info)


def cmd_distances(args) -> int:
    from ..metrics import metric_solver
    from ..resolution import working_shape
    from ..sampling import farthest_point_sampling

    _check_npz(args.out, "--out")
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


def _distances_parser(sub) -> None:
    q = sub.add_parser("distances", help="distance matrix between farthest point samples")
    q.add_argument("mesh")
    _add_metric_args(q)
    q.add_argument("--resolution", type=_working_size, default=DEFAULT_RESOLUTION,
                   help=f"working mesh vertex count (default {DEFAULT_RESOLUTION}; meshes "
                        "with fewer vertices are used as they are)")
    q.add_argument("--samples", type=_positive_int, default=None,
                   help="number of farthest point samples (default: all working vertices)")
    q.add_argument("--seed", type=_nonnegative_int, default=0, help="seed of the first sample (default 0)")
    q.add_argument("--out", required=True, help="output .npz with 'distances' (K,K) and 'samples' (K,)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    _add_input_args(q)
    q.set_defaults(func=cmd_distances)
