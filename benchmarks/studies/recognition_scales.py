"""Recognition measured at several heat scales: the same correspondences, other diffusion times.

Run:  nice .venv/bin/python benchmarks/studies/recognition_scales.py [--data DIR] [--per-class 12]
          [--seed 0] [--jobs 2] [--cache DIR] [--json benchmarks/studies/recognition_scales.json]

The combined ranking (``gromov pairwise --units area --samples 50 --rank-by combined``) measures
each pair's correspondence, found with the unit-area heat distance at tau = 0.005 of the area, by
the trimmed log ratios of the heat distance at *half* that time (G; ``RANK_TAU_SCALE`` 0.5, chosen
on TOSCA-like sets: docs/design/recognition.md, "Measured at half the diffusion time"). This study
matches the shapes of both collections once, as ``gh_matrix(..., rank_by="combined")`` does, and
reads the same correspondence's trimmed log ratios at s times the diffusion time, s in
:data:`SCALES` (``L@s``; ``L@0.5`` is G), from the same eigenpairs
(:meth:`gromov.ShapeMetric.ranking_surface`). The values at the other scales are read in the
worker that matched the pair, by wrapping ``gromov.gh._ranking`` for the duration of the run: the
matched values and the correspondences are unchanged (checked: ``L@0.5`` equals G pair by pair).

The shapes: at most ``--per-class`` of each class of TOSCA (80 meshes, 9 classes) and of the
watertight collection (10 classes of SHREC'07), drawn by ``bench_recognition.class_subset(labels,
per_class, seed)``; 0: all of them.

**Scores.** J = mean(1 - NN, 1 - first tier, EER) over both collections together, as in
``recognition_two_stage.py``. ``rows``: the combined ranking as it is, the same with G measured at
each other scale (one setting, ``rank_tau_scale`` of the combined ranking), each ``L@s`` alone.
``grid``: S^a L@s^b H^c G^d (weights on a grid of 0.1 summing to 1) for each s, the lowest J
first. ``split``: the grid judged on classes it was not chosen on, as ``signature_split`` does
(six seeded splits of the watertight classes into halves; the s and weights of lowest J on TOSCA
and one half, scored on the other half beside the combined ranking as it is), and the same for
the one setting (s only).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from _common import write_results  # noqa: E402
from bench_recognition import GROMOV_METRIC, class_subset, collection, gromov_source, scores  # noqa: E402
from recognition_two_stage import _scored, class_splits  # noqa: E402

#: The diffusion times, over the match's, at which each correspondence is measured.
SCALES = (0.5, 1.0, 2.0, 4.0)
#: The weights' grid.
GRID = np.round(np.arange(0.0, 1.0001, 0.1), 1)
N_SAMPLES = 50

_INDEX: dict = {}          # id(prepared shape) -> its index (inherited by the forked workers)
_OUT: str | None = None    # where the workers write their rows


def _wrap() -> None:
    """Wrap ``gromov.gh._ranking`` so that each matched pair also writes its trimmed log ratios
    at every scale of :data:`SCALES`, as a JSON line, to ``_OUT/PID.jsonl``."""
    import gromov.gh as gh

    original = getattr(gh._ranking, "__wrapped__", gh._ranking)

    def ranking(sx, sy, P, Q, fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual):
        value = original(sx, sy, P, Q, fit, dx, dy, diam, discrete, rank_tau_scale, rank_residual)
        if _OUT is not None and id(sx) in _INDEX and id(sy) in _INDEX:
            row = {"i": _INDEX[id(sx)], "j": _INDEX[id(sy)]}
            for s in SCALES:
                row[f"L@{s:g}"] = float(original(sx, sy, P, Q, fit, dx, dy, diam, discrete, s, "log"))
            with open(os.path.join(_OUT, f"{os.getpid()}.jsonl"), "a") as fh:
                fh.write(json.dumps(row) + "\n")
        return value

    ranking.__wrapped__ = original
    gh._ranking = ranking


def matrices(data: str, name: str, per_class: int, seed: int, jobs: int, cache: Path) -> dict:
    """One collection's matrices (S, G, H, the GH estimate and every ``L@s``) and labels, read
    from the cache where there."""
    global _INDEX, _OUT
    files, labels = collection(data, name)
    keep = class_subset(labels, per_class, seed)
    files, labels = [files[i] for i in keep], np.asarray(labels)[keep]
    path = cache / f"scales-{name}-pc{per_class}-seed{seed}.npz"
    if path.exists():
        z = np.load(path)
        return {k: z[k] for k in z.files}
    from gromov.errors import GromovWarning
    from gromov.experiments.pairwise import gh_matrix, prepare

    options = {**GROMOV_METRIC, "units": "area"}
    out_dir = cache / f"scales-{name}-rows"
    out_dir.mkdir(parents=True, exist_ok=True)
    for f in out_dir.glob("*.jsonl"):
        f.unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        t = time.perf_counter()
        shapes = prepare([str(f) for f in files], "diffusion", n_samples=N_SAMPLES, seed=seed, resolution=3000,
                         metric_options=options, rank_tau_scale=0.5, spectral=True, jobs=jobs)
        for s in shapes:    # every scale once here, not in each worker
            for scale in SCALES:
                s.ranking_surface(scale)
        t_prepare = time.perf_counter() - t
        _INDEX = {id(s): k for k, s in enumerate(shapes)}
        _wrap()
        _OUT = str(out_dir)
        try:
            t = time.perf_counter()
            g = gh_matrix(shapes, "diffusion", n_samples=N_SAMPLES, resolution=3000, metric_options=options,
                          seed=seed, jobs=jobs, spectral=True, rank_by="combined")
            t_match = time.perf_counter() - t
        finally:
            _OUT = None
    n = len(shapes)
    out = {"S": g.spectral, "G": g.trimmed, "H": g.signature, "GH": g.relative, "combined": g.combined,
           "labels": labels, "files": np.array([f.name for f in files]),
           "seconds_prepare": np.float64(t_prepare), "seconds_match": np.float64(t_match)}
    seen = np.eye(n, dtype=bool)
    for s in SCALES:
        out[f"L@{s:g}"] = np.zeros((n, n))
    for f in sorted(out_dir.glob("*.jsonl")):
        for line in f.read_text().splitlines():
            r = json.loads(line)
            i, j = r["i"], r["j"]
            seen[i, j] = seen[j, i] = True
            for s in SCALES:
                out[f"L@{s:g}"][i, j] = out[f"L@{s:g}"][j, i] = r[f"L@{s:g}"]
    if not seen.all():
        raise RuntimeError(f"{name}: the other scales are missing for {int((~seen).sum()) // 2} pairs")
    np.savez(path, **out)
    return out


def product(m: dict, scale: float = 0.5) -> np.ndarray:
    """The combined ranking (gromov.spectrum.combined) with G measured at ``scale``."""
    from gromov.spectrum import combined

    return combined(m["S"], m[f"L@{scale:g}"], signature=m["H"])


def weighted(m: dict, s: float, w) -> np.ndarray:
    """S^a L@s^b H^c G^d, ``w`` = (a, b, c, d)."""
    a, b, c, d = w
    return m["S"] ** a * m[f"L@{s:g}"] ** b * m["H"] ** c * m["G"] ** d


def grid_weights() -> list[tuple]:
    return [(float(a), float(b), float(c), float(round(1.0 - a - b - c, 6)) + 0.0) for a in GRID for b in GRID
            for c in GRID if a + b + c <= 1.0 + 1e-9]


def _row(name: str, ranked: dict, labs: dict, **extra) -> dict:
    return {"ranking": name, **extra, **_scored(ranked, labs)}


def split(mats: dict, labs: dict, collection_name: str, candidates: list, trials: int = 6, seed: int = 0) -> list:
    """``candidates``: (name, function of one collection's matrices); in each of ``trials`` seeded
    splits of ``collection_name``'s classes into halves, the candidate of lowest J on the other
    collections and one half, scored on the other half beside the combined ranking as it is."""
    out = []
    for train, fit, fit_labs, held, held_labels in class_splits(mats, labs, collection_name, trials, seed):
        name, f = min(candidates, key=lambda c: _scored({k: c[1](m) for k, m in fit.items()}, fit_labs)["pooled"]["J"])
        out.append({"chosen_on": train, "chosen": name, "held_out": scores(f(held), held_labels),
                    "as_it_is": scores(product(held), held_labels)})
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[2] / "shared" / "data")))
    ap.add_argument("--per-class", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cache", required=True, type=Path)
    ap.add_argument("--json", default=str(HERE / "recognition_scales.json"))
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    names = ("tosca", "watertight")
    mats = {c: matrices(args.data, c, args.per_class, args.seed, args.jobs, args.cache) for c in names}
    labs = {c: mats[c]["labels"] for c in names}
    for c, m in mats.items():
        off = ~np.eye(len(m["G"]), dtype=bool)
        if not np.array_equal(m["L@0.5"][off], m["G"][off]):
            raise RuntimeError(f"{c}: the trimmed log ratios at half the time are not the matrix's G")
    rows = [_row("combined, as it is", {c: product(m) for c, m in mats.items()}, labs, scale=0.5)]
    for s in SCALES[1:]:
        rows.append(_row(f"combined, G measured at {s:g} x the time", {c: product(m, s) for c, m in mats.items()},
                         labs, scale=s))
    for s in SCALES:
        rows.append(_row(f"L@{s:g} alone", {c: m[f"L@{s:g}"] for c, m in mats.items()}, labs, scale=s))
    one = [(f"combined, G at {s:g}", lambda m, s=s: product(m, s)) for s in SCALES]
    many = [(f"S^{w[0]:g} L@{s:g}^{w[1]:g} H^{w[2]:g} G^{w[3]:g}", s, w, lambda m, s=s, w=w: weighted(m, s, w))
            for s in SCALES[1:] for w in grid_weights()]
    grid = sorted((_row(name, {c: f(m) for c, m in mats.items()}, labs, scale=s, weights=w) for name, s, w, f in many),
                  key=lambda r: r["pooled"]["J"])
    given = list(argv if argv is not None else sys.argv[1:])
    source = gromov_source()
    if Path(source["path"]).is_relative_to(HERE.parents[1]):
        source["path"] = str(Path(source["path"]).relative_to(HERE.parents[1]))
    res = {"command": "python benchmarks/studies/recognition_scales.py "
                      + " ".join("CACHE" if a == str(args.cache) else a for a in given),
           "gromov_source": source, "per_class": args.per_class, "seed": args.seed,
           "shapes": {c: len(m["G"]) for c, m in mats.items()},
           "seconds": {c: {"prepare": float(m["seconds_prepare"]), "match": float(m["seconds_match"])}
                       for c, m in mats.items()},
           "rows": rows, "grid": grid[:40],
           "split_setting": split(mats, labs, "watertight", one),
           "split_grid": split(mats, labs, "watertight", [(name, f) for name, _, _, f in many])}
    write_results(args.json, json.loads(json.dumps(res, default=float)))

    def line(r):
        return f"J {r['pooled']['J']:.4f}  " + "  ".join(
            f"{c} {100 * r[c]['nn']:.1f}/{100 * r[c]['ft']:.1f}/{100 * r[c]['eer']:.1f}" for c in names)
    for r in rows + grid[:12]:
        print(f"{r['ranking']:<44} {line(r)}")
    for key in ("split_setting", "split_grid"):
        for r in res[key]:
            h, p = r["held_out"], r["as_it_is"]
            print(f"{key}: chosen on {','.join(r['chosen_on'])}: {r['chosen']}; held-out NN/FT/EER "
                  f"{100 * h['nn']:.1f}/{100 * h['ft']:.1f}/{100 * h['eer']:.1f}, as it is "
                  f"{100 * p['nn']:.1f}/{100 * p['ft']:.1f}/{100 * p['eer']:.1f}")


if __name__ == "__main__":
    main()
