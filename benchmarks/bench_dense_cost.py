"""What the dense maps add to one match: two 28k-vertex TOSCA cats, metrics prepared.

Run:  .venv/bin/python benchmarks/bench_dense_cost.py [--data DIR] [--repeat 3] [--json OUT]

``gromov.match(cat0, cat1)`` with ``dense=False``, ``"placed"``, ``"zoomout"`` (refined on the
working meshes) and ``True`` (refined on the input meshes), each the fastest of ``--repeat`` runs
after one warm-up; prints the seconds and what the dense maps add. The input refinement needs
each input mesh's Laplace-Beltrami eigenpairs, computed once per shape: the default row
computes them afresh on every run (a new pair of shapes, as ``gromov match`` on two files),
the row "input eigenpairs cached" reuses them (a shape matched again).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import gromov
from gromov.gh import ShapeMetric
from gromov.metrics.diffusion import correspondence_options

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _common import add_data_argument, write_results  # noqa: E402

MODES = {"sparse": False, "placed": "placed", "zoomout": "zoomout", "dense (default)": True,
         "input eigenpairs cached": True}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_argument(ap)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=str(HERE / "results" / "dense_cost.json"))
    args = ap.parse_args(argv)
    tosca = Path(args.data) / "tosca"
    # prepared as match measures a correspondence, so that the shapes it uses are these
    sx, sy = (ShapeMetric(gromov.load(tosca / f"cat{p}.off.gz"), metric_options=correspondence_options("diffusion", None))
              for p in (0, 1))
    gromov.match(sx, sy, dense=True)   # metrics, caches and compiled kernels
    seconds = {}
    for name, dense in MODES.items():
        runs = []
        for _ in range(args.repeat):
            if name != "input eigenpairs cached":
                for s in (sx, sy):
                    assert s.for_correspondence() is s
                    s._input_basis = s._input_rings = None
            t = time.perf_counter()
            gromov.match(sx, sy, dense=dense)
            runs.append(time.perf_counter() - t)
        seconds[name] = min(runs)
        print(f"  {name:16s} {seconds[name]:.3f} s")
    added = seconds["dense (default)"] - seconds["sparse"]
    print(f"  the dense maps add {added:.3f} s ({seconds['placed'] - seconds['sparse']:.3f} s placed only, "
          f"{seconds['input eigenpairs cached'] - seconds['sparse']:.3f} s with the eigenpairs cached)")
    write_results(args.json, {"pair": "cat0 -> cat1", "seconds": seconds, "added_s": added,
                              "cpus": os.cpu_count(), "load_average": os.getloadavg()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
