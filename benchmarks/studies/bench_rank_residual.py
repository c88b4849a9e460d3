"""How should recognition summarise a correspondence's residuals? Differences or log ratios.

Run:  .venv/bin/python benchmarks/studies/bench_rank_residual.py [--sets synthetic,stretched,close1,close0.5,heldout]
                                                         [--metrics diffusion,geodesic] [--json OUT]

Recognition (:func:`gromov.experiments.gh_matrix`, ``gromov reproduce``) ranks a pair of shapes
by a trimmed distortion of their correspondence (:func:`gromov.gmds.trimmed_rms`, the
best-fitting 80% of the sample pairs). Each pair is matched once, as ``gh_matrix`` matches it
(``orientation="ignore"``), and the same correspondence is then summarised four ways -- the
residuals ``(d_X - d_Y) / diameter`` ("difference", the additive form) or ``log(d_X / d_Y)``
("log", :func:`gromov.gmds.log_ratio_residuals`, a multiplicative distortion), each measured in
the metric of the match (scale 1) and, for the heat-kernel diffusion metric, with the heat
distance at half the diffusion time (``rank_tau_scale=0.5``, the default) -- through
:func:`gromov.gh.ranking_value`, the function ``match`` ranks with. Printed per ranking: the
equal error rate and the *margin* (smallest different-class over largest same-class distance;
above 1 when one threshold separates every pair).

The validation sets, never the paper's classes (cat, dog, david, victoria):

- ``synthetic``: ``make demo``'s set (Experiment 1 welds, Experiment 2 holes);
- ``stretched``: the same with non-isometric poses, ``Synthetic(pose_stretch=0.1)``
  (``gromov reproduce --pose-stretch 0.1``);
- ``close1``, ``close0.5``: the stretched synthetic people only, victoria's body the fraction
  1 or 0.5 of the way from david's (``benchmarks/studies/bench_close_humanoids.py``: 50 samples,
  reference + 4 poses, clean and welded);
- ``heldout``: TOSCA classes the paper did not use (wolf:2, horse:4, centaur:5, michael:6;
  ``gromov reproduce --classes ...``; needs the data).
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing as mp
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from gromov.experiments import datasets
from gromov.experiments.pairwise import _one_thread_per_worker, prepare
from gromov.experiments.recognition import equal_error_rate
from gromov.experiments.reproduce import DIFFUSION_FILL_HOLES, _collection, _Shapes, settings_for
from gromov.experiments.synthetic import Synthetic
from gromov.gh import RANK_TAU_SCALE, _match, ranking_value
from gromov.gmds import SurfacePoints, SymmetricGMDS

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument, margin, write_results  # noqa: E402

HELDOUT = {"wolf": 2, "horse": 4, "centaur": 5, "michael": 6}
RESIDUALS = ("difference", "log")
_SHAPES: list = []
_N = 0


def _keep_working(s) -> None:
    """Make ``s.locate`` leave a result's images on the working mesh (``match`` carries them to
    the input mesh by projection, which need not land on the same point): the images are then
    the very points ``match`` measured."""
    def locate(pts):
        return pts.face, pts.bary, pts.vertex(s.mesh.faces)
    s.locate = locate


def _pair(ij):
    i, j = ij
    x, y = _SHAPES[i], _SHAPES[j]
    heat = x.ranking_surface(RANK_TAU_SCALE) is not None
    r = _match(x, y, x.metric, n_samples=_N, seed=0, orientation="ignore", as_prepared=True,   # as gh_matrix
               rank_tau_scale=RANK_TAU_SCALE if heat else None, rank_residual="log")
    ip = SurfacePoints(r.x_to_y_face, r.x_to_y_bary)   # on the working meshes (_keep_working)
    iq = SurfacePoints(r.y_to_x_face, r.y_to_x_bary)
    P, Q = x.samples(_N, 0), y.samples(_N, 0)   # match's samples (working ids)
    out = {}
    for scale in ((1.0, RANK_TAU_SCALE) if heat else (1.0,)):
        if scale == 1.0:
            (sx, dx), (sy, dy) = (x.surface, x.diameter), (y.surface, y.diameter)
        else:
            (sx, dx), (sy, dy) = x.ranking_surface(scale), y.ranking_surface(scale)
        ex, ey = SymmetricGMDS(sx, sy, P, Q).blocks(ip, iq)
        for res in RESIDUALS:
            out[f"{res} @{scale:g}"] = ranking_value(ex, ey, max(dx, dy), res)
    last = f"log @{RANK_TAU_SCALE if heat else 1.0:g}"
    if not np.isclose(out[last], r.ranking_distance, rtol=1e-9):   # what match ranked by
        raise AssertionError(f"{last}: {out[last]} vs match's {r.ranking_distance}")
    return out


def _sets(names: list[str], data: Path):
    """{set: (settings, collection, {experiment: entries})}"""
    out = {}
    for name in names:
        if name in ("synthetic", "stretched"):
            st = settings_for("synthetic")
            coll = _collection("synthetic", None) if name == "synthetic" else Synthetic(pose_stretch=0.1)
            exps = {"weld": datasets.experiment1(coll, st.experiment1),
                    "holes": datasets.experiment2(coll, st.experiment2)}
        elif name.startswith("close"):
            st = dataclasses.replace(settings_for("synthetic"), n_samples=50, resolution=None)
            coll = Synthetic(victoria_blend=float(name[5:]), pose_stretch=0.1)
            exps = {"weld": datasets.experiment1(coll, {"david": 4, "victoria": 4})}
        elif name == "heldout":
            st = settings_for("tosca", classes=HELDOUT, topkids=False)
            coll = _collection("tosca", data)
            exps = {"weld": datasets.experiment1(coll, st.experiment1),
                    "holes": datasets.experiment2(coll, st.experiment2)}
        else:
            raise SystemExit(f"unknown set {name!r}")
        out[name] = (st, coll, exps)
    return out


def main(argv=None):
    global _N
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--sets", default="synthetic,stretched,close1,close0.5,heldout")
    ap.add_argument("--metrics", default="diffusion,geodesic")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    res = {"rank_tau_scale": RANK_TAU_SCALE, "sets": {}}
    t0 = time.perf_counter()
    for name, (st, coll, exps) in _sets(args.sets.split(","), Path(args.data)).items():
        shapes = _Shapes(coll, st.resolution)
        _N = st.n_samples
        for exp, entries in exps.items():
            items = [shapes.entry(e) for e in entries]
            labels = np.array([s.cls for s in items])
            pairs = [(i, j) for i in range(len(items)) for j in range(i + 1, len(items))]
            for metric in args.metrics.split(","):
                t = time.perf_counter()
                opts = dict(st.metric_options[metric])
                if metric == "diffusion":
                    opts.setdefault("fill_holes", DIFFUSION_FILL_HOLES)
                _SHAPES[:] = prepare([s.mesh for s in items], metric, n_samples=_N, seed=0, resolution=None,
                                     metric_options=opts, rank_tau_scale=RANK_TAU_SCALE)
                for s in _SHAPES:
                    _keep_working(s)
                with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("fork"),
                                         initializer=_one_thread_per_worker) as pool:
                    rows = list(pool.map(_pair, pairs, chunksize=8))
                row = {}
                for k in rows[0]:
                    D = np.zeros((len(items),) * 2)
                    for (i, j), v in zip(pairs, rows):
                        D[i, j] = D[j, i] = v[k]
                    row[k] = {"eer": float(equal_error_rate(D, labels)), "margin": margin(D, labels)}
                res["sets"].setdefault(name, {})[f"{exp}/{metric}"] = row
                print(f"{name:<10}{exp:<6}{metric:<10}"
                      + "  ".join(f"{k}: {100 * v['eer']:4.1f}% {v['margin']:.3f}" for k, v in row.items())
                      + f"   ({time.perf_counter() - t:.0f} s)", flush=True)
    res["seconds"] = round(time.perf_counter() - t0, 1)
    print(f"({res['seconds']:.0f} s)")
    write_results(args.json, res)
    return res


if __name__ == "__main__":
    main()
