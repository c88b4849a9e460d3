"""What the commands share when they run: the user error, JSON output, loading a shape, the
checks made before any metric is computed, status lines, and the shape store's warnings."""

from __future__ import annotations

import json
import logging
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .._json import finite as _finite


class _UserError(Exception):
    """A mistake in the command line or its inputs: one line ``gromov: error: ...``, status 2."""


def _dumps(o) -> str:
    """One JSON object, standard JSON only (``allow_nan=False``)."""
    return json.dumps(_finite(o), allow_nan=False)


#: Dense (n, n) float64 distance matrices held while one is computed: the matrix and a
#: transient of its size (``gromov distances`` on TOSCA cat0, 2,000 -> 4,000 working vertices:
#: peak memory 0.36 -> 0.55 GB with the diffusion metric, 0.35 -> 0.45 GB geodesic; ``gromov
#: match`` at 1,500 -> 3,000: 0.37 -> 0.60 GB; ``/usr/bin/time -f %M``).
DENSE_COPIES = 2


def _check_memory(sizes: list[int], what: str) -> None:
    """Refuse, before any metric is computed, working sizes whose dense distance matrices
    (8 n^2 bytes each, :data:`DENSE_COPIES` while computed) need more memory than is available."""
    from ..experiments.pairwise import _available_memory

    have = _available_memory()
    need = sum(DENSE_COPIES * 8 * n * n for n in sizes)
    if have is None or need <= have:
        return
    fit = int(np.sqrt(have / (DENSE_COPIES * 8 * len(sizes))) // 100 * 100)
    gb = lambda b: f"{b / 1e9:.1f} GB" if b >= 1e9 else f"{b / 1e6:.1f} MB"  # noqa: E731
    n = max(sizes)
    matrices = "matrices" if len(sizes) > 1 else "matrix"
    raise _UserError(f"{what}: {len(sizes)} dense distance {matrices} of up to {n:,} working "
                     f"vertices need about {gb(need)} (8 bytes x n^2 each, {DENSE_COPIES}x "
                     f"while computed) and {gb(have)} of memory are available; a --resolution of at "
                     f"most {fit:,} fits")


def _load(path: str, args=None):
    from ..io import load

    return load(path, max_decompressed=getattr(args, "max_decompressed", None))


def _check_pieces(args, path: str, shape) -> None:
    """Matching needs finite distances: refuse a mesh in several pieces with a metric that is
    infinite between them (geodesic, biharmonic), before any metric is computed."""
    from ..mesh import Mesh

    infinite = args.metric == "geodesic" or (args.metric == "diffusion" and args.kernel == "biharmonic")
    if infinite and isinstance(shape, Mesh) and shape.n_components > 1:
        what = "geodesic" if args.metric == "geodesic" else "biharmonic"
        raise _UserError(f"{path}: the working mesh has {shape.n_components} connected components; "
                         f"{what} distances between them are infinite and matching needs finite ones: "
                         "--metric diffusion --kernel heat measures across them (or match the largest "
                         "piece on its own)")


def _check_neighbors(args, shapes) -> None:
    """``--neighbors`` shapes a point cloud's graph or Laplacian: refused when every input is a
    mesh, whose metric is built on its faces and would ignore it."""
    from ..mesh import Mesh

    if getattr(args, "neighbors", None) is not None and all(isinstance(s, Mesh) for s in shapes):
        raise _UserError("--neighbors applies to point clouds; every input here is a mesh, whose "
                         "metric is built on its faces")


def _status(args, text: str) -> None:
    """One status line on stderr for a step that can take seconds: on a terminal (like the
    progress bars, never mixed into a script's captured output), unless ``-q``."""
    if not getattr(args, "quiet", False) and sys.stderr.isatty():
        print(f"gromov: {text}", file=sys.stderr, flush=True)


def _stem(path) -> str:
    """File name without folders, ``.gz`` and a mesh format's extension (``cat0.off.gz`` ->
    ``cat0``; the formats of :data:`gromov.io.FORMATS`)."""
    from ..io import FORMATS

    name = Path(path).name
    if name.lower().endswith(".gz") and len(name) > 3:
        name = name[:-3]
    base, dot, ext = name.rpartition(".")
    return base if dot and base and ext.lower() in FORMATS else name


def _count(n: int, noun: str) -> str:
    """``"1 pair"``, ``"3 pairs"``: a count and its noun, plural but for one."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


def _check_output(path: str, option: str, suffix: str, what: str) -> None:
    """An output file's name, checked before any work: it ends in ``suffix``, is no folder, and
    its folder exists."""
    p = Path(path)
    if p.suffix.lower() != suffix:
        raise _UserError(f"{option} writes {what}: give a file name ending in {suffix}, got {path!r}")
    if p.is_dir():
        raise _UserError(f"{option} {path} is a folder")
    _check_folder(path, option)


def _check_folder(path: str, option: str) -> None:
    """An output file's folder exists."""
    folder = Path(path).parent
    if not folder.exists():
        raise _UserError(f"{option}: output folder {folder} does not exist")


def _check_png(path: str, option: str) -> None:
    _check_output(path, option, ".png", "a PNG image")


def _check_npz(path: str, option: str) -> None:
    _check_output(path, option, ".npz", "a NumPy archive")


class _StoreWarnings(logging.Handler):
    """Prints the store's warnings (an invalid entry, a changed file) as one line each,
    ``gromov: warning: ...``; passes its other records on to the root logger."""

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:   # on its own line under a progress bar
            from tqdm import tqdm

            tqdm.write(f"gromov: warning: {record.getMessage()}", file=sys.stderr)
        else:
            logging.getLogger().handle(record)


def _open_store(args):
    """``(store, handler)``: the ``--store`` of ``index`` and ``pairwise``, whose warnings the
    handler prints (:func:`_close_store` removes it); ``(None, None)`` without ``--store``."""
    if getattr(args, "store", None) is None:
        return None, None
    from ..store import ShapeStore

    log = logging.getLogger("gromov.store")
    handler = _StoreWarnings()
    log.addHandler(handler)
    log.propagate = False
    try:
        return ShapeStore(args.store, load=lambda path: _load(path, args)), handler
    except BaseException:
        _close_store(None, handler)
        raise


@contextmanager
def _store_of(args):
    """The ``--store`` of the command open for a ``with`` block (None without ``--store``),
    closed and its warnings' handler removed after (:func:`_open_store`, :func:`_close_store`)."""
    store, handler = _open_store(args)
    try:
        yield store
    finally:
        _close_store(store, handler)


def _close_store(store, handler) -> None:
    if store is not None:
        store.close()
    if handler is not None:
        log = logging.getLogger("gromov.store")
        log.removeHandler(handler)
        log.propagate = True
