"""Partial shapes: a part of a TOSCA shape (a plane cut, large holes) matched to another pose, gromov beside pyFM.

Run:  .venv/bin/python benchmarks/bench_partial.py [--data DIR] [--classes cat,dog,...] [--per-class N]
                                                  [--kinds plane,holes] [--vertices N] [--radius F] [--keep LO,HI]
                                                  [--bridge 0|1|choose] [--json OUT]

The parts are those of SHREC'16 *Partial Matching of Deformable Shapes* (Cosmo et al., 3DOR
2016), made by :func:`gromov.perturb.cut`: ``plane`` keeps one side of a plane of random
direction holding 40-80% of the area, ``holes`` removes 5 geodesic disks grown until 20-40% of
the area is gone; the largest connected piece is kept. Part ``k`` (``k = 0 .. per_class - 1``)
of a class is cut from pose ``poses[k]`` with seed ``k`` and matched to the *next* pose
``poses[k + 1]`` (cyclically), keeping ``0.4 + 0.4 (k + 1/2) / per_class`` of the area (plane)
or ``0.6 + 0.2 (k + 1/2) / per_class`` (holes): the keeps of a class are spread evenly over the
range.

Resolution: every pose of a class is simplified to ``--vertices`` vertices (default 4000)
exactly as its lowest pose is (:meth:`gromov.resolution.WorkingMesh.transfer`: the same vertex
subset and triangles), so that the ground truth stays exact -- part vertex ``i`` is whole vertex
``vertex_map[i]`` -- and a pair costs seconds, not the minutes of the full 28k-53k-vertex meshes.
The part and the whole therefore share their triangles where they overlap (``--vertices 0``:
the full meshes).

Methods, per part -> whole pair:

- ``ours``: ``gromov.match(part, whole, dense=True)`` (defaults: diffusion, 100 samples, the
  dense map refined on the input meshes);
- ``ours_partial``: ``gromov.match(part, whole, partial=True, dense=True)`` (:mod:`gromov.partial`:
  the part's samples embedded into the whole alone, in the geodesic metric, samples near the
  part's boundary down-weighted; the dense map placed from the samples, then refined on the input
  meshes by ZoomOut with a rectangular functional map, :func:`gromov.partial.partial_zoomout`), its IoU
  that of the covered region it reports (``y_covered``), ``iou_images`` that of its images
  grown by one ring as for the others; with it, per class, the uncut pose matched to the next
  one both ways, full and partial (``full_vs_partial``: the relative distances and their ratio);
- ``ours_radius``: the same as ``ours`` with ``radius = F x`` the part's diameter in the metric (``--radius``,
  default 0.7; GMDS then counts only the pairs of samples closer than that; 0: not run);
- ``pyfm``: pyFM's quick-start, exactly as ``benchmarks/bench_dense.py`` runs it (both meshes
  area-normalised separately, 200 eigenpairs, WKS, a 30x30 map, ZoomOut).

Measured on every vertex of the part (:func:`gromov.evaluate.dense_error` on the whole's mesh):
mean and median error x100 / sqrt(area of the whole), pooled over the pairs' points (an image
on another piece of the whole than its truth, such as a gorilla's eye, counts as the whole's
diameter: ``off_piece`` says how often), the better of the direct and the mirrored ground truth (the class's lowest pose's reflection,
:func:`gromov.experiments.reproduce.reflection_map`) and the direct one alone; ``gross`` counts
pairs whose mean error exceeds a quarter of the whole's geodesic diameter (fast-marching double
sweep, as ``dense_error`` estimates it); seconds per pair: the match with both shapes' preparation
(a whole's metric or pyFM spectrum is computed once per pose and its time counted in every pair
that uses it), evaluation excluded.

Coverage: the region of the whole the part covers, as a map implies it -- the whole vertices
nearest to the image of some part vertex, grown by one ring -- against the true one -- the whole
vertices that are the truth of some part vertex, grown by one ring (the same construction, so a
perfect map has IoU 1): intersection over union, per pair, averaged per kind, against the true
region on the branch its errors are read on (the mirrored truth's region where the mirrored
reading fits better: a mirror image covers the mirrored region), the direct true region's beside
it (``iou_direct``); beside them the IoU of a map claiming every vertex of the whole (the true
region's share of them), the score of knowing nothing (``--add-baseline`` adds it to a results file made without it).

Diagnostics of ``ours`` (why a part fails), on the part's 100 samples in the match's own metric
(normalised heat diffusion) ÷ the whole's diameter in it: the one-sided RMS distortion of the
ground-truth map and of the map found (if the truth distorts more, the objective itself prefers
a wrong map), and of the ground truth between the same points on the uncut pose the part was cut
from (the poses' own non-isometry), with how much the cut moved the samples' distances -- as
matched, and with the part's diffusion time set to the uncut pose's (``t = tau x area`` shrinks
with the part's area) -- and the ground truth's distortion at that time; the
ground-truth residual, and that move, per sample by its distance to the cut (geodesic on the part, ÷ the
whole's geodesic diameter; the cut: the part's boundary vertices that are not boundary on the
whole); where the images of the whole's samples that lie outside the part land (their distance
to the cut, against the part's vertices'); and how many of the cut's loops the diffusion metric
closes (``fill_holes``: loops shorter than 0.5 sqrt(area)).
"""

from __future__ import annotations

import argparse
import sys
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
from scipy.sparse.csgraph import dijkstra

import gromov
from gromov.evaluate import GeodesicReference, dense_error
from gromov.experiments import datasets
from gromov.experiments.reproduce import reflection_map
from gromov.gh import ShapeMetric
from gromov.metrics.diffusion import correspondence_options
from gromov.partial import BOUNDARY_WIDTH
from gromov.perturb import CUT_PATCHES, cut

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import HERE, add_data_argument, write_results  # noqa: E402
from bench_dense import GROSS, PYFM, at_vertices, pyfm_p2p  # noqa: E402

KEEP = {"plane": (0.4, 0.8), "holes": (0.6, 0.8)}
METHODS = ("ours", "ours_radius", "ours_partial", "pyfm")
#: Bins of a sample's distance to the cut, ÷ the whole's geodesic diameter.
CUT_BINS = (0.0, 0.05, 0.1, 0.2, np.inf)
QUICK = {"classes": ["wolf", "centaur"], "per_class": 1}


def keeps(kind: str, per_class: int, span: tuple[float, float] | None = None) -> list[float]:
    """The area fractions a class's parts keep, spread evenly over ``span`` (default ``KEEP[kind]``)."""
    lo, hi = KEEP[kind] if span is None else span
    return [lo + (hi - lo) * (k + 0.5) / per_class for k in range(per_class)]


class ClassPoses:
    """A class's poses at one resolution (simplified as its lowest pose is), numbered 0..n-1, with
    each pose's prepared metric, pyFM spectrum and geodesic reference made once."""

    def __init__(self, tosca: datasets.TOSCA, cls: str, n_vertices: int):
        self.tosca, self.cls = tosca, cls
        self.poses = tosca.poses(cls)
        ref = tosca.load(cls, self.poses[0])
        self.work = gromov.simplify(ref, n_vertices) if n_vertices else None
        self._meshes, self._prepared = {}, {}
        self.symmetry = reflection_map(self.mesh(self.poses[0]))   # shared by the class's poses

    def mesh(self, pose: int) -> gromov.Mesh:
        if pose not in self._meshes:
            m = self.tosca.load(self.cls, pose)
            if self.work is not None:
                m = self.work.transfer(m).mesh
            self._meshes[pose] = gromov.Mesh(m.vertices, m.faces)   # a file of its own: ids 0..n-1
        return self._meshes[pose]

    def prepared(self, pose: int, what: str) -> tuple:
        """``(object, seconds)``: the pose's ``"metric"`` (ShapeMetric in the correspondence's
        options), ``"pyfm"`` (processed TriMesh) or ``"fmm"`` (GeodesicReference), made once."""
        key = (pose, what)
        if key not in self._prepared:
            y = self.mesh(pose)
            t = time.perf_counter()
            if what == "metric":
                obj = ShapeMetric(y, "diffusion", metric_options=correspondence_options("diffusion", None))
                obj.distances
            elif what == "geodesic":
                obj = ShapeMetric(y, "geodesic")
                obj.distances
            elif what == "pyfm":
                from pyFM.mesh import TriMesh

                obj = TriMesh(y.vertices, y.faces, **PYFM["trimesh"]).process(200)   # preprocess()'s k_process
            else:
                obj = GeodesicReference(y)
            self._prepared[key] = (obj, time.perf_counter() - t)
        return self._prepared[key]


def grow(mesh: gromov.Mesh, vertices: np.ndarray) -> np.ndarray:
    """Mask of ``vertices`` and their one-ring neighbours."""
    mask = np.zeros(mesh.n_vertices, bool)
    mask[vertices] = True
    return mask | (mesh.adjacency @ mask.astype(float) > 0)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def cut_distance(part: gromov.Mesh, truth: np.ndarray, source: gromov.Mesh) -> np.ndarray:
    """Edge-graph distance of every part vertex to the cut: the part's boundary vertices that
    are not on the boundary of the shape it was cut from."""
    bv = np.unique(part.boundary_edges.ravel())
    was = np.zeros(source.n_vertices, bool)
    was[np.unique(source.boundary_edges.ravel())] = True
    new = bv[~was[truth[bv]]]
    return dijkstra(part.adjacency, directed=False, indices=new, min_only=True)


def near_working(s: ShapeMetric, ids) -> np.ndarray:
    """Working vertex of ``s`` nearest each input vertex (as :func:`gromov.evaluate.image_errors`)."""
    return s.working.from_source(s.input.from_input_ids(np.asarray(ids, dtype=np.int64)))


def heat(s: ShapeMetric):
    """The heat-kernel solver of ``s`` (inside the wrapper that reports a metric computed with
    the small holes filled on the shape's own vertices)."""
    solver = s.solver
    while not hasattr(solver, "t"):
        solver = solver.inner
    return solver


def diagnose(r, sx: ShapeMetric, sy: ShapeMetric, sa: ShapeMetric, truth, d_cut, diameter,
             true_region) -> dict:
    """Why ``ours`` fails on a part (the module notes): truth against found distortion, the
    truth's residual by distance to the cut, where the whole's samples outside the part land.
    ``sa``: the uncut pose the part was cut from, for the same points' distances before the cut."""
    P = near_working(sx, r.x_samples)
    dx = sx.distances[np.ix_(P, P)]
    off = ~np.eye(len(P), dtype=bool)
    out = {}
    rows = {}
    # the same points on the uncut pose: the truth's residual there (the poses' own
    # non-isometry) and how much the cut moved each sample's distances
    A = near_working(sa, truth[r.x_samples])
    da = sa.distances[np.ix_(A, A)]
    Yt = near_working(sy, truth[r.x_samples])
    res = (da - sy.distances[np.ix_(Yt, Yt)]) / sy.diameter
    out["uncut_truth_rms"] = float(np.sqrt(np.mean(res[off] ** 2)))
    moved = np.abs(np.where(off, dx - da, 0.0)).sum(axis=1) / (len(P) - 1) / sy.diameter
    out["cut_change_rms"] = float(np.sqrt(np.mean(((dx - da) / sy.diameter)[off] ** 2)))
    # the same with the part's diffusion time set to the uncut pose's (t = tau x area: a part of
    # 60% of the area diffuses for 60% of the time): what is left is the cut's boundary
    same_t = ShapeMetric(sx.input, "diffusion", working=sx.working,
                         metric_options={**sx.metric_options, "tau": heat(sa).t / heat(sx).area})
    ds = same_t.distances[np.ix_(P, P)]
    moved_t = np.abs(np.where(off, ds - da, 0.0)).sum(axis=1) / (len(P) - 1) / sy.diameter
    out["cut_change_same_t_rms"] = float(np.sqrt(np.mean(((ds - da) / sy.diameter)[off] ** 2)))
    Yt_res = (ds - sy.distances[np.ix_(Yt, Yt)]) / sy.diameter
    out["truth_same_t_rms"] = float(np.sqrt(np.mean(Yt_res[off] ** 2)))
    for name, img in (("truth", truth[r.x_samples]), ("found", r.x_to_y_vertex)):
        Y = near_working(sy, img)
        res = (dx - sy.distances[np.ix_(Y, Y)]) / sy.diameter
        out[f"{name}_rms"] = float(np.sqrt(np.mean(res[off] ** 2)))
        rows[name] = np.abs(np.where(off, res, 0.0)).sum(axis=1) / (len(P) - 1)
        if name == "truth":
            out["truth_ratio_median"] = float(np.median(dx[off] / np.maximum(sy.distances[np.ix_(Y, Y)][off], 1e-12)))
    dc = d_cut[r.x_samples] / diameter
    out["truth_residual_by_cut"] = [float(rows["truth"][(dc >= lo) & (dc < hi)].mean())
                                    if ((dc >= lo) & (dc < hi)).any() else None
                                    for lo, hi in zip(CUT_BINS[:-1], CUT_BINS[1:])]
    for key, v in (("cut_change_by_cut", moved), ("cut_change_same_t_by_cut", moved_t)):
        out[key] = [float(v[(dc >= lo) & (dc < hi)].mean()) if ((dc >= lo) & (dc < hi)).any() else None
                    for lo, hi in zip(CUT_BINS[:-1], CUT_BINS[1:])]
    out["samples_by_cut"] = [int(((dc >= lo) & (dc < hi)).sum()) for lo, hi in zip(CUT_BINS[:-1], CUT_BINS[1:])]
    outside = ~true_region[r.y_samples]
    land = d_cut[r.y_to_x_vertex[outside]] / diameter
    out["whole_samples_outside"] = int(outside.sum())
    out["outside_images_cut_distance_median"] = float(np.median(land)) if land.size else None
    out["outside_images_near_cut"] = float(np.mean(land < 0.05)) if land.size else None
    out["part_vertices_near_cut"] = float(np.mean(d_cut / diameter < 0.05))
    out["part_cut_distance_median"] = float(np.median(d_cut / diameter))
    out["relative_distance"] = float(r.relative_distance)
    out["orientation"] = float(r.orientation)
    return out


def fill_closed(part: gromov.Mesh, truth, source: gromov.Mesh) -> tuple[int, int]:
    """How many of the part's new boundary loops (the cut's) the diffusion metric's default
    ``fill_holes`` (0.5 sqrt(area)) closes, of how many."""
    was = np.zeros(source.n_vertices, bool)
    was[np.unique(source.boundary_edges.ravel())] = True
    limit = 0.5 * np.sqrt(part.area)
    X, closed, total = part.vertices, 0, 0
    for loop in part.boundary_loops:
        if was[truth[loop]].all():
            continue
        total += 1
        closed += np.linalg.norm(X[np.roll(loop, -1)] - X[loop], axis=1).sum() < limit
    return int(closed), total


def evaluate_pair(poses: ClassPoses, kind: str, k: int, keep: float, radius: float, count: int,
                  methods=METHODS) -> dict | None:
    a, b = poses.poses[k % len(poses.poses)], poses.poses[(k + 1) % len(poses.poses)]
    source, whole = poses.mesh(a), poses.mesh(b)
    name = f"{poses.cls}{a}-{kind}{k}->{poses.cls}{b}"
    t = time.perf_counter()
    try:
        p = cut(source, keep, kind=kind, seed=k, **({"count": count} if kind == "holes" else {}))
    except ValueError as exc:
        print(f"  {name}: no part: {exc}", flush=True)
        return None
    t_cut = time.perf_counter() - t
    part, truth = gromov.Mesh(p.mesh.vertices, p.mesh.faces), p.vertex_map
    (sy, t_sy), (fmm, _) = poses.prepared(b, "metric"), poses.prepared(b, "fmm")
    row = {"pair": name, "kind": kind, "keep": keep, "kept": p.params["kept"], "tries": p.params["tries"],
           "side_fraction": p.params["side_fraction"], "part_vertices": part.n_vertices,
           "whole_vertices": whole.n_vertices, "cut_seconds": t_cut,
           "boundary_loops": p.boundary_loops_after}
    row["cut_loops_closed"], row["cut_loops"] = fill_closed(part, truth, source)

    t = time.perf_counter()
    sx = ShapeMetric(part, "diffusion", metric_options=correspondence_options("diffusion", None))
    sx.distances
    t_px = time.perf_counter() - t
    maps, seconds, regions = {}, {}, {}
    r = None
    if "ours" in methods:
        t = time.perf_counter()
        r = gromov.match(sx, sy, dense=True)
        seconds["ours"] = t_px + t_sy + time.perf_counter() - t
        maps["ours"] = (r.x_to_y_dense_face, r.x_to_y_dense_bary, r.x_to_y_dense_vertex)
    if "ours_partial" in methods:
        syg, t_syg = poses.prepared(b, "geodesic")
        t = time.perf_counter()
        sxg = ShapeMetric(part, "geodesic")
        rp = gromov.match(sxg, syg, partial=True, dense=True)
        seconds["ours_partial"] = t_syg + time.perf_counter() - t
        maps["ours_partial"] = (rp.x_to_y_dense_face, rp.x_to_y_dense_bary, rp.x_to_y_dense_vertex)
        regions["ours_partial"] = rp.y_covered
        row["partial"] = {"relative_distance": float(rp.relative_distance), "covered_fraction": float(rp.covered_fraction),
                          "true_fraction": float(part.area / source.area), "orientation": float(rp.orientation)}
    if radius and "ours" in methods:
        row["radius"] = radius * sx.diameter
        t = time.perf_counter()
        rr = gromov.match(sx, sy, dense=True, radius=row["radius"])
        seconds["ours_radius"] = t_px + t_sy + time.perf_counter() - t
        maps["ours_radius"] = (rr.x_to_y_dense_face, rr.x_to_y_dense_bary, rr.x_to_y_dense_vertex)
    if "pyfm" in methods:
        ref, t_ref = poses.prepared(b, "pyfm")
        t = time.perf_counter()
        p2p = pyfm_p2p(part, whole, ref)
        seconds["pyfm"] = t_ref + time.perf_counter() - t
        maps["pyfm"] = (*at_vertices(whole, p2p), p2p)

    true_region = grow(whole, truth)
    sym = np.asarray(poses.symmetry)[truth]
    true_mirrored = grow(whole, np.where(sym >= 0, sym, truth))   # the mirrored truth's region
    row["iou_whole_shape"] = float(true_region.mean())   # the IoU of a map that claims the whole shape
    t = time.perf_counter()
    for method, (face, bary, vertex) in maps.items():
        e = dense_error(face, bary, whole, truth, poses.symmetry, fmm=fmm)
        # an image on another piece of the whole (a gorilla's eye) than its truth: infinitely far,
        # counted as the whole's diameter
        cap = e.diameter / np.sqrt(e.area)
        truth_region = true_mirrored if e.branch == "mirrored" else true_region
        region = regions.get(method, grow(whole, vertex))
        errors, direct = (np.where(np.isfinite(x), x, cap) for x in (e.errors, e.direct))
        row[method] = {"mean": float(errors.mean()), "median": float(np.median(errors)),
                       "mean_direct": float(direct.mean()), "median_direct": float(np.median(direct)),
                       "per_diameter": float(errors.mean() / cap), "branch": e.branch,
                       "off_piece": float(np.mean(~np.isfinite(e.direct))), "seconds": seconds[method],
                       "iou": iou(region, truth_region), "iou_direct": iou(region, true_region),
                       "iou_images": iou(grow(whole, vertex), truth_region), "errors": errors, "direct": direct}
        diameter = e.diameter
    row["evaluation_seconds"] = time.perf_counter() - t
    row["whole_diameter"] = diameter
    row["to_diameter"] = float(np.sqrt(whole.area) / diameter)
    d_cut = cut_distance(part, truth, source)
    if r is None:   # the diagnostics are those of ``ours``
        d_cut = None
    try:
        if d_cut is not None:
            row["diagnostics"] = diagnose(r, sx, sy, poses.prepared(a, "metric")[0], truth, d_cut, diameter,
                                          true_region)
    except Exception as exc:   # a diagnostic must not stop the run: said, and left out
        print(f"  {name}: no diagnostics: {type(exc).__name__}: {exc}", flush=True)
    said = "   ".join(f"{m} {row[m]['mean'] * 100:6.2f} ({row[m]['seconds']:5.1f} s, IoU {row[m]['iou']:.2f})"
                       for m in METHODS if m in row)
    print(f"  {name:<28} keep {row['kept']:.2f}  {said}", flush=True)
    return row


def add_baseline(path: str, data: str) -> None:
    """Add ``iou_whole_shape`` (the IoU of a map claiming every vertex of the whole: the true
    region's share of its vertices) to a results file made without it, from the same seeded cuts."""
    import json

    res = json.loads(Path(path).read_text())
    tosca = datasets.TOSCA(Path(data) / "tosca")
    classes = {}
    for row in res["pairs"]:
        cls = row["pair"].split("-")[0]
        classes.setdefault(cls.rstrip("0123456789"), []).append(row)
    for cls, rows in classes.items():
        poses = ClassPoses(tosca, cls, res["run"]["vertices"])
        for row in rows:
            k = int(row["pair"].split("-")[1].split("->")[0].removeprefix(row["kind"]))
            a, b = poses.poses[k % len(poses.poses)], poses.poses[(k + 1) % len(poses.poses)]
            p = cut(poses.mesh(a), row["keep"], kind=row["kind"], seed=k,
                    **({"count": res["run"]["holes_count"]} if row["kind"] == "holes" else {}))
            if p.params["kept"] != row["kept"]:
                raise RuntimeError(f"{row['pair']}: the cut is not the one measured")
            row["iou_whole_shape"] = float(grow(poses.mesh(b), p.vertex_map).mean())
    for kind, summary in ((k, v) for k, v in res["summary"].items() if k in KEEP):
        summary["iou_whole_shape"] = float(np.mean([r["iou_whole_shape"] for r in res["pairs"] if r["kind"] == kind]))
        print(f"{kind}: IoU of claiming the whole shape {summary['iou_whole_shape']:.3f}")
    Path(path).write_text(json.dumps(res, indent=1))


def summarise(title: str, rows: list[dict]) -> dict:
    """Pool the points of the pairs per method (errors x100), print the table and return it."""
    out = {"pairs": len(rows)}
    if rows:
        out["iou_whole_shape"] = float(np.mean([r["iou_whole_shape"] for r in rows]))
    print(f"\n{title}: {len(rows)} pairs; error x100 / sqrt(area of the whole) on the part's vertices "
          "(best of direct and mirrored; direct only)")
    print(f"  {'':<14}{'mean':>7}{'median':>8}{'mean d':>8}{'med d':>7}{'gross':>9}{'IoU':>7}{'IoU d':>7}{'s/pair':>8}")
    for method in METHODS:
        have = [r for r in rows if method in r]
        if not have:
            continue
        err = np.concatenate([r[method]["errors"] for r in have])
        direct = np.concatenate([r[method]["direct"] for r in have])
        s = {"mean": 100 * float(err.mean()), "median": 100 * float(np.median(err)),
             "mean_direct": 100 * float(direct.mean()), "median_direct": 100 * float(np.median(direct)),
             "pair_median_of_means": 100 * float(np.median([r[method]["mean"] for r in have])),
             "gross": int(sum(r[method]["per_diameter"] > GROSS for r in have)), "n": len(have),
             "iou": float(np.mean([r[method]["iou"] for r in have])),
             "iou_direct": float(np.mean([r[method].get("iou_direct", r[method]["iou"]) for r in have])),
             "iou_images": float(np.mean([r[method]["iou_images"] for r in have])),
             "seconds_per_pair": float(np.mean([r[method]["seconds"] for r in have]))}
        out[method] = s
        print(f"  {method:<14}{s['mean']:>7.2f}{s['median']:>8.2f}{s['mean_direct']:>8.2f}"
              f"{s['median_direct']:>7.2f}{s['gross']:>5}/{len(have):<3}{s['iou']:>7.2f}{s['iou_direct']:>7.2f}"
              f"{s['seconds_per_pair']:>8.1f}")
    if rows:
        print(f"  (a map claiming the whole shape: IoU {out['iou_whole_shape']:.2f})")
    d = [r["diagnostics"] for r in rows if "diagnostics" in r]
    if d:
        n_cut = np.array([x["samples_by_cut"] for x in d])

        def pooled(key):   # per-bin means of the pairs, weighted by their samples in the bin
            v = np.array([[np.nan if y is None else y for y in x[key]] for x in d])
            return [float(np.nansum(v[:, i] * n_cut[:, i]) / max(n_cut[:, i].sum(), 1)) for i in range(v.shape[1])]

        weighted, moved = pooled("truth_residual_by_cut"), pooled("cut_change_by_cut")
        moved_t = pooled("cut_change_same_t_by_cut")
        outside = [x["outside_images_near_cut"] for x in d if x["outside_images_near_cut"] is not None]
        out["diagnostics"] = {
            "truth_rms": float(np.mean([x["truth_rms"] for x in d])),
            "uncut_truth_rms": float(np.mean([x["uncut_truth_rms"] for x in d])),
            "cut_change_rms": float(np.mean([x["cut_change_rms"] for x in d])),
            "cut_change_by_cut": moved,
            "cut_change_same_t_rms": float(np.mean([x["cut_change_same_t_rms"] for x in d])),
            "truth_same_t_rms": float(np.mean([x["truth_same_t_rms"] for x in d])),
            "cut_change_same_t_by_cut": moved_t,
            "found_rms": float(np.mean([x["found_rms"] for x in d])),
            "truth_worse_than_found": int(sum(x["truth_rms"] > x["found_rms"] for x in d)),
            "truth_ratio_median": float(np.median([x["truth_ratio_median"] for x in d])),
            "truth_residual_by_cut": weighted, "samples_by_cut": n_cut.sum(axis=0).tolist(),
            "cut_bins": [b if np.isfinite(b) else None for b in CUT_BINS],
            "outside_images_near_cut": float(np.mean(outside)) if outside else None,
            "part_vertices_near_cut": float(np.mean([x["part_vertices_near_cut"] for x in d])),
            "cut_loops_closed": int(sum(r["cut_loops_closed"] for r in rows)),
            "cut_loops": int(sum(r["cut_loops"] for r in rows))}
        g = out["diagnostics"]
        print(f"  ours' distortion on the part's samples (RMS / diameter): ground truth {g['truth_rms']:.4f}, "
              f"found {g['found_rms']:.4f} (truth worse in {g['truth_worse_than_found']}/{len(d)} pairs); "
              f"the same points uncut: ground truth {g['uncut_truth_rms']:.4f}; the cut moved their distances "
              f"by {g['cut_change_rms']:.4f} (RMS); part/whole distance ratio of true pairs (median) "
              f"{g['truth_ratio_median']:.3f}")
        print("  truth residual by the sample's distance to the cut (/ diameter): " + ", ".join(
            f"[{lo:g}, {hi:g}): {v:.4f} ({n})" for lo, hi, v, n in
            zip(CUT_BINS[:-1], CUT_BINS[1:], weighted, g["samples_by_cut"])))
        print("  change of the sample's distances by the cut, by the same bins: " + ", ".join(
            f"{v:.4f}" for v in moved) + "; with the uncut pose's diffusion time: " + ", ".join(
            f"{v:.4f}" for v in moved_t) + f" (RMS {g['cut_change_same_t_rms']:.4f}; ground truth's "
            f"distortion then {g['truth_same_t_rms']:.4f})")
        if outside:
            print(f"  images of the whole's samples outside the part within 0.05 diameter of the cut: "
                  f"{g['outside_images_near_cut']:.2f} (part vertices there: {g['part_vertices_near_cut']:.2f}); "
                  f"cut loops closed by fill_holes: {g['cut_loops_closed']}/{g['cut_loops']}")
    return out


def full_vs_partial(poses: ClassPoses, repeat: int = 3, compile_first: bool = False) -> dict:
    """The class's uncut pose matched to the next one, full and ``partial=True`` (geodesic): what
    partial matching reports for two whole shapes, and what it costs.

    Cost, two ways: *cold*, one call each from the meshes (each call makes its own metrics, as
    ``gromov match A B`` does); *warm*, on the two poses prepared once, every per-shape cache filled
    by a first call of each (distances, samples, curvature, the whole's intrinsic reflection), the
    median of ``repeat`` calls, full and partial in turn (what a pair costs in a collection).
    ``compile_first``: match copies of the two poses once before, uncounted (the process's first
    calls compile the kernels, which is not a match's cost)."""
    a, b = poses.poses[0], poses.poses[1 % len(poses.poses)]
    ma, mb = poses.mesh(a), poses.mesh(b)
    if compile_first:
        fresh = [gromov.Mesh(m.vertices.copy(), m.faces.copy()) for m in (ma, mb)]
        gromov.match(*fresh, "geodesic")
        gromov.match(*fresh, "geodesic", partial=True)
    t = time.perf_counter()
    gromov.match(ma, mb, "geodesic")
    cold_full = time.perf_counter() - t
    t = time.perf_counter()
    gromov.match(ma, mb, "geodesic", partial=True)
    cold_part = time.perf_counter() - t
    sx, sy = poses.prepared(a, "geodesic")[0], poses.prepared(b, "geodesic")[0]
    full, part = gromov.match(sx, sy, "geodesic"), gromov.match(sx, sy, "geodesic", partial=True)
    warm_full, warm_part = [], []
    for _ in range(repeat):
        t = time.perf_counter()
        gromov.match(sx, sy, "geodesic")
        warm_full.append(time.perf_counter() - t)
        t = time.perf_counter()
        gromov.match(sx, sy, "geodesic", partial=True)
        warm_part.append(time.perf_counter() - t)
    out = {"pair": f"{poses.cls}{a}->{poses.cls}{b}", "full": float(full.relative_distance),
           "partial": float(part.relative_distance), "ratio": float(part.relative_distance / full.relative_distance),
           "covered_fraction": float(part.covered_fraction),
           "cold_full_seconds": cold_full, "cold_partial_seconds": cold_part, "cold_cost_ratio": cold_part / cold_full,
           "full_seconds": float(np.median(warm_full)), "partial_seconds": float(np.median(warm_part))}
    out["cost_ratio"] = out["partial_seconds"] / out["full_seconds"]
    print(f"  {out['pair']} uncut: relative distance full {out['full']:.4f}, partial {out['partial']:.4f} "
          f"(ratio {out['ratio']:.3f}), covered {out['covered_fraction']:.2f}; partial / full time: "
          f"cold {out['cold_cost_ratio']:.2f} ({cold_part:.2f} / {cold_full:.2f} s), warm {out['cost_ratio']:.2f} "
          f"({out['partial_seconds']:.2f} / {out['full_seconds']:.2f} s)", flush=True)
    return out


def _rows_for_json(rows: list[dict]) -> list[dict]:
    return [{k: ({m: v for m, v in d.items() if m not in ("errors", "direct")} if k in METHODS else d)
             for k, d in r.items()} for r in rows]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--classes", default=None, help="TOSCA classes, comma-separated (default: all)")
    ap.add_argument("--per-class", type=int, default=4, help="parts per class and kind (default 4)")
    ap.add_argument("--kinds", default="plane,holes", help="plane, holes or both (default)")
    ap.add_argument("--vertices", type=int, default=4000,
                    help="simplify every pose of a class to this many vertices as its lowest pose is "
                         "(0: the full meshes; default 4000)")
    ap.add_argument("--radius", type=float, default=0.7,
                    help="ours_radius: radius = this x the part's diameter in the metric (0: not run)")
    ap.add_argument("--count", type=int, default=CUT_PATCHES, help="holes: disks per part")
    ap.add_argument("--keep", default=None, metavar="LO,HI",
                    help="the area fractions the parts keep, for every kind (default: plane 0.4,0.8, "
                         "holes 0.6,0.8)")
    ap.add_argument("--methods", default="ours,ours_partial,pyfm",
                    help=f"comma-separated, of {','.join(METHODS)} (ours_radius: with --radius; default "
                         "ours,ours_partial,pyfm)")
    ap.add_argument("--quick", action="store_true",
                    help=f"{','.join(QUICK['classes'])}, {QUICK['per_class']} part per class and kind")
    ap.add_argument("--bridge", choices=("0", "1", "choose"), default=None,
                    help="gromov.partial.PARTIAL_BRIDGE for this run (default: the package's)")
    ap.add_argument("--json", default=str(HERE / "results" / "partial.json"))
    ap.add_argument("--add-baseline", action="store_true",
                    help="add the IoU of claiming the whole shape to the --json file made without it "
                         "(recomputing its cuts; nothing is matched)")
    args = ap.parse_args(argv)
    if args.add_baseline:
        return add_baseline(args.json, args.data)
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    classes = (QUICK["classes"] if args.quick else
               tosca.classes if args.classes is None else [c for c in args.classes.split(",") if c])
    per_class = QUICK["per_class"] if args.quick else args.per_class
    kinds = [k for k in args.kinds.split(",") if k]
    methods = [m for m in args.methods.split(",") if m]
    unknown = (sorted(set(classes) - set(tosca.classes)) + sorted(set(kinds) - set(KEEP))
               + sorted(set(methods) - set(METHODS)))
    if unknown:
        ap.error(f"unknown classes, kinds or methods {unknown}")
    span = None
    if args.keep is not None:
        try:
            span = tuple(float(x) for x in args.keep.split(","))
        except ValueError:
            span = ()
        if len(span) != 2 or not 0.0 < span[0] <= span[1] < 1.0:
            ap.error(f"--keep takes LO,HI with 0 < LO <= HI < 1, got {args.keep!r}")
    if args.bridge is not None:
        gromov.partial.PARTIAL_BRIDGE = {"0": False, "1": True}.get(args.bridge, args.bridge)
    res = {"gromov": {"version": gromov.__version__,
                      "match": {"metric": "diffusion", "dense": "input", "n_samples": 100,
                                "radius_fraction_of_part_diameter": args.radius or None},
                      "partial": {"metric": "geodesic", "dense": "input", "n_samples": 100,
                                  "boundary_width": BOUNDARY_WIDTH, "bridge": gromov.partial.PARTIAL_BRIDGE}},
           "pyfm": {"version": version("pyfmaps"), "k_process": 200, **PYFM}, "gross_per_diameter": GROSS,
           "run": {"classes": classes, "per_class": per_class, "kinds": kinds, "methods": methods,
                   "vertices": args.vertices,
                   "keep": {k: keeps(k, per_class, span) for k in kinds}, "holes_count": args.count,
                   "command": "benchmarks/bench_partial.py " + " ".join(sys.argv[1:] if argv is None else argv)}}
    t0 = time.perf_counter()
    rows, uncut = [], []
    for cls in classes:
        t = time.perf_counter()
        poses = ClassPoses(tosca, cls, args.vertices)
        print(f"{cls}: poses {poses.poses}, {poses.mesh(poses.poses[0]).n_vertices} vertices "
              f"({time.perf_counter() - t:.1f} s)", flush=True)
        for kind in kinds:
            for k, keep in enumerate(keeps(kind, per_class, span)):
                row = evaluate_pair(poses, kind, k, keep, args.radius, args.count, methods)
                if row is not None:
                    rows.append(row)
        if "ours_partial" in methods:
            uncut.append(full_vs_partial(poses, compile_first=not uncut))
        # the pairs so far, in case the run is stopped (the summary comes at the end)
        write_results(args.json, {**res, "pairs": _rows_for_json(rows), "full_vs_partial": uncut, "complete": False,
                                  "total_seconds": time.perf_counter() - t0})
    res["summary"] = {kind: summarise(f"TOSCA parts, {kind}", [r for r in rows if r["kind"] == kind])
                      for kind in kinds}
    res["pairs"] = _rows_for_json(rows)
    if uncut:
        ratios = np.array([u["ratio"] for u in uncut])
        res["full_vs_partial"] = uncut
        res["summary"]["full_vs_partial"] = {"pairs": len(uncut), "ratio_min": float(ratios.min()),
                                             "ratio_max": float(ratios.max()),
                                             "within_10_percent": int(np.sum(np.abs(ratios - 1) <= 0.1)),
                                             "cold_cost_ratio_max": max(u["cold_cost_ratio"] for u in uncut),
                                             "cost_ratio_max": max(u["cost_ratio"] for u in uncut)}
        print(f"\nuncut poses, partial / full relative distance: {ratios.min():.3f} - {ratios.max():.3f} "
              f"({res['summary']['full_vs_partial']['within_10_percent']} of {len(uncut)} within 10%); partial / full "
              f"time at most {res['summary']['full_vs_partial']['cold_cost_ratio_max']:.2f} cold, "
              f"{res['summary']['full_vs_partial']['cost_ratio_max']:.2f} warm")
    res["total_seconds"], res["complete"] = time.perf_counter() - t0, True
    print(f"\ntotal {res['total_seconds']:.0f} s")
    write_results(args.json, res)
    return res


if __name__ == "__main__":
    main()
