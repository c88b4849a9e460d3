"""What the dense maps add to one match: two 28k-vertex TOSCA cats, metrics prepared.

Run:  .venv/bin/python benchmarks/bench_dense_cost.py [--data DIR] [--repeat 3] [--json OUT]

``gromov.match(cat0, cat1)`` with ``dense=False``, ``"placed"``, ``"zoomout"`` (refined on the
working meshes) and ``True`` (refined on the input meshes), each the fastest (and the median) of
``--repeat`` runs after one warm-up; prints the seconds and what the dense maps add, and which
factorisation the input eigensolve used ("cholmod" with ``cholespy`` installed, else
"superlu"). The input refinement needs
each input mesh's Laplace-Beltrami eigenpairs, computed once per shape: the default row
computes them afresh on every run (a new pair of shapes, as ``gromov match`` on two files),
the row "input eigenpairs cached" reuses them (a shape matched again), and "not relaxed,
eigenpairs cached" leaves out the local isometry step and what follows it
(``gromov.dense.DENSE_RELAX = False``), "not aligned" the local rigid alignment
(``DENSE_ALIGN = 0``), "no inverse round" the round of :func:`gromov.dense.consistent_maps`
(``DENSE_INVERSE = 0``), and "inverse round of 20 sweeps" relaxes its starts by up to 20 sweeps
(``INVERSE_SWEEPS = 20``).

Then the two eigendecompositions alone (``INPUT_K`` eigenpairs each), the ways measured taking turns
in each of ``--repeat`` rounds: scipy's ``eigsh(L, k, M, sigma)`` as it comes (SuperLU,
2k + 1 Lanczos vectors, BLAS threads as configured), the shift-invert solve of
:func:`gromov.dense.laplace_beltrami_basis` (3k/2 + 1 vectors, one BLAS thread) with SuperLU
and with CHOLMOD, and :func:`gromov.dense.prolonged_basis` (the default: the working mesh's
eigenpairs carried to the input mesh, one subspace iteration, Rayleigh-Ritz); medians, and how
far their eigenvalues (Ritz values for the last) are from the first's.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

import gromov
from gromov._eigen import shift_invert_eigsh, spd_solver
from gromov.dense import INPUT_K, prolonged_basis
from gromov.gh import ShapeMetric
from gromov.metrics.diffusion import correspondence_options, cotan_laplacian

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _common import add_data_argument, write_results  # noqa: E402

def scipy_eigsh(L, k, M, sigma):
    """scipy's ``eigsh`` as it comes (SuperLU shift-invert, 2k + 1 vectors, threaded BLAS),
    from the same fixed start vector: the reference the other ways are compared with."""
    from scipy.sparse.linalg import eigsh

    n = L.shape[0]
    return eigsh(L, k=k, M=M, sigma=sigma, which="LM", v0=np.full(n, 1.0 / np.sqrt(n)))


#: row -> (``match(..., dense=)``, input eigenpairs kept from the run before, the
#: ``gromov.dense`` settings changed for it)
MODES = {"sparse": (False, False, {}), "placed": ("placed", False, {}), "zoomout": ("zoomout", False, {}),
         "dense (default)": (True, False, {}), "input eigenpairs cached": (True, True, {}),
         "not relaxed, eigenpairs cached": (True, True, {"DENSE_RELAX": False}),
         "not aligned, eigenpairs cached": (True, True, {"DENSE_ALIGN": 0}),
         "no inverse round, eigenpairs cached": (True, True, {"DENSE_INVERSE": 0}),
         "inverse round of 20 sweeps, eigenpairs cached": (True, True, {"INVERSE_SWEEPS": 20})}


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
    factorisation = spd_solver(sp.identity(3, format="csr"))[1]
    print(f"  input eigensolve: ARPACK shift-invert, {factorisation} factorisation")
    seconds, medians = {}, {}
    for name, (dense, cached, settings) in MODES.items():
        runs = []
        saved = {k: getattr(gromov.dense, k) for k in settings}
        for _ in range(args.repeat):
            if not cached:
                for s in (sx, sy):
                    assert s.for_correspondence() is s
                    s._input_basis = s._input_rings = s._relax_rings = None
            try:
                for k, v in settings.items():
                    setattr(gromov.dense, k, v)
                t = time.perf_counter()
                gromov.match(sx, sy, dense=dense)
                runs.append(time.perf_counter() - t)
            finally:
                for k, v in saved.items():
                    setattr(gromov.dense, k, v)
        seconds[name], medians[name] = min(runs), statistics.median(runs)
        print(f"  {name:16s} {seconds[name]:.3f} s (median {medians[name]:.3f} s)")
    added = seconds["dense (default)"] - seconds["sparse"]
    print(f"  the dense maps add {added:.3f} s ({seconds['placed'] - seconds['sparse']:.3f} s placed only, "
          f"{seconds['input eigenpairs cached'] - seconds['sparse']:.3f} s with the eigenpairs cached)")
    print(f"  the local isometry step (gromov.dense.DENSE_RELAX), with the inverse round that needs it, adds "
          f"{seconds['input eigenpairs cached'] - seconds['not relaxed, eigenpairs cached']:.3f} s")
    print(f"  the local rigid alignment (gromov.dense.DENSE_ALIGN) adds "
          f"{seconds['input eigenpairs cached'] - seconds['not aligned, eigenpairs cached']:.3f} s")
    print(f"  the round of each direction offered the other's inverse (gromov.dense.DENSE_INVERSE) adds "
          f"{seconds['input eigenpairs cached'] - seconds['no inverse round, eigenpairs cached']:.3f} s, "
          f"of 20 sweeps (INVERSE_SWEEPS = 20) "
          f"{seconds['inverse round of 20 sweeps, eigenpairs cached'] - seconds['no inverse round, eigenpairs cached']:.3f} s")
    added_median = medians["dense (default)"] - medians["sparse"]
    print(f"  medians: the dense maps add {added_median:.3f} s")
    eigensolve = eigensolves([sx.working, sy.working], args.repeat)
    write_results(args.json, {"pair": "cat0 -> cat1", "factorisation": factorisation, "repeat": args.repeat,
                              "seconds": seconds, "added_s": added, "median_seconds": medians,
                              "added_median_s": added_median, "eigensolve": eigensolve, "cpus": os.cpu_count(),
                              "load_average": os.getloadavg()})
    return 0


def eigensolves(workings, repeat: int, k: int = INPUT_K) -> dict:
    """Seconds for the eigendecompositions of the input meshes of all ``workings`` (working
    meshes, a median of ``repeat`` rounds, the ways taking turns), and each way's largest
    eigenvalue difference from scipy's default, relative to the largest eigenvalue."""
    problems = []
    for w in workings:
        L, M = cotan_laplacian(w.source)
        problems.append((L, M, -1e-2 / w.source.area, w))
    def ritz(L, M, s, w):
        phi, _ = prolonged_basis(w, k)
        return np.einsum("ij,ij->j", phi, L @ phi), phi

    ways = {"scipy eigsh (SuperLU, 2k+1 vectors, threaded BLAS)": lambda L, M, s, w: scipy_eigsh(L, k, M, s),
            "SuperLU, 3k/2+1 vectors, 1 BLAS thread": lambda L, M, s, w: shift_invert_eigsh(L, M, k, sigma=s,
                                                                                              method="superlu")}
    if spd_solver(sp.identity(3, format="csr"))[1] == "cholmod":
        ways["CHOLMOD, 3k/2+1 vectors, 1 BLAS thread"] = (
            lambda L, M, s, w: shift_invert_eigsh(L, M, k, sigma=s, method="cholmod"))
    ways["prolonged from the working mesh, 1 iteration (default)"] = ritz
    runs = {name: [] for name in ways}
    eigenvalues = {}
    for r in range(repeat):
        for name in (list(ways) if r % 2 == 0 else list(ways)[::-1]):
            t = time.perf_counter()
            lam = [np.sort(ways[name](*p)[0]) for p in problems]
            runs[name].append(time.perf_counter() - t)
            eigenvalues[name] = lam
    first = eigenvalues[next(iter(ways))]
    out = {"meshes": len(workings), "k": k, "rounds": repeat, "median_s": {}, "max_eigenvalue_rel_diff": {}}
    for name in ways:
        out["median_s"][name] = statistics.median(runs[name])
        out["max_eigenvalue_rel_diff"][name] = max(float(np.abs(a - b).max() / b.max())
                                                   for a, b in zip(eigenvalues[name], first))
        print(f"  eigensolve, {name}: {out['median_s'][name]:.3f} s (median), eigenvalues within "
              f"{out['max_eigenvalue_rel_diff'][name]:.1e}")
    return out


if __name__ == "__main__":
    sys.exit(main())
