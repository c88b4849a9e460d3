"""Peak memory of ``gromov pairwise`` on a collection of 100 shapes at 3,000 working vertices.

Run:  .venv/bin/python benchmarks/bench_memory.py [--data DIR] [--topkids 20] [--jobs 2]
                                                 [--store DIR] [--json OUT]

The 80 TOSCA shapes and the first ``--topkids`` TOPKIDS poses (kid00, kid01, ...; 100 shapes by
default), every pair matched by ``gromov pairwise`` with the default diffusion metric, in a
child process. Once a second, the proportional set size (PSS: each shared page counted once,
split between the processes sharing it) and the resident size (RSS) of that process and of all
its children (the ``--jobs`` worker processes, forked after the metrics are prepared and sharing
them) are read with psutil; the peak of their summed PSS is what the run needs of the machine.
Beside it, the model of docs/guide/recognition.md: 8n² bytes of distances per shape.

With ``--store DIR`` the run records its entries and pairs there (a second run on that store
reads them instead of computing them, and its peak is that of reading all shapes back).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from _common import add_data_argument, write_results


def files_of(data: Path, topkids: int) -> list[str]:
    tosca = sorted(str(f) for f in (data / "tosca").glob("*.off.gz"))
    kids = [str(data / "topkids" / f"kid{i:02d}.off.gz") for i in range(topkids)]
    return tosca + kids


def watch(pid: int, every: float = 1.0) -> tuple[dict, list, threading.Thread]:
    """Sample the process ``pid`` and its children until it ends: ``(peak, trace, thread)``."""
    import psutil

    peak = {"pss_mb": 0.0, "rss_sum_mb": 0.0, "rss_largest_mb": 0.0, "processes": 0, "at_s": 0.0}
    trace: list = []
    t0 = time.perf_counter()

    def run():
        try:
            root = psutil.Process(pid)
        except psutil.Error:
            return
        while True:
            try:
                procs = [root, *root.children(recursive=True)]
            except psutil.Error:
                return
            pss = rss = largest = 0.0
            for p in procs:
                try:
                    m = p.memory_full_info()
                except psutil.Error:
                    continue
                pss += m.pss / 1e6
                rss += m.rss / 1e6
                largest = max(largest, m.rss / 1e6)
            at = time.perf_counter() - t0
            trace.append([round(at, 1), round(pss), round(rss), len(procs)])
            if pss > peak["pss_mb"]:
                peak.update(pss_mb=pss, rss_sum_mb=rss, rss_largest_mb=largest, processes=len(procs), at_s=at)
            try:
                if root.status() == psutil.STATUS_ZOMBIE:
                    return
            except psutil.Error:   # gone
                return
            time.sleep(every)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return peak, trace, thread


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--topkids", type=int, default=20, help="TOPKIDS poses added to the 80 TOSCA shapes")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--store", default=None, help="record entries and pairs in this store")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)

    import psutil

    files = files_of(Path(args.data), args.topkids)
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "gromov", "pairwise", *files, "--jobs", str(args.jobs), "--json", "-q",
               "--out", str(Path(tmp) / "matrix.npz")]
        if args.store:
            cmd += ["--store", args.store]
        t = time.perf_counter()
        with open(Path(tmp) / "stdout.json", "w") as out:
            proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.PIPE, text=True)
            peak, trace, thread = watch(proc.pid)
            _, err = proc.communicate()
        seconds = time.perf_counter() - t
        thread.join()
        if proc.returncode:
            print(err, file=sys.stderr)
            return proc.returncode
        got = json.loads((Path(tmp) / "stdout.json").read_text())
    shown = ["gromov", "pairwise", f"<{len(files)} files>", "--jobs", str(args.jobs)]
    row = {"shapes": len(files), "pairs": len(files) * (len(files) - 1) // 2, "jobs": args.jobs,
           "seconds": seconds, "peak": peak, "machine_memory_gb": psutil.virtual_memory().total / 1e9,
           "model_distances_gb": len(files) * 8 * 3000 ** 2 / 1e9, "run": " ".join(shown),
           "shapes_in_matrix": len(got["files"])}
    print(f"{len(files)} shapes, {row['pairs']} pairs, --jobs {args.jobs}: {seconds / 60:.1f} min; peak PSS "
          f"{peak['pss_mb'] / 1e3:.2f} GB over {peak['processes']} processes (summed RSS "
          f"{peak['rss_sum_mb'] / 1e3:.2f} GB, largest process {peak['rss_largest_mb'] / 1e3:.2f} GB) at "
          f"{peak['at_s']:.0f} s; 8n² x {len(files)} at n = 3,000: {row['model_distances_gb']:.1f} GB")
    write_results(args.json, {"command": "python benchmarks/bench_memory.py " + " ".join(
        argv if argv is not None else sys.argv[1:]), **row, "trace": trace})
    return 0


if __name__ == "__main__":
    sys.exit(main())
