"""The two dense maps of a match checked against each other: where X -> Y -> X does not come
back, is the inverse of the map Y -> X the better image?

Run:  .venv/bin/python benchmarks/studies/probe_dense_cycle.py [--data DIR] --remeshed DIR
                                                                [--kids N] [--held-out] [--json OUT]

``gromov.match(x, y, dense=True)`` gives both maps, T: X -> Y and S: Y -> X. A vertex v of X is
*cycle-inconsistent* when S(T(v)) lies farther than ``EPS`` x sqrt(area of X) from v (Euclidean).
Its alternative image is the inverse of S there: the vertex u of Y whose image S(u) is nearest
to v (kept only where that is within the same distance). Which of the two maps to trust is read
from how much of its target each leaves uncovered: the area fraction of Y farther than two mean
edges of X (scaled to Y's size) from every image T(v), and the same for S on X. A correct map
between two meshes of one surface covers all of it; a region of X placed onto another part of
Y leaves a part of Y without preimage.

Variants, each applied to T only (the result X -> Y):

- ``as is``: the match's map;
- ``coverage``: inconsistent vertices take the inverse of S when T leaves more than twice as
  much of Y uncovered as S leaves of X, plus 0.2% of the area;
- ``coverage, S onto``: the same, and only when S leaves at most 0.1% of X uncovered.

Pairs: each class's remeshed pose 0 (``benchmarks/remesh.py``) against itself with 20 holes and
with 3 welds, both directions, as ``benchmarks/bench_dense.py --perturbed`` makes them; the
TOSCA pose pairs on the remeshed copies, both directions (``bench_dense.py --remeshed``); and
TOPKIDS kidXX -> kid00. ``--held-out``: instead, each class's *other* remeshed pose (the one
``bench_dense.py`` pairs with pose 0) against itself with holes and welds made with seed 1,
pairs on which the rule was not tried. Scored as ``bench_dense.py`` scores (every vertex with
a truth, error x 100 / sqrt(area) of the target, the better of direct and mirrored where a
symmetry is known). A study of a repair that is not in the package.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import gromov
from gromov.evaluate import GeodesicReference, dense_error
from gromov.experiments import datasets
from gromov.experiments.reproduce import reflection_map
from gromov.perturb import holes, weld

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # benchmarks/: _common and the comparisons
from _common import add_data_argument  # noqa: E402
from bench_dense import TOSCA_PAIRS, at_vertices  # noqa: E402
from remesh import POSES, true_images  # noqa: E402

#: Cycle tolerance, x sqrt(area) of the source.
EPS = 0.05
#: Coverage radius, in mean edges of the source scaled to the target.
GROW = 2.0


def uncovered(src: gromov.Mesh, dst: gromov.Mesh, T: np.ndarray) -> float:
    """Area fraction of ``dst`` farther than GROW mean edges of ``src`` (scaled) from every T(v)."""
    r = GROW * src.mean_edge_length * np.sqrt(dst.area / src.area)
    d, _ = cKDTree(dst.vertices[T]).query(dst.vertices)
    m = dst.vertex_areas
    return float(m[d > r].sum() / m.sum())


def repaired(x: gromov.Mesh, y: gromov.Mesh, T: np.ndarray, S: np.ndarray) -> tuple[dict, dict]:
    """The variants of T (vertex index of Y per vertex index of X) and the features read."""
    ax, ay = np.sqrt(x.area), np.sqrt(y.area)
    off_x = np.linalg.norm(x.vertices[S[T]] - x.vertices, axis=1) / ax > EPS
    off_y = np.linalg.norm(y.vertices[T[S]] - y.vertices, axis=1) / ay > EPS
    u_t, u_s = uncovered(x, y, T), uncovered(y, x, S)
    d, inv = cKDTree(x.vertices[S]).query(x.vertices)
    swap = off_x & (d / ax <= EPS)
    worse = u_t > 2.0 * u_s + 0.002
    out = {"as is": T}
    out["coverage"] = np.where(swap, inv, T) if worse else T
    out["coverage, S onto"] = np.where(swap, inv, T) if worse and u_s <= 0.001 else T
    features = {"inconsistent_x": float(off_x.mean()), "inconsistent_y": float(off_y.mean()),
                "uncovered_by_T": u_t, "uncovered_by_S": u_s, "swappable": float(swap.mean())}
    return out, features


def cases(root: Path, folder: Path, kids: int, held_out: bool = False):
    """``(name, x, y, truth (file id of Y per vertex index of X, -1: none), symmetry or None)``."""
    seed = 1 if held_out else 0
    for cls in TOSCA_PAIRS:
        base = f"{cls}{POSES[cls]}" if held_out else f"{cls}0"
        clean = gromov.load(folder / f"{base}.off")
        for kind, make in (("holes", lambda m: holes(m, 20, seed=seed)), ("weld", lambda m: weld(m, 3, seed=seed))):
            p = make(clean)
            noisy, back = gromov.Mesh(p.mesh.vertices, p.mesh.faces), clean.input_ids[p.vertex_map]
            forward = np.full(clean.n_vertices, -1)
            forward[back] = np.arange(noisy.n_vertices)
            yield f"{base}+{kind}->{base}", noisy, clean, back[noisy.input_ids], None
            yield f"{base}->{base}+{kind}", clean, noisy, forward[clean.input_ids], None
    if held_out:
        return
    tosca = datasets.TOSCA(root / "tosca")
    for cls in TOSCA_PAIRS:
        names = [f"{cls}0", f"{cls}{POSES[cls]}"]
        originals = {p: tosca.load(cls, p) for p in (0, POSES[cls])}
        refl = reflection_map(originals[0])
        copies = {n: (gromov.load(folder / f"{n}.off"), np.loadtxt(folder / f"{n}.ids.txt", dtype=np.int64))
                  for n in names}
        for a, b in ((names[0], names[1]), (names[1], names[0])):
            (x, ids_x), (y, ids_y) = copies[a], copies[b]
            orig_y = originals[int(b[len(cls):])].vertices
            yield (f"{a}->{b} remeshed", x, y, true_images(ids_x, orig_y, y.vertices)[x.input_ids],
                   true_images(refl[ids_y], orig_y, y.vertices))
    top = datasets.TopKids(root / "topkids")
    y = top.load(top.reference)
    sym = top.symmetry(top.reference)
    for k in [n for n in top.names if n != top.reference][:kids]:
        x = top.load(k)
        yield f"{k}->{top.reference}", x, y, top.ground_truth(k)[x.input_ids], sym


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--remeshed", required=True, help="folder of benchmarks/remesh.py's copies")
    ap.add_argument("--kids", type=int, default=25, help="TOPKIDS kid01..kidN -> kid00")
    ap.add_argument("--held-out", action="store_true", help="other poses, other noise (seed 1)")
    ap.add_argument("--json", default=None, help="default: probe_dense_cycle[_heldout].json here")
    args = ap.parse_args(argv)
    if args.json is None:
        args.json = str(HERE / ("probe_dense_cycle_heldout.json" if args.held_out else "probe_dense_cycle.json"))
    warnings.simplefilter("ignore")
    rows, fmms = {}, {}
    for name, x, y, truth, sym in cases(Path(args.data), Path(args.remeshed), args.kids, args.held_out):
        r = gromov.match(x, y, dense=True, seed=0)
        # per vertex index (the dense arrays are per file id)
        T = y.from_input_ids(r.x_to_y_dense_vertex[x.input_ids])
        S = x.from_input_ids(r.y_to_x_dense_vertex[y.input_ids])
        maps, features = repaired(x, y, T, S)
        fmm = fmms.setdefault(id(y), GeodesicReference(y))
        has = truth >= 0
        row = {"features": features}
        for label, t in maps.items():
            face, bary = at_vertices(y, t)
            e = dense_error(face[has], bary[has], y, truth[has], sym, fmm=fmm)
            row[label] = {"mean": 100 * e.mean, "median": float(100 * np.median(e.errors)),
                          "changed": float((t != T).mean())}
        rows[name] = row
        print(f"{name:<34}" + "  ".join(f"{k} {v['mean']:6.2f}" for k, v in row.items() if k != "features")
              + "   " + " ".join(f"{k} {v:.4f}" for k, v in features.items()), flush=True)
    summary = {label: {"mean of the pairs' means": float(np.mean([r[label]["mean"] for r in rows.values()])),
                       "pairs better": sum(r[label]["mean"] < r["as is"]["mean"] - 0.01 for r in rows.values()),
                       "pairs worse": sum(r[label]["mean"] > r["as is"]["mean"] + 0.01 for r in rows.values())}
               for label in ("as is", "coverage", "coverage, S onto")}
    print(json.dumps(summary, indent=1))
    command = "python benchmarks/studies/probe_dense_cycle.py --remeshed R" + (" --held-out" if args.held_out else "")
    Path(args.json).write_text(json.dumps({"command": command,
                                           "eps": EPS, "grow": GROW, "summary": summary, "pairs": rows}, indent=1))
    print("wrote", args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
