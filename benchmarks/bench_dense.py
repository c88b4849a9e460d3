"""Dense correspondence: ``gromov.match(..., dense=True)`` beside functional maps (pyFM).

Run:  .venv/bin/python benchmarks/bench_dense.py [--data DIR] [--topkids N] [--classes cat,dog,...]
                                                [--remeshed DIR] [--perturbed DIR] [--local K] [--relax on|off] [--inverse R] [--quick] [--json OUT]

The anchor is pyFM (``pip install pyfmaps``, import ``pyFM``) as its quick-start runs it: both
meshes area-normalised and centred, 200 Laplace-Beltrami eigenpairs, WKS descriptors (every
second one kept), a 30x30 functional map fitted with the quick-start weights (orientation term
on), ZoomOut refinement (16 iterations of 5), then the vertex-to-vertex map. pyFM's ``p2p_21``
maps mesh2's vertices to mesh1, so a map X -> Y is ``FunctionalMapping(Y, X)``'s. The same
parameters on every pair, no tuning.

Pairs: SHREC'16 TOPKIDS kidXX -> kid00 (XX = 01..25; symmetric ground truth: kid00's symmetry
file) and, per TOSCA class with a pose 0, pose 0 <-> the next pose, both directions (ground
truth: the same vertex; symmetric reading: the mirror map of pose 0,
:func:`gromov.experiments.reproduce.reflection_map`, shared by the class's poses). With
``--remeshed DIR`` (made by ``benchmarks/remesh.py``), the same pairs on copies of the poses
remeshed independently (no shared vertex or triangle; truth carried by the nearest original
vertex), and pose 0 at two densities against each other (``cls0-2000`` <-> ``cls0-8000``).
With ``--perturbed DIR`` (the same copies), each class's remeshed pose 0 against itself with
topological noise (:func:`gromov.perturb.holes`, 20 holes as the paper's Experiment 2; and
:func:`gromov.perturb.weld`, 3 welds), both directions: truth by the perturbation's vertex map;
from the whole shape only the vertices the perturbed one keeps are scored.

Measured per pair, on the target's input mesh with :func:`gromov.evaluate.dense_error`
(geodesic error by fast marching / sqrt(area), the better of the direct and the mirrored
ground truth; "direct" counts the direct one only): ours at its 100 samples, dense (every
vertex of X) and dense read at the samples' vertices (the dense map and the samples on the same
points), pyFM at the same samples and dense. The summary pools the points of all pairs
(mean and median x100), "/diam" is the mean error divided by the target's geodesic diameter,
"gross" counts pairs whose mean error per diameter exceeds 0.25, and it lists the pairs whose
dense mean is above the samples' mean, over every vertex and at the samples' vertices. Seconds per pair: the match
for ours (``gromov.match``, shape preparation included), the whole pyFM pipeline for the
anchor, evaluation excluded; work on a reference reused by every pair (kid00) is done once for
both methods and reported apart.
"""

from __future__ import annotations

import argparse
import sys
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np

import gromov
import gromov.dense
from gromov.evaluate import GeodesicReference, dense_error
from gromov.experiments import datasets
from gromov.experiments.reproduce import reflection_map
from gromov.gh import ShapeMetric
from gromov.metrics.diffusion import correspondence_options

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import HERE, add_data_argument, write_results  # noqa: E402

#: Class -> the pose matched with pose 0 (the next pose the data README lists).
TOSCA_PAIRS = {"cat": 1, "dog": 1, "horse": 5, "centaur": 1, "wolf": 1, "david": 1, "michael": 1, "victoria": 1}
QUICK_CLASSES = ("wolf", "centaur")
GROSS = 0.25
#: pyFM's documented quick-start (README of pyfmaps 1.3.1).
PYFM = {"trimesh": {"area_normalize": True, "center": True},
        "preprocess": {"descr_type": "WKS", "subsample_step": 2},
        "fit": {"K": 30, "w_descr": 1e0, "w_lap": 1e-1, "w_dcomm": 1e0, "w_orient": 1e0},
        "zoomout_refine": {"nit": 16, "step": 5}}
KINDS = ("ours_samples", "ours_dense", "pyfm_samples", "pyfm_dense")
#: Our dense map read at our own samples' vertices: beside "ours_samples", the two on the same points.
SAME_POINTS = "ours_dense_at_samples"
#: ``gromov.match``'s ``dense``: "input" (the default, as ``dense=True``), "zoomout" or "placed" (``--dense``)
DENSE = {"mode": "input"}


def at_vertices(mesh: gromov.Mesh, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``v`` (indices of ``mesh``) as points: a face holding each and the unit
    barycentric coordinates of its corner. Returns ``face (k,)``, ``bary (k, 3)``."""
    indptr, face_ids = mesh.vertex_faces
    v = np.asarray(v, dtype=np.int64)
    if np.any(indptr[v + 1] == indptr[v]):
        raise ValueError("a vertex without a face has no barycentric image")
    f = face_ids[indptr[v]]
    return f, np.eye(3)[np.argmax(mesh.faces[f] == v[:, None], axis=1)]


def add_study_arguments(ap, sets: str = "topkids,remeshed,perturbed") -> None:
    """The arguments the dense studies share: ``--remeshed``, ``--sets``, ``--points``."""
    ap.add_argument("--remeshed", required=True, help="the folder benchmarks/remesh.py --out filled")
    ap.add_argument("--sets", default=sets)
    ap.add_argument("--points", type=int, default=2000, help="vertices of X scored per map")


def random_point_error(x: gromov.Mesh, y: gromov.Mesh, truth: np.ndarray, sym, fmm, points: int):
    """A study's scorer: the mean error x 100 / sqrt(area) of an input-vertex map X -> Y (indices
    of ``y``) on the same ``points`` random vertices of X with a truth (seeded), the better of the
    direct and mirrored readings as :func:`evaluate_pair` scores them."""
    tr = truth[x.input_ids]
    ok = np.flatnonzero(tr >= 0)
    if len(ok) > points:
        ok = np.sort(np.random.default_rng(0).choice(ok, points, replace=False))

    def error(t: np.ndarray) -> float:
        face, bary = at_vertices(y, t[ok])
        return 100 * dense_error(face, bary, y, tr[ok], sym, fmm=fmm).mean
    return error


def pyfm_p2p(x: gromov.Mesh, y, reference=None) -> np.ndarray:
    """pyFM's quick-start map X -> Y: for each vertex index of ``x``, a vertex index of ``y``.
    ``reference``: a processed ``TriMesh`` of ``y`` (its spectrum is reused)."""
    from pyFM.functional import FunctionalMapping
    from pyFM.mesh import TriMesh

    ty = reference if reference is not None else TriMesh(y.vertices, y.faces, **PYFM["trimesh"])
    model = FunctionalMapping(ty, TriMesh(x.vertices, x.faces, **PYFM["trimesh"]))  # p2p_21: X -> Y
    model.preprocess(**PYFM["preprocess"])
    model.fit(**PYFM["fit"])
    return model.get_p2p(model.zoomout_refine(**PYFM["zoomout_refine"]))


def evaluate_pair(name, x, y, yref, truth, sym, fmm, pyfm_ref=None) -> dict:
    """Match ``x`` -> ``y`` with both methods and measure the four maps.

    ``yref`` is what ``gromov.match`` gets for Y (the mesh or a reused ShapeMetric), ``truth``
    the true Y file id of each X file id, ``sym`` Y's mirror map (file ids) or None."""
    t = time.perf_counter()
    r = gromov.match(x, yref, dense=DENSE["mode"])
    t_ours = time.perf_counter() - t
    t = time.perf_counter()
    p2p = y.input_ids[pyfm_p2p(x, y, pyfm_ref)]  # Y file id per X vertex index
    t_pyfm = time.perf_counter() - t
    n = len(r.x_to_y_dense_face)  # ours: one entry per X file id
    on_samples = x.from_input_ids(r.x_samples)
    maps = {"ours_samples": (r.x_to_y_face, r.x_to_y_bary, truth[r.x_samples]),
            "ours_dense": (r.x_to_y_dense_face, r.x_to_y_dense_bary, truth[np.arange(n)]),
            SAME_POINTS: (r.x_to_y_dense_face[r.x_samples], r.x_to_y_dense_bary[r.x_samples], truth[r.x_samples]),
            "pyfm_samples": (*at_vertices(y, y.from_input_ids(p2p[on_samples])), truth[r.x_samples]),
            "pyfm_dense": (*at_vertices(y, y.from_input_ids(p2p)), truth[x.input_ids])}
    row = {"pair": name, "seconds": {"ours": t_ours, "pyfm": t_pyfm}}
    t = time.perf_counter()
    for kind, (face, bary, tru) in maps.items():
        if (tru < 0).any():   # X vertices without a true image (removed from Y): not scored
            face, bary, tru = face[tru >= 0], bary[tru >= 0], tru[tru >= 0]
        e = dense_error(face, bary, y, tru, sym, fmm=fmm)
        row[kind] = {"mean": e.mean, "median": float(np.median(e.errors)), "mean_direct": e.mean_direct,
                     "median_direct": float(np.median(e.direct)), "per_diameter": float(e.per_diameter().mean()),
                     "branch": e.branch, "errors": e.errors, "direct": e.direct,
                     "to_diameter": float(np.sqrt(e.area) / e.diameter)}
    row["seconds"]["evaluation"] = time.perf_counter() - t
    print(f"  {name:<16} ours {row['ours_dense']['mean']:.4f} ({t_ours:5.1f} s)   "
          f"pyFM {row['pyfm_dense']['mean']:.4f} ({t_pyfm:5.1f} s)", flush=True)
    return row


def summarise(title: str, rows: list[dict], has_symmetry: bool) -> dict:
    """Pool the pairs' points per map kind, print the table and return it (errors x100)."""
    out = {}
    for kind in KINDS + (SAME_POINTS,):
        err = np.concatenate([r[kind]["errors"] for r in rows])
        direct = np.concatenate([r[kind]["direct"] for r in rows])
        per_diam = np.concatenate([r[kind]["errors"] * r[kind]["to_diameter"] for r in rows])
        who = "ours" if kind.startswith("ours") else "pyfm"
        out[kind] = {"mean": 100 * err.mean(), "median": 100 * np.median(err),
                     "mean_direct": 100 * direct.mean(), "median_direct": 100 * np.median(direct),
                     "per_diameter": float(per_diam.mean()),
                     "gross": sum(r[kind]["per_diameter"] > GROSS for r in rows),
                     "seconds_per_pair": float(np.mean([r["seconds"][who] for r in rows]))}
    out = {k: {m: float(v) if m != "gross" else int(v) for m, v in d.items()} for k, d in out.items()}
    out["ratio_dense"] = out["pyfm_dense"]["mean"] / out["ours_dense"]["mean"]
    out["ratio_dense_direct"] = out["pyfm_dense"]["mean_direct"] / out["ours_dense"]["mean_direct"]
    # where our dense map is less precise than our samples: over every vertex (its mean against
    # the samples'), and on the same points (the dense map read at the samples' vertices)
    out["dense_above_samples"] = {
        "every_vertex": [r["pair"] for r in rows if r["ours_dense"]["mean"] > r["ours_samples"]["mean"]],
        "same_points": [r["pair"] for r in rows if r[SAME_POINTS]["mean"] > r["ours_samples"]["mean"]]}
    print(f"\n{title}: {len(rows)} pairs; error x100 / sqrt(area)"
          + (" (best of direct and mirrored; direct only)" if has_symmetry else ""))
    print(f"  {'':<22}{'mean':>7}{'median':>8}{'mean d':>8}{'med d':>7}{'/diam':>8}{'gross':>7}{'s/pair':>8}")
    labels = {"ours_samples": "ours, at samples", "ours_dense": "ours, dense",
              "pyfm_samples": "pyFM, at our samples", "pyfm_dense": "pyFM, dense",
              SAME_POINTS: "ours, dense at samples"}
    for kind in KINDS + (SAME_POINTS,):
        s = out[kind]
        print(f"  {labels[kind]:<22}{s['mean']:>7.2f}{s['median']:>8.2f}{s['mean_direct']:>8.2f}"
              f"{s['median_direct']:>7.2f}{s['per_diameter']:>8.4f}{s['gross']:>4}/{len(rows):<2}"
              f"{s['seconds_per_pair']:>8.1f}")
    print(f"  ratio pyFM / ours, mean dense error: {out['ratio_dense']:.2f} "
          f"(direct only: {out['ratio_dense_direct']:.2f})")
    above = out["dense_above_samples"]
    print(f"  pairs whose dense mean is above the samples': {len(above['every_vertex'])} over every vertex, "
          f"{len(above['same_points'])} at the samples' vertices {above['same_points']}")
    return out


def _rows_for_json(rows: list[dict]) -> list[dict]:
    return [{k: ({m: v for m, v in d.items() if m not in ("errors", "direct")} if k in KINDS + (SAME_POINTS, "exact_vertex") else d)
             for k, d in r.items()} for r in rows]


def run_topkids(root: Path, n: int) -> dict:
    """kid01..kidN -> kid00, kid00 prepared once for both methods."""
    from pyFM.mesh import TriMesh

    kids = datasets.TopKids(root / "topkids")
    y = kids.load(kids.reference)
    t = time.perf_counter()
    sy = ShapeMetric(y, "diffusion", metric_options=correspondence_options("diffusion", None))
    sy.distances  # the reference's metric, once
    t_ours = time.perf_counter() - t
    t = time.perf_counter()
    ref = TriMesh(y.vertices, y.faces, **PYFM["trimesh"]).process(200)  # preprocess()'s k_process
    t_pyfm = time.perf_counter() - t
    fmm, sym = GeodesicReference(y), kids.symmetry(kids.reference)
    print(f"TOPKIDS: {kids.reference} prepared once, ours {t_ours:.1f} s, pyFM {t_pyfm:.1f} s")
    names = [k for k in kids.names if k != kids.reference][:n]
    rows = [evaluate_pair(f"{k}->{kids.reference}", kids.load(k), y, sy, kids.ground_truth(k), sym, fmm, ref)
            for k in names]
    summary = summarise("TOPKIDS kidXX -> kid00", rows, True)
    return {"summary": summary, "reference_seconds": {"ours": t_ours, "pyfm": t_pyfm},
            "pairs": _rows_for_json(rows)}


def run_tosca(root: Path, classes: list[str]) -> dict:
    """Pose 0 <-> the next pose of each class, both directions, from scratch per pair."""
    tosca = datasets.TOSCA(root / "tosca")
    rows = []
    for cls in classes:
        a, b = 0, TOSCA_PAIRS[cls]
        meshes = {p: tosca.load(cls, p) for p in (a, b)}
        sym = reflection_map(meshes[a])  # same vertex numbering in every pose of the class
        for p, q in ((a, b), (b, a)):
            x, y = meshes[p], meshes[q]
            truth = np.arange(int(x.input_ids.max()) + 1)
            rows.append(evaluate_pair(f"{cls}{p}->{cls}{q}", x, y, y, truth, sym, GeodesicReference(y)))
    summary = summarise("TOSCA pose 0 <-> next pose", rows, True)
    return {"summary": summary, "classes": classes, "pairs": _rows_for_json(rows)}


def run_remeshed(root: Path, folder: Path, classes: list[str]) -> dict:
    """The TOSCA pairs on independently remeshed copies (``benchmarks/remesh.py``), both
    directions, and each class's pose 0 at two densities; truth by the nearest original vertex."""
    from remesh import POSES, true_images

    tosca = datasets.TOSCA(root / "tosca")
    densities = sorted({p.name.split("-")[1].split(".")[0] for p in folder.glob("*-*.off")}, key=int)
    rows = []
    for cls in classes:
        names = [f"{cls}0", f"{cls}{POSES[cls]}"]
        pairs = [(names[0], names[1]), (names[1], names[0])]
        if len(densities) >= 2:
            lo, hi = (f"{cls}0-{densities[0]}", f"{cls}0-{densities[-1]}")
            names += [lo, hi]
            pairs += [(lo, hi), (hi, lo)]
        if not all((folder / f"{n}.off").exists() for n in names):
            raise FileNotFoundError(f"{folder} lacks a copy of {cls}: run benchmarks/remesh.py --out {folder}")
        originals = {p: tosca.load(cls, p) for p in (0, POSES[cls])}
        refl = reflection_map(originals[0])   # shared by the class's poses
        copies = {n: (gromov.load(folder / f"{n}.off"), np.loadtxt(folder / f"{n}.ids.txt", dtype=np.int64))
                  for n in names}
        pose = {n: int(n.split("-")[0][len(cls):]) for n in names}
        for a, b in pairs:
            (x, ids_x), (y, ids_y) = copies[a], copies[b]
            orig_y = originals[pose[b]].vertices
            truth = true_images(ids_x, orig_y, y.vertices)
            sym = true_images(refl[ids_y], orig_y, y.vertices)
            fmm = GeodesicReference(y)
            rows.append(evaluate_pair(f"{a}->{b}", x, y, y, truth, sym, fmm))
            if pose[a] == pose[b]:   # one surface at two densities: the best a vertex map can score
                rows[-1]["exact_vertex"] = exact_vertex_error(x, y, truth, sym, fmm)
    poses = [r for r in rows if "-" not in r["pair"].split("->")[0]]
    density = [r for r in rows if r not in poses]
    out = {"classes": classes, "summary": summarise("TOSCA remeshed, pose 0 <-> next pose", poses, True),
           "pairs": _rows_for_json(poses)}
    if density:
        summary = summarise("TOSCA remeshed, pose 0 at two densities", density, True)
        err = np.concatenate([r["exact_vertex"]["errors"] for r in density])
        summary["exact_vertex"] = {"mean": float(100 * err.mean()), "median": float(100 * np.median(err))}
        print(f"  {'exact map, at vertices':<22}{summary['exact_vertex']['mean']:>7.2f}"
              f"{summary['exact_vertex']['median']:>8.2f}   (the floor the vertex-rounded truth sets)")
        out["density"] = {"summary": summary, "pairs": _rows_for_json(density)}
    return out


def exact_vertex_error(x: gromov.Mesh, y: gromov.Mesh, truth, sym, fmm) -> dict:
    """The error of the exact map between two meshes of one surface, rounded to vertices: each
    vertex of X to the vertex of Y nearest its closest point on Y. The truth, carried to each
    copy by the nearest original vertex, is itself off by up to an edge; no vertex-to-vertex map
    scores below this."""
    from scipy.spatial import cKDTree

    from gromov._project import project_among

    _, near = cKDTree(y.vertices).query(x.vertices, k=8)
    face, bary, _ = project_among(x.vertices, y, np.arange(0, near.size + 1, 8), near.ravel())
    corner = np.argmax(bary, axis=1)
    e = dense_error(face, np.eye(3)[corner], y, truth[x.input_ids], sym, fmm=fmm)
    return {"mean": e.mean, "median": float(np.median(e.errors)), "errors": e.errors}


def run_perturbed(folder: Path, classes: list[str]) -> dict:
    """Each class's remeshed pose 0 against itself with 20 holes and with 3 welds, both ways."""
    from gromov.perturb import holes, weld

    out = {}
    for kind, make in (("holes", lambda m: holes(m, 20)), ("weld", lambda m: weld(m, 3))):
        rows = []
        for cls in classes:
            clean = gromov.load(folder / f"{cls}0.off")
            try:
                p = make(clean)
            except ValueError as exc:   # no room for the noise on this shape
                print(f"  {cls}0: no {kind}: {exc}")
                continue
            # numbered 0..n-1 as a file of its own; noisy vertex i is clean vertex back[i]
            noisy, back = gromov.Mesh(p.mesh.vertices, p.mesh.faces), clean.input_ids[p.vertex_map]
            forward = np.full(clean.n_vertices, -1)
            forward[back] = np.arange(noisy.n_vertices)
            rows.append((evaluate_pair(f"{cls}0+{kind}->{cls}0", noisy, clean, clean, back, None,
                                       GeodesicReference(clean)),
                         evaluate_pair(f"{cls}0->{cls}0+{kind}", clean, noisy, noisy, forward, None,
                                       GeodesicReference(noisy))))
        to_clean, to_noisy = [a for a, _ in rows], [b for _, b in rows]
        out[kind] = {"summary": summarise(f"remeshed pose 0 with {kind} <-> without (direct only)",
                                          to_clean + to_noisy, False),
                     "to_clean": summarise(f"{kind} -> clean", to_clean, False),
                     "to_noisy": summarise(f"clean -> {kind}", to_noisy, False),
                     "pairs": _rows_for_json(to_clean + to_noisy)}
    return out


def print_variants(name: str, row: dict, width: int = 30) -> None:
    """A dense study's line for one map: its refined error and each variant's."""
    print(f"  {name:<{width}} refined {row['refined']:.3f}  "
          + "  ".join(f"{k}: {v:.3f}" for k, v in row["variants"].items()), flush=True)


def refined_maps(x: gromov.Mesh, y: gromov.Mesh, yref) -> tuple[np.ndarray, np.ndarray]:
    """A dense study's start: the input-vertex maps T: X -> Y (indices of ``y``) and S: Y -> X
    (indices of ``x``) of ``gromov.match(x, yref, dense=True)`` with
    ``gromov.dense.DENSE_RELAX`` off and ``DENSE_ALIGN = 0``: the refined maps."""
    saved = gromov.dense.DENSE_RELAX, gromov.dense.DENSE_ALIGN
    gromov.dense.DENSE_RELAX, gromov.dense.DENSE_ALIGN = False, 0
    try:
        r = gromov.match(x, yref, dense=True)
    finally:
        gromov.dense.DENSE_RELAX, gromov.dense.DENSE_ALIGN = saved
    return (y.from_input_ids(r.x_to_y_dense_vertex[x.input_ids]),
            x.from_input_ids(r.y_to_x_dense_vertex[y.input_ids]))


def variant_summary(rows: list, variants, base: str) -> dict:
    """A dense study's summary of its rows (each with ``refined``, ``variants`` and ``seconds``
    per variant): the maps, the refined mean, and per variant the mean of the maps' means, how
    many maps it makes better or worse (by 0.001) than ``base``, and its mean seconds."""
    ref = np.array([r["variants"][base] for r in rows])
    out = {"maps": len(rows), "refined": float(np.mean([r["refined"] for r in rows]))}
    for key in variants:
        vals = np.array([r["variants"][key] for r in rows])
        out[key] = {"mean": float(vals.mean()), "better": int(np.sum(vals < ref - 1e-3)),
                    "worse": int(np.sum(vals > ref + 1e-3)),
                    "seconds_mean": float(np.mean([r["seconds"][key] for r in rows]))}
    return out


def variant_line(s: dict) -> str:
    """A :func:`variant_summary` as one printed line."""
    return f"refined {s['refined']:.3f}  " + "  ".join(
        f"{k}: {v['mean']:.3f} (+{v['better']} -{v['worse']})" for k, v in s.items() if isinstance(v, dict))


def variant_scorer(variants: dict, run, extra=None):
    """A variant study's ``scorer`` (:func:`variant_study`): on each pair, both refined maps
    (:func:`refined_maps`) taken through ``run(x, y, T, S, spec)`` for each variant's ``spec`` in
    ``variants``, the result scored on ``points`` random vertices of X
    (:func:`random_point_error`) and timed; ``extra(x, y)``, a dict, joins the row."""
    def scorer(points: int):
        def evaluate_pair(name, x, y, yref, truth, sym, fmm, pyfm_ref=None):
            T, S = refined_maps(x, y, yref)
            error = random_point_error(x, y, truth, sym, fmm, points)
            row = {"pair": name, "refined": error(T), "variants": {}, "seconds": {},
                   **(extra(x, y) if extra is not None else {})}
            for name_v, spec in variants.items():
                t = time.perf_counter()
                out = run(x, y, T, S, spec)
                row["seconds"][name_v] = time.perf_counter() - t
                row["variants"][name_v] = error(out)
            print_variants(name, row)
            return row
        return evaluate_pair
    return scorer


def variant_study(argv, doc: str, json_name: str, scorer, variants, base: str, described: dict) -> int:
    """A dense variant study's ``main``: its arguments (``--data``, :func:`add_study_arguments`,
    ``--json`` defaulting to ``benchmarks/studies/json_name``), its sets run with
    ``scorer(points)`` and summarised by :func:`variant_summary` against ``base``, and the JSON:
    ``described`` (what the variants are), the points and the sets."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    add_data_argument(ap)
    add_study_arguments(ap)
    ap.add_argument("--json", default=str(HERE / "studies" / json_name))
    args = ap.parse_args(argv)
    out = {**described, "points": args.points}
    out["sets"] = study_parts(ap, args, scorer(args.points), lambda rows: variant_summary(rows, variants, base),
                              variant_line)
    write_results(args.json, out)
    return 0


def study_parts(ap, args, evaluate, summary, line, allowed=("topkids", "remeshed", "perturbed")) -> dict:
    """A dense study's sets (``args.sets``, checked against ``allowed``) run by
    :func:`study_sets` with ``evaluate``: per part ``{"summary": summary(rows), "pairs": rows}``,
    printed as ``part: line(summary)``."""
    sets = args.sets.split(",")
    for name in sets:
        if name not in allowed:
            ap.error(f"unknown set {name!r}")
    out = {}
    for part, rows in study_sets(sets, Path(args.data), Path(args.remeshed), evaluate).items():
        out[part] = {"summary": summary(rows), "pairs": rows}
        print(f"{part}: {line(out[part]['summary'])}", flush=True)
    return out


def study_sets(sets, data: Path, folder: Path | None, evaluate) -> dict[str, list[dict]]:
    """The rows a study's own ``evaluate`` (called as :func:`evaluate_pair` is, returning its row)
    gives on each of ``sets``, split into parts: ``topkids`` (kidXX -> kid00: part ``topkids``),
    ``tosca`` (the TOSCA pairs as given, both ways: part ``tosca``),
    ``remeshed`` (the TOSCA pairs on ``folder``'s copies: ``poses``, and pose 0 at two densities:
    ``densities``), ``perturbed`` (``holes`` and ``welds``). The benchmark's tables are not made;
    the exact map's errors that this benchmark adds to a density row are left out."""
    global evaluate_pair, summarise, _rows_for_json
    saved = evaluate_pair, summarise, _rows_for_json
    classes = list(TOSCA_PAIRS)
    parts: dict[str, list[dict]] = {}
    try:
        summarise, _rows_for_json = (lambda *a, **k: {}), (lambda r: r)
        for name in sets:
            rows: list[dict] = []

            def evaluate_pair(*a, rows=rows, **k):
                rows.append(evaluate(*a, **k))
                return rows[-1]

            print(name, flush=True)
            if name == "topkids":
                run_topkids(data, 25)
                split = {"topkids": rows}
            elif name == "tosca":
                run_tosca(data, classes)
                split = {"tosca": rows}
            elif name == "remeshed":
                run_remeshed(data, folder, classes)
                density = [r for r in rows if "-" in r["pair"].split("->")[0]]
                split = {"poses": [r for r in rows if r not in density], "densities": density}
            elif name == "perturbed":
                run_perturbed(folder, classes)
                split = {"holes": [r for r in rows if "holes" in r["pair"]],
                         "welds": [r for r in rows if "weld" in r["pair"]]}
            else:
                raise ValueError(f"unknown set {name!r}")
            parts.update({part: [{k: v for k, v in r.items() if k != "exact_vertex"} for r in part_rows]
                          for part, part_rows in split.items()})
    finally:
        evaluate_pair, summarise, _rows_for_json = saved
    return parts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--topkids", type=int, default=25, help="how many kids (0: none)")
    ap.add_argument("--classes", default=",".join(TOSCA_PAIRS), help="TOSCA classes ('': none)")
    ap.add_argument("--remeshed", default=None,
                    help="also the TOSCA pairs on the copies benchmarks/remesh.py made in this folder")
    ap.add_argument("--remeshed-classes", default=",".join(TOSCA_PAIRS), help="their classes")
    ap.add_argument("--perturbed", default=None,
                    help="each class's copy of pose 0 in this folder (benchmarks/remesh.py) against itself "
                         "with holes and welds")
    ap.add_argument("--dense", choices=("input", "zoomout", "placed"), default="input",
                    help="our dense map: refined on the input meshes (default), on the working meshes, "
                         "or placed only")
    ap.add_argument("--candidates", type=int, default=None,
                    help="gromov.dense.DENSE_CANDIDATES for this run (default: the package's)")
    ap.add_argument("--local", type=int, default=None,
                    help="gromov.dense.DENSE_LOCAL for this run (default: the package's; 0: every landmark, "
                         "trimmed)")
    ap.add_argument("--relax", choices=("on", "off"), default=None,
                    help="gromov.dense.DENSE_RELAX for this run (default: the package's)")
    ap.add_argument("--inverse", type=int, default=None,
                    help="gromov.dense.DENSE_INVERSE for this run (default: the package's)")
    ap.add_argument("--quick", action="store_true", help=f"3 kids, classes {','.join(QUICK_CLASSES)}")
    ap.add_argument("--json", default=str(HERE / "results" / "dense.json"))
    args = ap.parse_args(argv)
    DENSE["mode"] = args.dense
    if args.candidates is not None:
        gromov.dense.DENSE_CANDIDATES = args.candidates
    if args.local is not None:
        gromov.dense.DENSE_LOCAL = args.local
    if args.relax is not None:
        gromov.dense.DENSE_RELAX = args.relax == "on"
    if args.inverse is not None:
        gromov.dense.DENSE_INVERSE = args.inverse
    classes = list(QUICK_CLASSES) if args.quick else [c for c in args.classes.split(",") if c]
    unknown = sorted(set(classes) - set(TOSCA_PAIRS))
    if unknown:
        ap.error(f"unknown or pose-0-less TOSCA classes {unknown}; choose from {','.join(TOSCA_PAIRS)}")
    n_kids = 3 if args.quick else args.topkids
    res = {"gromov": {"version": gromov.__version__, "match": {"metric": "diffusion", "dense": args.dense,
                                                                "n_samples": 100,
                                                                "candidates": gromov.dense.DENSE_CANDIDATES,
                                                                "local": gromov.dense.DENSE_LOCAL,
                                                                "relax": gromov.dense.DENSE_RELAX,
                                                                "inverse": gromov.dense.DENSE_INVERSE}},
           "pyfm": {"version": version("pyfmaps"), "k_process": 200, **PYFM}, "gross_per_diameter": GROSS}
    t0 = time.perf_counter()
    if n_kids > 0:
        res["topkids"] = run_topkids(Path(args.data), n_kids)
    if classes:
        res["tosca"] = run_tosca(Path(args.data), classes)
    if args.remeshed:
        res["remeshed"] = run_remeshed(Path(args.data), Path(args.remeshed), args.remeshed_classes.split(","))
    if args.perturbed:
        res["perturbed"] = run_perturbed(Path(args.perturbed), args.remeshed_classes.split(","))
    res["total_seconds"] = time.perf_counter() - t0
    print(f"\ntotal {res['total_seconds']:.0f} s")
    write_results(args.json, res)
    return res


if __name__ == "__main__":
    main()
