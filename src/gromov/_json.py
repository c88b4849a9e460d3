"""Standard JSON from results that may hold numpy values or NaN."""

from __future__ import annotations

import numpy as np


def finite(o):
    """``o`` with every NaN or infinite number as None: standard JSON has no NaN or Infinity
    (a value that is not a number, e.g. the orientation of a point cloud's map, is null)."""
    if isinstance(o, dict):
        return {k: finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [finite(v) for v in o]
    if isinstance(o, np.ndarray):
        return finite(o.tolist())
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    if isinstance(o, np.integer):
        return int(o)
    return o
