"""Property-based tests (Hypothesis) of the mesh readers and of ``gromov info``.

Round trips: random meshes and point clouds, written in every format (OFF, OBJ, PLY and
STL in text and binary, XYZ, TOSCA ``.vert``/``.tri``, MAT and the meshio formats, plain and
gzipped), read back equal -- exactly, or to float32 for STL.

Hostile input: such files cut short, with bytes flipped, inserted or deleted, lines doubled,
dropped or made huge, tokens replaced by hostile ones (``nan``, ``1e400``, ``1_000``,
Arabic-Indic digits, 40-digit integers, a 100,000-character word...), gzip data damaged or
over a decompression limit. A reader must return a valid shape (finite float64
coordinates, int64 faces in range) or raise :class:`~gromov.errors.MeshFormatError` whose
one-line message names the file, stays short and wraps no Python exception text -- never
another exception, a warning other than :class:`~gromov.errors.GromovWarning`, or a hang
(every read runs under a 10 s alarm, and under Hypothesis' deadline). ``gromov info`` on
such files exits 0, or 2 with one short ``gromov: error:`` line on stderr.

Settings profiles: ``gromov-fuzz`` (derandomized, 20 to 40 examples a test, 2 s deadline;
about 10 s in all) runs with the suite. The longer campaign, ``gromov-fuzz-campaign``, draws
new random examples each run, 100 times as many, with no deadline (about 3 minutes;
failures are kept in ``.hypothesis/`` and replayed first)::

    GROMOV_FUZZ=1 .venv/bin/pytest -q tests/test_fuzz.py
"""

from __future__ import annotations

import contextlib
import gzip
import io
import os
import re
import signal
import sys
import tempfile
import warnings
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra.numpy import arrays  # noqa: E402

from gromov.cli import main  # noqa: E402
from gromov.errors import GromovWarning, MeshFormatError  # noqa: E402
from gromov.io import load, save  # noqa: E402
from gromov.mesh import Mesh, PointCloud  # noqa: E402

CAMPAIGN = os.environ.get("GROMOV_FUZZ") == "1"
_COMMON = dict(suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
               print_blob=True)
settings.register_profile("gromov-fuzz", deadline=timedelta(seconds=2), derandomize=True,
                          database=None, **_COMMON)
settings.register_profile("gromov-fuzz-campaign", deadline=None, **_COMMON)
PROFILE = settings.get_profile("gromov-fuzz-campaign" if CAMPAIGN else "gromov-fuzz")


def examples(n: int) -> settings:
    """The module's profile (not loaded globally: other tests keep Hypothesis' defaults),
    with ``n`` examples in the default run and 100 times as many in the campaign."""
    return settings(PROFILE, max_examples=100 * n if CAMPAIGN else n)


try:
    import meshio  # noqa: F401
    MESHIO = ["vtk", "vtu", "msh", "mesh"]
except ImportError:  # optional: gromov[formats]
    MESHIO = []

# --------------------------------------------------------------------------- helpers
ALARM_S = 10
# Python's own exception names: a message must say what is wrong with the file instead
INTERNAL = re.compile(r"\b(Overflow|Index|Key|Type|Value|Attribute|Memory|Recursion|"
                      r"ZeroDivision|UnboundLocal|Runtime|Assertion)Error\b|Traceback|struct\.error")
MAX_MESSAGE = 320   # characters besides the file names


@contextlib.contextmanager
def alarm(seconds: int = ALARM_S):
    """Fail instead of hanging: a read that takes longer than ``seconds`` is interrupted."""
    def hang(signum, frame):
        raise TimeoutError(f"no answer in {seconds} s: a hang")
    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def check_message(msg: str, *names: str) -> None:
    assert "\n" not in msg, msg[:500]
    assert any(n in msg for n in names), msg[:500]
    rest = msg
    for n in names:
        rest = rest.replace(n, "")
    assert len(rest) <= MAX_MESSAGE, msg[:500]
    assert not INTERNAL.search(msg), msg[:500]


def check_shape(shape) -> None:
    assert isinstance(shape, PointCloud)
    v = shape.vertices
    assert v.dtype == np.float64 and v.ndim == 2 and v.shape[1] == 3 and len(v) > 0
    assert np.isfinite(v).all()
    if isinstance(shape, Mesh):
        f = shape.faces
        assert f.dtype == np.int64 and f.ndim == 2 and f.shape[1] == 3 and len(f) > 0
        assert f.min() >= 0 and f.max() < len(v)


def load_or_refuse(path: Path, *names: str, **kw):
    """``load(path)``: a valid shape, or ``None`` after a MeshFormatError with a good message.
    Anything else -- another exception, a warning other than GromovWarning, a hang -- fails."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", GromovWarning)
        try:
            with alarm():
                shape = load(path, **kw)
        except MeshFormatError as exc:
            check_message(str(exc), str(path), *names)
            return None
    check_shape(shape)
    return shape


# --------------------------------------------------------------------------- strategies
# 0 or 1e-30 <= |x| <= 1e12: two different coordinates then differ by more than 1e-75, the
# smallest extent a shape may have (gromov.mesh.as_vertices)
coords = st.one_of(st.just(0.0), st.floats(1e-30, 1e12), st.floats(-1e12, -1e-30))


@st.composite
def shapes(draw) -> Mesh | PointCloud:
    """3 to 10 points, and half the time 1 to 8 triangles on them."""
    n = draw(st.integers(3, 10))
    v = draw(arrays(np.float64, (n, 3), elements=coords))
    if draw(st.booleans()):
        return PointCloud(v)
    tris = draw(st.lists(st.permutations(range(n)).map(lambda p: p[:3]), min_size=1, max_size=8))
    return Mesh(v, np.array(tris, np.int64))


def ascii_ply(shape: PointCloud) -> bytes:
    faces = shape.faces if isinstance(shape, Mesh) else np.empty((0, 3), np.int64)
    head = ["ply", "format ascii 1.0", f"element vertex {shape.n_vertices}",
            "property double x", "property double y", "property double z",
            f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    rows = [f"{x!r} {y!r} {z!r}" for x, y, z in shape.vertices.tolist()]
    rows += [f"3 {a} {b} {c}" for a, b, c in faces.tolist()]
    return ("\n".join(head + rows) + "\n").encode()


def ascii_stl(mesh: Mesh) -> bytes:
    out = ["solid fuzz"]
    for tri in mesh.vertices[mesh.faces].tolist():
        out += ["  facet normal 0 0 1", "    outer loop",
                *(f"      vertex {x!r} {y!r} {z!r}" for x, y, z in tri),
                "    endloop", "  endfacet"]
    return ("\n".join(out + ["endsolid fuzz"]) + "\n").encode()


# (name, ext, holds point clouds, text) of each way a file is written
KINDS = [("off", "off", True, True), ("obj", "obj", True, True), ("ply", "ply", True, False),
         ("ply-ascii", "ply", True, True), ("stl", "stl", False, False),
         ("stl-ascii", "stl", False, True), ("xyz", "xyz", True, True),
         ("vert", "vert", False, True), ("tri", "tri", False, True), ("mat", "mat", True, False),
         *((e, e, True, e == "mesh") for e in MESHIO)]
TEXT_KINDS = [k[0] for k in KINDS if k[3]]
BINARY_KINDS = [k[0] for k in KINDS if not k[3]]


def write_kind(shape: PointCloud, kind: str, folder: Path, gz: bool = False) -> Path:
    """Write ``shape`` as ``kind`` (``"ply-ascii"``, ``"stl-ascii"`` by hand, others by
    :func:`gromov.save`); returns the path to load (for TOSCA: the ``.vert`` or ``.tri``)."""
    ext = dict((k[0], k[1]) for k in KINDS)[kind]
    path = folder / f"s.{ext}{'.gz' if gz else ''}"
    if kind in ("ply-ascii", "stl-ascii"):
        data = ascii_ply(shape) if kind == "ply-ascii" else ascii_stl(shape)
        path.write_bytes(gzip.compress(data) if gz else data)
    else:
        save(shape, path)
    return path


def fit(shape: PointCloud, kind: str) -> PointCloud:
    """``shape`` as ``kind`` can hold it: points only for XYZ, a mesh for STL and TOSCA."""
    if kind == "xyz":
        return PointCloud(shape.vertices)
    if not isinstance(shape, Mesh) and not dict((k[0], k[2]) for k in KINDS)[kind]:
        return Mesh(shape.vertices, np.array([[0, 1, 2]]))
    return shape


# --------------------------------------------------------------------------- round trips
@examples(40)
@given(shape=shapes(), kind=st.sampled_from([k[0] for k in KINDS]), gz=st.booleans())
def test_round_trip_every_format(shape, kind, gz):
    shape = fit(shape, kind)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_kind(shape, kind, Path(tmp), gz)
        with alarm():
            back = load(path, repair=False)
    check_shape(back)
    assert type(back) is type(shape)
    if kind.startswith("stl"):  # corners merged, float32 in binary STL
        want = shape.vertices[shape.faces]
        want = want.astype(np.float32).astype(np.float64) if kind == "stl" else want
        np.testing.assert_array_equal(back.vertices[back.faces], want)
        return
    np.testing.assert_array_equal(back.vertices, shape.vertices)
    if isinstance(shape, Mesh):
        np.testing.assert_array_equal(back.faces, shape.faces)


# --------------------------------------------------------------------------- hostile files
HOSTILE_TOKENS = [
    "nan", "NaN", "inf", "-inf", "infinity", "1e400", "-1e400", "1e39", "1e-400", "1_000",
    "\u0661", "\u0663.5", "\uff11", "\u00bd", "0x1F", "9" * 40, "-" + "9" * 40, "3.5", "-1",
    "0", "2", "300", "65536", "4294967296", "1e308", "+.5", "1,5", "x" * 100_000, "\x00",
    "\ufffd", "solid", "endsolid", "facet", "vertex", "endfacet", "end_header", "element",
    "property", "list", "uchar", "f", "v", "OFF", "#", "/", "3//", "1/x", "",
    "1" * 100_000, "1" * 100_000 + "x", "1e80", "-1e-320"]


@st.composite
def mutated(draw, data: bytes, text: bool) -> bytes:
    """``data`` damaged by 1 to 3 random edits."""
    for _ in range(draw(st.integers(1, 3))):
        n = len(data)
        i = draw(st.integers(0, max(n - 1, 0)))
        edit = draw(st.sampled_from(["cut", "byte", "insert", "delete", "token", "line",
                                     "long line"] if text else
                                    ["cut", "byte", "insert", "delete", "repeat"]))
        if edit == "cut":
            data = data[:i]
        elif edit == "byte":
            data = data[:i] + bytes([draw(st.integers(0, 255))]) + data[i + 1:]
        elif edit == "insert":
            data = data[:i] + draw(st.binary(min_size=1, max_size=12)) + data[i:]
        elif edit == "delete":
            data = data[:i] + data[i + draw(st.integers(1, 16)):]
        elif edit == "repeat":  # a run of bytes repeated, as in a damaged length field
            data = data[:i] + data[i:i + 8] * draw(st.integers(2, 64)) + data[i + 8:]
        elif edit == "token":
            spans = [m.span() for m in re.finditer(rb"\S+", data)]
            if spans:
                a, b = spans[draw(st.integers(0, len(spans) - 1))]
                data = data[:a] + draw(st.sampled_from(HOSTILE_TOKENS)).encode() + data[b:]
        elif edit == "line":
            lines = data.split(b"\n")
            j = draw(st.integers(0, len(lines) - 1))
            how = draw(st.sampled_from(["drop", "double", "blank"]))
            lines[j:j + 1] = {"drop": [], "double": [lines[j]] * 2, "blank": [b""]}[how]
            data = b"\n".join(lines)
        else:  # a megabyte-long line somewhere
            cut = data.rfind(b"\n", 0, i) + 1
            data = data[:cut] + b"1 " * 50_000 + b"\n" + data[cut:]
    return data


def _hostile(shape: PointCloud, kind: str, folder: Path, draw, gz: str) -> tuple[Path, tuple]:
    """Write ``shape`` as ``kind`` and damage one of its files: its content (``gz`` ``""``),
    its content then gzipped (``"payload"``) or its gzip stream (``"stream"``). Returns the
    path to load and the names a message may give (a TOSCA pair's other file)."""
    path = write_kind(shape, kind, folder)
    victim = path
    if kind in ("vert", "tri"):
        victim = folder / f"s.{draw(st.sampled_from(['vert', 'tri']))}"
    original = victim.read_bytes()
    if gz == "stream":
        data = draw(mutated(gzip.compress(original), text=False))
    else:
        data = draw(mutated(original, kind in TEXT_KINDS))
        data = gzip.compress(data) if gz else data
    if gz:
        victim.unlink()
        packed = victim.with_name(victim.name + ".gz")
        packed.write_bytes(data)
        path = packed if victim == path else path
    else:
        victim.write_bytes(data)
    return path, tuple(str(p) for p in folder.iterdir())


@examples(70)
@given(shape=shapes(), kind=st.sampled_from(list(TEXT_KINDS) + list(BINARY_KINDS)), data=st.data())
def test_hostile_files_are_read_or_refused_cleanly(shape, kind, data):
    """Text and binary formats alike."""
    shape = fit(shape, kind)
    with tempfile.TemporaryDirectory() as tmp:
        path, others = _hostile(shape, kind, Path(tmp), data.draw, gz="")
        load_or_refuse(path, *others)


@examples(25)
@given(shape=shapes(), kind=st.sampled_from([k[0] for k in KINDS]),
       gz=st.sampled_from(["payload", "stream"]), limit=st.none() | st.integers(1, 4096),
       data=st.data())
def test_hostile_gzip_files_are_read_or_refused_cleanly(shape, kind, gz, limit, data):
    shape = fit(shape, kind)
    with tempfile.TemporaryDirectory() as tmp:
        path, others = _hostile(shape, kind, Path(tmp), data.draw, gz=gz)
        load_or_refuse(path, *others, max_decompressed=limit)


GARBAGE = ["1_000", "\u0661", "\u0661\u0662", "\uff11", "0x1F", "1,5", "1e", "--1", "nan(1)",
           "x" * 100_000, "1" * 100_000 + "x", "1.5.5", "\x00"]
_NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


@examples(40)
@given(shape=shapes(), kind=st.sampled_from([k for k in TEXT_KINDS if k != "mesh"]),
       data=st.data())
def test_garbage_in_place_of_a_number_is_refused_naming_its_line(shape, kind, data):
    """No silent success: any number of a text file's data replaced by garbage is an error,
    whose message names the line (our text readers; Medit is meshio's)."""
    shape = fit(shape, kind)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_kind(shape, kind, Path(tmp))
        victim = path
        if kind in ("vert", "tri"):
            victim = Path(tmp) / f"s.{data.draw(st.sampled_from(['vert', 'tri']))}"
        text = victim.read_bytes()
        body = text.index(b"end_header\n") + 11 if kind == "ply-ascii" else 0
        spans = [m.span() for m in _NUMBER.finditer(text, body)
                 if (m.start() == 0 or text[m.start() - 1:m.start()].isspace())
                 and (m.end() == len(text) or text[m.end():m.end() + 1].isspace())]
        a, b = spans[data.draw(st.integers(0, len(spans) - 1))]
        garbage = data.draw(st.sampled_from(GARBAGE))
        victim.write_bytes(text[:a] + garbage.encode() + text[b:])
        line = text.count(b"\n", 0, a) + 1
        with pytest.raises(MeshFormatError) as info, alarm():
            load(path)
    msg = str(info.value)
    check_message(msg, str(path), str(victim))
    assert str(victim) in msg and f"line {line}" in msg, (msg, line)


# --------------------------------------------------------------------------- the CLI
@pytest.fixture(scope="module")
def warm_cli(tmp_path_factory):
    """Compile the geodesic kernels once, before the deadline applies."""
    path = tmp_path_factory.mktemp("warm") / "t.off"
    save(Mesh(np.eye(3), np.array([[0, 1, 2]])), path)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["info", str(path)]) == 0


def _show_on_stderr(message, category, filename, lineno, file=None, line=None):
    """Python's default ``showwarning`` (pytest records warnings instead of printing them)."""
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def run_info(path: Path, *extra: str) -> tuple[int, list[str]]:
    """``gromov info PATH``, in process: exit status and stderr lines, as a terminal shows."""
    err = io.StringIO()
    with warnings.catch_warnings(), alarm(), contextlib.redirect_stdout(io.StringIO()), \
            contextlib.redirect_stderr(err):
        warnings.showwarning = _show_on_stderr
        rc = main(["info", str(path), *extra])
    return rc, [ln for ln in err.getvalue().splitlines() if ln.strip()]


def check_cli(rc: int, lines: list[str], *names: str) -> None:
    assert rc in (0, 2), (rc, lines)
    for ln in lines:   # warnings and the error: each one short line
        assert ln.startswith("gromov: "), ln[:300]
        assert len(ln) <= MAX_MESSAGE + 40 + sum(map(len, names)), ln[:300]
    errors = [ln for ln in lines if ln.startswith("gromov: error: ")]
    assert errors == ([lines[-1]] if rc == 2 else []), lines
    if rc == 2:
        check_message(lines[-1], *names)


@examples(20)
@given(shape=shapes(), kind=st.sampled_from([k[0] for k in KINDS]),
       gz=st.sampled_from(["", "payload"]), data=st.data())
def test_cli_info_exits_0_or_2_with_one_short_line(warm_cli, shape, kind, gz, data):
    shape = fit(shape, kind)
    with tempfile.TemporaryDirectory() as tmp:
        path, others = _hostile(shape, kind, Path(tmp), data.draw, gz=gz)
        rc, lines = run_info(path)
    check_cli(rc, lines, str(path), *others)
