"""The argument groups several commands share (input, metric, heat kernel, ranking), the
validators of single values (``type=`` of ``add_argument``), and the library options the metric
arguments stand for, checked against each other."""

from __future__ import annotations

import argparse
import re

import numpy as np

from .._defaults import (DEFAULT_UNITS, DIFFUSION_FILL_HOLES, GZIP_FLOOR, GZIP_RATIO, HEAT_UNITS,
                         LOCAL_SCALING_K, RANK_RESIDUAL, RANK_RESIDUALS, RANK_TAU_SCALE)
from ._common import _UserError


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


def _sample_count(text: str) -> int:
    """Samples per shape of a match: a correspondence needs three."""
    return _int_at_least(text, 3, "an integer >= 3")


def _working_size(text: str) -> int:
    """Vertices of a working mesh: a tetrahedron's four at least."""
    return _int_at_least(text, 4, "an integer >= 4")


def _nonnegative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not (np.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {v}")
    return v


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {v}")
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


def _classes(text: str) -> dict:
    out = {}
    for item in text.split(","):
        name, sep, n = item.partition(":")
        if not sep or not name.strip():
            raise argparse.ArgumentTypeError(f"expected CLASS:N[,CLASS:N...], got {item!r}")
        out[name.strip()] = _positive_int(n)
    return out   # the rest is checked by reproduce (settings_for)


def _rank_tau_scale(text: str) -> float | None:
    """``--rank-tau-scale``: a positive number; 1 is the metric of the match itself (None)."""
    from ..gh import check_rank_tau_scale

    try:
        v = check_rank_tau_scale(float(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    return None if v == 1.0 else v


def _norm_arg(text: str) -> str:
    from ..gmds import parse_norm

    try:
        parse_norm(text)
    except (TypeError, ValueError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _add_input_args(p: argparse.ArgumentParser) -> None:

    p.add_argument("--max-decompressed", type=_size, default=None, metavar="SIZE",
                   help=f"largest size a .gz input (or a compressed MATLAB variable) may decompress to, "
                        f"e.g. 4G (default: {GZIP_RATIO} times the compressed size, at least "
                        f"{GZIP_FLOOR // 2**20}M; refuses gzip bombs)")


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
                        "--units normalized, 0.005 with raw, length or area)")
    p.add_argument("--units", choices=HEAT_UNITS, default=None,
                   help="heat-kernel diffusion distance between normalised heat distributions "
                        "(normalized), in units of 1/length (raw), scaled to the geodesic "
                        "distance below the diffusion radius (length) or to unit area (area: "
                        "blind to size); default "
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
    p.add_argument("--kernel", choices=("heat", "connectivity", "gaussian", "biharmonic"), default=None,
                   help="diffusion kernel: the resolution-independent Laplace-Beltrami heat kernel "
                        "(default), the paper's connectivity kernel, a Gaussian k-NN kernel, or the "
                        "biharmonic distance (heat-kernel distances integrated over all times)")
    p.add_argument("--steps", type=_positive_int, default=None,
                   help="diffusion steps m of the graph kernels (default 50)")
    p.add_argument("--neighbors", type=_positive_int, default=None, metavar="K",
                   help="point clouds: each point's nearest neighbours in the geodesic metric's graph "
                        "(default 10) or in the heat / biharmonic kernels' Laplacian (default 20)")
    _add_heat_args(p, units_default)


def _kernel(args) -> str:
    """The diffusion kernel given, or the default: the heat kernel."""
    return getattr(args, "kernel", None) or "heat"


def _metric_options(args) -> dict:
    """The metric's options from the command line; an option of another metric than the one
    chosen is refused, not dropped."""
    if args.metric != "diffusion":
        for flag in ("--tau", "--units", "--fill-holes", "--kernel", "--steps"):
            if getattr(args, flag[2:].replace("-", "_"), None) is not None:
                raise _UserError(f"{flag} applies to --metric diffusion")
    if args.metric != "geodesic" and args.geodesic_method is not None:
        raise _UserError("--geodesic-method applies to --metric geodesic")
    refine = getattr(args, "refine", None) or None  # 0: the default, as if not given
    if refine is not None and (args.metric != "geodesic" or args.geodesic_method not in (None, "fmm")):
        raise _UserError("--refine applies to --metric geodesic with the fast marching (fmm)")
    neighbors = getattr(args, "neighbors", None)
    if neighbors is not None and not (args.metric == "geodesic" and args.geodesic_method in (None, "dijkstra")
                                      or args.metric == "diffusion" and _kernel(args) in ("heat", "biharmonic")):
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
    kernel = _kernel(args)
    opts = {"kernel": kernel}
    if args.tau is not None:
        if kernel != "heat":
            raise _UserError("--tau is the heat kernel's diffusion time: use it with --kernel heat")
        opts["tau"] = args.tau
    units = getattr(args, "units", None)
    if units is not None:
        if kernel != "heat":
            raise _UserError("--units applies to the heat kernel: use it with --kernel heat")
        opts["units"] = units
    steps = getattr(args, "steps", None)
    if steps is not None:
        if kernel not in ("connectivity", "gaussian"):
            raise _UserError("--steps is the graph kernels' number of diffusion steps: use it with "
                             "--kernel connectivity or gaussian")
        opts["m"] = steps

    fill = getattr(args, "fill_holes", None)
    if fill is not None and not 0 <= fill < float("inf"):
        raise _UserError(f"--fill-holes must be a finite number >= 0 (0: leave holes open), got {fill}")
    # recorded as used: the library's default unless given, None when switched off
    opts["fill_holes"] = DIFFUSION_FILL_HOLES if fill is None else (fill or None)
    return opts
