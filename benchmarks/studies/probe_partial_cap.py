"""How many of the whole's eigenfunctions the part's refinement needs: the cap on k_Y.

Run:  .venv/bin/python benchmarks/studies/probe_partial_cap.py [--data DIR] [--vertices 4000]
                                                               [--keep 0.45] [--json OUT]

:func:`gromov.partial.partial_zoomout` takes k_Y = k_X / r eigenfunctions of the whole for k_X
of the part (r: the part's area over the whole's): up to k_Y = 195 at k_X = 78 for the smallest
plane cuts of ``benchmarks/bench_partial.py`` (40-80% of the area), 262 at k_X = 118. For each TOSCA class: one
plane cut keeping ``--keep`` of the area of its lowest pose (seed 0; every pose simplified to
``--vertices`` vertices as ``bench_partial.py`` does), matched into the next pose with
``gromov.match(part, whole, partial=True, dense="placed")``, then refined (k_X from 10 by 4 to
80) with k_Y capped at ``ky_max`` = 80, 120, 160 and not capped. Scored as ``probe_partial_refine.py`` (every vertex of
the part, :func:`gromov.evaluate.dense_error` x 100 / sqrt(area), the better of the direct and
mirrored readings). Then the cost of the whole's eigensolve at each cap on the largest full
(unsimplified) TOSCA pose, one BLAS thread: :func:`gromov.dense.prolonged_basis` from its working
mesh (what the refinement uses), and the Lanczos solve on the input mesh
(:func:`gromov.dense.laplace_beltrami_basis`).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import gromov
from gromov.dense import laplace_beltrami_basis, prolonged_basis
from gromov.evaluate import dense_error
from gromov.experiments import datasets
from gromov.partial import partial_zoomout
from gromov.perturb import cut
from gromov.shape_metric import ShapeMetric

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/
from _common import add_data_argument, write_results  # noqa: E402
from bench_dense import at_vertices  # noqa: E402
from bench_partial import ClassPoses  # noqa: E402

HERE = Path(__file__).resolve().parent
CAPS = (80, 120, 160, 10**6)
#: The refinement runs to k_X = 78 (from 10 by 4), as ``probe_partial_refine.py`` measured it.
K_END = 80


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--keep", type=float, default=0.45)
    ap.add_argument("--json", default=str(HERE / "probe_partial_cap.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    rows = {}
    name = lambda cap: "no cap" if cap >= 10**6 else f"k_Y <= {cap}"   # noqa: E731
    for cls in tosca.classes:
        poses = ClassPoses(tosca, cls, args.vertices)
        if len(poses.poses) < 2:
            continue
        a, b = poses.poses[0], poses.poses[1]
        p = cut(poses.mesh(a), args.keep, kind="plane", seed=0)
        part, truth, whole = gromov.Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map, poses.mesh(b)
        sx, sy = ShapeMetric(part, "geodesic"), ShapeMetric(whole, "geodesic")
        r = gromov.match(sx, sy, partial=True, dense="placed")
        placed = whole.from_input_ids(r.x_to_y_dense_vertex)

        def score(T):
            e = dense_error(*at_vertices(whole, T), whole, truth, poses.symmetry)
            err = 100 * np.where(np.isfinite(e.errors), e.errors, e.diameter / np.sqrt(e.area))
            return {"mean": float(err.mean()), "median": float(np.median(err))}

        row = {"ratio": float(part.area / whole.area), "placed": score(placed)}
        for cap in sorted(CAPS, reverse=True):   # the largest basis first: the smaller ones reuse it
            t = time.perf_counter()
            row[name(cap)] = score(partial_zoomout(sx, sy, placed, k_end=K_END, ky_max=cap)) | {
                "seconds": time.perf_counter() - t}
        rows[f"{cls}{a}-plane0->{cls}{b}"] = row
        print(cls, f"r={row['ratio']:.2f}",
              {k: f"{v['mean']:.2f} / {v['median']:.2f}" for k, v in row.items() if k != "ratio"}, flush=True)
    keys = [k for k in next(iter(rows.values())) if k != "ratio"]
    summary = {k: {"mean": float(np.mean([r[k]["mean"] for r in rows.values()])),
                   "median_of_medians": float(np.median([r[k]["median"] for r in rows.values()]))} for k in keys}
    print({k: f"{v['mean']:.2f} / {v['median_of_medians']:.2f}" for k, v in summary.items()})
    # the whole's eigensolve at each cap, on the largest full pose
    meshes = {(cls, tosca.poses(cls)[0]): tosca.load(cls, tosca.poses(cls)[0]) for cls in tosca.classes}
    big = max(meshes, key=lambda cp: meshes[cp].n_vertices)
    mesh = meshes[big]
    working = ShapeMetric(mesh, "geodesic").working
    cost = {"prolonged": {}, "lanczos": {}}
    for cap in (80, 120, 160, 200):
        for how, solve in (("prolonged", lambda k: prolonged_basis(working, k)),
                           ("lanczos", lambda k: laplace_beltrami_basis(mesh, k))):
            t = time.perf_counter()
            solve(cap)
            cost[how][str(cap)] = time.perf_counter() - t
            print(f"{big[0]}{big[1]} ({mesh.n_vertices} vertices): {cap} eigenpairs, {how} "
                  f"{cost[how][str(cap)]:.1f} s", flush=True)
    write_results(args.json, {"command": "python benchmarks/studies/probe_partial_cap.py", "vertices": args.vertices,
                              "keep": args.keep, "summary": summary, "pairs": rows,
                              "eigensolve": {"shape": f"{big[0]}{big[1]}", "vertices": mesh.n_vertices,
                                             "seconds": cost}})
    return 0


if __name__ == "__main__":
    sys.exit(main())
