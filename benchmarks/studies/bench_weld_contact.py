"""How much does a welded vertex move each metric? Held-out TOSCA classes, no optimiser involved.

Run:  .venv/bin/python benchmarks/studies/bench_weld_contact.py [--data DIR] [--classes horse,centaur,wolf,michael]
                                                       [--json OUT]

The paper (Bronstein et al. 2010, §5) expects diffusion distances to barely move when two
touching parts of a shape are welded together, and geodesic distances to change drastically.
This measures the change directly, as the distortion of the ground-truth map between a clean
deformation and the same deformation with 3 merged-vertex welds (``perturb.weld(join="pinch")``,
as ``gromov reproduce`` welds):

    added distortion = dis(reference -> welded pose) - dis(reference -> clean pose),

``dis`` the RMS over 100 farthest-point samples of the reference of
``|d_X(p_i, p_j) - d_Y(p'_i, p'_j)|`` (``p'`` the same input vertex on the pose), divided by
the larger diameter. Per held-out class (none is in the paper's experiments) the first two
deformations, all poses simplified identically.

1. **Gap**: welds searched within 1.5, 3 and 5 mean edge lengths (the default of
   ``perturb.weld`` is 5) at 3,000 vertices: does a weld across a smaller gap (faces stretched
   less) move the metric less?
2. **Resolution**: the weld sites of the 3,000-vertex pose (the widest search above that found
   3 sites) kept fixed in space
   and welded at the nearest vertices of the same pose simplified to 1,500, 3,000 and 6,000
   vertices: does the change shrink as the mesh is refined?

Metrics: geodesic (fast marching), heat-kernel diffusion at tau = 0.005 (the default), the
paper's connectivity-kernel graph diffusion (m = 50; zero on the clean pairs, whose poses
share connectivity).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from gromov import Mesh, farthest_point_sampling, perturb
from gromov.experiments.datasets import TOSCA
from gromov.experiments.reproduce import _Shapes
from gromov.gh import ShapeMetric

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common and the comparisons
from _common import add_data_argument, write_results  # noqa: E402
from bench_heldout import _rows_of  # noqa: E402

METRICS = {
    "geodesic": ("geodesic", {}),
    "heat 0.005": ("diffusion", {"kernel": "heat", "tau": 0.005}),
    "connectivity m=50": ("diffusion", {"kernel": "connectivity"}),
}
GAPS = (1.5, 3.0, 5.0)
RESOLUTIONS = (1500, 3000, 6000)
WELDS, SEED = 3, 7


def _pinch(mesh: Mesh, pairs) -> Mesh:
    """Merge ``v`` into ``u`` for each ``(u, v)`` (what ``perturb.weld(join="pinch")`` does at a
    site it chose), keeping the input ids of the other vertices."""
    f = np.array(mesh.faces)
    for u, v in pairs:
        f[f == v] = u
    keep = np.setdiff1d(np.arange(mesh.n_vertices), [v for _, v in pairs])
    new = np.full(mesh.n_vertices, -1, np.int64)
    new[keep] = np.arange(len(keep))
    return Mesh(mesh.vertices[keep], new[f], input_ids=mesh.input_ids[keep])


class _Reference:
    """The reference pose's metric and samples, per metric."""

    def __init__(self, mesh: Mesh):
        self.mesh, self.cache = mesh, {}

    def get(self, name):
        if name not in self.cache:
            metric, opts = METRICS[name]
            s = ShapeMetric(self.mesh, metric, resolution=None, metric_options=opts)
            P = farthest_point_sampling(s.distances, 100, seed=0).indices
            self.cache[name] = (s, P)
        return self.cache[name]


def _distortion(ref: _Reference, name: str, pose: Mesh) -> float:
    sx, P = ref.get(name)
    metric, opts = METRICS[name]
    sy = ShapeMetric(pose, metric, resolution=None, metric_options=opts)
    q = _rows_of(pose, ref.mesh.input_ids[P])
    ok = q >= 0
    a, b = sx.distances[np.ix_(P[ok], P[ok])], sy.distances[np.ix_(q[ok], q[ok])]
    r = (a - b)[~np.eye(int(ok.sum()), dtype=bool)]
    return float(np.sqrt(np.mean(r**2)) / max(sx.diameter, sy.diameter))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default="horse,centaur,wolf,michael")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    tosca = TOSCA(Path(args.data) / "tosca")
    shapes = {n: _Shapes(tosca, n) for n in RESOLUTIONS}
    rows = []
    t0 = time.perf_counter()
    for cls in args.classes.split(","):
        refs = {n: _Reference(shapes[n].work(cls, 0).mesh) for n in RESOLUTIONS}
        for pose in [p for p in tosca.poses(cls) if p != 0][:2]:
            y = shapes[3000].work(cls, pose).mesh
            edge = y.mean_edge_length
            clean = {name: _distortion(refs[3000], name, y) for name in METRICS}
            sites = None
            # 1. gap
            for gap in GAPS:
                row = {"class": cls, "pose": pose, "study": "gap", "setting": gap}
                try:
                    p = perturb.weld(y, WELDS, radius=gap * edge, seed=SEED, join="pinch")
                except ValueError:
                    rows.append({**row, "welds": 0})
                    print(f"  {cls}{pose} gap {gap}: no {WELDS} sites", flush=True)
                    continue
                u, v = p.sites[:, 0], p.sites[:, 1]
                row["contact_edges"] = float(np.mean(np.linalg.norm(y.vertices[u] - y.vertices[v], axis=1)) / edge)
                row["welds"] = len(p.sites)
                row["added"] = {name: _distortion(refs[3000], name, p.mesh) - clean[name] for name in METRICS}
                rows.append(row)
                sites = y.vertices[p.sites.reshape(-1)].reshape(-1, 2, 3)  # the widest search's
            # 2. resolution, sites fixed in space
            for n in RESOLUTIONS if sites is not None else ():
                yn = shapes[n].work(cls, pose).mesh
                tree = cKDTree(yn.vertices)
                pairs = [(int(tree.query(a)[1]), int(tree.query(b)[1])) for a, b in sites]
                w = _pinch(yn, pairs)
                cn = clean if n == 3000 else {name: _distortion(refs[n], name, yn) for name in METRICS}
                rows.append({"class": cls, "pose": pose, "study": "resolution", "setting": n, "welds": len(pairs),
                             "contact_edges": float(np.mean([np.linalg.norm(yn.vertices[a] - yn.vertices[b])
                                                             for a, b in pairs]) / yn.mean_edge_length),
                             "clean": cn,
                             "added": {name: _distortion(refs[n], name, w) - cn[name] for name in METRICS}})
            print(f"  {cls}{pose}: {time.perf_counter() - t0:.0f} s", flush=True)

    print(f"\nadded ground-truth distortion (RMS / diameter) of {WELDS} merged-vertex welds, mean over "
          f"{len({(r['class'], r['pose']) for r in rows})} held-out poses ({time.perf_counter() - t0:.0f} s)")
    summary = {}
    for study, settings, label in (("gap", GAPS, "search radius (edges)"),
                                   ("resolution", RESOLUTIONS, "working vertices")):
        print(f"\n{study}: {label}")
        print(f"  {'':<22}" + "".join(f"{s:>12g}" for s in settings))
        sel = {s: [r for r in rows if r["study"] == study and r["setting"] == s and r["welds"]] for s in settings}
        print(f"  {'poses welded':<22}" + "".join(f"{len(sel[s]):>12d}" for s in settings))
        print(f"  {'contact (edges)':<22}" + "".join(f"{np.mean([r['contact_edges'] for r in sel[s]]):>12.2f}"
                                                    for s in settings))
        for name in METRICS:
            vals = [float(np.mean([r["added"][name] for r in sel[s]])) for s in settings]
            summary[f"{study}/{name}"] = dict(zip(map(str, settings), vals))
            print(f"  {name:<22}" + "".join(f"{v:>+12.4f}" for v in vals))
    clean = [r for r in rows if r["study"] == "resolution" and r["setting"] == 3000]
    print("\nclean distortion at 3,000 vertices, for scale: " + ", ".join(
        f"{name} {np.mean([r['clean'][name] for r in clean]):.4f}" for name in METRICS))
    write_results(args.json, {"classes": args.classes, "welds": WELDS, "seed": SEED, "summary": summary,
                              "rows": rows})


if __name__ == "__main__":
    main()
