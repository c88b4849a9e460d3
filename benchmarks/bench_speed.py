"""Speed a user feels: first run, start-up, one pair of a matrix, one match end to end, welds.

Run:  .venv/bin/python benchmarks/bench_speed.py [--data DIR] [--json OUT] [--skip PARTS]

Each part measures gromov and its anchor side by side in the same run, on the TOSCA cats:

1. **first run**: ``gromov match cat0 cat1 -q`` as a new process with an empty numba cache
   folder (``NUMBA_CACHE_DIR``; every kernel compiles), then again with that cache (warm);
2. **start-up**: ``python -c "import gromov"`` and ``gromov --help``, the fastest of 5;
3. **one pair** of a recognition matrix, the metrics computed: the symmetric match that
   ``gromov.experiments.gh_matrix`` runs per pair (``orientation="ignore"``, the default
   diffusion metric, 100 samples, 3,000 working vertices) on one thread, against POT's
   ``ot.gromov.gromov_wasserstein`` (square loss, uniform weights) on the same two 100 x 100
   sample matrices; the median of 5;
4. **end to end**: ``gromov match cat0 cat1`` (warm) against the pipeline a user would assemble
   from potpourri3d and POT, as a new process too: load both meshes, 100 farthest point
   samples on each, heat-method geodesic distances from every sample
   (``potpourri3d.MeshHeatMethodDistanceSolver``), POT's Gromov-Wasserstein between the two
   100 x 100 matrices, each sample of cat0 sent to the sample of cat1 it has the most mass
   with. Both are scored the same way: the mean geodesic distance on cat1 (fast marching on
   the input mesh) between each sample's image vertex and its true image (same vertex id in a
   TOSCA class), divided by cat1's geodesic diameter, the better of the direct and the
   left/right mirrored reading; and ``gromov match --metric geodesic``'s time;
5. **perturb weld** per TOSCA class: ``gromov perturb weld CLASS OUT --count 3 -q`` (its
   defaults) on each class's first pose, seconds and the peak resident memory of the process
   (``VmHWM``).

Machines are noisy: read the ratios, measured side by side, rather than the seconds.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import HERE, add_data_argument, write_results

BIN = Path(sys.executable).parent
CLASSES = ("cat", "dog", "horse", "centaur", "wolf", "david", "michael", "victoria", "gorilla")
PARTS = ("first", "startup", "pair", "end", "weld")


PIPELINE = r"""
import sys, time
t0 = time.perf_counter()
import numpy as np, potpourri3d as pp3d, ot
import gromov
def fps(v, k):
    out = [0]; d = np.linalg.norm(v - v[0], axis=1)
    for _ in range(k - 1):
        out.append(int(np.argmax(d))); d = np.minimum(d, np.linalg.norm(v - v[out[-1]], axis=1))
    return np.array(out)
def geodesics(m, s):
    solver = pp3d.MeshHeatMethodDistanceSolver(m.vertices, m.faces)
    D = np.stack([solver.compute_distance(int(i))[s] for i in s])
    return 0.5 * (D + D.T)
x, y = gromov.load(sys.argv[1]), gromov.load(sys.argv[2])
P, Q = fps(x.vertices, 100), fps(y.vertices, 100)
dx, dy = geodesics(x, P), geodesics(y, Q)
a = np.full(100, 0.01)
T = ot.gromov.gromov_wasserstein(dx, dy, a, a, loss_fun="square_loss")
img = Q[np.argmax(T, axis=1)]
np.savez(sys.argv[3], samples=P, images=img, seconds=time.perf_counter() - t0)
"""


def _timed(cmd, env=None) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed: {out.stderr[-500:]}")
    return time.perf_counter() - t, out


def first_run(tosca: Path, tmp: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / "numba-cache"))
    cmd = [BIN / "gromov", "match", tosca / "cat0.off.gz", tosca / "cat1.off.gz", "-q"]
    cold, _ = _timed(cmd, env)
    warm, _ = _timed(cmd, env)
    row = {"cold_s": cold, "warm_s": warm, "ratio": cold / warm}
    print(f"[1] first gromov match {cold:.1f} s, warm {warm:.1f} s: {row['ratio']:.2f}x")
    return row


def startup() -> dict:
    imp = min(_timed([sys.executable, "-c", "import gromov"])[0] for _ in range(5))
    helps = min(_timed([BIN / "gromov", "--help"])[0] for _ in range(5))
    bare = min(_timed([sys.executable, "-c", "pass"])[0] for _ in range(5))
    row = {"import_s": imp, "help_s": helps, "python_s": bare}
    print(f"[2] python -c 'import gromov' {imp:.3f} s, gromov --help {helps:.3f} s (python alone {bare:.3f} s)")
    return row


def one_pair(tosca: Path, repeat: int = 5) -> dict:
    import numba
    import ot
    from threadpoolctl import threadpool_limits

    from gromov.experiments.pairwise import prepare
    from gromov.gh import _match

    numba.set_num_threads(1)
    with threadpool_limits(1):
        sx, sy = prepare([tosca / "cat0.off.gz", tosca / "cat1.off.gz"], "diffusion", n_samples=100)

        def ours():
            return _match(sx, sy, "diffusion", n_samples=100, orientation="ignore", as_prepared=True)

        P, Q = sx.samples(100, 0), sy.samples(100, 0)
        dx, dy = sx.distances[np.ix_(P, P)], sy.distances[np.ix_(Q, Q)]
        a = np.full(100, 0.01)
        ours()   # compile
        times = {"ours": [], "pot": []}
        for _ in range(repeat):   # interleaved: other work slows both alike
            t = time.perf_counter()
            ours()
            times["ours"].append(time.perf_counter() - t)
            t = time.perf_counter()
            ot.gromov.gromov_wasserstein(dx, dy, a, a, loss_fun="square_loss")
            times["pot"].append(time.perf_counter() - t)
    row = {k: float(np.median(v)) for k, v in times.items()}
    row["ratio"] = row["ours"] / row["pot"]
    print(f"[3] one pair, metrics computed, one thread: gromov {row['ours']:.3f} s, POT GW {row['pot']:.4f} s, "
          f"ratio {row['ratio']:.0f}")
    return row


def _sample_error(samples, images, y, ref, sym) -> float:
    """Mean geodesic error / geodesic diameter of vertex images on ``y``, the better reading."""
    from gromov.evaluate import dense_errors

    def err(truth):
        face = np.full(y.n_vertices, -1)
        for c in range(3):
            face[y.faces[:, c]] = np.arange(len(y.faces))
        f = face[images]
        bary = np.eye(3)[np.argmax(y.faces[f] == images[:, None], axis=1)]
        return float(dense_errors(f, bary, y, truth, fmm=ref).mean())

    far = int(np.argmax(ref.fmm.distances(np.array([0]))[0]))   # farthest from a vertex
    diameter = float(ref.fmm.distances(np.array([far])).max())   # a second sweep: the diameter
    return min(err(samples), err(sym[samples])) / diameter


def end_to_end(tosca: Path, tmp: Path) -> dict:
    import gromov
    from gromov.evaluate import GeodesicReference
    from gromov.experiments.reproduce import reflection_map

    a, b = tosca / "cat0.off.gz", tosca / "cat1.off.gz"
    out = tmp / "m.npz"
    _timed([BIN / "gromov", "match", a, b, "-q", "--out", out])   # warm
    t_ours, _ = _timed([BIN / "gromov", "match", a, b, "-q", "--out", out])
    script = tmp / "pipeline.py"
    script.write_text(PIPELINE)
    t_pipe, _ = _timed([sys.executable, script, a, b, tmp / "p.npz"])
    y = gromov.load(b)
    ref, sym = GeodesicReference(y), reflection_map(y)
    with np.load(out) as z:
        e_ours = _sample_error(z["x_samples"], z["x_to_y_vertex"], y, ref, sym)
    with np.load(tmp / "p.npz") as z:
        e_pipe = _sample_error(z["samples"], z["images"], y, ref, sym)
    t_geo, _ = _timed([BIN / "gromov", "match", a, b, "-q", "--metric", "geodesic"])
    row = {"gromov_s": t_ours, "pipeline_s": t_pipe, "time_ratio": t_ours / t_pipe, "gromov_geodesic_s": t_geo,
           "gromov_error": e_ours, "pipeline_error": e_pipe, "error_ratio": e_ours / e_pipe}
    print(f"[4] end to end: gromov match {t_ours:.1f} s, potpourri3d + POT {t_pipe:.1f} s "
          f"(ratio {row['time_ratio']:.2f}); error / diameter {e_ours:.4f} vs {e_pipe:.4f} "
          f"(ratio {row['error_ratio']:.2f}); with --metric geodesic {t_geo:.1f} s")
    return row


def welds(tosca: Path, tmp: Path) -> dict:
    rows = {}
    for cls in CLASSES:
        first = min(int(f.name[len(cls):-len(".off.gz")]) for f in tosca.glob(f"{cls}[0-9]*.off.gz"))
        cmd = [sys.executable, "-c",
               # VmHWM: this process's peak; ru_maxrss would carry the parent's over the exec
               "import re, sys; from gromov.cli import main; code = main(sys.argv[1:]); "
               "print(re.search(r'VmHWM:\\s*(\\d+)', open('/proc/self/status').read()).group(1)); sys.exit(code)",
               "perturb", "weld", str(tosca / f"{cls}{first}.off.gz"), str(tmp / f"{cls}-weld.off"), "--count", "3", "-q"]
        t = time.perf_counter()
        out = subprocess.run(cmd, capture_output=True, text=True, check=False)
        seconds = time.perf_counter() - t
        rss = int(out.stdout.split()[-1]) / 1024 if out.returncode == 0 else None
        rows[f"{cls}{first}"] = {"ok": out.returncode == 0, "seconds": seconds, "peak_mb": rss,
                     "error": None if out.returncode == 0 else out.stderr.strip()[-200:]}
        print(f"[5] perturb weld {cls}{first} --count 3: {'ok' if out.returncode == 0 else 'FAILED'} "
              f"{seconds:.1f} s, peak {rss if rss is None else round(rss)} MB", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--json", default=str(HERE / "results" / "speed.json"))
    ap.add_argument("--skip", default="", help=f"comma-separated parts to leave out: {', '.join(PARTS)}")
    args = ap.parse_args(argv)
    skip = {s for s in args.skip.split(",") if s}
    if skip - set(PARTS):
        ap.error(f"--skip takes {', '.join(PARTS)}")
    tosca = Path(args.data) / "tosca"
    res = {"date": time.strftime("%Y-%m-%d"), "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if "first" not in skip:
            res["first_run"] = first_run(tosca, tmp)
        if "startup" not in skip:
            res["startup"] = startup()
        if "pair" not in skip:
            res["one_pair"] = one_pair(tosca)
        if "end" not in skip:
            res["end_to_end"] = end_to_end(tosca, tmp)
        if "weld" not in skip:
            res["weld"] = welds(tosca, tmp)
    res["peak_rss_mb_self"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    res["command"] = "python benchmarks/bench_speed.py" + "".join(f" {a}" for a in (argv if argv is not None else sys.argv[1:]))
    write_results(args.json, res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
