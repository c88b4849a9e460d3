"""Hostile input found by fuzzing the readers: each a clean error (or a correct result) in
the library and, through ``gromov info``, exit status 2 with one short line on stderr.

Small cases are files in ``fixtures/hostile/``; large ones (megabyte tokens and lines, gzip
bombs) are made by the tests.
"""

from __future__ import annotations

import gzip
import struct
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

import gromov
import gromov.io
from gromov.cli import main
from gromov.errors import MeshFormatError
from gromov.io import load
from gromov.mesh import Mesh, PointCloud

HOSTILE = Path(__file__).resolve().parent / "fixtures" / "hostile"
MAX_LINE = 300  # characters of an error line besides the file name


def info_error(path: Path, capsys, *extra: str) -> str:
    """``gromov info PATH``: asserts exit status 2 and one short error line; returns it."""
    rc = main(["info", str(path), *extra])
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert rc == 2, err[:500]
    assert len(lines) == 1 and lines[0].startswith(f"gromov: error: {path}: "), err[:500]
    assert len(lines[0]) - len(str(path)) <= MAX_LINE, lines[0][:500]
    assert "Traceback" not in err and "Error:" not in err
    return lines[0]


def refused(path: Path, match: str, capsys, *extra: str, **kw) -> None:
    """``load`` raises MeshFormatError matching ``match``; ``gromov info`` exits 2 saying so."""
    with pytest.raises(MeshFormatError, match=match) as info:
        load(path, **kw)
    assert str(info.value).startswith(f"{path}: ")
    line = info_error(path, capsys, *extra)
    assert line == f"gromov: error: {info.value}"


# --------------------------------------------------------------------------- the corpus
CORPUS = [
    # PLY values are checked against their declared type before the cast (which would wrap)
    ("ply_int_nan.ply", r"line 11: 'vertex' property 'x' holds nan, which does not fit its "
                        r"type int \(integers -2147483648\.\.2147483647\)"),
    ("ply_uchar_300.ply", r"line 11: 'vertex' property 'x' holds 300, which does not fit its "
                          r"type uchar \(integers 0\.\.255\)"),
    ("ply_int_fraction.ply", r"line 11: 'vertex' property 'x' holds 1\.5, which does not fit"),
    ("ply_uint_index_negative.ply", r"line 13: 'face' property 'vertex_indices' holds -1, "
                                    r"which does not fit its type uint"),
    ("ply_uchar_count_300.ply", r"line 13: 'face' property 'vertex_indices' list length holds "
                                r"300, which does not fit its type uchar"),
    ("ply_float_overflow.ply", r"line 11: 'vertex' property 'x' holds 1e\+39, which does not "
                               r"fit its type float \(float32"),
    ("ply_double_1e400.ply", r"line 11: 'vertex' record, property 'x': '1e400' overflows "
                             r"float64"),
    ("ply_count_unicode.ply", r"bad header line 3: .* \(expected 'element NAME COUNT'\)"),
    # OBJ: empty faces, non-ASCII-decimal numbers, garbage, huge indices
    ("obj_empty_face.obj", r"line 5: a face needs at least 3 vertices, found 0"),
    ("obj_underscore.obj", r"line 2: non-numeric value '1_000' in vertex, coordinate x"),
    ("obj_trailing_garbage.obj", r"line 2: non-numeric value 'garbage' in vertex, value 4"),
    ("obj_huge_index.obj", r"line 4: vertex index '9{40}' is out of range"),
    ("obj_bad_reference.obj", r"line 4: vertex reference '2/x' is not an integer"),
    # OFF
    ("off_arabic_digit.off", r"line 4: non-numeric value '\u0661' in vertex, coordinate x"),
    ("off_underscore.off", r"line 4: non-numeric value '1_000' in vertex, coordinate x"),
    ("off_trailing_garbage.off", r"line 4: non-numeric value 'garbage' in vertex, value 4"),
    ("off_unicode_count.off", r"bad header: line 2 should hold 'n_vertices n_faces"),
    ("off_unicode_index.off", r"line 6: vertex index '\u0662' is not an integer"),
    ("off_huge_index.off", r"line 6: vertex index '9{40}' is out of range"),
    ("off_1e400.off", r"line 4: vertex, coordinate z: '1e400' overflows float64"),
    ("off_inf.off", r"1 vertices have NaN or infinite coordinates, first vertex 1 \(line 4\)"),
    ("off_nan_face_count.off", r"line 6: face vertex count 'nan' is not an integer"),
    # XYZ
    ("xyz_trailing_garbage.xyz", r"line 2: non-numeric value 'zz' in point, value 4"),
    ("xyz_arabic_digit.xyz", r"line 2: non-numeric value '\u0662' in point, coordinate y"),
    ("xyz_1e400.xyz", r"line 2: point, coordinate x: '-1e400' overflows float64"),
    ("xyz_empty_field.xyz", r"line 2: empty value between commas \('1,,2,3'\)"),
    # TOSCA (the message names the .tri file)
    ("tosca_huge_index.tri", r"line 1: vertex index '9{40}' is out of range"),
    # ASCII STL, checked against its grammar
    ("stl_garbage_after_coordinates.stl", r"line 5: expected 'vertex', found '7'"),
    ("stl_1e400.stl", r"line 5: vertex 2 z: '1e400' overflows float64"),
    ("stl_underscore.stl", r"line 5: non-numeric vertex coordinate '1_0' \(vertex 2 x\)"),
]


def test_corpus_is_complete():
    named = {name for name, _ in CORPUS} | {"tosca_huge_index.vert"}
    assert named == {p.name for p in HOSTILE.iterdir()}


@pytest.mark.parametrize("name,match", CORPUS)
def test_corpus_refused_with_exit_2(name, match, capsys):
    refused(HOSTILE / name, match, capsys)


# --------------------------------------------------------------------------- long input
def _stl(n_facets: int, solid: str = "t") -> str:
    facet = ("facet normal 0 0 1\nouter loop\nvertex {i} 0 0\nvertex {i} 1 0\nvertex {i} 0 1\n"
             "endloop\nendfacet\n")
    return f"solid {solid}\n" + "".join(facet.format(i=i) for i in range(n_facets)) + \
        f"endsolid {solid}\n"


def test_stl_megabyte_token_is_a_clean_error(tmp_path, capsys):
    # 20,000 facets (420,000 tokens) and one token of 10^6 characters: a fixed-width token
    # array would need 420,000 x 10^6 x 4 bytes
    text = _stl(20_000).replace("vertex 10000 1 0", "vertex " + "1" * 10**6 + "x 1 0", 1)
    path = tmp_path / "long.stl"
    path.write_text(text)
    t = time.perf_counter()
    refused(path, r"line 70005: non-numeric vertex coordinate '1{60}'\.\.\. \(1000001 "
                  r"characters\) \(vertex 2 x\)", capsys)
    assert time.perf_counter() - t < 20


def test_stl_long_name_keywords_in_capitals_crlf_and_two_solids_read(tmp_path):
    one = _stl(2, "n" * 10**5).upper().replace("\n", "\r\n")
    path = tmp_path / "ok.stl"
    path.write_text(one + _stl(1, "second"))
    m = load(path, repair=False)
    corners = m.vertices[m.faces].reshape(-1, 3)
    np.testing.assert_array_equal(corners, [[0, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0],
                                            [1, 1, 0], [1, 0, 1], [0, 0, 0], [0, 1, 0],
                                            [0, 0, 1]])


TRI = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
LONG = 8 * 2**20   # the longest lines seen repeated whole on stderr: 8 MB


@pytest.mark.parametrize("name,text,match", [
    ("v.off", TRI.replace("1 0 0", "1 0 " + "x" * LONG),
     r"line 4: non-numeric value 'x{60}'\.\.\. \(8388608 characters\) in vertex, coordinate z"),
    ("f.off", TRI.replace("3 0 1 2", "9999999 0" + " 1" * (LONG // 2)),
     r"line 6: face announces 9999999 vertices but lists only 4194305: '9999999 0 1 1"),
    ("d.xyz", "0 0 0\n" + "1,5 " * (LONG // 4) + "\n",
     r"line 2: both commas and blanks between values \('1,5 1,5"),
    ("t.ply", gromov.io._format_ply(PointCloud(np.eye(3)), "").decode("latin-1").replace(
        "comment written by gromov", "comment\nelement " + "e" * LONG), r"bad header line 4: "
        r"'element e{52}'\.\.\. \(8388616 characters\) \(expected 'element NAME COUNT'\)"),
    ("e.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n0 0 0" + " 7" * (LONG // 2) + "\n",
     r"line 8: 'vertex' record needs exactly 3 values, found 4194307: '0 0 0 7 7"),
    ("r.tri", "1 2" + " 3" * (LONG // 2) + "\n",
     r"line 1: a triangle needs exactly 3 vertex indices, found 4194306: '1 2 3 3"),
])
def test_long_lines_are_quoted_in_60_characters(tmp_path, capsys, name, text, match):
    path = tmp_path / name
    path.write_bytes(text.encode("latin-1"))
    if name.endswith(".tri"):
        (tmp_path / "r.vert").write_text("0 0 0\n1 0 0\n0 1 0\n")
    refused(path, match, capsys)


# --------------------------------------------------------------------------- gzip bombs
def _bomb(n_members: int, member: bytes = b"\n" * 2**24) -> bytes:
    """``n_members`` gzip members of 16 MiB of newlines each, concatenated (valid gzip)."""
    return gzip.compress(member, 9) * n_members


def test_gzip_bomb_refused_fast_and_small(tmp_path, capsys):
    # 600 MiB of newlines in a 0.6 MB .xyz.gz: read whole, they took minutes and gigabytes
    path = tmp_path / "bomb.xyz.gz"
    path.write_bytes(b"".join([gzip.compress(b"0 0 0\n"), _bomb(36)]))
    assert path.stat().st_size < 700_000
    tracemalloc.start()
    t = time.perf_counter()
    with pytest.raises(MeshFormatError, match=r"bomb\.xyz\.gz: the file decompresses to more "
                                              r"than 5\d\.\d MiB, the limit for 5\d\d KiB of "
                                              r"compressed data \(100 times its size, at least 16 "
                                              r"MiB: a gzip bomb\?\); if the file is genuine, "
                                              r"raise the limit with --max-decompressed SIZE "
                                              r"\(max_decompressed= in gromov\.load\)"):
        load(path)
    seconds = time.perf_counter() - t
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert seconds < 10
    assert peak < 3 * 100 * path.stat().st_size   # the limit, twice (chunks, joined), and change
    info_error(path, capsys)


def test_small_bomb_refused_under_the_floor_only_when_asked(tmp_path, capsys, monkeypatch):
    # 2,000 points at the origin: 12 KB that compress 100+ times, read under the 16 MiB floor
    path = tmp_path / "origin.xyz.gz"
    path.write_bytes(gzip.compress(b"0 0 0\n" * 2000, 9))
    assert 12_000 / path.stat().st_size > 100
    assert load(path).n_vertices == 2000
    monkeypatch.setattr(gromov.io, "GZIP_FLOOR", 1024)   # a small floor: the ratio decides
    refused(path, r"the file decompresses to more than \d\.\d+ KiB, the limit for \d+ bytes of "
                  r"compressed data \(100 times its size, at least 1 KiB: a gzip bomb\?\)", capsys)
    # raised limits: the keyword and the CLI option
    assert load(path, max_decompressed=12_000).n_vertices == 2000
    assert main(["info", str(path), "--max-decompressed", "1M"]) == 0
    out = capsys.readouterr()
    assert "point cloud" in out.out and out.err == ""
    # a lowered one
    refused(path, r"the file decompresses to more than 11\.7 KiB, the limit set by --max-decompressed "
                  r"\(max_decompressed= in gromov\.load\)", capsys, "--max-decompressed", "11999",
            max_decompressed=11_999)


@pytest.mark.parametrize("value,match", [
    ("abc", "expected a size such as 4G, 500M or 1000000"), ("0", "at least 1 byte"),
    ("-5M", "expected a size"), ("1.5x", "expected a size")])
def test_max_decompressed_option_errors(tmp_path, capsys, value, match):
    path = tmp_path / "t.off"
    path.write_text(TRI)
    with pytest.raises(SystemExit) as exit_:
        main(["info", str(path), f"--max-decompressed={value}"])
    assert exit_.value.code == 2
    lines = capsys.readouterr().err.splitlines()
    assert lines[-1].startswith("gromov info: error: argument --max-decompressed: ")
    assert match in lines[-1] and len(lines) == 2    # argparse's usage line, then the error


@pytest.mark.parametrize("text,size", [("4G", 4 * 2**30), ("500m", 500 * 2**20),
                                       ("1.5 KiB", 1536), ("2GB", 2 * 2**30), ("1000", 1000)])
def test_max_decompressed_sizes(text, size):
    from gromov.cli._args import _size

    assert _size(text) == size


def test_max_decompressed_keyword_checked(tmp_path):
    path = tmp_path / "t.off"
    path.write_text(TRI)
    with pytest.raises(ValueError, match="at least 1 byte, got 0"):
        load(path, max_decompressed=0)
    with pytest.raises(TypeError, match="must be an int"):
        load(path, max_decompressed="1G")
    with pytest.raises(TypeError, match="must be an int"):
        load(path, max_decompressed=True)


def test_gzip_limit_applies_to_both_files_of_a_tosca_pair(tmp_path, capsys):
    (tmp_path / "p.vert").write_text("0 0 0\n1 0 0\n0 1 0\n")
    tri = tmp_path / "p.tri.gz"
    tri.write_bytes(gzip.compress(b"1 2 3\n" + b"\n" * 10_000))
    refused(tri, r"p\.tri\.gz: the file decompresses to more than 1000 bytes", capsys,
            "--max-decompressed", "1000", max_decompressed=1000)


# --------------------------------------------------------------------------- MATLAB
def test_mat_element_of_unknown_type_is_refused_not_a_crash(tmp_path):
    # scipy 1.17's loadmat crashes the interpreter (segmentation fault) on a numeric data
    # element whose type code has no dtype: run the CLI in a process of its own
    path = tmp_path / "t.mat"
    gromov.save(Mesh(np.eye(3) + 0.5, np.array([[0, 1, 2]])), path)
    data = path.read_bytes()
    x = data.index(struct.pack("<II", 9, 24))   # X: miDOUBLE, 3 values
    path.write_bytes(data[:x] + struct.pack("<I", 92) + data[x + 4:])
    r = subprocess.run([sys.executable, "-m", "gromov", "info", str(path)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2, r.stderr[-500:]
    assert r.stderr == (f"gromov: error: {path}: not a readable MATLAB MAT-file (data element "
                        f"at byte {x} has unknown type 92)\n")


def test_mat_deep_nesting_refused(tmp_path, capsys):
    from scipy.io import savemat

    nested: object = np.zeros((1, 1))
    for _ in range(40):
        nested = np.array([nested, 0], dtype=object)   # a cell inside a cell...
    path = tmp_path / "deep.mat"
    savemat(path, {"X": np.zeros((3, 1)), "Y": np.zeros((3, 1)), "Z": np.zeros((3, 1)),
                   "deep": nested})
    refused(path, r"not a readable MATLAB MAT-file \(arrays nested more than 32 levels deep\)",
            capsys)


def test_mat_compressed_variable_bomb_refused(tmp_path, capsys, monkeypatch):
    from scipy.io import savemat

    path = tmp_path / "z.mat"
    savemat(path, {"X": np.zeros((20_000, 1)), "Y": np.zeros((20_000, 1)),
                   "Z": np.zeros((20_000, 1))}, do_compression=True)
    assert load(path).n_vertices == 20_000
    monkeypatch.setattr(gromov.io, "GZIP_FLOOR", 1024)   # 160 kB of zeros: 1000 times smaller
    refused(path, r"z\.mat: a compressed variable \(byte 128\) decompresses to more than "
                  r"[\d.]+ KiB, the limit for \d+ bytes of compressed data", capsys)
    assert load(path, max_decompressed=10**6).n_vertices == 20_000


# --------------------------------------------------------------------------- binary PLY
def test_binary_ply_negative_list_length(tmp_path, capsys):
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
            "property float y\nproperty float z\nelement face 1\n"
            "property list char int vertex_indices\nend_header\n").encode()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()
    path = tmp_path / "neg.ply"
    path.write_bytes(head + v + struct.pack("<b3i", -3, 0, 1, 2))
    refused(path, r"'face' property 'vertex_indices': negative list length -3", capsys)


@pytest.mark.parametrize("header,match", [
    ("element vertex 3\nproperty float x\nproperty float x\n",
     r"bad header line 5: 'property float x': property 'x' declared twice in element 'vertex'"),
    ("element vertex 3\nproperty float x\nelement vertex 2\n",
     r"bad header line 5: 'element vertex 2': element 'vertex' declared twice"),
    ("element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement junk 9\n",
     r"bad header: element 'junk' has 9 records but no properties"),
    ("element vertex 99999999999999999999\n", r"bad header line 3: 'element vertex 9{20}' "
                                              r"\(expected 'element NAME COUNT'\)"),
])
def test_ply_header_contradictions(tmp_path, capsys, header, match):
    path = tmp_path / "h.ply"
    path.write_text(f"ply\nformat binary_little_endian 1.0\n{header}end_header\n")
    refused(path, match, capsys)


# --------------------------------------------------------------------------- correct results
def test_unusual_but_valid_text_reads_exactly(tmp_path):
    off = tmp_path / "n.off"   # number spellings a C or Python writer may produce
    off.write_text("OFF\n3 1 0\n+1. .5 1E3\n-0.0 2e-3 -.25\n7 8 9\n3 0 1 2\n")
    np.testing.assert_array_equal(load(off, repair=False).vertices,
                                  [[1, 0.5, 1000], [0, 0.002, -0.25], [7, 8, 9]])
    obj = tmp_path / "r.obj"   # v/vt/vn references
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2//1 3/1\n")
    np.testing.assert_array_equal(load(obj).faces, [[0, 1, 2]])
    xyz = tmp_path / "c.xyz"   # a trailing comma ends a comma-separated line
    xyz.write_text("1,2,3,\n4,5,6,\n")
    np.testing.assert_array_equal(load(xyz).vertices, [[1, 2, 3], [4, 5, 6]])
    ply = tmp_path / "t.ply"   # integer types at the ends of their ranges
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty uchar x\nproperty char y\n"
                   "property ushort z\nelement face 1\nproperty list uchar uint vertex_indices\n"
                   "end_header\n255 -128 65535\n0 127 0\n0 0 1\n3 0 1 2\n")
    np.testing.assert_array_equal(load(ply, repair=False).vertices,
                                  [[255, -128, 65535], [0, 127, 0], [0, 0, 1]])


def test_line_numbers_count_newlines_only(tmp_path, capsys):
    # a form feed and a U+2028 inside lines are blanks, not line breaks
    path = tmp_path / "ff.off"
    path.write_text("OFF\n3 1 0\n0\x0c0 0\n1\u20280 0\n0 1 0\n3 0 1 x\n", encoding="utf-8")
    refused(path, r"line 6: vertex index 'x' is not an integer", capsys)


def test_mesh_read_is_still_a_mesh(tmp_path):
    path = tmp_path / "ok.off"
    path.write_text(TRI)
    m = load(path)
    assert isinstance(m, Mesh) and m.n_faces == 1
