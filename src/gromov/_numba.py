"""numba's on-disk cache of compiled kernels: a writable folder for it, chosen before numba loads
(:func:`set_up_cache`, called when ``gromov`` is imported)."""

from __future__ import annotations


def set_up_cache() -> None:
    """Give numba's on-disk cache of compiled kernels a writable folder, before numba loads.

    numba caches beside the sources (``__pycache__``) or, where that is read-only, in the
    user's cache folder; with neither writable (a read-only install and no writable home)
    every ``@njit(cache=True)`` fails with "no locator available". Then, unless the user set
    ``NUMBA_CACHE_DIR``, the cache goes to ``<temp>/gromov-numba-<uid>``; where even that is
    not writable the kernels are compiled but not cached, in each run (a warning says so).
    """
    import os
    import sys
    import tempfile

    if os.environ.get("NUMBA_CACHE_DIR"):
        return

    def writable(folder: str) -> bool:
        try:
            os.makedirs(folder, exist_ok=True)
            tempfile.TemporaryFile(dir=folder).close()
        except OSError:
            return False
        return True

    if writable(os.path.join(os.path.dirname(os.path.abspath(__file__)), "__pycache__")):
        return
    if sys.platform == "darwin":
        user = os.path.expanduser("~/Library/Caches")
    elif sys.platform == "win32":
        user = os.environ.get("LOCALAPPDATA", os.path.expanduser("~"))
    else:
        user = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    if writable(os.path.join(user, "numba")):
        return
    uid = os.getuid() if hasattr(os, "getuid") else 0
    try:
        folder = os.path.join(tempfile.gettempdir(), f"gromov-numba-{uid}")
    except FileNotFoundError:   # no writable temporary folder at all
        folder = None
    if folder is not None and writable(folder):
        os.environ["NUMBA_CACHE_DIR"] = folder
        config = sys.modules.get("numba.core.config")
        if config is not None:   # numba loaded before gromov: it reads the folder per kernel
            config.CACHE_DIR = folder
        return
    import warnings

    import numba

    plain = numba.njit

    def njit(*args, **kwargs):   # the kernels' @njit(cache=True), compiled but not cached
        kwargs.pop("cache", None)
        return plain(*args, **kwargs)

    numba.njit = njit
    warnings.warn("gromov: no writable folder for numba's cache of compiled kernels (the package "
                  "folder, the user's cache folder and the temporary folder are read-only), so they "
                  "are compiled again in each run: set NUMBA_CACHE_DIR to a writable folder",
                  RuntimeWarning, stacklevel=3)
