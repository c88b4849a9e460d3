"""Why some TOPKIDS maps score better against the mirrored ground truth: front/back turns.

Run:  .venv/bin/python benchmarks/studies/probe_front_back.py [--data DIR] [--kids kid10,kid15] [--turn-margin F]
                                                      [--basins] [--json OUT]

kidXX -> kid00, matched as ``gromov match`` does (diffusion, 3,000 working vertices, 100
samples, ``orientation="prefer"``), and again with ``orientation="ignore"``. Per pair:

- the orientation agreement of the map (:func:`gromov.orientation.orientation_agreement`) and
  that of the ground truth on the same samples (the true map keeps the orientation);
- the samples' mean error ÷ kid00's geodesic diameter against the direct and against the
  left/right mirrored ground truth (``kid00_sym.txt``);
- the RMS distortion of the two-sided sample correspondence, and that of the correspondence
  GMDS reaches from the *true* images of the samples, in the heat distance the match uses, at
  a quarter of its diffusion time, and in geodesic distance, each as all pairs and as the best
  fitting 70% (:func:`gromov.gmds.trimmed_rms`).

``--basins``: GMDS from every start of the search (its extended starts, and up to 8 more
orientation-preserving and 8 more reversing coarse starts per stage and direction, extended),
each result sorted by its error into a *basin* -- right (direct error below 0.1 of the
diameter), half turn (keeps the orientation, nearer the mirrored truth), left/right mirror
(reverses it, mirrored error below 0.1), front/back mirror (reverses it, direct error below
0.2), other -- with each basin's lowest distortion and the median difference of the smoothed
mean curvature (:func:`gromov.gh.curvature_mismatch`) of that map, at the default smoothing, a
fifth of it and none.

``--turn-margin 1`` turns off the choice by curvature of ``orientation="prefer"``
(:data:`gromov.gh.TURN_MARGIN`; no mismatch is lower by 100%): the matches as they were before
it.

A map that keeps the orientation (agreement near 1, like the truth) and yet is nearer the
mirrored ground truth sends left to right *and* front to back: a half turn about the body's
long axis. Where its distortion is below the truth's in every metric, no choice by distortion
can prefer the truth.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument, write_results

from gromov.evaluate import image_errors
from gromov.experiments import datasets
from gromov.gh import ShapeMetric, SymmetricGMDS, match
from gromov.gmds import trimmed_rms
from gromov.metrics.diffusion import correspondence_options
from gromov.orientation import orientation_agreement
from gromov.search import _at_vertices

HERE = Path(__file__).resolve().parent


def _working(s: ShapeMetric, ids) -> np.ndarray:
    """The working vertices nearest to input vertices ``ids``."""
    return s.working.from_source(s.input.from_input_ids(ids))


def _distortions(gm: SymmetricGMDS, img_p, img_q) -> tuple[float, float]:
    dx, dy = gm.blocks(img_p, img_q)
    r = (dx - dy)[~np.eye(len(dx), dtype=bool)]
    return float(np.sqrt(np.mean(r**2))), trimmed_rms(r, 0.7)


def probe(kids: datasets.TopKids, name: str, sy: ShapeMetric, gy: ShapeMetric, sym: np.ndarray) -> dict:
    x, y = kids.load(name), kids.load(kids.reference)
    gt = kids.ground_truth(name)
    sx = ShapeMetric(x, "diffusion", metric_options=correspondence_options("diffusion", None))
    gx = ShapeMetric(x, "geodesic")
    row = {"pair": f"{name}->{kids.reference}"}
    P, Q = sx.samples(100, 0), sy.samples(100, 0)
    xs = sx.working.to_input_ids(P)
    for mode in ("prefer", "ignore"):
        r = match(sx, sy, orientation=mode)
        row[mode] = {"orientation": r.orientation,
                     "error_direct": float(image_errors(r.x_samples, r.x_to_y_vertex, gy, gt).mean()),
                     "error_mirrored": float(image_errors(r.x_samples, r.x_to_y_vertex, gy, sym[gt]).mean())}
        if mode == "prefer":
            ours = _at_vertices(sx, sy, _working(sy, r.x_to_y_vertex), _working(sx, r.y_to_x_vertex))
    # the truth on the same samples: its orientation, and GMDS started from it
    (nx, _), (ny, _) = sx.normals, sy.normals
    tp = _working(sy, gt[xs])
    row["truth_orientation"] = orientation_agreement(sx.mesh.vertices[P], nx[P], sx.distances[np.ix_(P, P)],
                                                     sy.mesh.vertices[tp], ny[tp])
    _, inv = cKDTree(y.vertices[gt]).query(y.vertices[sy.working.to_input_ids(Q)])
    gm = SymmetricGMDS(sx.surface, sy.surface, P, Q)
    fp, fq, *_ = gm.solve(*_at_vertices(sx, sy, tp, _working(sx, inv)))
    truth = _at_vertices(sx, sy, fp.vertex(sy.mesh.faces), fq.vertex(sx.mesh.faces))
    row["truth_gmds_error"] = float(image_errors(xs, sy.working.to_input_ids(truth[0].vertex(sy.mesh.faces)),
                                                 gy, gt).mean())
    metrics = {"heat": (sx.surface, sy.surface),
               "heat_quarter_time": (sx.ranking_surface(0.25)[0], sy.ranking_surface(0.25)[0]),
               "geodesic": (gx.surface, gy.surface)}
    row["distortion"] = {}
    for key, (ax, ay) in metrics.items():
        g = SymmetricGMDS(ax, ay, P, Q)
        (o_all, o_trim), (t_all, t_trim) = _distortions(g, *ours), _distortions(g, *truth)
        row["distortion"][key] = {"ours": o_all, "truth": t_all, "ours_trimmed": o_trim, "truth_trimmed": t_trim}
    p = row["prefer"]
    turned = p["orientation"] > 0.5 and p["error_mirrored"] < p["error_direct"]
    row["half_turn"] = bool(turned)
    d = row["distortion"]
    print(f"{row['pair']:<13} agreement {p['orientation']:.2f} (truth {row['truth_orientation']:.2f})  "
          f"error direct {p['error_direct']:.3f} mirrored {p['error_mirrored']:.3f}"
          f"{'  HALF TURN' if turned else ''}; ignore: {row['ignore']['orientation']:.2f}, "
          f"{row['ignore']['error_direct']:.3f} / {row['ignore']['error_mirrored']:.3f}\n"
          + "".join(f"    {k:<17} distortion ours {v['ours']:.4g} truth {v['truth']:.4g} ({v['truth'] / v['ours']:.2f}x);"
                    f" best 70% ours {v['ours_trimmed']:.4g} truth {v['truth_trimmed']:.4g} "
                    f"({v['truth_trimmed'] / v['ours_trimmed']:.2f}x)\n" for k, v in d.items()), end="", flush=True)
    return row


def basins(kids: datasets.TopKids, name: str, sy: ShapeMetric, gy: ShapeMetric, sym: np.ndarray) -> dict:
    """The basins of the search's starts (``--basins``, see the module's text)."""
    from gromov.curvature import CURVATURE_SCALE, mean_curvature
    from gromov.gh import SearchOptions, pair_orientation
    from gromov.search import _Starts

    gt = kids.ground_truth(name)
    sx = ShapeMetric(kids.load(name), "diffusion", metric_options=correspondence_options("diffusion", None))
    P, Q = sx.samples(100, 0), sy.samples(100, 0)
    xs = sx.working.to_input_ids(P)
    gm = SymmetricGMDS(sx.surface, sy.surface, P, Q)
    scales = {"default": CURVATURE_SCALE, "fifth": CURVATURE_SCALE / 5, "none": 0.0}
    hx = {k: mean_curvature(sx.mesh, sx.normals[0], scale=v) for k, v in scales.items()}
    hy = {k: mean_curvature(sy.mesh, sy.normals[0], scale=v) for k, v in scales.items()}
    starts = _Starts(sx, sy, P, Q, SearchOptions())
    pairs = starts.plain(all_starts=True) + starts.preserving(8) + starts.preserving(8, reversing=True)
    found = {}
    for a, b in pairs:
        fp, fq, *_ = gm.solve(*_at_vertices(sx, sy, a, b))
        d, o = gm.distortion(fp, fq, 2.0), pair_orientation(sx, sy, P, Q, fp, fq)
        vp, vq = fp.vertex(sy.mesh.faces), fq.vertex(sx.mesh.faces)
        img = sy.working.to_input_ids(vp)
        ed = float(image_errors(xs, img, gy, gt).mean())
        em = float(image_errors(xs, img, gy, sym[gt]).mean())
        basin = ("right" if ed < 0.1 else "half turn" if o > 0.5 and em < ed else
                 "left/right mirror" if o < 0.5 and em < 0.1 else "front/back mirror" if o < 0.5 and ed < 0.2
                 else "other")
        if basin not in found or d < found[basin]["distortion"]:
            mismatch = {k: 0.5 * float(np.median(np.abs(hx[k][P] - hy[k][vp])) + np.median(np.abs(hy[k][Q] - hx[k][vq])))
                        for k in scales}
            found[basin] = {"distortion": d, "orientation": o, "error_direct": ed, "error_mirrored": em,
                            "curvature_mismatch": mismatch, "starts": found.get(basin, {}).get("starts", 0)}
        found[basin]["starts"] += 1
    print(f"{name}->{kids.reference}: {len(pairs)} starts")
    for k, v in sorted(found.items(), key=lambda kv: kv[1]["distortion"]):
        print(f"    {k:<18} {v['starts']:3d} starts, lowest distortion {v['distortion']:.4f} (agreement "
              f"{v['orientation']:.2f}, error {v['error_direct']:.3f} / {v['error_mirrored']:.3f}), curvature "
              "mismatch " + ", ".join(f"{s} {m:.3f}" for s, m in v["curvature_mismatch"].items()), flush=True)
    return {"pair": f"{name}->{kids.reference}", "starts": len(pairs), "basins": found}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--kids", default=None, help="comma-separated kids (default: kid01..kid25)")
    ap.add_argument("--turn-margin", type=float, default=None, metavar="F",
                    help="gromov.gh.TURN_MARGIN for this run (1: no choice by curvature)")
    ap.add_argument("--basins", action="store_true", help="GMDS from every start, by basin (see above)")
    ap.add_argument("--json", default=str(HERE / "front_back.json"))
    args = ap.parse_args(argv)
    import gromov.gh

    if args.turn_margin is not None:
        gromov.gh.TURN_MARGIN = args.turn_margin
    warnings.simplefilter("ignore")
    kids = datasets.TopKids(Path(args.data) / "topkids")
    names = args.kids.split(",") if args.kids else [k for k in kids.names if k != kids.reference]
    y = kids.load(kids.reference)
    sy = ShapeMetric(y, "diffusion", metric_options=correspondence_options("diffusion", None))
    gy = ShapeMetric(y, "geodesic")
    sym = kids.symmetry(kids.reference)
    if args.basins:
        rows = [basins(kids, k, sy, gy, sym) for k in names]
        write_results(args.json, {"command": "python benchmarks/studies/probe_front_back.py --basins --kids "
                                  + ",".join(names) + f" --json benchmarks/studies/{Path(args.json).name}",
                                  "pairs": rows})
        return 0
    rows = [probe(kids, k, sy, gy, sym) for k in names]
    turned = [r for r in rows if r["half_turn"]]
    lower = {k: sum(r["distortion"][k]["ours"] < r["distortion"][k]["truth"] for r in turned)
             for k in ("heat", "heat_quarter_time", "geodesic")}
    summary = {"pairs": len(rows), "half_turns": [r["pair"] for r in turned],
               "half_turns_below_truth": lower,
               "truth_orientation_min": min(r["truth_orientation"] for r in rows)}
    print(f"{len(turned)} of {len(rows)} maps are half turns; their distortion is below the truth's in "
          + ", ".join(f"{k} {v}/{len(turned)}" for k, v in lower.items()))
    summary["mean_error"] = float(np.mean([min(r["prefer"]["error_direct"], r["prefer"]["error_mirrored"])
                                           for r in rows]))
    summary["mean_error_direct"] = float(np.mean([r["prefer"]["error_direct"] for r in rows]))
    print(f"samples' mean error / diameter: {summary['mean_error']:.4f} (the better reading), "
          f"{summary['mean_error_direct']:.4f} (direct)")
    command = "python benchmarks/studies/probe_front_back.py" + (f" --turn-margin {args.turn_margin:g}" if args.turn_margin
                                                         is not None else "")
    if args.json != str(HERE / "front_back.json"):
        command += f" --json benchmarks/studies/{Path(args.json).name}"
    write_results(args.json, {"command": command, "turn_margin": gromov.gh.TURN_MARGIN, "summary": summary,
                              "pairs": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
