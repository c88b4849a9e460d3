"""Refining a part's dense map on the input meshes: ZoomOut with a rectangular functional map.

Run:  .venv/bin/python benchmarks/studies/probe_partial_refine.py [--data DIR] [--vertices 4000]
                                                                  [--json OUT]

For each TOSCA class: one plane cut keeping 60% of the area of its lowest pose (seed 0), as
``benchmarks/bench_partial.py`` makes its parts (every pose simplified to ``--vertices``
vertices), matched into the next pose with ``gromov.match(part, whole, partial=True,
dense=True)`` (the placed map), then refined by ZoomOut's steps on the input meshes' own
Laplace-Beltrami eigenfunctions, from k_X = 10 by 4 to 40 or 80, searched within two rings of
the current image, with the functional map C = Phi_X^T M_X Phi_Y[T] of k_X eigenfunctions of the
part by k_Y of the whole:

- ``square``: k_Y = k_X (the full-shape refinement's choice);
- ``rectangular``: k_Y = k_X / (area of the part / area of the whole), the slope of a part's
  functional map (Rodola, Cosmo, Bronstein, Torsello & Cremers, "Partial functional
  correspondence", CGF 2017): the part's first k_X eigenfunctions span about the frequencies of
  the whole's first k_X / ratio.

Scored on every vertex of the part by :func:`gromov.evaluate.dense_error` on the whole
(x 100 / sqrt(area), the better of the direct and mirrored readings; an image on another piece
counted as the diameter): mean / median.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import gromov
from gromov import dense as D
from gromov._arrays import one_blas_thread, readonly
from gromov.evaluate import dense_error
from gromov.experiments import datasets
from gromov.gh import ShapeMetric
from gromov.perturb import cut

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/
from _common import add_data_argument, write_results  # noqa: E402
from bench_dense import at_vertices  # noqa: E402
from bench_partial import ClassPoses  # noqa: E402

HERE = Path(__file__).resolve().parent


def refine(sx, sy, T, kx_end: int, rectangular: bool, kx_start: int = 10, step: int = 4, rings: int = 2):
    """ZoomOut steps from the part X into the whole Y (module docstring)."""
    ratio = sx.input.area / sy.input.area
    ky = (lambda k: int(round(k / ratio))) if rectangular else (lambda k: k)
    phx, mx = D._input_basis(sx, kx_end)
    phy, _ = D._input_basis(sy, ky(kx_end))
    ptr, ids = D.ring_neighbourhoods(sy.input, rings)
    with one_blas_thread():
        for kx in range(kx_start, kx_end + 1, step):
            k = min(ky(kx), phy.shape[1])
            C = phx[:, :kx].T @ (mx[:, None] * phy[T, :k])
            b = np.ascontiguousarray(phy[:, :k] @ C.T)
            T = D._nearest_in_rings(*(readonly(np.ascontiguousarray(z)) for z in (phx[:, :kx], b, T, ptr, ids)))
    return T


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--vertices", type=int, default=4000)
    ap.add_argument("--json", default=str(HERE / "probe_partial_refine.json"))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    rows = {}
    for cls in tosca.classes:
        poses = ClassPoses(tosca, cls, args.vertices)
        if len(poses.poses) < 2:
            continue
        a, b = poses.poses[0], poses.poses[1]
        p = cut(poses.mesh(a), 0.6, kind="plane", seed=0)
        part, truth, whole = gromov.Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map, poses.mesh(b)
        sx, sy = ShapeMetric(part, "geodesic"), ShapeMetric(whole, "geodesic")
        r = gromov.match(sx, sy, partial=True, dense=True)
        placed = whole.from_input_ids(r.x_to_y_dense_vertex)

        def score(T):
            e = dense_error(*at_vertices(whole, T), whole, truth, poses.symmetry)
            err = 100 * np.where(np.isfinite(e.errors), e.errors, e.diameter / np.sqrt(e.area))
            return {"mean": float(err.mean()), "median": float(np.median(err))}

        row = {"placed": score(placed)}
        for kx in (40, 80):
            for rect in (False, True):
                t = time.perf_counter()
                T = refine(sx, sy, placed, kx, rect)
                row[f"{'rectangular' if rect else 'square'}, k_X to {kx}"] = score(T) | {
                    "seconds": time.perf_counter() - t}
        rows[f"{cls}{a}-plane0->{cls}{b}"] = row
        print(cls, {k: f"{v['mean']:.2f} / {v['median']:.2f}" for k, v in row.items()}, flush=True)
    keys = list(next(iter(rows.values())))
    summary = {k: {"mean": float(np.mean([r[k]["mean"] for r in rows.values()])),
                   "median_of_medians": float(np.median([r[k]["median"] for r in rows.values()]))} for k in keys}
    print({k: f"{v['mean']:.2f} / {v['median_of_medians']:.2f}" for k, v in summary.items()})
    write_results(args.json, {"command": "python benchmarks/studies/probe_partial_refine.py", "vertices": args.vertices,
                              "summary": summary, "pairs": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
