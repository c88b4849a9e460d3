"""The ground-truth map of a part scored as parts are ranked: is a miss the search's or the score's?

Run:  .venv/bin/python benchmarks/studies/partial_truth.py [--data DIR]
          [--json benchmarks/studies/partial_truth.json] [--all] [STUDY_JSON ...]

Reads results of ``partial_recognition.py`` (default: the seven sets of
docs/design/partial.md, :data:`STUDIES`) and, for each part its ranking score placed nearest a
whole of another class (every part with ``--all``), cuts the part again exactly as that study did
(:func:`gromov.perturb.cut`, its kind, share and seed) and scores the *true* map of the part into
every other pose of its class by the value ``partial_matrix`` ranks with, ranking distance ÷
covered fraction (docs/design/partial.md, "The partial matrix"):

    R = ½ √( [Σ_ij w_i w_j r_ij² + Σ_i (Σ_j w_i w_j) λ² area(Y) (H_X(p_i) − H_Y(q_i))²] / Σ_ij w_i w_j ) / diam(Y)

on the samples ``match_partial`` uses (100 farthest-point samples of the part's working mesh, seed
0, weights by the distance to the part's boundary), each sample's image the working point of the
pose's working mesh where its true vertex lies (the input vertex's closest point; TOSCA's poses of a class share their vertex numbering: ground truth,
read here and nowhere in the library); the covered fraction of the true map is measured as
``match_partial`` measures its own (every working vertex of the part carried, the whole's working
vertices within ``COVER_RADIUS`` mean edges of an image, closed by ``COVER_CLOSE``). Per part:
the best score the search found into the part's class and into any other class, and the true
map's score into each pose of the class. When even the best true score lies above the other
class's found one, no search ranks the part right by this value.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
import warnings
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(BENCH))

from _common import add_data_argument, write_results

HERE = Path(__file__).resolve().parent
#: The part-recognition sets measured in docs/design/partial.md, "The partial matrix".
STUDIES = tuple(str(HERE / f"partial_recognition{s}.json") for s in
                ("", "_holes", "_plane45", "_pose2", "_holes_pose2", "_pose3", "_holes_pose3"))


def class_of(name: str) -> str:
    """``david13`` -> ``david``."""
    return name.rstrip("0123456789")


def found_scores(row: dict) -> dict:
    """The study's scores of one part: ranking distance ÷ covered fraction, per whole."""
    return {w: row["ranking_distances"][w] / row["covered_fraction"][w] for w in row["ranking_distances"]}


def truth_score(sx, P, src_ids, part_ids, sy) -> dict:
    """The true map of the part (working metric ``sx``, samples ``P`` with input-vertex ids
    ``src_ids`` on the whole it was cut from; ``part_ids`` the same for every working vertex)
    into the pose ``sy``, scored as ``match_partial``'s ranking distance ÷ covered fraction."""
    import gromov.partial as gp
    from gromov.gmds import SurfacePoints

    wp = gp.sample_weights(gp.boundary_distance(sx.mesh)[P], gp.BOUNDARY_WIDTH * np.sqrt(sy.mesh.area))
    W = np.outer(wp, wp)
    np.fill_diagonal(W, 0.0)
    img = SurfacePoints(sy.working.source_face[src_ids], sy.working.source_bary[src_ids])
    stress = float(np.sum(W * (sx.distances[np.ix_(P, P)] - gp._between(sy, img)) ** 2))
    hx = gp.part_curvature(sx, sy)[P]
    hy = sy.curvature[img.vertex(sy.mesh.faces)]
    bent = float(np.sum(W.sum(axis=1) * gp.PARTIAL_CURVATURE**2 * sy.mesh.area * (hx - hy) ** 2))
    R = 0.5 * np.sqrt((stress + bent) / W.sum()) / sy.diameter
    h = sy.mesh.mean_edge_length
    covered_w = gp.covered_region(sy.mesh, sy.working.from_source(part_ids), gp.COVER_RADIUS * h, gp.COVER_CLOSE * h)
    areas = sy.input.vertex_areas
    cover = float(areas[covered_w[sy.working.source_nearest]].sum() / areas.sum())
    return {"ranking_distance": float(R), "relative_distance": float(0.5 * np.sqrt(stress / W.sum()) / sy.diameter),
            "covered_fraction": cover, "score": float(R / cover)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("studies", nargs="*", metavar="STUDY_JSON",
                    help="results of partial_recognition.py (default: the seven sets, STUDIES)")
    ap.add_argument("--all", action="store_true", help="every part, not only those ranked nearest another class")
    ap.add_argument("--json", default=str(HERE / "partial_truth.json"))
    args = ap.parse_args(argv)

    import gromov
    from gromov import ShapeMetric
    from gromov.errors import GromovWarning
    from gromov.experiments import datasets
    from gromov.perturb import cut

    warnings.simplefilter("ignore", GromovWarning)
    t0 = time.perf_counter()
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    poses: dict = {}
    parts = []
    for study in args.studies or STUDIES:
        res = json.loads(Path(study).read_text())
        for row in res["rows"]:
            sc = found_scores(row)
            cls = row["class"]
            other = min((w for w in sc if class_of(w) != cls), key=sc.get)
            own = min((w for w in sc if class_of(w) == cls), key=sc.get)
            if sc[own] < sc[other] and not args.all:
                continue
            k = tosca.poses(cls).index(row["pose"])
            p = cut(tosca.load(cls, row["pose"]), res["keep"], kind=res["kind"], seed=k)
            sx = ShapeMetric(gromov.Mesh(p.mesh.vertices, p.mesh.faces), "geodesic")
            P = sx.samples(100, 0)
            src_ids = p.vertex_map[sx.working.to_source(P)]
            part_ids = p.vertex_map[sx.working.to_source(np.arange(sx.mesh.n_vertices))]
            truth = {}
            if any(c != cls for c, _ in poses):   # one class's poses in memory at a time
                poses.clear()
            for q in tosca.poses(cls):
                if q == row["pose"]:
                    continue
                if (cls, q) not in poses:
                    poses[(cls, q)] = ShapeMetric(tosca.load(cls, q), "geodesic")
                truth[f"{cls}{q}"] = truth_score(sx, P, src_ids, part_ids, poses[(cls, q)])
            best_truth = min(truth, key=lambda w: truth[w]["score"])
            entry = {"study": Path(study).name, "part": f"{cls}{row['pose']}", "kind": res["kind"], "keep": res["keep"],
                     "found_own": {"whole": own, "score": sc[own]}, "found_other": {"whole": other, "score": sc[other]},
                     "truth": truth, "truth_best": {"whole": best_truth, "score": truth[best_truth]["score"]},
                     "truth_ahead_of_other": truth[best_truth]["score"] < sc[other]}
            parts.append(entry)
            print(f"{entry['part']} {res['kind']} {res['keep']}: found own {own} {sc[own]:.5f}, other {other} "
                  f"{sc[other]:.5f}; truth best {best_truth} {truth[best_truth]['score']:.5f} "
                  f"(R {truth[best_truth]['ranking_distance']:.5f}, covered {truth[best_truth]['covered_fraction']:.3f})",
                  flush=True)
    res = {"command": "python benchmarks/studies/partial_truth.py " + shlex.join(
               argv if argv is not None else sys.argv[1:]),
           "parts": parts, "truth_ahead_of_other": sum(p["truth_ahead_of_other"] for p in parts),
           "seconds": time.perf_counter() - t0}
    write_results(args.json, res)
    print(f"{len(parts)} parts; the true map's best score is ahead of the other class's found one for "
          f"{res['truth_ahead_of_other']}", flush=True)


if __name__ == "__main__":
    main()
