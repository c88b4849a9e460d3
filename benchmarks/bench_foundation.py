"""Foundation benchmarks: geodesics, diffusion distances, loading and simplification.

Run:  .venv/bin/python benchmarks/bench_foundation.py [--data DIR] [--n 3000] [--json OUT]
(or ``make bench``). Every anchor is measured side by side in the same run, on the same
working mesh; the script prints times, errors and ratios. Timings on a shared machine are
noisy: each timed step takes the best of ``--repeat`` runs.

1. Geodesic all-pairs on a ~3,000-vertex TOSCA cat working mesh: our fast marching (also with
   ``refine`` levels, ``--refine``) vs
   potpourri3d's heat method and potpourri3d's fast marching (geometry-central), with the
   error of each against exact MMP geodesics (pygeodesic) from ``--sources`` random sources;
   the exact method's all-pairs time is extrapolated from those sources.
2. Diffusion distance matrix at the same size: the paper's graph diffusion (spectral, with
   truncation bound) vs the dense eigendecomposition it replaces, and the heat-kernel variant.
3. Loading and simplifying a 52k-vertex TOSCA mesh (david0), vs trimesh's OFF loader.
"""

from __future__ import annotations

import argparse
import gzip
import io
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

import gromov
from gromov.metrics import GeodesicSolver, GraphDiffusionSolver, HeatDiffusionSolver
from gromov.shapes import icosphere

HERE = Path(__file__).resolve().parent


def best_of(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def rel_err(d, ref):
    off = ref > 0
    r = np.abs(d - ref)[off] / ref[off]
    return float(r.mean()), float(r.max())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[1] / "shared" / "data")))
    p.add_argument("--n", type=int, default=3000, help="working mesh size")
    p.add_argument("--sources", type=int, default=30, help="sources for the exact-error reference")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--refine", default="1,2",
                   help="also time our fast marching with these refine levels (comma separated, "
                        "best of one run each; '' for none)")
    p.add_argument("--json", default=None, help="also write the numbers to this file")
    args = p.parse_args(argv)
    tosca = Path(args.data) / "tosca"
    res = {"date": time.strftime("%Y-%m-%d"), "python": sys.version.split()[0],
           "machine": f"{platform.machine()}, {os.cpu_count()} cores", "gromov": gromov.__version__}

    # ------------------------------------------------------------------ 1. geodesics
    cat = gromov.load(tosca / "cat0.off.gz")
    w = gromov.simplify(cat, args.n).mesh
    V, F = np.array(w.vertices), np.array(w.faces)
    n = w.n_vertices
    print(f"[1] geodesic all pairs, TOSCA cat0 working mesh: {n} vertices, {w.n_faces} faces")
    src = np.random.default_rng(0).choice(n, args.sources, replace=False)

    t_ex, exact = best_of(lambda: GeodesicSolver(w, method="exact").from_sources(src), 1)
    exact_all = t_ex / len(src) * n

    GeodesicSolver(icosphere(1)).pairwise()  # compile / load the numba cache
    t_fmm, d_fmm = best_of(lambda: GeodesicSolver(w, method="fmm").pairwise(), args.repeat)

    import potpourri3d as pp3d

    def heat_all():
        s = pp3d.MeshHeatMethodDistanceSolver(V, F)
        return np.stack([s.compute_distance(i) for i in range(n)])

    def pp3d_fmm_all():
        s = pp3d.MeshFastMarchingDistanceSolver(V, F)
        return np.stack([s.compute_distance([[(i, [])]]) for i in range(n)])

    t_heat, d_heat = best_of(heat_all, args.repeat)
    t_ppf, d_ppf = best_of(pp3d_fmm_all, 1)
    rows = [("gromov fmm (ours)", t_fmm, d_fmm[src])]
    for r in (int(x) for x in args.refine.split(",") if x.strip()):
        t_r, d_r = best_of(lambda: GeodesicSolver(w, method="fmm", refine=r).pairwise(), 1)
        rows.append((f"gromov fmm refine={r}", t_r, d_r[src]))
    rows += [("potpourri3d heat", t_heat, d_heat[src]), ("potpourri3d fmm", t_ppf, d_ppf[src])]
    print(f"    {'method':<22}{'time [s]':>10}{'vs ours':>9}{'mean rel err':>14}{'max rel err':>13}")
    geo = {"n_vertices": n, "sources": int(len(src)), "exact_seconds_extrapolated": exact_all}
    for name, t, d in rows:
        me, mx = rel_err(d, exact)
        print(f"    {name:<22}{t:>10.2f}{t / t_fmm:>8.2f}x{me:>14.4%}{mx:>13.3%}")
        geo[name] = {"seconds": t, "ratio_to_ours": t / t_fmm, "mean_rel_err": me, "max_rel_err": mx}
    print(f"    {'exact MMP (pygeodesic)':<22}{exact_all:>10.1f}{exact_all / t_fmm:>8.1f}x"
          f"   (extrapolated from {len(src)} sources)")
    res["geodesic_all_pairs"] = geo

    # ------------------------------------------------------------------ 2. diffusion
    print(f"\n[2] diffusion distance matrix, same {n}-vertex mesh")
    t_g, s_g = best_of(lambda: (lambda s: (s.pairwise(), s)[1])(GraphDiffusionSolver(w)), args.repeat)
    t_d, s_d = best_of(lambda: (lambda s: (s.pairwise(), s)[1])(GraphDiffusionSolver(w, dense_below=10**9)), 1)
    t_h, s_h = best_of(lambda: (lambda s: (s.pairwise(), s)[1])(HeatDiffusionSolver(w)), args.repeat)
    err = float(np.abs(s_g.pairwise() - s_d.pairwise()).max() / s_d.pairwise().max())
    print(f"    graph (connectivity, m=50), spectral: {t_g:.2f} s, {len(s_g.eigenvalues)} eigenpairs, "
          f"truncation bound on d^2 {s_g.truncation_bound:.1e}, max error vs dense {err:.1e}")
    print(f"    graph, dense eigendecomposition:     {t_d:.2f} s   ({t_d / t_g:.1f}x the spectral time)")
    print(f"    heat kernel (cotan, tau=0.005):       {t_h:.2f} s, {len(s_h.eigenvalues)} eigenpairs")
    res["diffusion"] = {"graph_spectral_seconds": t_g, "graph_dense_seconds": t_d, "heat_seconds": t_h,
                        "graph_eigenpairs": len(s_g.eigenvalues), "graph_max_rel_err_vs_dense": err}

    # ------------------------------------------------------------------ 3. load + simplify
    path = tosca / "david0.off.gz"
    t_load, david = best_of(lambda: gromov.load(path), args.repeat)
    t_simp, wd = best_of(lambda: gromov.simplify(david, args.n), args.repeat)

    def trimesh_load():
        import trimesh

        with gzip.open(path, "rb") as fh:
            return trimesh.load(io.BytesIO(fh.read()), file_type="off", process=False)

    t_tri, _ = best_of(trimesh_load, args.repeat)
    print(f"\n[3] david0 ({david.n_vertices} vertices): load {t_load:.2f} s (trimesh's OFF loader "
          f"{t_tri:.2f} s), simplify to {wd.n_vertices} {t_simp:.2f} s, total {t_load + t_simp:.2f} s")
    res["load_simplify"] = {"n_vertices": david.n_vertices, "load_seconds": t_load,
                            "trimesh_load_seconds": t_tri, "simplify_seconds": t_simp,
                            "working_vertices": wd.n_vertices}
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
