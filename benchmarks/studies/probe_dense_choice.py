"""Two placements refined, the one ZoomOut explains better kept: all landmarks or the nearest?

Run:  .venv/bin/python benchmarks/studies/probe_dense_choice.py [--data DIR] --remeshed R
          [--sets topkids,tosca,remeshed,weld,holes] [--held-out] [--json benchmarks/studies/probe_dense_choice.json]

R is made by ``benchmarks/remesh.py --out R``. The dense map of a pair starts from a placement of
every working vertex by its distances to the landmarks (docs/design/dense.md): from all of them,
trimmed (the default), or from its 16 nearest (``DENSE_LOCAL = 16``), which repairs welds and loses
on TOPKIDS pairs whose samples are partly wrong. Here both placements of the X -> Y map of each
pair (the match as ``gromov.match(..., dense=True)`` makes it; its landmarks captured) are refined
on the input meshes by the default ZoomOut (``input_zoomout``) and each refined map's ZoomOut
energy is measured, the mean over X's input vertices of

    E_k(T) = || Phi_X(v) - Phi_Y(T(v)) C_k^T ||^2,   C_k = Phi_X^T M_X Phi_Y[T]   (first k)

(Melzi et al., SIGGRAPH Asia 2019: the objective ZoomOut descends, bases at unit total area), at
k = 60 (after the refinement's steps up to 60) and at k = 180 (its last). Each map is scored
against the ground truth as ``bench_dense.py`` scores it (x 100 / sqrt(area), the better of the
direct and mirrored readings where the target has a symmetry map); the rows say which map each
energy keeps, and what the kept maps score. Sets: ``topkids`` kidXX -> kid00; ``tosca`` the
benchmark's TOSCA pairs as given, both ways; ``remeshed`` the same pairs on R's copies, both ways;
``weld`` and ``holes`` each class's copy of pose 0 with 3 welds (20 holes) -> without and back;
with ``--held-out`` of the class's other pose, with other noise (seed 1).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
import warnings
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(BENCH))

from _common import add_data_argument, write_results
from bench_dense import TOSCA_PAIRS, at_vertices

HERE = Path(__file__).resolve().parent
SPLIT = 60          # the energy after the refinement's steps up to this k ...
LOCAL = 16          # ... of the placement from this many nearest landmarks, beside all of them
_CAPTURED: dict = {}


def energy(sx, sy, T: np.ndarray, k: int) -> float:
    """Mean ZoomOut energy of the input-vertex map ``T`` on the first ``k`` eigenfunctions."""
    import gromov.dense as gd

    phx, mx = gd._input_basis(sx, gd.INPUT_K)
    phy, my = gd._input_basis(sy, gd.INPUT_K)
    k = min(k, phx.shape[1], phy.shape[1])
    a = phx[:, :k] * np.sqrt(mx.sum())
    ma = mx[:, None] * phx[:, :k] / np.sqrt(mx.sum())
    b = phy[:, :k] * np.sqrt(my.sum())
    C = ma.T @ b[T]
    return float(np.mean(np.sum((a - b[T] @ C.T) ** 2, axis=1)))


def _capturing(original):
    """``dense_maps`` that also refines both placements of X -> Y and keeps them."""
    import gromov.dense as gd

    def dense_maps(sx, sy, landmarks_x, landmarks_y, **kw):
        out = original(sx, sy, landmarks_x, landmarks_y, **kw)
        ax = np.hstack([gd.landmark_distances(sx, p, gd.DENSE_TAU_SCALE) for p in landmarks_x])
        ay = np.hstack([gd.landmark_distances(sy, p, gd.DENSE_TAU_SCALE) for p in landmarks_y])
        for name, t in (("all", gd.anchored_map(ax, ay)), ("local", gd.local_anchored_map(ax, ay, LOCAL))):
            vertex = gd._input_images(sx, sy, t)[2]
            v60 = gd.input_zoomout(sx, sy, vertex, k_end=SPLIT)
            e60 = energy(sx, sy, v60, SPLIT)
            v = gd.input_zoomout(sx, sy, v60, k_start=SPLIT + gd.INPUT_STEP)
            _CAPTURED[name] = {"vertex": v, "e60": e60, "e180": energy(sx, sy, v, gd.INPUT_K)}
        _CAPTURED["sx"], _CAPTURED["sy"] = sx, sy
        return out

    return dense_maps


def score(y, sy, sx, vertex, truth, sym, fmm) -> dict:
    """The input-vertex map ``vertex`` (X's input vertices -> Y's) scored against ``truth``
    (Y file id per X file id)."""
    from gromov.evaluate import dense_error

    tru = truth[sx.input.input_ids]
    ok = tru >= 0
    face, bary = at_vertices(y, y.from_input_ids(sy.input.input_ids[vertex[ok]]))
    e = dense_error(face, bary, y, tru[ok], sym, fmm=fmm)
    return {"mean": 100 * e.mean, "median": 100 * float(np.median(e.errors)), "branch": e.branch}


def pairs(root: Path, remeshed: Path | None, sets: list[str], held_out: bool = False):
    """``(set, name, x, y, truth, sym)`` for every pair of the chosen sets."""
    import gromov
    from gromov.experiments import datasets
    from gromov.experiments.reproduce import reflection_map
    from gromov.perturb import holes, weld

    if "topkids" in sets:
        kids = datasets.TopKids(root / "topkids")
        y = kids.load(kids.reference)
        sym = kids.symmetry(kids.reference)
        for k in kids.names:
            if k != kids.reference:
                yield "topkids", f"{k}->{kids.reference}", kids.load(k), y, kids.ground_truth(k), sym
    if "tosca" in sets:
        tosca = datasets.TOSCA(root / "tosca")
        for cls, b in TOSCA_PAIRS.items():
            meshes = {p: tosca.load(cls, p) for p in (0, b)}
            sym = reflection_map(meshes[0])
            for p, q in ((0, b), (b, 0)):
                truth = np.arange(int(meshes[p].input_ids.max()) + 1)
                yield "tosca", f"{cls}{p}->{cls}{q}", meshes[p], meshes[q], truth, sym
    if remeshed is None:
        return
    from remesh import POSES, true_images

    tosca = datasets.TOSCA(root / "tosca")
    for cls in TOSCA_PAIRS:
        if "remeshed" in sets:
            names = [f"{cls}0", f"{cls}{POSES[cls]}"]
            originals = {p: tosca.load(cls, p) for p in (0, POSES[cls])}
            refl = reflection_map(originals[0])
            copies = {n: (gromov.load(remeshed / f"{n}.off"), np.loadtxt(remeshed / f"{n}.ids.txt", dtype=np.int64))
                      for n in names}
            for a, b in ((names[0], names[1]), (names[1], names[0])):
                (x, ids_x), (y, ids_y) = copies[a], copies[b]
                orig_y = originals[int(b[len(cls):])].vertices
                yield ("remeshed", f"{a}->{b}", x, y, true_images(ids_x, orig_y, y.vertices),
                       true_images(refl[ids_y], orig_y, y.vertices))
        seed, base = (1, f"{cls}{POSES[cls]}") if held_out else (0, f"{cls}0")
        for kind, make in (("holes", lambda m: holes(m, 20, seed=seed)), ("weld", lambda m: weld(m, 3, seed=seed))):
            if kind not in sets:
                continue
            clean = gromov.load(remeshed / f"{base}.off")
            try:
                p = make(clean)
            except ValueError:
                continue
            noisy, back = gromov.Mesh(p.mesh.vertices, p.mesh.faces), clean.input_ids[p.vertex_map]
            forward = np.full(clean.n_vertices, -1)
            forward[back] = np.arange(noisy.n_vertices)
            yield kind, f"{base}+{kind}->{base}", noisy, clean, back, None
            yield kind, f"{base}->{base}+{kind}", clean, noisy, forward, None


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--remeshed", default=None, help="copies made by benchmarks/remesh.py")
    ap.add_argument("--sets", default="topkids,tosca,remeshed,weld,holes")
    ap.add_argument("--held-out", action="store_true",
                    help="weld and holes on each class's other pose, with other noise (seed 1)")
    ap.add_argument("--json", default=str(HERE / "probe_dense_choice.json"))
    args = ap.parse_args(argv)

    import gromov
    import gromov.dense as gd
    from gromov.errors import GromovWarning
    from gromov.evaluate import GeodesicReference, dense_error

    warnings.simplefilter("ignore", GromovWarning)
    gd.dense_maps = _capturing(gd.dense_maps)
    sets = [s for s in args.sets.split(",") if s]
    t0 = time.perf_counter()
    rows = []
    for kind, name, x, y, truth, sym in pairs(Path(args.data), Path(args.remeshed) if args.remeshed else None, sets,
                                                   args.held_out):
        t = time.perf_counter()
        r = gromov.match(x, y, dense=True)
        sx, sy = _CAPTURED["sx"], _CAPTURED["sy"]
        fmm = GeodesicReference(y)
        row = {"set": kind, "pair": name, "seconds": time.perf_counter() - t}
        n = len(r.x_to_y_dense_face)
        tru = truth[np.arange(n)]
        ok = tru >= 0
        e = dense_error(r.x_to_y_dense_face[ok], r.x_to_y_dense_bary[ok], y, tru[ok], sym, fmm=fmm)
        row["default"] = {"mean": 100 * e.mean, "median": 100 * float(np.median(e.errors))}
        for v in ("all", "local"):
            row[v] = {**score(y, sy, sx, _CAPTURED[v]["vertex"], truth, sym, fmm),
                      "e60": _CAPTURED[v]["e60"], "e180": _CAPTURED[v]["e180"]}
        for k in ("e60", "e180"):
            row[f"kept_by_{k}"] = "local" if row["local"][k] < row["all"][k] else "all"
        rows.append(row)
        print(f"{kind:<9}{name:<24} default {row['default']['mean']:6.2f}  all {row['all']['mean']:6.2f} "
              f"(E60 {row['all']['e60']:.3f}, E180 {row['all']['e180']:.3f})  local {row['local']['mean']:6.2f} "
              f"(E60 {row['local']['e60']:.3f}, E180 {row['local']['e180']:.3f})  "
              f"{time.perf_counter() - t:.0f} s", flush=True)
    summary = {}
    for kind in sets:
        rs = [r for r in rows if r["set"] == kind]
        if not rs:
            continue
        summary[kind] = {v: float(np.mean([r[v]["mean"] for r in rs])) for v in ("default", "all", "local")}
        for k in ("e60", "e180"):
            summary[kind][f"kept_by_{k}"] = float(np.mean([r[r[f"kept_by_{k}"]]["mean"] for r in rs]))
        summary[kind]["best_of_two"] = float(np.mean([min(r["all"]["mean"], r["local"]["mean"]) for r in rs]))
        print(f"{kind}: mean of the pairs' means " + ", ".join(f"{k} {v:.2f}" for k, v in summary[kind].items()))
    given = list(argv if argv is not None else sys.argv[1:])
    if args.remeshed:   # the copies' folder is the reader's own: R, as in the docstring
        given = [("R" if a == args.remeshed else a.replace(args.remeshed, "R")) for a in given]
    write_results(args.json, {"command": "python benchmarks/studies/probe_dense_choice.py " + shlex.join(given),
                              "local": LOCAL, "split": SPLIT, "summary": summary, "rows": rows,
                              "seconds": time.perf_counter() - t0})


if __name__ == "__main__":
    main()
