"""Which whole is a part of? TOSCA parts ranked against the 80 TOSCA wholes by the partial distance.

Run:  .venv/bin/python benchmarks/studies/partial_recognition.py [--data DIR] [--per-class 1]
          [--offset 0] [--keep 0.6] [--kind plane] [--jobs 2]
          [--json benchmarks/studies/partial_recognition.json] [--set KIND KEEP JSON ...] [--bridge 0|1|choose]

For each TOSCA class, ``--per-class`` parts are cut (:func:`gromov.perturb.cut`, ``--kind``,
keeping ``--keep`` of the area, seed = the pose's place in the class's list) from the class's
poses in order, from the ``--offset``-th on; each part is matched into every one of the 80 wholes
except the pose it was cut from (:func:`gromov.partial.match_partial` as ``partial_matrix`` calls
it: the geodesic metric, 3,000 working vertices, 100 samples, ``bridge=PARTIAL_RANK_BRIDGE``;
every whole prepared once and shared with the ``--jobs`` forked workers). Each pair's relative
distance, covered fraction and ranking distance (the search's objective ÷ the whole's diameter)
are written; the wholes are ranked three ways, and for each the fraction of parts whose nearest
whole is of their class is reported (the aim: at least 95%): by the relative distance
(``nearest_of_own_class``), by it ÷ the covered fraction (``nearest_of_own_class_by_score``), and
by the ranking distance ÷ the covered fraction, what ``gromov pairwise --partial`` ranks by
(``nearest_of_own_class_by_ranking_score``; each row's ``nearest`` and ``rank_of_own_class``).
Each whole's geodesic diameter and area (``wholes_info``) and each part's area are in the JSON,
for other rankings. ``--rescore JSON`` adds the score's rankings to a results file made before,
from its rows, without matching again. ``--set KIND KEEP JSON``, repeated, runs several sets of
parts against the wholes prepared once (instead of ``--kind``, ``--keep``, ``--json``);
``--bridge`` the parts' ``bridge`` (default ``gromov.partial.PARTIAL_RANK_BRIDGE``).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import shlex
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(BENCH))

from _common import write_results  # noqa: E402

HERE = Path(__file__).resolve().parent
_WHOLES: list = []
_PART = None
_BRIDGE = False   # as gromov.partial.PARTIAL_RANK_BRIDGE, read in main


def _one(j: int) -> tuple[float, float, float]:
    """In a worker: the part matched into whole ``j``: ``(relative distance, covered fraction,
    ranking distance)``."""
    from gromov.partial import match_partial

    r = match_partial(_PART, _WHOLES[j], bridge=_BRIDGE)   # as match(..., partial=True), bridge given
    return float(r.relative_distance), float(r.covered_fraction), float(r.ranking_distance)


def own_class_first(rows: list, by_score: bool, key: str = "distances") -> float:
    """The fraction of parts whose best whole (by ``row[key]``: the relative distance, or the
    ranking distance; or that ÷ its covered fraction) is of the part's class."""
    hits = []
    for row in rows:
        names = list(row[key])
        d = np.array([row[key][n] for n in names])
        if by_score:
            with np.errstate(divide="ignore"):
                d = d / np.array([row["covered_fraction"][n] for n in names])
        hits.append(names[int(np.argmin(d))].rstrip("0123456789") == row["class"])
    return float(np.mean(hits))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(BENCH.parent.parent / "shared" / "data")))
    ap.add_argument("--per-class", type=int, default=1)
    ap.add_argument("--offset", type=int, default=0,
                    help="cut the parts from each class's poses from this one on (in order), seeds from it on")
    ap.add_argument("--keep", type=float, default=0.6)
    ap.add_argument("--kind", choices=("plane", "holes"), default="plane")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=str(HERE / "partial_recognition.json"))
    ap.add_argument("--set", nargs=3, action="append", metavar=("KIND", "KEEP", "JSON"), dest="sets",
                    help="a set of parts (repeatable), instead of --kind, --keep and --json")
    ap.add_argument("--bridge", choices=("0", "1", "choose"), default=None,
                    help="match_partial's bridge for this run (default: gromov.partial.PARTIAL_RANK_BRIDGE, "
                         "what partial_matrix ranks with)")
    ap.add_argument("--rescore", default=None, metavar="JSON", help="add the score's ranking to this file and stop")
    args = ap.parse_args(argv)
    if args.rescore:
        import json

        res = json.loads(Path(args.rescore).read_text())
        res["nearest_of_own_class_by_score"] = own_class_first(res["rows"], True)
        if all("ranking_distances" in r for r in res["rows"]):
            res["nearest_of_own_class_by_ranking_score"] = own_class_first(res["rows"], True, "ranking_distances")
        Path(args.rescore).write_text(json.dumps(res, indent=1))
        print(f"{args.rescore}: own class first by the relative distance {res['nearest_of_own_class']:.1%}, "
              f"by the distance's score {res['nearest_of_own_class_by_score']:.1%}, by the ranking score "
              f"{res.get('nearest_of_own_class_by_ranking_score', float('nan')):.1%}")
        return
    global _WHOLES

    import gromov
    import gromov.partial
    from gromov import ShapeMetric
    from gromov.errors import GromovWarning
    from gromov.experiments import datasets

    global _BRIDGE
    _BRIDGE = gromov.partial.PARTIAL_RANK_BRIDGE if args.bridge is None else \
        {"0": False, "1": True}.get(args.bridge, args.bridge)
    sets = [(k, float(v), j) for k, v, j in args.sets] if args.sets else [(args.kind, args.keep, args.json)]
    for kind, _, _ in sets:
        if kind not in ("plane", "holes"):
            ap.error(f"--set KIND must be plane or holes, got {kind!r}")
    warnings.simplefilter("ignore", GromovWarning)
    t0 = time.perf_counter()
    tosca = datasets.TOSCA(Path(args.data) / "tosca")
    names = [(c, p) for c in tosca.classes for p in tosca.poses(c)]
    _WHOLES = [ShapeMetric(tosca.load(c, p), "geodesic") for c, p in names]
    for s in _WHOLES:
        s.distances, s.diameter, s.descriptors, s.samples(100, 0)  # noqa: B018 - prepared once, before the fork
    t_prepare = time.perf_counter() - t0
    print(f"{len(_WHOLES)} wholes prepared in {t_prepare:.0f} s", flush=True)
    for kind, keep, out in sets:
        run_set(tosca, names, kind, keep, out, args, argv, t_prepare)


def run_set(tosca, names, kind: str, keep: float, out: str, args, argv, t_prepare: float) -> None:
    """One set of parts (``kind``, keeping ``keep`` of the area), each matched into every whole
    but its source; the results written to ``out``."""
    global _PART

    import gromov
    import gromov.partial
    from gromov import ShapeMetric
    from gromov.perturb import cut

    t0 = time.perf_counter()
    rows = []
    for cls in tosca.classes:
        for k, pose in enumerate(tosca.poses(cls)[args.offset:args.offset + args.per_class], start=args.offset):
            src = names.index((cls, pose))
            p = cut(tosca.load(cls, pose), keep, kind=kind, seed=k)
            _PART = ShapeMetric(gromov.Mesh(p.mesh.vertices, p.mesh.faces), "geodesic")
            _PART.distances  # noqa: B018
            others = [j for j in range(len(names)) if j != src]
            t = time.perf_counter()
            with ProcessPoolExecutor(args.jobs, mp_context=mp.get_context("fork")) as pool:
                got = list(pool.map(_one, others))
            d = np.array([g[0] for g in got])
            cover = np.array([g[1] for g in got])
            ranking = np.array([g[2] for g in got])
            order = np.argsort(ranking / cover, kind="stable")
            ranked = [names[others[i]][0] for i in order]
            first_right = ranked.index(cls) + 1   # by the score that gromov ranks with
            rows.append({"class": cls, "pose": pose, "part_area_share": float(p.mesh.area / _WHOLES[src].input.area),
                         "part_area": float(p.mesh.area),
                         "nearest": f"{ranked[0]}{names[others[order[0]]][1]}", "correct": ranked[0] == cls,
                         "rank_of_own_class": first_right, "seconds": time.perf_counter() - t,
                         "distances": {f"{names[j][0]}{names[j][1]}": float(v) for j, v in zip(others, d)},
                         "covered_fraction": {f"{names[j][0]}{names[j][1]}": float(v) for j, v in zip(others, cover)},
                         "ranking_distances": {f"{names[j][0]}{names[j][1]}": float(v) for j, v in zip(others, ranking)}})
            print(f"{cls}{pose}: nearest {rows[-1]['nearest']} (own class at rank {first_right}), "
                  f"{rows[-1]['seconds']:.0f} s", flush=True)
    acc = own_class_first(rows, False)
    res = {"command": "python benchmarks/studies/partial_recognition.py " + shlex.join(
               argv if argv is not None else sys.argv[1:]),
           "kind": kind, "keep": keep, "per_class": args.per_class, "wholes": len(names),
           "metric": "geodesic", "bridge": _BRIDGE, "nearest_of_own_class": acc,
           "nearest_of_own_class_by_score": own_class_first(rows, True),
           "nearest_of_own_class_by_ranking_score": own_class_first(rows, True, "ranking_distances"),
           "offset": args.offset, "parts": len(rows),
           "seconds_prepare": t_prepare, "seconds": t_prepare + time.perf_counter() - t0, "jobs": args.jobs,
           "load_average_end": os.getloadavg(), "rows": rows,
           # each whole's geodesic diameter and area, for rankings other than the relative distance
           "wholes_info": {f"{c}{q}": {"diameter": float(w.diameter), "area": float(w.input.area)}
                           for (c, q), w in zip(names, _WHOLES)}}
    write_results(out, res)
    print(f"{kind} {keep}: nearest whole of the part's class: {acc:.1%} of {len(rows)} parts by the relative "
          f"distance, {res['nearest_of_own_class_by_score']:.1%} by it ÷ the covered fraction, "
          f"{res['nearest_of_own_class_by_ranking_score']:.1%} by the ranking score", flush=True)


if __name__ == "__main__":
    main()
