"""Array helpers for the compiled kernels."""

from __future__ import annotations

import numpy as np


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (``a`` itself when it is read-only already).

    Numba compiles a kernel once per argument type, and the writeable flag is part of an
    array's type: handing a kernel the same arrays always read-only keeps it to one
    compilation (a first ``gromov.match`` compiled the coarse search twice, once for a
    shape's read-only distance matrix and once for a writable slice of it).
    """
    if not a.flags.writeable:
        return a
    v = a.view()
    v.flags.writeable = False
    return v
