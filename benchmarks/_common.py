"""What the diagnostic benchmarks share: the data option, the default diffusion metric spelled
out, residual summaries and the results file (with the machine it was made on). Scripts run as
``python benchmarks/NAME.py`` find this module beside them."""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from gromov.gmds import sample_trimmed_rms, trimmed_rms

HERE = Path(__file__).resolve().parent
#: The library's default diffusion metric, spelled out so that a results file says what it used.
HEAT = {"kernel": "heat", "tau": 0.005, "fill_holes": 0.5}


def add_data_argument(ap: argparse.ArgumentParser) -> None:
    """``--data DIR``: the research data (default ``$GROMOV_DATA`` or ``../shared/data``)."""
    ap.add_argument("--data", default=os.environ.get("GROMOV_DATA", str(HERE.parents[1] / "shared" / "data")))


def residual_summaries(e: np.ndarray, diam: float, sample_keeps=(0.7,)) -> dict:
    """A residual matrix ``e`` (distances on X minus on Y, same samples) summarised, each ÷
    ``diam``: ``rms`` over the off-diagonal pairs, ``trim80`` the RMS of the best-fitting 80% of
    them (:func:`gromov.gmds.trimmed_rms`, what recognition ranks by) and ``strimK`` the RMS over
    the pairs of the best-fitting K% of the samples (:func:`gromov.gmds.sample_trimmed_rms`)."""
    r = e[~np.eye(len(e), dtype=bool)]
    out = {"rms": float(np.sqrt(np.mean(r**2))) / diam, "trim80": trimmed_rms(r, 0.8) / diam}
    out.update({f"strim{round(100 * k)}": sample_trimmed_rms(e, k) / diam for k in sample_keeps})
    return out


def margin(D: np.ndarray, labels: np.ndarray) -> float:
    """Smallest different-class distance over the largest same-class one (above 1: one
    threshold separates every pair of a symmetric distance matrix ``D``)."""
    same = labels[:, None] == labels[None, :]
    off = ~np.eye(len(labels), dtype=bool)
    return float(D[~same].min() / D[same & off].max())


def write_results(path: str | None, payload: dict) -> None:
    """Write ``payload`` with today's date and the machine (CPU model, BLAS:
    :func:`gromov.experiments.reproduce.environment`) as the JSON results file ``path``
    (nothing if None)."""
    if path:
        from gromov.experiments.reproduce import environment

        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps({"date": time.strftime("%Y-%m-%d"), "environment": environment(),
                                          **payload}, indent=1))
