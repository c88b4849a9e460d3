"""``gromov reproduce`` (the paper's experiments, results.json and a report) and ``gromov demo``
(distances and matches on built-in shapes)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from .._defaults import LOCAL_SCALING_K, WELD_JOINS
from .._version import __version__
from ._args import (_add_heat_args, _add_rank_args, _classes, _diffusion_options, _nonnegative_int, _positive_int,
                    _sample_count)
from ._common import _UserError, _close_store, _open_store


def cmd_reproduce(args) -> int:
    import os

    from ..experiments.datasets import data_root
    from ..experiments.report import PAPER, PAPER_CLASSES, other_classes
    from ..experiments.reproduce import METRICS, RESULT_KEYS, check_dependencies, reproduce

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


def _reproduce_parser(sub) -> None:
    q = sub.add_parser("reproduce", help="the paper's experiments, results.json and an HTML report")
    q.add_argument("--data", nargs="?", const="", default=None, metavar="DIR",
                   help="directory with tosca/ (and topkids/); '--data' alone: $GROMOV_DATA. "
                        "Without it: the built-in synthetic set")
    q.add_argument("--out", default="gromov-reproduce", help="output directory (default gromov-reproduce)")
    q.add_argument("--quick", action="store_true", help="a smaller run (fewer shapes and samples)")
    q.add_argument("--jobs", type=_positive_int, default=None,
                   help="worker processes (default: the CPUs available)")
    q.add_argument("--seed", type=_nonnegative_int, default=0, help="sampling seed (default 0)")
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


def cmd_demo(args) -> int:
    from ..metrics import metric_solver
    from ..sampling import farthest_point_sampling
    from ..shapes import torus

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

    from ..gh import match
    from ..shapes import grid, rolled_grid

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


def _demo_parser(sub) -> None:
    q = sub.add_parser("demo", help="distances and samples on a built-in shape")
    q.add_argument("--samples", type=_sample_count, default=12)
    q.add_argument("--seed", type=_nonnegative_int, default=0)
    q.set_defaults(func=cmd_demo)
