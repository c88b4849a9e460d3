"""A persistent on-disk store of per-shape work and of pair results.

A shape's working mesh, dense metric and the rest of what :class:`gromov.ShapeMetric`
computes once per shape are kept in one ``.npz`` file per shape and set of options (numpy's
documented format), catalogued in an SQLite database (``catalogue.sqlite``) that also records
pair results as they finish, so that work over a collection of shapes is done once and an
interrupted run continues where it stopped (:func:`gromov.experiments.gh_matrix`'s ``store``,
``gromov index``, ``gromov pairwise --store``, ``gromov match --store`` and
``gromov reproduce --store``).

Layout of a store folder::

    catalogue.sqlite         tables entries, pairs, extras, meta (WAL mode)
    entries/KEY-CHECKSUM.npz one per shape and options

An entry's key is the SHA-256 of its source's content (a file's bytes, or a shape's arrays),
the options that change the per-shape work (metric, its options, resolution, the ranking's
diffusion time) and the gromov version, so a changed file or option never finds stale data.
Every entry is checked against the SHA-256 of its file when read; a missing, truncated or
altered entry, or a file changed since it was indexed, is logged as a warning and the shape
is computed again. Files are written atomically (:mod:`gromov._atomic`) under names that
include their checksum, and a catalogue row is added only after its file is complete, so
processes killed at any point, or several writing the same store at once, leave it usable.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import inspect
import io
import json
import logging
import os
import sqlite3
import time
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._atomic import atomic_write_bytes
from ._defaults import DEFAULT_RESOLUTION
from ._version import __version__
from .errors import GromovError
from .gh import _match   # its parameters: what a pair is keyed by (match_options_key)
from .gmds import EmbeddedDistance
from .mesh import Mesh, PointCloud, as_shape
from .resolution import WorkingCloud, WorkingMesh
from .shape_metric import ShapeMetric

__all__ = ["CATALOGUE", "FORMAT", "PAIR_ARRAYS", "PairRecord", "ShapeStore", "StoreEntry", "StoreError",
           "file_sha256"]

logger = logging.getLogger(__name__)

#: Layout version of a store (the ``meta`` table's ``format``); part of every key.
FORMAT = 1
#: The catalogue's file name in a store folder.
CATALOGUE = "catalogue.sqlite"
#: Seconds a writer waits for another process's transaction on the catalogue.
BUSY_TIMEOUT = 120.0
#: The sample correspondence arrays of a recorded pair (:attr:`PairRecord.arrays`).
PAIR_ARRAYS = ("x_samples", "x_to_y_face", "x_to_y_bary", "x_to_y_vertex",
               "y_samples", "y_to_x_face", "y_to_x_bary", "y_to_x_vertex")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS entries (
    key TEXT PRIMARY KEY,
    path TEXT,
    content_hash TEXT NOT NULL,
    options TEXT NOT NULL,
    version TEXT NOT NULL,
    file TEXT NOT NULL,
    checksum TEXT NOT NULL,
    n_vertices INTEGER NOT NULL,
    bytes INTEGER NOT NULL,
    created REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS entries_path ON entries (path);
CREATE TABLE IF NOT EXISTS pairs (
    key TEXT PRIMARY KEY,
    x TEXT NOT NULL,
    y TEXT NOT NULL,
    options TEXT NOT NULL,
    version TEXT NOT NULL,
    distance REAL,
    relative_distance REAL,
    distortion_trimmed REAL,
    relative_trimmed REAL,
    ranking_distance REAL,
    arrays BLOB NOT NULL,
    seconds REAL,
    created REAL NOT NULL,
    signature_distortion REAL
);
CREATE TABLE IF NOT EXISTS extras (
    entry TEXT NOT NULL,
    name TEXT NOT NULL,
    arrays BLOB NOT NULL,
    created REAL NOT NULL,
    PRIMARY KEY (entry, name)
);
"""


class StoreError(GromovError, ValueError):
    """A folder is not a usable shape store (another format, or not a store at all)."""


@dataclass(frozen=True)
class StoreEntry:
    """One row of the catalogue's ``entries`` table: a shape's stored work.

    ``path``: the file's absolute path when it was indexed (None for a shape given as
    arrays); ``content_hash``: SHA-256 of the file's bytes (or of the arrays);
    ``options``: the per-shape options (JSON object); ``file``: the ``.npz`` file, relative
    to the store; ``checksum``: SHA-256 of its bytes; ``created``: seconds since the epoch.
    """

    key: str
    path: str | None
    content_hash: str
    options: dict
    version: str
    file: str
    checksum: str
    n_vertices: int
    bytes: int
    created: float


@dataclass(frozen=True)
class PairRecord:
    """A pair result recorded by :func:`gromov.experiments.gh_matrix` with a store: the
    :class:`gromov.MatchResult` fields of ``match(X, Y, orientation="ignore")``, X and Y the
    entries ``x`` and ``y``. ``arrays``: the sample correspondences (:data:`PAIR_ARRAYS`).
    ``signature_distortion``: NaN for a pair matched without spectral signatures (or recorded
    before the store kept it)."""

    key: str
    x: str
    y: str
    options: dict
    version: str
    distance: float
    relative_distance: float
    distortion_trimmed: float
    relative_trimmed: float
    ranking_distance: float
    arrays: dict
    seconds: float
    created: float
    signature_distortion: float = float("nan")


def _plain(obj):
    """``obj`` with numpy scalars and tuples made JSON's own types."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (np.generic, np.ndarray)):
        return _plain(obj.tolist()) if isinstance(obj, np.ndarray) else obj.item()
    return obj


def _dumps(obj) -> str:
    """Canonical JSON: sorted keys, no spaces (the text that is hashed into keys)."""
    return json.dumps(_plain(obj), sort_keys=True, separators=(",", ":"), allow_nan=True)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes, read in blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _arrays_sha256(shape: PointCloud, extra: dict | None = None) -> str:
    """SHA-256 of a shape's arrays (kind, dtype, shape and bytes of each; the file index where
    loading merged or dropped vertices), and of ``extra``."""
    h = hashlib.sha256()
    arrays = {"kind": np.array("mesh" if isinstance(shape, Mesh) else "cloud"), "vertices": shape.vertices,
              "input_ids": shape.input_ids}
    if isinstance(shape, Mesh):
        arrays["faces"] = shape.faces
    fi = shape.file_index
    if not (len(fi) == shape.n_vertices and np.array_equal(fi, np.arange(shape.n_vertices))):
        arrays["file_index"] = fi   # file vertices that loading merged or dropped (else not hashed:
        #                             the keys of shapes without any stay as they were)
    arrays.update(extra or {})
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


# ----------------------------------------------------------------------------- entry arrays
def _entry_arrays(s: ShapeMetric, rank_tau_scale: float | None) -> dict:
    """Everything a match reads of one shape, as named arrays (computing what is missing)."""
    inp, work = s.input, s.working
    out = {"format": np.int64(FORMAT), "kind": np.array("mesh" if s.has_faces else "cloud"),
           "metric": np.array(s.metric), "metric_options": np.array(_dumps(s.metric_options)),
           "input_vertices": inp.vertices, "input_ids": inp.input_ids, "file_index": inp.file_index,
           "working_vertices": s.mesh.vertices, "vertex_ids": work.vertex_ids,
           "source_nearest": work.source_nearest,
           "distances": s.distances, "diameter": np.float64(s.diameter), "finite": np.bool_(s.finite),
           "descriptors": s.descriptors}
    normals, orientable = s.normals
    out.update(normals=normals, orientable=np.bool_(orientable))
    if s.has_faces:
        out.update(input_faces=inp.faces, working_faces=s.mesh.faces, source_face=work.source_face,
                   source_bary=work.source_bary, source_residual=work.source_residual,
                   source_owner=work.source_owner)
    ranking = None if rank_tau_scale is None else s.ranking_surface(rank_tau_scale)
    if ranking is not None:
        out.update(ranking_tau_scale=np.float64(rank_tau_scale), ranking_embedding=ranking[0].embedding,
                   ranking_diameter=np.float64(ranking[1]))
    inner = getattr(s.solver, "inner", s.solver)   # through a hole-filling wrapper
    if getattr(inner, "_psi", None) is not None and inner.eigenvalues is not None:
        # a spectral metric's eigenpairs: other diffusion times and the dense maps' basis
        # (gromov.dense) are taken from them, as from a fresh shape's
        out.update(spectral_embedding=inner._psi, spectral_eigenvalues=inner.eigenvalues,
                   spectral_truncation_bound=np.float64(inner.truncation_bound))
        if getattr(inner, "_basis", None) is not None:
            out.update(spectral_basis_eigenvalues=inner._basis[0], spectral_basis=inner._basis[1])
    return out


def _shape_from_arrays(a: dict) -> ShapeMetric:
    """The :class:`ShapeMetric` whose caches hold the stored arrays: no metric is computed."""
    if int(a["format"]) != FORMAT:
        raise StoreError(f"entry format {int(a['format'])}, expected {FORMAT}")
    ids = a["input_ids"]
    file_index = a["file_index"] if "file_index" in a else None   # entries written before it
    vid = _readonly(a["vertex_ids"])
    if str(a["kind"]) == "mesh":
        inp = Mesh(a["input_vertices"], a["input_faces"], input_ids=ids, file_index=file_index)
        mesh = Mesh(a["working_vertices"], a["working_faces"], input_ids=ids[vid])
        working = WorkingMesh(mesh, inp, vid, *(_readonly(a[k]) for k in (
            "source_face", "source_bary", "source_nearest", "source_residual", "source_owner")))
    else:
        inp = PointCloud(a["input_vertices"], input_ids=ids, file_index=file_index)
        working = WorkingCloud(PointCloud(a["working_vertices"], input_ids=ids[vid]), inp, vid,
                               _readonly(a["source_nearest"]))
    s = ShapeMetric(inp, str(a["metric"]), metric_options=json.loads(str(a["metric_options"])),
                    working=working)
    d = a["distances"]
    if d.shape != (s.mesh.n_vertices,) * 2:
        raise StoreError(f"distances of shape {d.shape} for {s.mesh.n_vertices} working vertices")
    s.solver._pairwise = _readonly(d)
    s._diameter, s._finite = float(a["diameter"]), bool(a["finite"])
    s._descriptors = a["descriptors"]
    s._normals = (a["normals"], bool(a["orientable"]))
    if "ranking_embedding" in a:
        s._ranking[float(a["ranking_tau_scale"])] = (EmbeddedDistance(s.mesh, a["ranking_embedding"]),
                                                      float(a["ranking_diameter"]))
    if "spectral_embedding" in a:
        inner = getattr(s.solver, "inner", s.solver)
        psi = a["spectral_embedding"]
        if not hasattr(inner, "_psi") or len(psi) != inner.n_vertices:
            raise StoreError(f"a spectral embedding of {len(psi)} rows for a {type(inner).__name__} of "
                             f"{inner.n_vertices} vertices")
        inner._psi = _readonly(psi)
        inner.eigenvalues = a["spectral_eigenvalues"]
        inner.truncation_bound = float(a["spectral_truncation_bound"])
        if "spectral_basis" in a:
            inner._basis = (a["spectral_basis_eigenvalues"], a["spectral_basis"])
    return s


def _npz_bytes(arrays: dict) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _read_npz(data: bytes) -> dict:
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


# ----------------------------------------------------------------------------- the store
class ShapeStore:
    """A folder holding per-shape work (working mesh, metric...) and pair results.

    Parameters
    ----------
    root : str or os.PathLike
        The store's folder; created with its catalogue if it does not exist.
    load : callable, optional
        Reads a shape file, ``load(path) -> Mesh or PointCloud`` (default :func:`gromov.load`);
        called only for shapes that are not stored yet.

    Attributes
    ----------
    computed, reused : int
        Shapes this object computed and stored, and shapes it read back from the store.
    pairs_reused : int
        Pair results :func:`gromov.experiments.gh_matrix` took from the store.
    problems : list of str
        What was found wrong with stored entries (each also logged as a warning).

    Examples
    --------
    >>> store = ShapeStore("shapes.store")                                     # doctest: +SKIP
    >>> cats = store.shapes(["cat0.off", "cat1.off"], "diffusion")            # doctest: +SKIP
    >>> gromov.match(*cats).distance                                           # doctest: +SKIP
    """

    def __init__(self, root: str | os.PathLike, *, load=None):
        self.root = Path(root)
        if self.root.exists() and not self.root.is_dir():
            raise StoreError(f"{self.root} is not a folder")
        (self.root / "entries").mkdir(parents=True, exist_ok=True)
        self._load = load
        self._conn: sqlite3.Connection | None = None
        self._pid = -1
        self._inherited: list = []   # a forked worker's copies of its parent's connection
        self._keys: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self.computed = self.reused = self.pairs_reused = 0
        self.problems: list[str] = []
        self._db()   # create or check the catalogue now

    def __repr__(self) -> str:
        return f"ShapeStore({str(self.root)!r})"

    # ------------------------------------------------------------------ catalogue
    def _db(self) -> sqlite3.Connection:
        """This process's connection (a forked worker opens its own)."""
        if self._conn is None or self._pid != os.getpid():
            if self._conn is not None:   # never closed here: SQLite connections do not survive a fork
                self._inherited.append(self._conn)
            conn = sqlite3.connect(self.root / CATALOGUE, timeout=BUSY_TIMEOUT, isolation_level=None)
            deadline = time.monotonic() + BUSY_TIMEOUT
            while True:   # switching to WAL takes a lock that a busy handler does not always wait for
                try:
                    conn.execute("PRAGMA journal_mode=WAL")
                    break
                except sqlite3.OperationalError:
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.05)
            conn.execute("PRAGMA synchronous=NORMAL")
            with self._transaction(conn):
                for statement in _SCHEMA.split(";"):
                    if statement.strip():
                        conn.execute(statement)
                columns = [row[1] for row in conn.execute("PRAGMA table_info(pairs)")]
                if "signature_distortion" not in columns:   # a catalogue written before the column
                    conn.execute("ALTER TABLE pairs ADD COLUMN signature_distortion REAL")
                conn.execute("INSERT OR IGNORE INTO meta VALUES ('format', ?)", (str(FORMAT),))
                found = conn.execute("SELECT value FROM meta WHERE name = 'format'").fetchone()[0]
            if found != str(FORMAT):
                conn.close()
                raise StoreError(f"{self.root} is a store of format {found}; this gromov reads format {FORMAT}")
            self._conn, self._pid = conn, os.getpid()
        return self._conn

    @staticmethod
    @contextlib.contextmanager
    def _transaction(conn: sqlite3.Connection):
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield conn
        except BaseException:
            if conn.in_transaction:   # (SQLite may have rolled back already)
                conn.execute("ROLLBACK")
            raise
        conn.execute("COMMIT")

    def close(self) -> None:
        """Close this process's connection to the catalogue."""
        if self._conn is not None and self._pid == os.getpid():
            self._conn.close()
        self._conn = None

    def entries(self) -> list[StoreEntry]:
        """All entries of the catalogue, oldest first."""
        rows = self._db().execute("SELECT key, path, content_hash, options, version, file, checksum, "
                                  "n_vertices, bytes, created FROM entries ORDER BY created, key").fetchall()
        return [StoreEntry(r[0], r[1], r[2], json.loads(r[3]), *r[4:]) for r in rows]

    def pairs(self) -> list[PairRecord]:
        """All recorded pair results, oldest first."""
        rows = self._db().execute("SELECT key, x, y, options, version, distance, relative_distance, "
                                  "distortion_trimmed, relative_trimmed, ranking_distance, arrays, seconds, "
                                  "created, signature_distortion FROM pairs ORDER BY created, key").fetchall()
        return [PairRecord(r[0], r[1], r[2], json.loads(r[3]), r[4], *(_float(v) for v in r[5:10]),
                           _read_npz(r[10]), r[11], r[12], _float(r[13])) for r in rows]

    def verify(self) -> list[str]:
        """Check the catalogue (SQLite's integrity check) and every entry against its checksum.

        Returns
        -------
        list of str
            One line per problem; empty when the store is sound. Nothing is changed.
        """
        db = self._db()
        out = [f"catalogue: {r[0]}" for r in db.execute("PRAGMA integrity_check").fetchall() if r[0] != "ok"]
        for e in self.entries():
            data, reason = self._read(e.file, e.checksum)
            if reason is None:
                try:
                    _read_npz(data)
                except Exception as exc:   # noqa: BLE001 - any unreadable file is a problem to report
                    reason = f"cannot be read ({type(exc).__name__}: {exc})"
            if reason is not None:
                out.append(f"{e.path or e.key}: entry {e.file} {reason}")
        return out

    # ------------------------------------------------------------------ keys
    @staticmethod
    def shape_options(metric: str, *, resolution: int | None = DEFAULT_RESOLUTION,
                      metric_options: dict | None = None, rank_tau_scale: float | None = None) -> dict:
        """The per-shape options an entry is keyed by: the diffusion metric's defaults filled in
        (kernel, hole filling; the heat kernel's units and diffusion time), so that a default
        named and one left out are the same entry, and ``rank_tau_scale`` only where it applies
        (the heat kernel)."""
        opts = dict(metric_options or {})
        if metric == "diffusion":
            from .metrics import DIFFUSION_FILL_HOLES
            from .metrics.diffusion import DEFAULT_TAU, DEFAULT_UNITS

            opts.setdefault("kernel", "heat")
            opts.setdefault("fill_holes", DIFFUSION_FILL_HOLES)
            if opts["kernel"] == "heat":
                opts.setdefault("units", DEFAULT_UNITS)
                opts.setdefault("tau", DEFAULT_TAU[opts["units"]])
        heat = metric == "diffusion" and opts["kernel"] == "heat"
        return {"metric": metric, "metric_options": _plain(opts),
                "resolution": None if resolution is None else int(resolution),
                "rank_tau_scale": float(rank_tau_scale) if heat and rank_tau_scale is not None else None}

    @staticmethod
    def entry_key(content_hash: str, options: dict) -> str:
        """SHA-256 of the content hash, the options, the gromov version and the store format."""
        return _sha256(_dumps({"content": content_hash, "options": options, "version": __version__,
                               "format": FORMAT}).encode())

    @staticmethod
    def pair_key(x: str, y: str, options: dict) -> str:
        """SHA-256 of the two entry keys (in order: X, Y), the match options and the version."""
        return _sha256(_dumps({"x": x, "y": y, "options": options, "version": __version__,
                               "format": FORMAT}).encode())

    def key_of(self, shape: ShapeMetric) -> str | None:
        """The entry key of a :class:`ShapeMetric` this store returned, else None."""
        return self._keys.get(shape)

    def key_for(self, source, metric: str = "diffusion", *, resolution: int | None = DEFAULT_RESOLUTION,
                metric_options: dict | None = None, rank_tau_scale: float | None = None) -> str:
        """The entry key :meth:`shape` gives ``source`` with these options, computing nothing
        (e.g. to keep arrays derived from that shape with :meth:`put_extra`)."""
        if isinstance(source, ShapeMetric) and source in self._keys:
            return self._keys[source]
        _, content, options, _ = self._source(source, metric, resolution, metric_options, rank_tau_scale)
        return self.entry_key(content, options)

    # ------------------------------------------------------------------ shapes
    def shape(self, source, metric: str = "diffusion", *, resolution: int | None = DEFAULT_RESOLUTION,
              metric_options: dict | None = None, rank_tau_scale: float | None = None) -> ShapeMetric:
        """The :class:`ShapeMetric` of ``source``, read from the store or computed and stored.

        Parameters
        ----------
        source : str, os.PathLike, Mesh, PointCloud or ShapeMetric
            A file (keyed by its bytes), a shape (keyed by its arrays), or a prepared
            ``ShapeMetric`` (keyed by its input and working arrays; its metric must be
            ``metric``, and its own metric options are used).
        metric, resolution, metric_options
            As in :class:`ShapeMetric`.
        rank_tau_scale : float, optional
            Also store the heat distance recognition ranks by
            (:meth:`ShapeMetric.ranking_surface`).

        Returns
        -------
        ShapeMetric
            With its distances, diameter, signatures, normals (a spectral metric's eigenpairs,
            and the ranking metric) in place; read back from the store it gives bit-identical
            matches to a fresh one, dense maps included.
        """
        return self._keyed(source, metric, resolution, metric_options, rank_tau_scale)[1]

    def shapes(self, sources, metric: str = "diffusion", *, resolution: int | None = DEFAULT_RESOLUTION,
               metric_options: dict | None = None, rank_tau_scale: float | None = None,
               progress: bool = False) -> list[ShapeMetric]:
        """:meth:`shape` of each source, in order (``progress``: a tqdm bar on stderr)."""
        from tqdm import tqdm

        sources = list(sources)
        done = all(isinstance(s, ShapeMetric) and s in self._keys for s in sources)
        return [self._keyed(s, metric, resolution, metric_options, rank_tau_scale)[1]
                for s in tqdm(sources, desc="shapes", disable=not progress or done, leave=False)]

    def _source(self, source, metric, resolution, metric_options, rank_tau_scale):
        """``(path, content hash, options, loader)`` of a source."""
        if isinstance(source, ShapeMetric):
            if source.metric != metric:
                raise ValueError(f"a ShapeMetric prepared for {source.metric!r} was given for metric {metric!r}")
            w = source.working
            extra = {"working_vertex_ids": w.vertex_ids}
            if source.has_faces:
                extra["working_faces"] = source.mesh.faces
            options = self.shape_options(metric, resolution=None, metric_options=source.metric_options,
                                         rank_tau_scale=rank_tau_scale)
            options["working"] = "given"
            return None, _arrays_sha256(source.input, extra), options, lambda: source
        options = self.shape_options(metric, resolution=resolution, metric_options=metric_options,
                                     rank_tau_scale=rank_tau_scale)

        def make(shape):
            return lambda: ShapeMetric(shape, metric, resolution=resolution, metric_options=metric_options)

        if isinstance(source, (str, os.PathLike)):
            path = os.path.realpath(os.fspath(source))
            if not os.path.isfile(path):
                raise FileNotFoundError(f"no such file: {os.fspath(source)}")

            def load():
                if self._load is not None:
                    return self._load(os.fspath(source))
                from .io import load as read

                return read(source)

            return path, file_sha256(path), options, lambda: make(load())()
        shape = as_shape(source)
        return None, _arrays_sha256(shape), options, make(shape)

    def _keyed(self, source, metric, resolution, metric_options, rank_tau_scale) -> tuple[str, ShapeMetric]:
        if isinstance(source, ShapeMetric) and source in self._keys:
            return self._keys[source], source
        path, content, options, build = self._source(source, metric, resolution, metric_options, rank_tau_scale)
        key = self.entry_key(content, options)
        label = path or f"shape {content[:12]}"
        db = self._db()
        if path is not None:   # the same file and options indexed before with other content
            stale = db.execute("SELECT key, file FROM entries WHERE path = ? AND options = ? AND version = ? "
                               "AND content_hash != ?", (path, _dumps(options), __version__, content)).fetchall()
            if stale:
                self._problem(f"{path} changed since it was indexed; its stored entry is not used and "
                              "the shape is computed again")
                with self._transaction(db):
                    db.executemany("DELETE FROM entries WHERE key = ?", [(k,) for k, _ in stale])
                for _, f in stale:
                    self._remove(f)
        row = db.execute("SELECT file, checksum FROM entries WHERE key = ?", (key,)).fetchone()
        bad = None
        if row is not None:
            data, reason = self._read(*row)
            if reason is None:
                try:
                    s = _shape_from_arrays(_read_npz(data))
                except Exception as exc:   # noqa: BLE001 - an unreadable entry is recomputed
                    reason = f"cannot be read ({type(exc).__name__}: {exc})"
            del data
            if reason is None:
                self.reused += 1
                self._keys[s] = key
                logger.debug("%s: read from the store (%s)", label, row[0])
                return key, s
            self._problem(f"{label}: stored entry {row[0]} {reason}; the shape is computed again")
            bad = row
        s = self._compute(key, path, content, options, build, label, bad)
        self._keys[s] = key
        return key, s

    def _compute(self, key, path, content, options, build, label, bad) -> ShapeMetric:
        logger.info("%s: computing its %s metric for the store", label, options["metric"])
        s = build()
        data = _npz_bytes(_entry_arrays(s, options["rank_tau_scale"]))
        checksum = _sha256(data)
        name = f"entries/{key}-{checksum[:16]}.npz"
        atomic_write_bytes(self.root / name, data)
        self.computed += 1
        db = self._db()
        with self._transaction(db):
            row = db.execute("SELECT file, checksum FROM entries WHERE key = ?", (key,)).fetchone()
            mine = row is None or (bad is not None and tuple(row) == tuple(bad))
            if mine:   # else another process stored the same shape first: keep its entry
                db.execute("INSERT OR REPLACE INTO entries VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                           (key, path, content, _dumps(options), __version__, name, checksum,
                            s.mesh.n_vertices, len(data), time.time()))
        if not mine and row[0] != name:
            self._remove(name)
        elif mine and bad is not None and bad[0] != name:
            self._remove(bad[0])
        return s

    def _read(self, file: str, checksum: str) -> tuple[bytes | None, str | None]:
        """The bytes of an entry file and None, or None and what is wrong with it."""
        try:
            data = (self.root / file).read_bytes()
        except FileNotFoundError:
            return None, "is missing"
        except OSError as exc:
            return None, f"cannot be read ({exc.strerror})"
        if _sha256(data) != checksum:
            return None, "does not match its checksum (truncated or altered)"
        return data, None

    def _remove(self, file: str) -> None:
        with contextlib.suppress(OSError):
            (self.root / file).unlink()

    def _problem(self, message: str) -> None:
        self.problems.append(message)
        logger.warning("%s", message)

    # ------------------------------------------------------------------ pairs
    def pair_values(self, keys) -> dict:
        """``{pair key: (distance, relative_distance, ranking_distance, signature_distortion)}``
        of the given pair keys that are recorded (NaN where a value was not)."""
        keys = list(keys)
        out = {}
        db = self._db()
        for i in range(0, len(keys), 500):
            chunk = keys[i:i + 500]
            q = ("SELECT key, distance, relative_distance, ranking_distance, signature_distortion FROM pairs "
                 "WHERE key IN "
                 f"({','.join('?' * len(chunk))})")
            for k, *v in db.execute(q, chunk).fetchall():
                out[k] = tuple(_float(x) for x in v)
        return out

    def pair_values_among(self, keys, options: dict) -> dict:
        """``{(x, y): (distance, relative_distance, ranking_distance, signature_distortion)}`` of
        the recorded pairs
        between the entries ``keys`` (each pair as it was recorded: X, Y) matched with
        ``options`` (:func:`match_options_key`) by this gromov version."""
        keys = set(keys)
        rows = self._db().execute("SELECT x, y, distance, relative_distance, ranking_distance, "
                                  "signature_distortion FROM pairs WHERE options = ? AND version = ?", (_dumps(options), __version__))
        return {(x, y): tuple(_float(v) for v in vals) for x, y, *vals in rows
                if x in keys and y in keys}

    def record_pair(self, key: str, x: str, y: str, options: dict, result) -> None:
        """Record a :class:`gromov.MatchResult` under ``key`` (kept if already there; a pair
        recorded without its signature distortion is given the result's)."""
        blob = _npz_bytes({k: np.asarray(getattr(result, k)) for k in PAIR_ARRAYS})
        db = self._db()
        with self._transaction(db):
            db.execute("INSERT INTO pairs (key, x, y, options, version, distance, relative_distance, "
                       "distortion_trimmed, relative_trimmed, ranking_distance, arrays, seconds, created, "
                       "signature_distortion) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
                       "ON CONFLICT (key) DO UPDATE SET signature_distortion = excluded.signature_distortion "
                       "WHERE pairs.signature_distortion IS NULL",
                       (key, x, y, _dumps(options), __version__, *(float(getattr(result, k)) for k in (
                           "distance", "relative_distance", "distortion_trimmed", "relative_trimmed",
                           "ranking_distance")), blob, float(result.seconds), time.time(),
                        float(getattr(result, "signature_distortion", float("nan")))))

    # ------------------------------------------------------------------ extra per-entry arrays
    def put_extra(self, key: str, name: str, arrays: dict) -> None:
        """Keep named arrays derived from entry ``key`` (e.g. per-shape invariants,
        :mod:`gromov.retrieval`) under ``name`` in the catalogue's ``extras`` table, replacing
        what was there under that name."""
        blob = _npz_bytes({k: np.asarray(v) for k, v in arrays.items()})
        db = self._db()
        with self._transaction(db):
            db.execute("INSERT OR REPLACE INTO extras VALUES (?, ?, ?, ?)", (key, name, blob, time.time()))

    def extra(self, key: str, name: str) -> dict | None:
        """The arrays kept with :meth:`put_extra` for entry ``key`` under ``name``, or None
        (none kept, or not readable)."""
        row = self._db().execute("SELECT arrays FROM extras WHERE entry = ? AND name = ?", (key, name)).fetchone()
        if row is None:
            return None
        try:
            return _read_npz(row[0])
        except Exception:   # noqa: BLE001 - unreadable: as if not kept
            return None


def _float(v) -> float:
    """A REAL column's value (SQLite stores NaN as NULL)."""
    return float("nan") if v is None else float(v)


def match_options_key(n_samples: int, seed: int, options: dict) -> dict:
    """The options a pair of :func:`gromov.experiments.gh_matrix` is keyed by: every option
    of :func:`gromov.match` that can change its result, with the defaults filled in, and
    ``orientation="ignore"`` (the matrix's estimate)."""
    params = inspect.signature(_match).parameters
    skip = {"X", "Y", "metric", "resolution", "metric_options", "dense", "as_prepared", "signature"}
    out = {k: p.default for k, p in params.items() if k not in skip}
    # (the signature distortion is a value recorded with the pair, not an option of its match)
    options = {k: v for k, v in options.items() if k != "signature"}
    unknown = set(options) - set(out)
    if unknown:
        raise TypeError(f"unknown match options: {sorted(unknown)}")
    out.update(options, n_samples=int(n_samples), seed=int(seed), orientation="ignore")
    out["search"] = dataclasses.asdict(out["search"])
    return _plain(out)


def as_store(store) -> ShapeStore:
    """``store`` if it is a :class:`ShapeStore`, else the store in that folder."""
    return store if isinstance(store, ShapeStore) else ShapeStore(store)
