"""Experiments layer: datasets, perturbations, evaluation and reports.

The core library never imports this package. Its main names are importable from here
(``from gromov.experiments import gh_matrix``); each submodule is imported on first use.
``reproduce`` is the submodule of that name: ``from gromov.experiments.reproduce import reproduce``.
"""

from __future__ import annotations

import importlib

_LAZY = {
    "gh_matrix": "pairwise", "match_pairs": "pairwise", "PairwiseGH": "pairwise", "prepare": "pairwise",
    "roc": "recognition", "ROC": "recognition", "equal_error_rate": "recognition",
    "local_scaling": "recognition", "mds_map": "recognition",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
