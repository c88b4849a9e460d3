"""Reading and writing meshes: OFF, OBJ, PLY, STL, TOSCA, MATLAB, VTK, Gmsh and Medit files.

All I/O lives here, with one reader and one writer per format in the registry
:data:`FORMATS` (extension -> :class:`FileFormat`), so adding a format means adding one
entry. Any file may be gzip-compressed: a name ending in ``.gz`` (``cat0.off.gz``) is
decompressed on reading and compressed on writing. Decompression streams and stops at a
limit (see :data:`GZIP_RATIO` and ``load(..., max_decompressed=)``), so a small file that
inflates to gigabytes (a gzip bomb) is refused in a fraction of a second.

Design choices
--------------
* **Vertex ids are sacred.** Vertices are returned exactly in file order, unreferenced
  ones included, never merged or sorted by the reader; faces keep file order too. Only
  :func:`gromov.mesh.repair` (run by :func:`load` unless ``repair=False``) removes
  anything, and the result's ``input_ids`` map back to the file's 0-based vertex numbers.
* **Strict parsing.** Every reader is our own small numpy parser (fast path:
  ``numpy.loadtxt``'s C tokenizer; on any irregularity a line-by-line pass finds the
  culprit and names its line). Numbers are ASCII decimal literals (``inf``/``nan`` are
  read, then refused as coordinates): Python's ``float`` would also take ``1_000`` and
  non-ASCII (e.g. Arabic-Indic) digits, which are refused, as is any non-numeric token
  on a vertex or face line. A coordinate that overflows float64 (``1e400``) is an error,
  as is one beyond :data:`MAX_COORDINATE` (1e75), and so is a PLY value that does not fit its declared type (``nan`` or ``300`` in a
  ``uchar`` property): values are checked before they are cast, never wrapped.
  trimesh 5.2 was evaluated and not used for reading: with
  ``process=False`` it silently accepts truncated OFF/ASCII-PLY/ASCII-STL files (fewer
  faces than the header says, or an empty ``Scene``), maps OBJ index ``0`` to a wrong
  vertex, drops 2-vertex OBJ faces, reorders faces of mixed triangle/quad PLY files,
  writes PLY vertices as float32 and fails on a truncated binary STL with an unrelated
  ``ModuleNotFoundError``.
* **Errors.** Every problem with a file raises :class:`~gromov.errors.MeshFormatError`
  whose message starts with the file name, says where (line, record, property or
  coordinate) and quotes at most 60 characters of the offending input; a missing file raises
  :class:`MeshFileNotFoundError`, which is both a ``MeshFormatError`` and a
  ``FileNotFoundError``; a format whose optional package is not installed raises
  :class:`MissingDependencyError`, both a ``MeshFormatError`` and an ``ImportError``.
* **Optional formats.** VTK (``.vtk``, ``.vtu``), Gmsh (``.msh``) and Medit (``.mesh``)
  files are parsed by meshio (``pip install "gromov[formats]"``), imported only when such
  a file is read or written.
  Its readers are called directly on a file (``meshio.read`` would ``sys.exit`` on a bad
  file); whatever they raise on malformed input becomes a ``MeshFormatError``.

Format notes
------------
OFF
    0-based indices; ``#`` comments, blank lines, counts on the ``OFF`` line or the next
    one, colour values after the face indices; ``COFF``/``NOFF``/``STOFF`` vertex
    lines may carry extra values (ignored). Binary OFF is not supported.
OBJ
    ``v`` and ``f`` statements (``f 1/2/3`` and negative relative indices allowed);
    texture coordinates, normals, groups and materials are ignored.
PLY
    ASCII and binary (both endiannesses); ``vertex`` element with ``x y z`` and an
    optional ``face`` element with a ``vertex_indices`` (or ``vertex_index``) list.
    Written as binary little-endian with ``double`` coordinates (exact round trip).
STL
    ASCII and binary. STL has no shared vertices: corners with identical coordinates
    are merged while reading (silently; this is how the format works), and vertices are
    numbered by first appearance. Binary STL stores float32, so a round trip is exact
    only to float32 precision.
TOSCA ``.vert``/``.tri``
    ``.vert``: one ``x y z`` per line; ``.tri``: one triangle per line, 1-based.
    Loading either file reads both; saving writes both.
XYZ ``.xyz`` (point clouds)
    One point per line, ``x y z`` separated by blanks or by commas (not both on one line: a
    line like ``1,5 2,25 3,0`` has decimal commas, which are refused); further values on a line
    (normals, colours, intensities) are ignored; ``#`` comments and blank lines are skipped.
    Always a point cloud. Written as ``x y z`` lines in shortest round-trip form (exact);
    a mesh is refused (its faces would be lost: save ``PointCloud(mesh.vertices)``).
MATLAB ``.mat``
    The TOSCA/SHREC layout: one struct (TOSCA calls it ``surface``, any name is accepted)
    with column vectors ``X``, ``Y``, ``Z`` and an optional m x 3 matrix ``TRIV`` of
    1-based triangle indices (no ``TRIV``: a point cloud); variables ``X``, ``Y``, ``Z``
    [, ``TRIV``] at the top level of the file are read alike. Several such structs in one
    file are an error (the message names them). Versions 4 to 7 are read with
    :func:`scipy.io.loadmat`; version 7.3 files are HDF5, which scipy cannot read, and are
    rejected with a message saying so. The element tags of a version 5 file are checked
    first: on a data element of an unknown type scipy 1.17 crashes the interpreter, so such
    files, arrays of other classes than numbers, characters, cells and structs (function
    handles, objects), nesting deeper than 32 levels and compressed variables over the
    decompression limit are refused. Written as a version 5 file holding a struct
    ``surface`` with float64 ``X``, ``Y``, ``Z`` and ``TRIV`` (as TOSCA's files do): exact.
VTK ``.vtk``/``.vtu``, Gmsh ``.msh``, Medit ``.mesh`` (optional, meshio)
    Vertices are meshio's points (2-D points get z = 0); faces are the ``triangle``,
    ``quad`` and ``polygon`` cell blocks, in file order; other cells (vertices, lines,
    second-order elements...) are ignored, and a file whose only cells are volume cells
    (tetrahedra, hexahedra...) is rejected: extract its boundary surface first. No faces:
    a point cloud. Legacy ``.vtk`` must be an ``UNSTRUCTURED_GRID`` (meshio does not read
    ``POLYDATA``); ``.msh`` is read as Gmsh (not ANSYS). Written with float64
    coordinates, so the round trip is exact: legacy VTK 4.2 binary, VTU binary
    (zlib-compressed), Gmsh 4.1 binary, Medit ASCII with 17 significant digits; a point
    cloud is written with one ``vertex`` cell per point (none in Medit). A ``.gz`` file is
    decompressed into a temporary file for meshio (and written through one).

Polygons with more than three vertices are split into triangle fans, with a
:class:`~gromov.errors.GromovWarning`. So are meshio's own warnings (which it would print to
stderr through rich, out of reach of ``warnings`` filters): ``GromovWarning("FILE: meshio: ...")``.
"""

from __future__ import annotations

import contextlib
import contextvars
import gzip
import logging
import os
import re
import struct
import tempfile
import threading
import warnings
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

import numpy as np

from . import mesh as _mesh
from ._atomic import atomic_path, atomic_write_bytes
from .errors import GromovWarning, MeshError, MeshFormatError
from .mesh import COORDINATE_LIMIT, Mesh, PointCloud

__all__ = ["load", "save", "FORMATS", "FileFormat", "MeshFileNotFoundError",
           "MissingDependencyError", "GZIP_RATIO", "GZIP_FLOOR", "MAX_COORDINATE"]

logger = logging.getLogger(__name__)


class MeshFileNotFoundError(MeshFormatError, FileNotFoundError):
    """A mesh file (or the partner file of a TOSCA ``.vert``/``.tri`` pair) does not exist.

    Caught by ``except MeshFormatError``, ``except ValueError`` and
    ``except FileNotFoundError`` alike. The message names the missing file.
    """


class MissingDependencyError(MeshFormatError, ImportError):
    """A file format needs an optional package that is not installed (meshio for VTK,
    Gmsh and Medit files).

    Caught by ``except MeshFormatError``, ``except ValueError`` and ``except ImportError``
    alike. The message names the file and says what to install
    (``pip install "gromov[formats]"``).
    """


# Exceptions that malformed input can raise inside numpy / struct / the decoders; they are
# turned into MeshFormatError with the file name (anything else is a bug and propagates).
_PARSE_ERRORS = (ValueError, IndexError, KeyError, TypeError, OverflowError, struct.error,
                 UnicodeError, EOFError, zlib.error)


def _err(name: str, problem: str) -> MeshFormatError:
    return MeshFormatError(f"{name}: {problem}")


#: Most characters of the input that a message quotes.
_QUOTE_CHARS = 60


def _q(text: str | bytes) -> str:
    """``repr`` of ``text`` (stripped), cut to 60 characters with its length
    said: a message quotes the offending input, never all of a megabyte-long line."""
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    text = text.strip()
    if len(text) <= _QUOTE_CHARS:
        return repr(text)
    return f"{text[:_QUOTE_CHARS]!r}... ({len(text)} characters)"


# Numbers as the formats write them: ASCII decimal literals (`re.ASCII`: \d is 0-9 only).
# Python's float()/int() also accept "1_000" and non-ASCII digits; those tokens are refused.
# Possessive quantifiers (++, *+, ?+): a 10^6-digit token that ends in a letter fails in
# linear time, where backtracking over the split of its digits would take quadratic time.
_FLOAT = r"[+-]?+(?:(?:\d++(?:\.\d*+)?+|\.\d++)(?:[eE][+-]?+\d++)?+|(?i:infinity|inf|nan))"
_FLOAT_RE = re.compile(_FLOAT, re.ASCII)
_INT_RE = re.compile(r"[+-]?+\d++", re.ASCII)
_COUNT_RE = re.compile(r"\d++", re.ASCII)
# Face indices beyond this are out of range of any mesh (and of int64 arithmetic)
_MAX_INDEX = 2**53
_XYZ_FIELDS = ("coordinate x", "coordinate y", "coordinate z")


def _is_float(tok: str) -> bool:
    return _FLOAT_RE.fullmatch(tok) is not None


def _field(fields: Sequence[str], c: int) -> str:
    return fields[c] if c < len(fields) else f"value {c + 1}"


def _cut(text: str, n: int = 2 * _QUOTE_CHARS) -> str:
    """``text`` on one line, cut to ``n`` characters (another library's message, which may
    quote the file)."""
    text = " ".join(text.split())
    return text if len(text) <= n else text[:n] + "..."


def _library_error(exc: BaseException, own: tuple[type[BaseException], ...],
                   file: str | None = None, name: str | None = None) -> str:
    """What a third-party reader said about a file: its own error class and message (cut
    short), or, for an internal failure of that library (``IndexError``...), only that the
    content is malformed -- never Python's text about the library's internals."""
    if not isinstance(exc, own):
        logger.debug("reader failed with %s: %s", type(exc).__name__, _cut(str(exc)))
        return "malformed content"
    msg = str(exc) if file is None else str(exc).replace(file, name)
    return f"{type(exc).__name__}: {_cut(msg)}" if msg.strip() else type(exc).__name__


# --------------------------------------------------------------------------- raw shape
@dataclass
class RawShape:
    """What a reader returns: file content before validation, triangulation and repair.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3), float64
        In file order.
    counts : ndarray of int, shape (m,), or None
        Number of vertices of each polygon; ``None`` (or empty) for a point cloud.
    flat : ndarray of int, shape (counts.sum(),), or None
        The polygons' vertex indices, concatenated, already converted to 0-based.
    base : int
        Index base of the file format (0 or 1), only used in error messages.
    vertex_file, face_file : str
        Files the vertices and the faces were read from (used in messages).
    vertex_lines, face_lines : sequence of int, optional
        1-based line number of each vertex / polygon in its file (text formats).
    """

    vertices: np.ndarray
    counts: np.ndarray | None
    flat: np.ndarray | None
    base: int
    vertex_file: str
    face_file: str
    vertex_lines: Sequence[int] | None = None
    face_lines: Sequence[int] | None = None


# --------------------------------------------------------------------------- text helpers
def _decode(data: bytes) -> str:
    return data.decode("utf-8", errors="replace")


_OTHER_LINE_BREAKS = "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_LINE_BREAK = re.compile(r"\r\n|\r|\n")


def _split_lines(text: str) -> list[str]:
    """Lines ended by ``\\n``, ``\\r\\n`` or ``\\r``, as an editor numbers them
    (``str.splitlines`` also breaks at form feeds, ``\\x1c``, ``\\u2028``...)."""
    if not any(c in text for c in _OTHER_LINE_BREAKS):  # (8 scans beat one regex 10 times)
        return text.splitlines()
    return _LINE_BREAK.split(text)


def _content_lines(text: str, comment: str | None = "#") -> tuple[list[str], list[int]]:
    """Lines with comments stripped and blank lines dropped, plus their 1-based numbers."""
    lines = _split_lines(text)
    if comment is not None and comment in text:
        lines = [ln.partition(comment)[0] for ln in lines]
    nums = [i for i, ln in enumerate(lines, 1) if ln and not ln.isspace()]
    content = lines if len(nums) == len(lines) else [lines[i - 1] for i in nums]
    return content, nums


def _loadtxt(rows: list[str], dtype=np.float64) -> np.ndarray | None:
    """``numpy.loadtxt`` on whitespace-separated rows, or ``None`` if they are irregular.

    Its C parser reads ASCII decimal literals only (no ``1_000``, no non-ASCII digits) and
    skips blank rows: callers compare the row count."""
    if not any(map(str.strip, rows)):  # (loadtxt would warn: no data)
        return None
    try:
        return np.loadtxt(rows, dtype=dtype, ndmin=2, comments=None)
    except (ValueError, OverflowError):
        return None


def _int_or_none(tok: str) -> int | None:
    """The integer a token spells (``"3.0"`` too), or ``None`` (``"3.5"``, ``"nan"``,
    ``"1_000"``...). Magnitudes beyond :data:`_MAX_INDEX` come back as +-``_MAX_INDEX``."""
    if _INT_RE.fullmatch(tok):
        if len(tok) < 18:
            return int(tok)
        return -_MAX_INDEX if tok[0] == "-" else _MAX_INDEX
    if _FLOAT_RE.fullmatch(tok):
        f = float(tok)
        if f.is_integer():  # False for nan and inf
            return int(max(min(f, _MAX_INDEX), -_MAX_INDEX))
    return None


def _float_rows(rows: list[str], nums: Sequence[int], name: str, what: str, ncols: int,
                exact: bool, fields: Sequence[str] = _XYZ_FIELDS) -> np.ndarray:
    """Parse ``rows`` of at least (or, if ``exact``, exactly) ``ncols`` numbers; first ``ncols``.

    Every token must be a number (extra values are read, then ignored); ``fields`` name the
    columns in messages."""
    a = _loadtxt(rows)
    if a is not None and a.shape[0] == len(rows) and (
            a.shape[1] == ncols if exact else a.shape[1] >= ncols):
        a = a[:, :ncols]
    else:
        a = np.empty((len(rows), ncols))
        for r, (row, line) in enumerate(zip(rows, nums)):
            toks = row.split()
            for c, tok in enumerate(toks):
                if not _is_float(tok):
                    raise _err(name, f"line {line}: non-numeric value {_q(tok)} in {what}, "
                                     f"{_field(fields, c)}")
            if len(toks) < ncols or (exact and len(toks) != ncols):
                raise _err(name, f"line {line}: {what} needs {'exactly ' if exact else ''}"
                                 f"{ncols} values, found {len(toks)}: {_q(row)}")
            a[r] = [float(t) for t in toks[:ncols]]
    _check_overflow(a, rows, nums, name, what, fields)
    return a


def _check_overflow(a: np.ndarray, rows: list[str], nums: Sequence[int], name: str, what: str,
                    fields: Sequence[str]) -> None:
    """Refuse a finite literal that overflowed to infinity (``1e400``). ``inf``/``nan``
    literals pass here and are refused as coordinates by :func:`_finish`."""
    inf = np.isinf(a)
    if not inf.any():
        return
    r, c = (int(x[0]) for x in np.nonzero(inf))
    tok = rows[r].split()[c]
    if tok.lstrip("+-").lower() not in ("inf", "infinity"):
        raise _err(name, f"line {nums[r]}: {what}, {_field(fields, c)}: {_q(tok)} overflows "
                         "float64 (largest finite value about 1.8e308)")


def _polygon_rows(rows: list[str], nums: Sequence[int], name: str, *, counted: bool,
                  base: int) -> tuple[np.ndarray, np.ndarray]:
    """Parse face rows into ``(counts, flat)`` 0-based indices.

    ``counted``: OFF/PLY style ``k i1 .. ik [extra values ignored]``; otherwise every row is
    exactly three indices (TOSCA ``.tri``).
    """
    m = len(rows)
    a = _loadtxt(rows)
    if a is not None and a.shape[0] == m:
        # columns holding indices (OFF/PLY rows may end with colour values, ignored)
        idx = None
        if counted:
            k0 = a[0, 0]
            if np.all(a[:, 0] == k0) and 3 <= k0 < a.shape[1] and float(k0).is_integer():
                idx = a[:, 1:int(k0) + 1]
        elif a.shape[1] == 3:
            idx = a
        if idx is not None and np.all(np.abs(idx) < _MAX_INDEX) and np.all(idx == np.round(idx)):
            return np.full(m, idx.shape[1], np.int64), (idx.astype(np.int64) - base).ravel()
    # slow path: mixed polygon sizes, or an error to locate
    counts = np.empty(m, np.int64)
    flat: list[int] = []
    for r, (row, line) in enumerate(zip(rows, nums)):
        toks = row.split()
        plain = row.isascii() and "_" not in row  # then int() reads exactly what _INT_RE does
        if counted:
            try:
                k = int(toks[0]) if plain else _int_or_none(toks[0])
            except ValueError:
                k = _int_or_none(toks[0])
            if k is None:
                raise _err(name, f"line {line}: face vertex count {_q(toks[0])} is not an "
                                 "integer")
            if k < 3:
                raise _err(name, f"line {line}: a face needs at least 3 vertices, found {k}")
            if len(toks) < k + 1:
                raise _err(name, f"line {line}: face announces {k} vertices but lists only "
                                 f"{len(toks) - 1}: {_q(row)}")
            idx = toks[1:k + 1]
            if len(toks) > k + 1:
                bad = next((t for t in toks[k + 1:] if not _is_float(t)), None)
                if bad is not None:
                    raise _err(name, f"line {line}: non-numeric value {_q(bad)} after the "
                                     f"face's {k} vertex indices")
        else:
            if len(toks) != 3:
                raise _err(name, f"line {line}: a triangle needs exactly 3 vertex indices, "
                                 f"found {len(toks)}: {_q(row)}")
            idx, k = toks, 3
        try:
            ids = [int(t) for t in idx] if plain else None
        except ValueError:
            ids = None
        if ids is None or min(ids) <= -_MAX_INDEX or max(ids) >= _MAX_INDEX:
            ids = []
            for t in idx:
                i = _int_or_none(t)
                if i is None:
                    raise _err(name, f"line {line}: vertex index {_q(t)} is not an integer")
                if abs(i) >= _MAX_INDEX:
                    raise _err(name, f"line {line}: vertex index {_q(t)} is out of range")
                ids.append(i)
        flat.extend(ids)
        counts[r] = k
    flat_a = np.asarray(flat, dtype=np.int64)
    return counts, flat_a - base if base else flat_a


def _repr_rows(v: np.ndarray, prefix: str = "") -> str:
    """One ``x y z`` line per row, floats in shortest round-trip (``repr``) form."""
    return "".join(f"{prefix}{x!r} {y!r} {z!r}\n" for x, y, z in v.tolist())


def _int_rows(f: np.ndarray, prefix: str = "") -> str:
    return "".join(f"{prefix}{a} {b} {c}\n" for a, b, c in f.tolist())


def _truncated(name: str, what: str, expected: int, found: int, total: str) -> MeshFormatError:
    return _err(name, f"file is truncated: {total} but only {found} of the {expected} {what} "
                      "lines are present")


# --------------------------------------------------------------------------- OFF
_OFF_HEADER = re.compile(r"(ST)?C?N?OFF")


def _parse_off(data: bytes, name: str) -> RawShape:
    content, nums = _content_lines(_decode(data))
    if not content:
        raise _err(name, "file is empty (no data besides comments and blank lines)")
    head = content[0].split()
    kw = head[0]
    if not _OFF_HEADER.fullmatch(kw):
        if kw.endswith("OFF") and kw[:-3] and set(kw[:-3]) <= set("STCN4n"):
            raise _err(name, f"unsupported OFF variant {_q(kw)} (only 3-D OFF is read)")
        raise _err(name, f"bad header: expected 'OFF' on line {nums[0]}, "
                         f"found {_q(content[0])}")
    if len(head) > 1 and head[1].upper() == "BINARY":
        raise _err(name, "binary OFF is not supported; convert it to text OFF, PLY or STL")
    i = 1
    counts_toks, counts_line = head[1:], nums[0]
    if not counts_toks:
        if len(content) < 2:
            raise _err(name, "bad header: file ends after 'OFF', the vertex/face counts are "
                             "missing")
        counts_toks, counts_line, i = content[1].split(), nums[1], 2
    cnt = [int(t) for t in counts_toks] if all(_COUNT_RE.fullmatch(t) and len(t) <= 18
                                               for t in counts_toks) else []
    if len(cnt) not in (2, 3):
        raise _err(name, f"bad header: line {counts_line} should hold 'n_vertices n_faces "
                         f"[n_edges]' (non-negative integers), found {_q(' '.join(counts_toks))}")
    nv, nf = cnt[0], cnt[1]
    if nv == 0:
        raise _err(name, "header announces 0 vertices: the file holds no shape")
    total = f"the header announces {nv} vertices and {nf} faces"
    have = len(content) - i
    if have < nv:
        raise _truncated(name, "vertex", nv, have, total)
    if have < nv + nf:
        raise _truncated(name, "face", nf, have - nv, total)
    if have > nv + nf:
        raise _err(name, f"{total} but the file has {have - nv - nf} more non-comment lines "
                         f"(first at line {nums[i + nv + nf]}); wrong counts in the header?")
    vrows, vnums = content[i:i + nv], nums[i:i + nv]
    vertices = _float_rows(vrows, vnums, name, "vertex", 3, exact=False)
    frows, fnums = content[i + nv:], nums[i + nv:]
    counts, flat = _polygon_rows(frows, fnums, name, counted=True, base=0) if nf else (None, None)
    return RawShape(vertices, counts, flat, 0, name, name, vnums, fnums)


def _format_off(shape: PointCloud, name: str) -> bytes:
    v = shape.vertices
    f = shape.faces if isinstance(shape, Mesh) else np.empty((0, 3), np.int64)
    return (f"OFF\n{len(v)} {len(f)} 0\n" + _repr_rows(v) + _int_rows(f, "3 ")).encode()


# --------------------------------------------------------------------------- OBJ
_OBJ_IGNORED = {"vt", "vn", "vp", "g", "o", "s", "usemtl", "mtllib", "l", "p", "cstype", "deg",
                "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp",
                "end", "con", "mg", "bevel", "c_interp", "d_interp", "lod", "maplib", "usemap",
                "shadow_obj", "trace_obj", "ctech", "stech"}


# a face's vertex reference: v, v/vt, v//vn or v/vt/vn (only v is read)
_OBJ_REF = re.compile(r"([+-]?+\d++)(?:/[+-]?+\d*+){0,2}+", re.ASCII)


def _parse_obj(data: bytes, name: str) -> RawShape:
    content, nums = _content_lines(_decode(data))
    if not content:
        raise _err(name, "file is empty (no data besides comments and blank lines)")
    vrows: list[str] = []
    vnums: list[int] = []
    frows: list[str] = []
    fnums: list[int] = []
    fseen: list[int] = []  # vertices defined before each face (for negative indices)
    unknown: dict[str, int] = {}
    for row, line in zip(content, nums):
        kw, *more = row.split(None, 1)
        rest = more[0] if more else ""
        if kw == "v":
            vrows.append(rest)
            vnums.append(line)
        elif kw == "f":
            frows.append(rest)
            fnums.append(line)
            fseen.append(len(vrows))
        elif kw not in _OBJ_IGNORED:
            unknown.setdefault(kw, line)
    if not vrows:
        hint = f" (first unknown statement {_q(next(iter(unknown))[:20])} at line " \
               f"{next(iter(unknown.values()))})" if unknown else ""
        raise _err(name, f"no vertices: the file has no 'v' lines; is it really OBJ?{hint}")
    if unknown:
        logger.debug("%s: ignored %d kinds of OBJ statements, e.g. %s", name, len(unknown),
                     [_q(k) for k in sorted(unknown)[:5]])
    vertices = _float_rows(vrows, vnums, name, "vertex", 3, exact=False)
    if not frows:
        return RawShape(vertices, None, None, 1, name, name, vnums, None)
    # fast path: plain 'f a b c' rows with positive indices and equal sizes (loadtxt skips
    # blank rows: an empty 'f' line leaves it one row short, and goes to the slow path)
    if not any("/" in r or "-" in r for r in frows):
        a = _loadtxt(frows, np.int64)
        if a is not None and a.shape[0] == len(frows) and a.shape[1] >= 3 and a.min() > 0:
            return RawShape(vertices, np.full(len(a), a.shape[1], np.int64), (a - 1).ravel(),
                            1, name, name, vnums, fnums)
    counts = np.empty(len(frows), np.int64)
    flat: list[int] = []
    for r, (row, line, seen) in enumerate(zip(frows, fnums, fseen)):
        toks = row.split()
        if len(toks) < 3:
            raise _err(name, f"line {line}: a face needs at least 3 vertices, found {len(toks)}")
        for tok in toks:
            ref = _OBJ_REF.fullmatch(tok)
            if ref is None:
                raise _err(name, f"line {line}: vertex reference {_q(tok)} is not an "
                                 "integer (or v/vt/vn integers)")
            i = _int_or_none(ref.group(1))
            if abs(i) >= _MAX_INDEX:
                raise _err(name, f"line {line}: vertex index {_q(ref.group(1))} is out of range")
            if i == 0:
                raise _err(name, f"line {line}: vertex index 0 is invalid (OBJ indices start at 1)")
            if i < 0:
                if seen + i < 0:
                    raise _err(name, f"line {line}: relative vertex index {i} points before the "
                                     f"first vertex (only {seen} vertices defined so far)")
                flat.append(seen + i)
            else:
                flat.append(i - 1)
        counts[r] = len(toks)
    return RawShape(vertices, counts, np.asarray(flat, np.int64), 1, name, name, vnums, fnums)


def _format_obj(shape: PointCloud, name: str) -> bytes:
    out = "# written by gromov\n" + _repr_rows(shape.vertices, "v ")
    if isinstance(shape, Mesh):
        out += _int_rows(shape.faces + 1, "f ")
    return out.encode()


# --------------------------------------------------------------------------- PLY
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}
_PLY_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int",
              "u4": "uint", "f4": "float", "f8": "double"}
_STRUCT = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "f4": "f", "f8": "d"}


@dataclass
class _PlyProp:
    name: str
    dtype: str               # item type ("f4", "i4", ...)
    count_dtype: str | None  # list length type, None for a scalar property


@dataclass
class _PlyElement:
    name: str
    count: int
    props: list[_PlyProp]


def _prop(el: _PlyElement, p: _PlyProp) -> str:
    """``'vertex' property 'x'``, for messages."""
    return f"{_q(el.name)} property {_q(p.name)}"


def _ply_total(elements: list[_PlyElement]) -> str:
    """``"42 vertex, 80 face"``: the header's record counts, for messages (at most 4 named)."""
    text = ", ".join(f"{e.count} {e.name[:20]}" for e in elements[:4])
    return text + (f" and {len(elements) - 4} more elements" if len(elements) > 4 else "")


def _ply_header(data: bytes, name: str) -> tuple[str, list[_PlyElement], int]:
    first = data[:4]
    if first != b"ply\n" and data[:5] != b"ply\r\n":
        raise _err(name, f"bad header: a PLY file starts with 'ply', found {data[:10]!r}")
    end = re.search(rb"^end_header[ \t]*\r?$", data, re.MULTILINE)
    if end is None:
        raise _err(name, "bad header: no 'end_header' line (file truncated in its header?)")
    body = data.find(b"\n", end.end())
    body = len(data) if body < 0 else body + 1
    lines = _split_lines(data[:end.start()].decode("ascii", errors="replace"))
    fmt = None
    elements: list[_PlyElement] = []
    for ln, raw in enumerate(lines[1:], 2):
        toks = raw.split()
        if not toks or toks[0] in ("comment", "obj_info"):
            continue

        def bad(why: str = "") -> MeshFormatError:
            return _err(name, f"bad header line {ln}: {_q(raw)}{why}")

        if toks[0] == "format":
            if len(toks) != 3 or toks[1] not in ("ascii", "binary_little_endian",
                                                  "binary_big_endian"):
                raise bad()
            fmt = toks[1]
        elif toks[0] == "element":
            if len(toks) != 3 or not _COUNT_RE.fullmatch(toks[2]) or len(toks[2]) > 18:
                raise bad(" (expected 'element NAME COUNT')")
            if any(e.name == toks[1] for e in elements):
                raise bad(f": element {_q(toks[1])} declared twice")
            elements.append(_PlyElement(toks[1], int(toks[2]), []))
        elif toks[0] == "property":
            if not elements:
                raise bad(" (a property before any element)")
            el = elements[-1]
            if len(toks) == 3 and toks[1] in _PLY_TYPES:
                prop = _PlyProp(toks[2], _PLY_TYPES[toks[1]], None)
            elif len(toks) == 5 and toks[1] == "list" and toks[2] in _PLY_TYPES \
                    and toks[3] in _PLY_TYPES and _PLY_TYPES[toks[2]][0] in "iu":
                prop = _PlyProp(toks[4], _PLY_TYPES[toks[3]], _PLY_TYPES[toks[2]])
            else:
                raise bad()
            if any(p.name == prop.name for p in el.props):
                raise bad(f": property {_q(prop.name)} declared twice in element {_q(el.name)}")
            el.props.append(prop)
        else:
            raise bad()
    if fmt is None:
        raise _err(name, "bad header: no 'format' line")
    empty = next((e for e in elements if e.count and not e.props), None)
    if empty is not None:
        raise _err(name, f"bad header: element {_q(empty.name)} has {empty.count} records but "
                         "no properties")
    return fmt, elements, body


# A decoded element: property name -> scalar column, or (counts, flat) for a list property.
_Columns = dict[str, "np.ndarray | tuple[np.ndarray, np.ndarray]"]


def _ply_ascii_generic(rows, nums, el: _PlyElement, name: str) -> _Columns:
    scal: dict[str, list[float]] = {p.name: [] for p in el.props if p.count_dtype is None}
    lists: dict[str, tuple[list[int], list[float]]] = {
        p.name: ([], []) for p in el.props if p.count_dtype is not None}
    for row, line in zip(rows, nums):
        toks = row.split()
        pos = 0
        for p in el.props:
            if pos >= len(toks):
                raise _err(name, f"line {line}: the {_q(el.name)} record ends before property "
                                 f"{_q(p.name)}: {_q(row)}")
            tok = toks[pos]
            if p.count_dtype is None:
                if not _is_float(tok):
                    raise _err(name, f"line {line}: non-numeric value {_q(tok)} in "
                                     f"{_prop(el, p)}")
                scal[p.name].append(float(tok))
                pos += 1
                continue
            k = _int_or_none(tok)
            if k is None or k < 0:
                raise _err(name, f"line {line}: {_prop(el, p)}: list length {_q(tok)} is not a "
                                 "non-negative integer")
            items = toks[pos + 1:pos + 1 + k]
            if len(items) < k:
                raise _err(name, f"line {line}: {_prop(el, p)}: the list announces {k} values "
                                 f"but the record has only {len(items)} after it")
            bad = next((t for t in items if not _is_float(t)), None)
            if bad is not None:
                raise _err(name, f"line {line}: non-numeric value {_q(bad)} in {_prop(el, p)}")
            lists[p.name][0].append(k)
            lists[p.name][1].extend(float(t) for t in items)
            pos += 1 + k
        if pos != len(toks):
            raise _err(name, f"line {line}: {_q(el.name)} record has {len(toks) - pos} extra "
                             f"values: {_q(row)}")
    cols: _Columns = {k: np.asarray(v, np.float64) for k, v in scal.items()}
    cols.update({k: (np.asarray(c, np.int64), np.asarray(f, np.float64))
                 for k, (c, f) in lists.items()})
    return cols


def _ply_ascii(body: bytes, elements: list[_PlyElement], name: str, header_lines: int,
               wanted: set[str]) -> tuple[dict[str, _Columns], dict[str, list[int]]]:
    content, nums = _content_lines(_decode(body), comment=None)
    nums = [n + header_lines for n in nums]
    out: dict[str, _Columns] = {}
    lines_of: dict[str, list[int]] = {}
    pos = 0
    total = _ply_total(elements)
    for el in elements:
        rows, rnums = content[pos:pos + el.count], nums[pos:pos + el.count]
        if len(rows) < el.count:
            raise _err(name, f"file is truncated: the header announces {total} records but only "
                             f"{len(rows)} of the {el.count} {_q(el.name)} lines are present")
        pos += el.count
        if el.name not in wanted or el.count == 0:
            continue
        lines_of[el.name] = rnums
        nlist = sum(p.count_dtype is not None for p in el.props)
        if nlist == 0:
            a = _float_rows(rows, rnums, name, f"{_q(el.name)} record", len(el.props),
                            exact=True, fields=[f"property {_q(p.name)}" for p in el.props])
            out[el.name] = {p.name: a[:, j] for j, p in enumerate(el.props)}
            continue
        if nlist == 1 and el.props[0].count_dtype is not None and el.name == "face":
            a = _loadtxt(rows)
            if a is not None and a.shape[0] == len(rows):
                k = a[:, 0]
                if np.isfinite(k[0]) and np.all(k == k[0]) \
                        and a.shape[1] == k[0] + len(el.props):
                    counts, flat = _polygon_rows(rows, rnums, name, counted=True, base=0)
                    cols = {el.props[0].name: (counts, flat)}
                    cols.update({p.name: a[:, -len(el.props) + j]
                                 for j, p in enumerate(el.props) if j})
                    out[el.name] = cols
                    continue
        out[el.name] = _ply_ascii_generic(rows, rnums, el, name)
    if pos < len(content):
        raise _err(name, f"the header announces {total} records but the file has "
                         f"{len(content) - pos} more lines (first at line {nums[pos]})")
    return out, lines_of


def _ply_fit(values: np.ndarray, dtype: str) -> np.ndarray:
    """Mask of the values (read as text) that do not fit the PLY type ``dtype``: NaN,
    fractions or out-of-range values for an integer type; finite values beyond float32 for
    ``float``."""
    v = np.asarray(values)
    if dtype[0] in "iu":
        info = np.iinfo(dtype)
        with np.errstate(invalid="ignore"):
            ok = (v >= info.min) & (v <= info.max)
            if v.dtype.kind == "f":
                ok &= v == np.round(v)
        return ~ok
    if dtype == "f4" and v.dtype.kind == "f":
        with np.errstate(over="ignore"):
            return np.isfinite(v) & ~np.isfinite(v.astype(np.float32))
    return np.zeros(v.shape, bool)


def _ply_type_text(dtype: str) -> str:
    if dtype[0] in "iu":
        info = np.iinfo(dtype)
        return f"{_PLY_NAMES[dtype]} (integers {info.min}..{info.max})"
    return f"{_PLY_NAMES[dtype]} (float32, magnitude up to 3.4e38)"


def _num_text(x: float) -> str:
    x = float(x)
    return str(int(x)) if x.is_integer() and abs(x) < 1e16 else repr(x)


def _ply_check_types(cols: _Columns, el: _PlyElement, lines: Sequence[int], name: str) -> None:
    """Refuse text values that do not fit their declared type (``nan`` or ``300`` in a
    ``uchar`` property) before anything casts them: a cast would wrap them silently."""
    for p in el.props:
        col = cols[p.name]
        if p.count_dtype is None:
            checks = [(col, p.dtype, "", lambda i: i)]
        else:
            counts, flat = col
            ends = np.cumsum(counts)
            checks = [(counts, p.count_dtype, " list length", lambda i: i),
                      (flat, p.dtype, "",
                       lambda i, ends=ends: int(np.searchsorted(ends, i, side="right")))]
        for values, dtype, what, record in checks:
            bad = _ply_fit(values, dtype)
            if bad.any():
                i = int(np.argmax(bad))
                raise _err(name, f"line {lines[record(i)]}: {_prop(el, p)}{what} holds "
                                 f"{_num_text(values[i])}, which does not fit its type "
                                 f"{_ply_type_text(dtype)}")


def _ply_binary(body: bytes, elements: list[_PlyElement], endian: str, name: str,
                wanted: set[str]) -> dict[str, _Columns]:
    out: dict[str, _Columns] = {}
    off = 0
    total = _ply_total(elements)
    trunc = _err(name, f"file is truncated: the header announces {total} records but the "
                       "binary data ends early")

    def negative(p: _PlyProp, k: int) -> MeshFormatError:
        return _err(name, f"{_prop(el, p)}: negative list length {k}")

    for el in elements:
        if el.count == 0:
            continue
        lists = [p for p in el.props if p.count_dtype is not None]
        # fast path: fixed layout (no lists, or every list as long as in the first record)
        fields, pos = [], off
        try:
            for j, p in enumerate(el.props):
                if p.count_dtype is None:
                    fields.append((f"p{j}", endian + p.dtype))
                    pos += np.dtype(p.dtype).itemsize
                else:
                    (k,) = struct.unpack_from(endian + _STRUCT[p.count_dtype], body, pos)
                    if k < 0:
                        raise negative(p, k)
                    fields.append((f"n{j}", endian + p.count_dtype))
                    fields.append((f"p{j}", endian + p.dtype, (k,)))
                    pos += np.dtype(p.count_dtype).itemsize + k * np.dtype(p.dtype).itemsize
        except struct.error:
            raise trunc from None
        if pos > len(body):
            raise trunc
        arr = None
        try:
            dt = np.dtype(fields)
        except ValueError:  # a record too large for a numpy dtype: read record by record
            dt = None
        if dt is not None and off + el.count * dt.itemsize <= len(body):
            arr = np.frombuffer(body, dt, el.count, off)
            if any(np.any(arr[f"n{j}"] != arr[f"n{j}"][0])
                   for j, p in enumerate(el.props) if p.count_dtype is not None):
                arr = None
        if arr is not None:
            off += el.count * dt.itemsize
            if el.name in wanted:
                cols: _Columns = {}
                for j, p in enumerate(el.props):
                    if p.count_dtype is None:
                        cols[p.name] = arr[f"p{j}"]
                    else:
                        k = arr[f"p{j}"].shape[1] if arr[f"p{j}"].ndim == 2 else 1
                        cols[p.name] = (np.full(el.count, k, np.int64),
                                        arr[f"p{j}"].reshape(el.count, -1).ravel())
                out[el.name] = cols
            continue
        if not lists:
            raise trunc
        # slow path: variable-length lists, record by record
        scal: dict[str, list] = {p.name: [] for p in el.props if p.count_dtype is None}
        lst: dict[str, tuple[list[int], list]] = {p.name: ([], []) for p in lists}
        fmts = {p.name: (struct.Struct(endian + _STRUCT[p.dtype]),
                         None if p.count_dtype is None else
                         struct.Struct(endian + _STRUCT[p.count_dtype])) for p in el.props}
        try:
            for _ in range(el.count):
                for p in el.props:
                    item, cnt = fmts[p.name]
                    if cnt is None:
                        scal[p.name].append(item.unpack_from(body, off)[0])
                        off += item.size
                    else:
                        (k,) = cnt.unpack_from(body, off)
                        if k < 0:
                            raise negative(p, k)
                        off += cnt.size
                        if off + k * item.size > len(body):
                            raise trunc
                        vals = struct.unpack_from(f"{endian}{k}{_STRUCT[p.dtype]}", body, off)
                        off += k * item.size
                        lst[p.name][0].append(k)
                        lst[p.name][1].extend(vals)
        except struct.error:
            raise trunc from None
        if el.name in wanted:
            cols = {k: np.asarray(v) for k, v in scal.items()}
            cols.update({k: (np.asarray(c, np.int64), np.asarray(f)) for k, (c, f) in lst.items()})
            out[el.name] = cols
    extra = body[off:]
    if extra.strip():
        raise _err(name, f"the header announces {total} records but {len(extra)} bytes of data "
                         "follow them; wrong counts in the header?")
    return out


def _parse_ply(data: bytes, name: str) -> RawShape:
    fmt, elements, body = _ply_header(data, name)
    by_name = {e.name: e for e in elements}
    vert = by_name.get("vertex")
    if vert is None or vert.count == 0:
        raise _err(name, "the PLY file has no vertices (no or empty 'vertex' element)")
    have = [p.name for p in vert.props if p.count_dtype is None]
    if not {"x", "y", "z"} <= set(have):
        raise _err(name, f"the 'vertex' element lacks x, y, z properties (has "
                         f"{_q(', '.join(have))})")
    face = by_name.get("face")
    index_prop = None
    if face is not None and face.count:
        index_prop = next((p.name for p in face.props if p.count_dtype is not None
                           and p.name in ("vertex_indices", "vertex_index")), None)
        if index_prop is None:
            raise _err(name, "the 'face' element has no 'vertex_indices' list property")
    wanted = {"vertex", "face"}
    vlines = flines = None
    if fmt == "ascii":
        header_lines = data[:body].count(b"\n")
        cols, lines_of = _ply_ascii(data[body:], elements, name, header_lines, wanted)
        vlines, flines = lines_of.get("vertex"), lines_of.get("face")
        for el in (vert, face if index_prop else None):
            if el is not None:
                _ply_check_types(cols[el.name], el, lines_of[el.name], name)
    else:
        cols = _ply_binary(data[body:], elements, "<" if fmt == "binary_little_endian" else ">",
                           name, wanted)
    vc = cols["vertex"]
    # ASCII values (checked to fit) are cast to the declared type, so ASCII and binary PLY
    # read alike
    decl = {p.name: p.dtype for p in vert.props}
    vertices = np.column_stack([np.asarray(vc[c]).astype(decl[c]).astype(np.float64)
                                for c in "xyz"])
    if index_prop is None:
        return RawShape(vertices, None, None, 0, name, name, vlines, None)
    counts, flat = cols["face"][index_prop]
    if len(counts) and counts.min() < 3:
        bad = int(np.argmax(counts < 3))
        where = f"line {flines[bad]}" if flines else f"face {bad}"
        raise _err(name, f"{where}: a face needs at least 3 vertices, found {int(counts[bad])}")
    flat = np.asarray(flat)
    if flat.dtype.kind == "f":
        whole = np.isfinite(flat) & (flat == np.round(flat)) & (np.abs(flat) < _MAX_INDEX)
        if not whole.all():
            i = int(np.argmax(~whole))
            face_i = int(np.searchsorted(np.cumsum(counts), i, side="right"))
            where = f"line {flines[face_i]}" if flines else f"face {face_i}"
            raise _err(name, f"{where}: vertex index {_num_text(flat[i])} is not an integer")
    return RawShape(vertices, counts, flat.astype(np.int64), 0, name, name, vlines, flines)


def _format_ply(shape: PointCloud, name: str) -> bytes:
    v = np.ascontiguousarray(shape.vertices, dtype="<f8")
    head = ["ply", "format binary_little_endian 1.0", "comment written by gromov",
            f"element vertex {len(v)}", "property double x", "property double y",
            "property double z"]
    out = [v.tobytes()]
    if isinstance(shape, Mesh):
        head += [f"element face {shape.n_faces}", "property list uchar int vertex_indices"]
        rec = np.empty(shape.n_faces, np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
        rec["n"] = 3
        rec["i"] = shape.faces
        out.append(rec.tobytes())
    return ("\n".join(head + ["end_header"]) + "\n").encode("ascii") + b"".join(out)


# --------------------------------------------------------------------------- STL
_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _parse_stl(data: bytes, name: str) -> RawShape:
    n_bin = struct.unpack_from("<I", data, 80)[0] if len(data) >= 84 else -1
    if n_bin >= 0 and len(data) == 84 + 50 * n_bin:
        corners = np.frombuffer(data, _STL_RECORD, n_bin, 84)["v"].reshape(-1, 3)
    elif data.lstrip()[:5].lower() == b"solid":
        corners = _parse_stl_ascii(data, name)
    elif n_bin >= 0:
        raise _err(name, f"binary STL of wrong size: the header announces {n_bin} triangles "
                         f"({84 + 50 * n_bin} bytes) but the file has {len(data)} bytes "
                         "(truncated?)")
    else:
        raise _err(name, f"not an STL file: {len(data)} bytes is too short for binary STL and "
                         "it does not start with 'solid'")
    if len(corners) == 0:
        raise _err(name, "the STL file holds no triangles")
    # STL has no shared vertices: merge identical corners, numbered by first appearance
    uniq, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    with np.errstate(invalid="ignore"):  # NaN bit patterns in damaged files: caught later
        vertices = np.asarray(uniq[order], np.float64)
    flat = rank[inverse.reshape(-1)].astype(np.int64)
    logger.debug("%s: merged %d STL corners into %d vertices", name, len(corners), len(vertices))
    return RawShape(vertices, np.full(len(flat) // 3, 3, np.int64), flat, 0, name, name)


def _parse_stl_ascii(data: bytes, name: str) -> np.ndarray:
    """Corners ``(3m, 3)`` of an ASCII STL file: one or more ``solid [name]`` ...
    ``endsolid [name]`` blocks of facets, keywords in any case. Checked token by token
    against the grammar (no fixed-width token array: a megabyte-long token costs nothing)."""
    low = data.lower()
    marks = _stl_solid_lines(low)
    bodies: list[tuple[int, int]] = []
    prev, start = 0, None
    for line_start, line_end, is_end in marks:
        if not is_end:
            if start is not None:
                raise _err(name, f"line {_line_at(low, line_start)}: 'solid' inside a solid "
                                 "(no 'endsolid' before it)")
            gap = low[prev:line_start]
            if gap.strip():
                where = prev + len(gap) - len(gap.lstrip())
                raise _err(name, f"line {_line_at(low, where)}: unexpected text "
                                 f"{_q(_token_at(data, where))} "
                                 + ("after 'endsolid'" if bodies else "before 'solid'"))
            start = line_end
        else:
            if start is None:
                raise _err(name, f"line {_line_at(low, line_start)}: 'endsolid' without a "
                                 "'solid' before it")
            bodies.append((start, line_start))
            start = None
        prev = line_end
    tail = low[prev:]
    if start is not None or not marks:
        toks = low.split()
        n_facet, n_end = toks.count(b"facet"), toks.count(b"endfacet")
        raise _err(name, f"ASCII STL is truncated or malformed: {n_facet} 'facet', {n_end} "
                         f"'endfacet' and {toks.count(b'vertex')} 'vertex' statements, no final "
                         "'endsolid'")
    if tail.strip():
        where = prev + len(tail) - len(tail.lstrip())
        raise _err(name, f"line {_line_at(low, where)}: unexpected text "
                         f"{_q(_token_at(data, where))} after the last 'endsolid'")
    corners = []
    for s, e in bodies:
        body = low[s:e]
        if _STL_FACETS.fullmatch(body) is None:
            _stl_locate_error(data, low, s, e, name)
        toks = body.split()  # the grammar matched: 21 tokens a facet
        if toks:
            cols = [toks[j::len(_STL_GRAMMAR)] for j in _STL_COORDS]
            corners.append(np.array(cols, dtype=np.float64).T.reshape(-1, 3))
    if not corners:
        return np.empty((0, 3))
    corners = np.concatenate(corners)
    inf = np.isinf(corners)
    if inf.any():  # an overflowing literal (1e400): find it and say so
        _stl_locate_error(data, low, *bodies[0], name, overflow=True)
        for s, e in bodies[1:]:
            _stl_locate_error(data, low, s, e, name, overflow=True)
    return corners


_STL_NUM = rb"[+-]?+(?:(?:\d++(?:\.\d*+)?+|\.\d++)(?:e[+-]?+\d++)?+|infinity|inf|nan)"
_STL_COORDS = (8, 9, 10, 12, 13, 14, 16, 17, 18)  # where the corners' coordinates are
# the tokens of one facet, and what each must be (a keyword, or a number naming its field)
_STL_GRAMMAR: tuple[bytes | str, ...] = (
    b"facet", b"normal", "normal x", "normal y", "normal z", b"outer", b"loop",
    *(t for c in (1, 2, 3) for t in (b"vertex", f"vertex {c} x", f"vertex {c} y",
                                     f"vertex {c} z")),
    b"endloop", b"endfacet")
_STL_FACET = re.compile(rb"\s*" + rb"\s+".join(
    re.escape(t) if isinstance(t, bytes) else b"(" + _STL_NUM + b")" for t in _STL_GRAMMAR)
    + rb"(?=\s|$)")
_STL_FACETS = re.compile(rb"(?:" + _STL_FACET.pattern + rb")*+\s*")
_STL_NUM_RE = re.compile(_STL_NUM)


def _stl_solid_lines(low: bytes) -> list[tuple[int, int, bool]]:
    """``(start, end, is_endsolid)`` of each line of ``low`` whose first word is ``solid`` or
    ``endsolid`` (``end`` before the line's newline; a name may follow the keyword)."""
    out = []
    pos = 0
    while (i := low.find(b"solid", pos)) >= 0:
        pos = i + 5
        is_end = low[max(i - 3, 0):i] == b"end"
        first = i - 3 if is_end else i
        line_start = low.rfind(b"\n", 0, first) + 1
        if low[line_start:first].strip() or not (pos == len(low) or low[pos:pos + 1].isspace()):
            continue  # not the line's first word, or a longer word ("solidx")
        line_end = low.find(b"\n", pos)
        pos = line_end = len(low) if line_end < 0 else line_end
        out.append((line_start, line_end, is_end))
    return out


def _line_at(data: bytes, pos: int) -> int:
    return data.count(b"\n", 0, pos) + 1


def _token_at(data: bytes, pos: int) -> bytes:
    m = re.compile(rb"\S+").match(data, pos)
    return m.group() if m else b""


def _stl_locate_error(data: bytes, low: bytes, s: int, e: int, name: str,
                      overflow: bool = False) -> None:
    """Raise the error of the first facet of ``low[s:e]`` that breaks the grammar (or, with
    ``overflow``, whose coordinate overflows float64), naming its line and field."""
    pos = s
    while True:
        m = _STL_FACET.match(low, pos, e)
        if m is None:
            break
        if overflow:
            for j, g in enumerate(m.groups()):
                if np.isinf(float(g)) and g.lstrip(b"+-") not in (b"inf", b"infinity"):
                    field = [t for t in _STL_GRAMMAR if isinstance(t, str)][j]
                    raise _err(name, f"line {_line_at(low, m.start(j + 1))}: {field}: "
                                     f"{_q(g)} overflows float64 (largest finite value about "
                                     "1.8e308)")
        pos = m.end()
    if overflow:
        return
    toks = list(re.compile(rb"\S+").finditer(low, pos, e))[:len(_STL_GRAMMAR) + 1]
    for want, tok in zip(_STL_GRAMMAR, toks):
        t = tok.group()
        if isinstance(want, bytes) and t != want:
            raise _err(name, f"line {_line_at(low, tok.start())}: expected {want.decode()!r}, "
                             f"found {_q(data[tok.start():tok.end()])}")
        if isinstance(want, str) and not _STL_NUM_RE.fullmatch(t):
            raise _err(name, f"line {_line_at(low, tok.start())}: non-numeric vertex coordinate "
                             f"{_q(data[tok.start():tok.end()])} ({want})"
                       if want.startswith("vertex") else
                       f"line {_line_at(low, tok.start())}: non-numeric {want} "
                       f"{_q(data[tok.start():tok.end()])}")
    if not toks or len(toks) > len(_STL_GRAMMAR):  # not reached: the grammar would match
        raise _err(name, f"line {_line_at(low, pos)}: malformed facet")
    missing = _STL_GRAMMAR[len(toks)]
    missing = missing.decode() if isinstance(missing, bytes) else f"a number ({missing})"
    raise _err(name, f"line {_line_at(low, toks[0].start())}: facet ends early: expected "
                     f"{missing!s} before 'endsolid'")


def _format_stl(shape: PointCloud, name: str) -> bytes:
    if not isinstance(shape, Mesh):
        raise _err(name, "STL stores triangles only; it cannot hold a point cloud "
                         "(use .ply, .off or .obj)")
    rec = np.zeros(shape.n_faces, _STL_RECORD)
    rec["normal"] = shape.face_normals
    rec["v"] = shape.vertices[shape.faces]
    return b"binary STL written by gromov".ljust(80, b" ") + \
        struct.pack("<I", shape.n_faces) + rec.tobytes()


# --------------------------------------------------------------------------- TOSCA .vert/.tri
def _tosca_paths(path: Path, ext: str, gz: bool) -> tuple[Path, Path]:
    """``(vert, tri)`` paths of the pair that ``path`` belongs to."""
    suffix = f".{ext}" + (".gz" if gz else "")
    stem = path.name[:-len(suffix)] if path.name.lower().endswith(suffix) else \
        path.name.removesuffix(".gz").rpartition(".")[0] or path.name
    other = "tri" if ext == "vert" else "vert"
    # the partner's extension in the case of this file's (cat0.VERT beside cat0.TRI), else any
    # case, gzipped or not as this file, else the other way
    own = path.name[len(stem) + 1:]
    upper = own.removesuffix(".gz").removesuffix(".GZ").isupper()
    want = [other.upper() if upper else other, other]
    names = [f"{stem}.{e}{z}" for z in ((".gz", ".GZ", "") if gz else ("", ".gz", ".GZ")) for e in want]
    partner = next((path.with_name(nm) for nm in names if path.with_name(nm).exists()), None)
    if partner is None:
        ok = {other, other + ".gz"}
        try:
            found = sorted(q for q in path.parent.iterdir() if q.name.startswith(stem + ".")
                           and q.name[len(stem) + 1:].lower() in ok)
        except OSError:
            found = []
        partner = found[0] if found else path.with_name(names[0])
    return (path, partner) if ext == "vert" else (partner, path)


def _read_tosca(path: Path, gz: bool, ext: str) -> RawShape:
    vpath, tpath = _tosca_paths(path, ext, gz)
    partner = tpath if ext == "vert" else vpath
    if not partner.exists():
        raise MeshFileNotFoundError(
            f"{path}: partner file {partner} not found (a TOSCA mesh is a .vert/.tri pair "
            "with the same name)")
    vname, tname = str(vpath), str(tpath)
    vdata = _read_bytes(vpath, vpath.name.lower().endswith(".gz"))
    vrows, vnums = _content_lines(_decode(vdata))
    if not vrows:
        raise _err(vname, "file is empty: a .vert file needs one 'x y z' line per vertex")
    vertices = _float_rows(vrows, vnums, vname, "vertex", 3, exact=True)
    tdata = _read_bytes(tpath, tpath.name.lower().endswith(".gz"), allow_empty=True)
    trows, tnums = _content_lines(_decode(tdata))
    if not trows:
        logger.info("%s: no triangles, reading %s as a point cloud", tname, vname)
        return RawShape(vertices, None, None, 1, vname, tname, vnums, None)
    counts, flat = _polygon_rows(trows, tnums, tname, counted=False, base=1)
    return RawShape(vertices, counts, flat, 1, vname, tname, vnums, tnums)


# --------------------------------------------------------------------------- XYZ
_BLANK_BETWEEN_VALUES = re.compile(r"[^\s,]\s+[^\s,]")
_EMPTY_FIELD = re.compile(r"^,|,\s*,")  # a missing value would shift the columns


def _parse_xyz(data: bytes, name: str) -> RawShape:
    rows, nums = _content_lines(_decode(data))
    if not rows:
        raise _err(name, "file is empty: an .xyz file needs one 'x y z' line per point")
    commas = [k for k, row in enumerate(rows) if "," in row]
    if commas:
        # commas separate values only where blanks do not (a line "1,5 2,25 3,0" has decimal commas)
        both = next((k for k in commas if _BLANK_BETWEEN_VALUES.search(rows[k].strip())), None)
        if both is not None:
            raise _err(name, f"line {nums[both]}: both commas and blanks between values "
                             f"({_q(rows[both])}): decimal commas are not supported; separate "
                             "values by blanks or by commas, with decimal points")
        empty = next((k for k in commas if _EMPTY_FIELD.search(rows[k].strip())), None)
        if empty is not None:
            raise _err(name, f"line {nums[empty]}: empty value between commas "
                             f"({_q(rows[empty])})")
        rows = [row.replace(",", " ") for row in rows]
    return RawShape(_float_rows(rows, nums, name, "point", 3, exact=False), None, None, 0, name, name,
                    nums, None)


def _format_xyz(shape: PointCloud, name: str) -> bytes:
    if isinstance(shape, Mesh):
        raise _err(name, "an .xyz file holds points only and would lose the mesh's faces; save a "
                         "mesh as .ply, .off or .obj, or its points as PointCloud(mesh.vertices)")
    return _repr_rows(shape.vertices).encode()


def _write_tosca(shape: PointCloud, path: Path, gz: bool, ext: str) -> None:
    if not isinstance(shape, Mesh):
        raise _err(str(path), "a .vert/.tri pair needs triangles; save a point cloud as .ply, "
                              ".off or .obj")
    vpath, tpath = _tosca_paths(path, ext, gz)
    _write_bytes(vpath, _repr_rows(shape.vertices).encode(), gz)
    _write_bytes(tpath, _int_rows(shape.faces + 1).encode(), gz)


# --------------------------------------------------------------------------- MATLAB .mat
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
# the 116-byte text at the start of a version 5 MAT-file; scipy writes the current time
# there, a fixed text makes the files we write reproducible byte for byte
_MAT_HEADER = b"MATLAB 5.0 MAT-file, written by gromov".ljust(116, b" ")
_MAT_XYZ = ("X", "Y", "Z")


def _mat_v73(name: str) -> MeshFormatError:
    return _err(name, "MATLAB v7.3 MAT-file (HDF5), which scipy.io.loadmat cannot read; "
                      "re-save it in MATLAB with save(..., '-v7') or convert it to .off/.ply")


def _shape_str(a: np.ndarray) -> str:
    return " x ".join(map(str, a.shape)) if a.ndim else "scalar"


def _mat_struct(value) -> tuple[dict, int] | None:
    """``(fields of the first element, number of elements)`` if ``value`` is a MATLAB struct
    as ``loadmat(..., struct_as_record=False)`` gives it (a ``mat_struct``, or an object
    array of them), else ``None``."""
    if hasattr(value, "_fieldnames"):  # scipy.io.matlab.mat_struct
        return {f: getattr(value, f) for f in value._fieldnames}, 1
    if not isinstance(value, np.ndarray) or value.size == 0:
        return None
    if value.dtype == object and all(hasattr(x, "_fieldnames") for x in value.flat):
        fields, _ = _mat_struct(value.reshape(-1)[0])
        return fields, value.size
    return None


def _mat_numbers(value, name: str, what: str) -> np.ndarray:
    """``value`` as a real numeric array, or a MeshFormatError saying what it holds."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        return value
    if isinstance(value, np.ndarray):
        kind = {"U": "text", "S": "text", "c": "complex numbers", "b": "logical values"}.get(
            value.dtype.kind, "a cell array or struct")
    elif hasattr(value, "tocsr"):
        kind = "a sparse matrix"
    elif _mat_struct(value) is not None:
        kind = "a struct"
    else:
        kind = f"a {type(value).__name__}"
    raise _err(name, f"{what} holds {kind}, not real numbers")


# Version 5 MAT-file element types that scipy's reader has a dtype for: a numeric or
# character data element of any other type (0, 8, 10, 11, 14, 15, 19...) makes scipy 1.17
# index past its table of dtypes and crash the interpreter (a segmentation fault; scipy
# pull requests 25349 and 25829).
_MI_DATA = frozenset({1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18})
_MI_MATRIX, _MI_COMPRESSED = 14, 15
_MX_NUMERIC = frozenset(range(6, 16))   # mxDOUBLE_CLASS .. mxUINT64_CLASS
_MX_CELL, _MX_STRUCT, _MX_OBJECT, _MX_CHAR, _MX_SPARSE = 1, 2, 3, 4, 5
_MAT_MAX_DEPTH = 32


class _MatMalformed(Exception):
    pass


def _mat_check(data: bytes, name: str) -> None:
    """Walk the element tags of a version 5 MAT-file (not its data) and refuse, before
    scipy reads it, what would crash scipy: a data element of a type it has no dtype for,
    nesting deeper than 32 levels; and a compressed variable over the decompression limit.
    Other files (version 4, HDF5) are left to scipy."""
    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        return
    e = "<" if data[126:128] == b"IM" else ">"
    if struct.unpack_from(e + "H", data, 124)[0] != 0x0100:  # not version 5 (7.3: HDF5)
        return
    try:
        _mat_walk(data, 128, len(data), e, name)
    except _MatMalformed as exc:
        raise _err(name, f"not a readable MATLAB MAT-file ({exc})") from None


def _mat_tag(buf: bytes, pos: int, end: int, e: str) -> tuple[int, int, int, int, bool]:
    """``(type, byte count, data start, next element, small)`` of the element at ``pos``."""
    if pos + 8 > end:
        raise _MatMalformed(f"element at byte {pos} is cut short")
    (w,) = struct.unpack_from(e + "I", buf, pos)
    if w >> 16:  # small data element: type and count in 4 bytes, data in the next 4
        if w >> 16 > 4:
            raise _MatMalformed(f"element at byte {pos} has a bad small-element size")
        return w & 0xFFFF, w >> 16, pos + 4, pos + 8, True
    (n,) = struct.unpack_from(e + "I", buf, pos + 4)
    if pos + 8 + n > end:
        raise _MatMalformed(f"element at byte {pos} ({n} bytes) runs past its container")
    return w, n, pos + 8, pos + 8 + n, False


def _mat_walk(buf: bytes, pos: int, end: int, e: str, name: str, depth: int = 0) -> None:
    """Check the variables in ``buf[pos:end]`` (each an array, or a compressed one)."""
    while pos + 8 <= end:
        mdtype, n, start, nxt, small = _mat_tag(buf, pos, end, e)
        if mdtype == _MI_COMPRESSED and not small and depth == 0:
            limit, default = _decompression_limit(n)
            try:
                inner = zlib.decompressobj().decompress(buf[start:start + n], limit + 1)
            except zlib.error as exc:
                raise _MatMalformed(f"bad compressed variable at byte {pos}: "
                                    f"{_cut(str(exc))}") from None
            if len(inner) > limit:
                raise _over_limit(name, f"a compressed variable (byte {pos})", limit, default, n)
            _mat_walk(inner, 0, len(inner), e, name, depth + 1)
        elif mdtype != _MI_MATRIX or small:
            raise _MatMalformed(f"element at byte {pos} should be a variable (an array), but "
                                f"has type {mdtype}")
        elif n:
            _mat_matrix(buf, start, start + n, e, 0)
        pos = nxt  # scipy seeks to the next variable, unpadded


def _mat_matrix(buf: bytes, pos: int, end: int, e: str, depth: int) -> None:
    """Check one array: its elements tile ``buf[pos:end]``, every data element has a type
    scipy has a dtype for, and the array holds exactly the data elements scipy reads in turn
    (with fewer, scipy would read the next array's tag as data)."""
    if depth > _MAT_MAX_DEPTH:
        raise _MatMalformed(f"arrays nested more than {_MAT_MAX_DEPTH} levels deep")
    if pos + 16 > end:
        raise _MatMalformed(f"array at byte {pos} is cut short")
    (flags,) = struct.unpack_from(e + "I", buf, pos + 8)  # scipy reads these 16 bytes as is
    mclass, is_complex = flags & 0xFF, flags >> 11 & 1
    subs = []
    p = pos + 16
    while p < end:
        mdtype, n, start, nxt, small = _mat_tag(buf, p, end, e)
        subs.append((p, mdtype, n, start, small))
        p = nxt if small else start + -(-n // 8) * 8
    head = {_MX_OBJECT: 5, _MX_STRUCT: 4}.get(mclass, 2)  # dims, name [, class, name length, names]
    expected = ({_MX_CHAR: 1, _MX_SPARSE: 3 + is_complex}.get(mclass, 1 + is_complex)
                if mclass in _MX_NUMERIC or mclass in (_MX_CHAR, _MX_SPARSE) else None)
    if mclass not in _MX_NUMERIC and mclass not in (_MX_CHAR, _MX_SPARSE, _MX_CELL, _MX_STRUCT,
                                                     _MX_OBJECT):
        raise _MatMalformed(f"array at byte {pos} is of MATLAB class {mclass}, which gromov "
                            "does not read (numbers, characters, cells and structs only)")
    if len(subs) < head or (expected is not None and len(subs) != head + expected):
        raise _MatMalformed(f"array at byte {pos} holds {len(subs)} elements, which does not "
                            f"fit its class {mclass}")
    for i, (p, mdtype, n, start, small) in enumerate(subs):
        if expected is not None or i < head:
            if mdtype not in _MI_DATA:
                raise _MatMalformed(f"data element at byte {p} has unknown type {mdtype}")
        elif mdtype != _MI_MATRIX or small:
            raise _MatMalformed(f"element at byte {p} should be a cell or field (an array), "
                                f"but has type {mdtype}")
        elif n:
            _mat_matrix(buf, start, start + n, e, depth + 1)


def _parse_mat(data: bytes, name: str) -> RawShape:
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    if data[:8] == _HDF5_SIGNATURE or data[512:520] == _HDF5_SIGNATURE:
        raise _mat_v73(name)
    _mat_check(data, name)
    try:
        # squeeze_me=False keeps shapes ((n, 1) columns, a 1 x 3 TRIV); structs come as
        # object arrays of mat_struct
        content = loadmat(BytesIO(data), squeeze_me=False, struct_as_record=False)
    except NotImplementedError:  # scipy's answer to a v7.3 header
        raise _mat_v73(name) from None
    # what scipy raises on damaged or foreign files (UnboundLocalError: a scipy bug on some
    # truncated files; MemoryError: a corrupted array size)
    except (MatReadError, OSError, UnboundLocalError, MemoryError, ArithmeticError,
            *_PARSE_ERRORS) as exc:
        raise _err(name, f"not a readable MATLAB MAT-file "
                         f"({_library_error(exc, (MatReadError,))})") from None
    variables = {k: v for k, v in content.items() if not k.startswith("__")}
    found: list[tuple[str, dict]] = []    # (label, fields) with X, Y and Z
    partial: list[tuple[str, dict]] = []  # with some of X, Y, Z, TRIV
    for var, value in variables.items():
        struct_ = _mat_struct(value)
        if struct_ is None:
            continue
        fields, size = struct_
        if not set(fields) & {*_MAT_XYZ, "TRIV"}:
            continue
        if size != 1:
            raise _err(name, f"variable {var!r} is a {_shape_str(value)} struct array; expected "
                             "a single struct with fields X, Y, Z and TRIV")
        (found if set(_MAT_XYZ) <= set(fields) else partial).append((f"struct {var!r}", fields))
    top = {k: variables[k] for k in (*_MAT_XYZ, "TRIV") if k in variables}
    if top:
        (found if set(_MAT_XYZ) <= set(top) else partial).append(("top-level variables", top))
    if len(found) > 1:
        raise _err(name, f"{len(found)} meshes in one file ("
                         f"{', '.join(label for label, _ in found)}); keep only one")
    if not found:
        if partial:
            label, fields = partial[0]
            missing = [c for c in _MAT_XYZ if c not in fields]
            raise _err(name, f"{label} lack{'s' if label.startswith('struct') else ''} "
                             f"{', '.join(missing)} (found {', '.join(fields)}); a mesh needs X, "
                             "Y, Z coordinate vectors and optionally TRIV")
        held = ", ".join(repr(k) for k in variables) or "no variables"
        raise _err(name, "no mesh found: expected a struct (such as TOSCA's 'surface') with "
                         "fields X, Y, Z and optionally TRIV, or variables X, Y, Z [, TRIV]; "
                         f"the file holds {held}")
    label, fields = found[0]

    def what(field: str) -> str:
        return f"variable {field!r}" if label.startswith("top") else f"field {field!r} of {label}"

    coords = []
    for c in _MAT_XYZ:
        a = _mat_numbers(fields[c], name, what(c))
        if a.ndim > 2 or (a.ndim == 2 and min(a.shape) > 1):
            raise _err(name, f"{what(c)} must be a vector (one coordinate per vertex), got a "
                             f"{_shape_str(a)} array")
        coords.append(a.reshape(-1).astype(np.float64))
    if len({len(c) for c in coords}) > 1:
        where = "the top-level variables" if label.startswith("top") else label
        raise _err(name, f"X, Y and Z of {where} have different lengths "
                         f"({', '.join(str(len(c)) for c in coords)})")
    vertices = np.column_stack(coords)
    triv = fields.get("TRIV")
    if triv is None:
        logger.debug("%s: no TRIV, reading a point cloud", name)
        return RawShape(vertices, None, None, 1, name, name)
    t = _mat_numbers(triv, name, what("TRIV"))
    if t.size == 0:
        logger.debug("%s: empty TRIV, reading a point cloud", name)
        return RawShape(vertices, None, None, 1, name, name)
    if t.ndim != 2 or t.shape[1] != 3:
        hint = " (transposed? TOSCA stores one triangle per row)" if t.ndim == 2 and \
            t.shape[0] == 3 else ""
        raise _err(name, f"{what('TRIV')} must be an m x 3 matrix of 1-based vertex indices, "
                         f"got a {_shape_str(t)} array{hint}")
    tf = t.astype(np.float64)
    bad = ~(np.isfinite(tf) & (tf == np.round(tf)) & (np.abs(tf) < 2**53)).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        k = int(bad.sum())
        raise _err(name, f"{what('TRIV')} holds non-integer vertex indices in {k} "
                         f"triangle{'s' if k > 1 else ''}, first triangle {i}: {tf[i].tolist()}")
    flat = tf.astype(np.int64).ravel() - 1
    return RawShape(vertices, np.full(len(t), 3, np.int64), flat, 1, name, name)


def _format_mat(shape: PointCloud, name: str) -> bytes:
    from scipy.io import savemat

    v = shape.vertices
    surface = {c: np.ascontiguousarray(v[:, j:j + 1]) for j, c in enumerate(_MAT_XYZ)}
    if isinstance(shape, Mesh):
        surface["TRIV"] = (shape.faces + 1).astype(np.float64)  # 1-based doubles, like TOSCA
    buf = BytesIO()
    savemat(buf, {"surface": surface}, format="5", do_compression=False, oned_as="column")
    return _MAT_HEADER + buf.getvalue()[len(_MAT_HEADER):]


# --------------------------------------------------------------------------- meshio formats
@dataclass(frozen=True)
class _MeshioFormat:
    module: str              # meshio submodule whose read()/write() handle the format
    label: str               # name in messages
    base: int                # index base of the file format (meshio converts to 0-based)
    write_options: tuple     # keyword arguments of the writer, as (key, value) pairs


_MESHIO = {
    "vtk": _MeshioFormat("vtk", "legacy VTK", 0, (("fmt_version", "4.2"), ("binary", True))),
    "vtu": _MeshioFormat("vtu", "VTK XML (.vtu)", 0, (("binary", True),
                                                      ("compression", "zlib"))),
    "msh": _MeshioFormat("gmsh", "Gmsh", 1, (("fmt_version", "4.1"), ("binary", True))),
    "mesh": _MeshioFormat("medit", "Medit", 1, (("float_fmt", ".16e"),)),
}
# meshio cell types read as faces, and prefixes of volume cell types (a volume mesh is refused)
_MESHIO_FACES = ("triangle", "quad", "polygon")
_MESHIO_VOLUME = ("tetra", "hexahedron", "wedge", "pyramid", "polyhedron")


def _import_meshio(name: str, verb: str, ext: str):
    try:
        import meshio
    except ImportError:
        raise MissingDependencyError(
            f'{name}: {verb} .{ext} files needs meshio, an optional dependency: '
            f'pip install "gromov[formats]"') from None
    return meshio


#: The file meshio is reading or writing for us, in this thread / context (None: not ours).
_MESHIO_FILE: contextvars.ContextVar[str | None] = contextvars.ContextVar("gromov_meshio_file", default=None)
_MESHIO_LOCK = threading.Lock()


@contextlib.contextmanager
def _meshio_warnings(meshio, name: str):
    """Turn meshio's warnings into :class:`GromovWarning` s naming the file while it reads or
    writes one for us. meshio prints them to stderr itself (``meshio._common.warn``, through
    rich), where ``warnings`` filters and logging cannot reach them, and each of its format
    modules holds its own reference to that function. Those references are replaced once, for
    good, by a forwarder that warns for the file named in a context variable (set here, for
    this thread or task only) and otherwise calls meshio's function as before -- so concurrent
    reads each name their own file, and meshio used elsewhere behaves as it always did."""
    _install_meshio_forwarder(meshio)
    token = _MESHIO_FILE.set(name)
    try:
        yield
    finally:
        _MESHIO_FILE.reset(token)


def _install_meshio_forwarder(meshio) -> None:
    import sys

    with _MESHIO_LOCK:
        original = getattr(meshio._common, "_gromov_original_warn", None)
        if original is None:
            original = meshio._common.warn

            def forward(string, highlight: bool = True) -> None:
                name = _MESHIO_FILE.get()
                if name is None:
                    original(string, highlight=highlight)
                else:
                    warnings.warn(f"{name}: meshio: {_cut(str(string))}", GromovWarning,
                                  stacklevel=2)

            meshio._common._gromov_original_warn = original
            meshio._common._gromov_forward = forward
        forward = meshio._common._gromov_forward
        # modules imported since (meshio imports its format modules lazily) get it too
        for key, module in list(sys.modules.items()):
            if (key == "meshio" or key.startswith("meshio.")) and getattr(module, "warn", None) is original:
                module.warn = forward


def _meshio_read_errors(meshio) -> tuple[type[BaseException], ...]:
    """What meshio's readers raise on malformed files (seen by fuzzing meshio 5.3)."""
    corrupt = getattr(getattr(meshio, "_exceptions", None), "CorruptionError", meshio.ReadError)
    return (meshio.ReadError, corrupt, AssertionError, MemoryError, OSError, *_PARSE_ERRORS)


def _read_meshio(path: Path, gz: bool, ext: str) -> RawShape:
    name = str(path)
    meshio = _import_meshio(name, "reading", ext)
    fmt = _MESHIO[ext]
    reader = getattr(meshio, fmt.module).read  # not meshio.read: it calls sys.exit on errors
    errors = _meshio_read_errors(meshio)

    def read(file: str):
        try:  # numpy's overflow/invalid warnings on damaged data: the result is checked
            with _meshio_warnings(meshio, name), np.errstate(all="ignore"):
                return reader(file)
        except errors as exc:
            own = (meshio.ReadError, *errors[1:2])
            raise _err(name, f"cannot read as {fmt.label} with meshio "
                             f"({_library_error(exc, own, file, name)})") from None

    if gz:  # meshio's readers want a file name: decompress into a temporary file
        data = _read_bytes(path, True)
        with tempfile.TemporaryDirectory(prefix="gromov-") as tmp:
            file = Path(tmp) / f"mesh.{ext}"
            file.write_bytes(data)
            m = read(str(file))
    else:
        if path.stat().st_size == 0:
            raise _err(name, "file is empty")
        m = read(name)
    pts = np.asarray(m.points)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise _err(name, f"points must have 2 or 3 coordinates, got an array of shape "
                         f"{pts.shape}")
    vertices = np.zeros((len(pts), 3))
    vertices[:, :pts.shape[1]] = pts  # 2-D points: z = 0
    counts, flat, ignored = [], [], {}
    for block in m.cells:
        d = np.asarray(block.data)
        if block.type in _MESHIO_FACES and d.ndim == 2 and d.shape[1] >= 3:
            counts.append(np.full(len(d), d.shape[1], np.int64))
            flat.append(d.astype(np.int64).ravel())
        else:
            ignored[block.type] = ignored.get(block.type, 0) + len(d)
    if ignored:
        logger.debug("%s: ignored %s cells %s", name, fmt.label, ignored)
    if not counts:
        volume = {t: k for t, k in ignored.items() if t.startswith(_MESHIO_VOLUME)}
        if volume:
            cells = ", ".join(f"{k} {t}" for t, k in volume.items())
            raise _err(name, f"volume meshes are not supported (the file has {cells} cells "
                             "and no triangles): extract the boundary surface first and save it "
                             "as a triangle mesh")
        higher = [t for t in ignored if t.startswith(("triangle", "quad"))]
        if higher:
            raise _err(name, f"second-order surface cells ({', '.join(higher)}) are not "
                             "supported; save the mesh with linear triangles")
        logger.debug("%s: %d points, no triangles: point cloud", name, len(vertices))
        return RawShape(vertices, None, None, fmt.base, name, name)
    return RawShape(vertices, np.concatenate(counts), np.concatenate(flat), fmt.base, name,
                    name)


def _write_meshio(shape: PointCloud, path: Path, gz: bool, ext: str) -> None:
    name = str(path)
    meshio = _import_meshio(name, "writing", ext)
    fmt = _MESHIO[ext]
    n = shape.n_vertices
    if isinstance(shape, Mesh):
        cells = [("triangle", shape.faces)]
    elif fmt.module == "medit":  # Medit has no vertex cells (meshio warns and skips them)
        cells = []
    else:  # VTU and Gmsh files need at least one cell
        cells = [("vertex", np.arange(n, dtype=np.int64)[:, None])]
    mesh = meshio.Mesh(shape.vertices, cells)
    writer = getattr(meshio, fmt.module).write
    if not gz:
        with _meshio_warnings(meshio, name), atomic_path(path) as tmp:
            writer(str(tmp), mesh, **dict(fmt.write_options))
        return
    with tempfile.TemporaryDirectory(prefix="gromov-") as tmp:
        file = Path(tmp) / f"mesh.{ext}"
        with _meshio_warnings(meshio, name):
            writer(str(file), mesh, **dict(fmt.write_options))
        _write_bytes(path, file.read_bytes(), True)


# --------------------------------------------------------------------------- bytes <-> files
#: Default limit on decompression: a ``.gz`` file may inflate to ``GZIP_RATIO`` times its
#: own size, and always to :data:`GZIP_FLOOR`. Meshes and point clouds compress 3 to 12
#: times (the 106 TOSCA and TOPKIDS ``.off.gz`` files: 2.8 to 3.6; gromov's icosphere,
#: torus and a 300 x 300 integer grid saved as OFF, OBJ, PLY, STL and XYZ: 2.9 to 11.7), a
#: gzip bomb about 1000 times, and parsing costs up to 0.2 s and 13 MB of memory per MB of
#: text (blank lines: ``gzip.compress(b"0 0 0\\n" + b"\\n" * 64_000_000)`` is a 62 KB
#: ``.xyz.gz`` that took 12.8 s and 0.84 GB to read without a limit). Past the limit the
#: read stops, having decompressed no more than the limit, with a
#: :class:`~gromov.errors.MeshFormatError`; ``load(..., max_decompressed=)`` and the CLI's
#: ``--max-decompressed`` set another limit.
from ._defaults import GZIP_RATIO  # noqa: E402
#: Files that decompress to at most this many bytes (16 MiB) are read whatever their ratio:
#: small files of repeated lines compress more than 100 times (100,000 points at the origin
#: saved as ``.xyz.gz``: 500 times), and parsing 16 MiB costs at most a few seconds.
from ._defaults import GZIP_FLOOR  # noqa: E402
_MAX_DECOMPRESSED: contextvars.ContextVar[int | None] = contextvars.ContextVar(
    "gromov_max_decompressed", default=None)
_GZIP_CHUNK = 16 * 2**20
_NON_BLANK = re.compile(rb"\S")


def _size_text(n: int) -> str:
    """``n`` bytes in binary units, as ``--max-decompressed`` reads them (``16 MiB``)."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"


def _decompression_limit(compressed: int) -> tuple[int, bool]:
    """``(limit in bytes, whether it is the default)`` for ``compressed`` bytes of data."""
    limit = _MAX_DECOMPRESSED.get()
    if limit is None:
        return max(GZIP_FLOOR, GZIP_RATIO * compressed), True
    return limit, False


def _over_limit(name: str, what: str, limit: int, default: bool, compressed: int
                ) -> MeshFormatError:
    if default:
        return _err(name, f"{what} decompresses to more than {_size_text(limit)}, the limit for "
                          f"{_size_text(compressed)} of compressed data ({GZIP_RATIO} times its "
                          f"size, at least {_size_text(GZIP_FLOOR)}: a gzip bomb?); if the file "
                          "is genuine, raise the limit with --max-decompressed SIZE "
                          "(max_decompressed= in gromov.load)")
    return _err(name, f"{what} decompresses to more than {_size_text(limit)}, the limit set by "
                      "--max-decompressed (max_decompressed= in gromov.load)")


def _gunzip(data: bytes, name: str) -> bytes:
    """Decompress gzip ``data`` (all members), streaming, stopping past the limit."""
    limit, default = _decompression_limit(len(data))
    chunks, total = [], 0
    try:
        with gzip.GzipFile(fileobj=BytesIO(data)) as f:
            while total <= limit:
                chunk = f.read(min(_GZIP_CHUNK, limit + 1 - total))
                if not chunk:
                    break
                chunks.append(chunk)
                total += len(chunk)
    except (OSError, EOFError, zlib.error) as exc:
        raise _err(name, f"bad gzip data ({_cut(str(exc))})") from None
    if total > limit:
        raise _over_limit(name, "the file", limit, default, len(data))
    return b"".join(chunks)


def _read_bytes(path: Path, gz: bool, *, allow_empty: bool = False) -> bytes:
    if path.is_dir():
        raise _err(str(path), "is a directory, not a mesh file")
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise MeshFileNotFoundError(f"{path}: no such file") from None
    except OSError as exc:
        raise _err(str(path), f"cannot read the file: {exc.strerror or exc}") from None
    if gz:
        if data[:2] != b"\x1f\x8b":
            raise _err(str(path), "bad gzip data: the name ends in .gz but the file is not "
                                  "gzip-compressed")
        data = _gunzip(data, str(path))
    if not allow_empty and _NON_BLANK.search(data) is None:
        raise _err(str(path), "file is empty" + (" after decompression" if gz else ""))
    return data


def _write_bytes(path: Path, data: bytes, gz: bool) -> None:
    if gz:
        data = gzip.compress(data, compresslevel=6, mtime=0)
    atomic_write_bytes(path, data)


def _bytes_reader(parse: Callable[[bytes, str], RawShape]) -> Callable[[Path, bool], RawShape]:
    def read(path: Path, gz: bool) -> RawShape:
        return parse(_read_bytes(path, gz), str(path))
    return read


def _bytes_writer(fmt: Callable[[PointCloud, str], bytes]
                  ) -> Callable[[PointCloud, Path, bool], None]:
    def write(shape: PointCloud, path: Path, gz: bool) -> None:
        _write_bytes(path, fmt(shape, str(path)), gz)
    return write


# --------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class FileFormat:
    """One entry of :data:`FORMATS`.

    Attributes
    ----------
    description : str
    read : callable ``(path: Path, gzipped: bool) -> RawShape``
        Reads the file (decompressing if ``gzipped``) into raw arrays; raises
        :class:`~gromov.errors.MeshFormatError` naming the file on any problem.
    write : callable ``(shape: PointCloud, path: Path, gzipped: bool) -> None``
    """

    description: str
    read: Callable[[Path, bool], RawShape]
    write: Callable[[PointCloud, Path, bool], None]


#: Extension (lower case, no dot, without ``.gz``) -> :class:`FileFormat`.
FORMATS: dict[str, FileFormat] = {
    "off": FileFormat("Object File Format, text", _bytes_reader(_parse_off),
                      _bytes_writer(_format_off)),
    "obj": FileFormat("Wavefront OBJ", _bytes_reader(_parse_obj), _bytes_writer(_format_obj)),
    "ply": FileFormat("Stanford PLY, ASCII or binary (written binary, float64)",
                      _bytes_reader(_parse_ply), _bytes_writer(_format_ply)),
    "stl": FileFormat("STL, ASCII or binary (written binary, float32)",
                      _bytes_reader(_parse_stl), _bytes_writer(_format_stl)),
    "vert": FileFormat("TOSCA .vert/.tri pair (1-based triangles)",
                       lambda p, gz: _read_tosca(p, gz, "vert"),
                       lambda s, p, gz: _write_tosca(s, p, gz, "vert")),
    "tri": FileFormat("TOSCA .vert/.tri pair (1-based triangles)",
                      lambda p, gz: _read_tosca(p, gz, "tri"),
                      lambda s, p, gz: _write_tosca(s, p, gz, "tri")),
    "xyz": FileFormat("XYZ point cloud, text (x y z per line)", _bytes_reader(_parse_xyz),
                      _bytes_writer(_format_xyz)),
    "mat": FileFormat("MATLAB v4-v7 MAT-file, TOSCA/SHREC struct with X, Y, Z and 1-based TRIV",
                      _bytes_reader(_parse_mat), _bytes_writer(_format_mat)),
    **{ext: FileFormat(f"{fmt.label} via meshio (optional: pip install \"gromov[formats]\")",
                       lambda p, gz, ext=ext: _read_meshio(p, gz, ext),
                       lambda s, p, gz, ext=ext: _write_meshio(s, p, gz, ext))
       for ext, fmt in _MESHIO.items()},
}


def _supported() -> str:
    return ", ".join("." + e for e in FORMATS) + " (each optionally followed by .gz)"


def _as_path(path) -> Path:
    try:
        return Path(os.fspath(path))
    except TypeError:
        raise TypeError(f"path must be a str or os.PathLike, got {type(path).__name__}") from None


def _resolve(path: Path, file_type: str | None) -> tuple[str, bool]:
    """``(format key, gzipped)`` from the file name, or from ``file_type`` when given."""
    name = path.name.lower()
    gz = name.endswith(".gz")
    if file_type is not None:
        ft = str(file_type).lower().lstrip(".")
        if ft.endswith(".gz") or ft == "gz":
            gz, ft = True, ft.removesuffix("gz").rstrip(".")
        if ft not in FORMATS:
            raise _err(str(path), f"unknown file_type {file_type!r}; supported: {_supported()}")
        return ft, gz
    stem = name[:-3] if gz else name
    ext = stem.rpartition(".")[2] if "." in stem else ""
    if ext not in FORMATS:
        got = f"extension '.{ext}'" if ext else "no extension"
        raise _err(str(path), f"unknown mesh format ({got}); supported: {_supported()}")
    return ext, gz


# --------------------------------------------------------------------------- validation
#: Largest coordinate magnitude read: the bound every Mesh and PointCloud holds
#: (:data:`gromov.mesh.COORDINATE_LIMIT`, where why is measured), checked here with the file's
#: line.
MAX_COORDINATE = COORDINATE_LIMIT


def _finish(raw: RawShape, name: str, repair: bool) -> Mesh | PointCloud:
    v = np.asarray(raw.vertices, np.float64)
    if v.shape[0] == 0:
        raise _err(raw.vertex_file, "the file holds no vertices")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        line = f" (line {raw.vertex_lines[i]})" if raw.vertex_lines is not None else ""
        raise _err(raw.vertex_file, f"{int(bad.sum())} vertices have NaN or infinite "
                                    f"coordinates, first vertex {i}{line}: {v[i].tolist()}")
    big = np.abs(v).max(axis=1) > MAX_COORDINATE
    if big.any():
        i = int(np.flatnonzero(big)[0])
        line = f" (line {raw.vertex_lines[i]})" if raw.vertex_lines is not None else ""
        raise _err(raw.vertex_file, f"{int(big.sum())} vertices have coordinates beyond "
                                    f"+-{MAX_COORDINATE:g}, first vertex {i}{line}: "
                                    f"{v[i].tolist()}; areas and their squares would overflow "
                                    "float64: scale the shape down")
    if raw.counts is None or len(raw.counts) == 0:
        logger.debug("%s: %d points, no faces: point cloud", name, len(v))
        return PointCloud(v)
    counts, flat = np.asarray(raw.counts, np.int64), np.asarray(raw.flat, np.int64)
    n = len(v)
    out = (flat < 0) | (flat >= n)
    if out.any():
        pos = int(np.argmax(out))
        face = int(np.searchsorted(np.cumsum(counts), pos, side="right"))
        line = f" (line {raw.face_lines[face]})" if raw.face_lines is not None else ""
        value = int(flat[pos]) + raw.base
        kind = "negative" if flat[pos] < 0 else "out-of-range"
        raise _err(raw.face_file, f"face {face}{line} has {kind} vertex index {value}: "
                                  f"valid indices are {raw.base}..{n - 1 + raw.base} "
                                  f"({n} vertices, {raw.base}-based); {int(out.sum())} bad "
                                  "indices in all")
    if np.all(counts == 3):
        tris = flat.reshape(-1, 3)
    else:
        tris = _fan(counts, flat)
        n_poly = int(np.count_nonzero(counts > 3))
        warnings.warn(f"{raw.face_file}: triangulated {n_poly} polygon(s) with more than 3 "
                      f"vertices as triangle fans ({len(counts)} faces -> {len(tris)} triangles)",
                      GromovWarning, stacklevel=3)
    try:
        shape = Mesh(v, tris)
        if repair:
            shape, _ = _mesh.repair(shape, source=name)
    except MeshFormatError:
        raise
    except MeshError as exc:
        raise _err(name, str(exc)) from None
    if logger.isEnabledFor(logging.INFO):
        nm = len(shape.nonmanifold_edges)
        if nm:
            logger.info("%s: %d non-manifold edges (kept)", name, nm)
        if shape.n_components > 1:
            logger.info("%s: %d connected components", name, shape.n_components)
    return shape


def _fan(counts: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """Fan triangulation ``(p0, pj, pj+1)`` of each polygon, polygons kept in order."""
    starts = np.cumsum(counts) - counts
    ntri = counts - 2
    poly = np.repeat(np.arange(len(counts)), ntri)
    j = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    s = starts[poly]
    return np.stack([flat[s], flat[s + j], flat[s + j + 1]], axis=1)


# --------------------------------------------------------------------------- public API
def load(path: str | os.PathLike, *, repair: bool = True, file_type: str | None = None,
         max_decompressed: int | None = None) -> Mesh | PointCloud:
    """Read a triangle mesh or point cloud from a file.

    Parameters
    ----------
    path : str or os.PathLike
        ``.off``, ``.obj``, ``.ply``, ``.stl``, ``.vert``, ``.tri``, ``.mat``, and with
        meshio installed ``.vtk``, ``.vtu``, ``.msh`` or ``.mesh`` (see :data:`FORMATS`),
        optionally gzip-compressed with a trailing ``.gz`` (``cat0.off.gz``). For a TOSCA
        pair, either ``cat0.vert`` or ``cat0.tri`` loads both files.
    repair : bool, default True
        Run :func:`gromov.mesh.repair` on the result: merge duplicate vertices, drop
        degenerate and repeated faces and unreferenced vertices, each with a
        :class:`~gromov.errors.GromovWarning`. The returned mesh's ``input_ids`` give, for
        each vertex, its 0-based index in the file. Non-manifold edges and multiple
        components are kept and only logged at INFO level.
    file_type : str, optional
        Format to use instead of the one implied by the extension, e.g. ``"off"`` or
        ``"off.gz"``. A name ending in ``.gz`` is always decompressed.
    max_decompressed : int, optional
        Largest size in bytes that a ``.gz`` file may decompress to. Default:
        :data:`GZIP_RATIO` (100) times the compressed size, and at least
        :data:`GZIP_FLOOR` (16 MiB): real meshes compress 3 to 12 times, gzip bombs about
        1000 times. Decompression streams and stops at the limit.

    Returns
    -------
    Mesh or PointCloud
        A :class:`~gromov.mesh.PointCloud` when the file has vertices but no faces.
        Vertices are in file order (``input_ids`` is ``arange(n)`` unless ``repair``
        removed something); polygons with more than 3 vertices are fan-triangulated with
        a :class:`~gromov.errors.GromovWarning`.

    Raises
    ------
    MeshFileNotFoundError
        The file, or the partner of a ``.vert``/``.tri`` file, does not exist (also a
        ``FileNotFoundError``).
    MissingDependencyError
        A ``.vtk``, ``.vtu``, ``.msh`` or ``.mesh`` file and meshio is not installed (also
        a ``MeshFormatError`` and an ``ImportError``).
    MeshFormatError
        Anything else wrong with the file: a directory, unknown extension, empty file,
        bad header, truncated data, non-numeric values, NaN/inf coordinates or ones that
        overflow float64 or exceed :data:`MAX_COORDINATE` (1e75), PLY values that do not fit their declared type, negative or
        out-of-range face indices, empty faces, bad gzip data or more than
        ``max_decompressed`` bytes of it, a MATLAB v7.3 file, a volume mesh, or no triangle
        left after repair. The message starts with the file name, says where the problem is
        and quotes at most 60 characters of the file.
    TypeError
        ``path`` is not a str or path-like, or ``max_decompressed`` not an int.
    ValueError
        ``max_decompressed`` is less than 1.

    Examples
    --------
    >>> cat = load("tosca/cat0.off.gz")                       # doctest: +SKIP
    >>> cat.n_vertices, cat.input_ids[:3]                     # doctest: +SKIP
    (27894, array([0, 1, 2]))
    """
    if max_decompressed is not None:
        if isinstance(max_decompressed, bool) or not isinstance(max_decompressed,
                                                                (int, np.integer)):
            raise TypeError(f"max_decompressed must be an int (bytes) or None, got "
                            f"{type(max_decompressed).__name__}")
        if max_decompressed < 1:
            raise ValueError(f"max_decompressed must be at least 1 byte, got {max_decompressed}")
        max_decompressed = int(max_decompressed)
    p = _as_path(path)
    key, gz = _resolve(p, file_type)
    if p.is_dir():
        raise _err(str(p), "is a directory, not a mesh file")
    if not p.exists():
        raise MeshFileNotFoundError(f"{p}: no such file")
    name = str(p)
    token = _MAX_DECOMPRESSED.set(max_decompressed)
    try:
        raw = FORMATS[key].read(p, gz)
        return _finish(raw, name, repair)
    except MeshFormatError:
        raise
    except MeshError as exc:
        raise _err(name, _cut(str(exc))) from None
    except _PARSE_ERRORS as exc:
        # a parser let a malformed detail through to numpy or struct: say what is wrong
        # with the file, not with the parser
        logger.debug("%s: %s: %s", name, type(exc).__name__, _cut(str(exc)))
        raise _err(name, f"cannot parse as {key.upper()}: malformed content") from None
    finally:
        _MAX_DECOMPRESSED.reset(token)


def save(shape: Mesh | PointCloud, path: str | os.PathLike, *,
         file_type: str | None = None) -> None:
    """Write a mesh or point cloud; the format follows the extension.

    Parameters
    ----------
    shape : Mesh or PointCloud
        Written with vertices and faces in their current order (``input_ids`` are not
        stored). Point clouds can be written in every format but STL and ``.vert``/``.tri``.
    path : str or os.PathLike
        Output file; a trailing ``.gz`` gzip-compresses it. ``x.vert`` or ``x.tri``
        writes both ``x.vert`` and ``x.tri`` (compressed alike).
    file_type : str, optional
        Format to use instead of the one implied by the extension.

    Notes
    -----
    Text formats (OFF, OBJ, ``.vert``) write coordinates in shortest round-trip
    (``repr``) form; PLY, ``.mat``, VTK, VTU and Gmsh write float64 and Medit 17
    significant digits, so :func:`load` gives back identical arrays. STL is written
    binary, float32, and has no vertex numbering: reading it back merges corners and
    numbers vertices by first appearance in the faces.

    Raises
    ------
    TypeError
        ``shape`` is not a :class:`~gromov.mesh.PointCloud`/:class:`~gromov.mesh.Mesh`.
    MissingDependencyError
        A meshio format (``.vtk``, ``.vtu``, ``.msh``, ``.mesh``) and meshio is not installed.
    MeshFormatError
        Unknown extension, or a point cloud given for a triangles-only format (STL,
        ``.vert``/``.tri``).
    OSError
        The file cannot be written.
    """
    if not isinstance(shape, PointCloud):
        raise TypeError(f"shape must be a gromov Mesh or PointCloud, got {type(shape).__name__}")
    p = _as_path(path)
    key, gz = _resolve(p, file_type)
    FORMATS[key].write(shape, p, gz)
    logger.debug("wrote %r to %s", shape, p)
