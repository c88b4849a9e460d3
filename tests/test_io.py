"""Tests for gromov.io: round trips, syntax variants, repairs, every error path, real data."""

from __future__ import annotations

import gzip
import importlib.util
import logging
import re
import struct
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from gromov.errors import GromovWarning, MeshError, MeshFormatError
from gromov.io import FORMATS, MeshFileNotFoundError, MissingDependencyError, load, save
from gromov.mesh import Mesh, PointCloud
from gromov.shapes import icosphere

FIXTURES = Path(__file__).resolve().parent / "fixtures"

# VTK, Gmsh and Medit are read through the optional meshio (in the `test` extra)
MESHIO = ["vtk", "vtu", "msh", "mesh"]
needs_meshio = pytest.mark.skipif(importlib.util.find_spec("meshio") is None,
                                  reason='meshio not installed: pip install "gromov[formats]"')


def with_meshio(names):
    """``names`` as pytest params, those of a meshio format marked ``needs_meshio``."""
    return [pytest.param(n, marks=needs_meshio) if n.removesuffix(".gz").rpartition(".")[2]
            in MESHIO else n for n in names]


# --------------------------------------------------------------------------- helpers
@pytest.fixture
def sphere() -> Mesh:
    # irregular coordinates (not short decimals) so that float formatting matters
    m = icosphere(1)
    return Mesh(m.vertices * np.pi + [0.1, -1e-7, 12345.678], m.faces)


def write(path: Path, text: str | bytes) -> Path:
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def raises_naming(path, exc=MeshFormatError, match=""):
    """``pytest.raises`` that also checks that the message names the file."""
    class _Ctx:
        def __enter__(self):
            self._cm = pytest.raises(exc, match=match)
            self.info = self._cm.__enter__()
            return self.info

        def __exit__(self, *a):
            out = self._cm.__exit__(*a)
            assert str(path) in str(self.info.value), str(self.info.value)
            return out
    return _Ctx()


def load_quiet(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", GromovWarning)  # fail if anything gets repaired
        return load(path, **kw)


TRI = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"


# --------------------------------------------------------------------------- round trips
EXACT = ["off", "obj", "ply", "vert", "tri", "mat", *MESHIO]


@pytest.mark.parametrize("gz", [False, True])
@pytest.mark.parametrize("name", with_meshio([f"s.{e}" for e in EXACT]))
def test_round_trip_exact(tmp_path, sphere, name, gz):
    path = tmp_path / f"{name}{'.gz' if gz else ''}"
    save(sphere, path)
    back = load_quiet(path)
    assert isinstance(back, Mesh)
    np.testing.assert_array_equal(back.vertices, sphere.vertices)  # bit-exact, same order
    np.testing.assert_array_equal(back.faces, sphere.faces)
    np.testing.assert_array_equal(back.input_ids, np.arange(sphere.n_vertices))
    if gz:
        assert path.read_bytes()[:2] == b"\x1f\x8b"


@pytest.mark.parametrize("gz", [False, True])
def test_round_trip_vert_tri_writes_both_files(tmp_path, sphere, gz):
    z = ".gz" if gz else ""
    save(sphere, tmp_path / f"cat0.tri{z}")
    assert (tmp_path / f"cat0.vert{z}").is_file() and (tmp_path / f"cat0.tri{z}").is_file()
    opener = gzip.open if gz else open
    with opener(tmp_path / f"cat0.tri{z}", "rt") as fh:
        first = [int(t) for t in fh.readline().split()]
    assert first == (sphere.faces[0] + 1).tolist()  # .tri is 1-based
    a, b = load_quiet(tmp_path / f"cat0.vert{z}"), load_quiet(tmp_path / f"cat0.tri{z}")
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(a.vertices, sphere.vertices)


def test_partner_found_with_other_compression(tmp_path, sphere):
    save(sphere, tmp_path / "x.vert")
    (tmp_path / "x.tri.gz").write_bytes(gzip.compress((tmp_path / "x.tri").read_bytes()))
    (tmp_path / "x.tri").unlink()
    np.testing.assert_array_equal(load_quiet(tmp_path / "x.vert").faces, sphere.faces)


def test_round_trip_stl_float32_first_appearance_order(tmp_path):
    # STL has no vertex ids: vertices come back numbered by first appearance in the faces,
    # and binary STL is float32. Build a mesh for which both are no-ops.
    m = icosphere(1)
    order = np.unique(m.faces.ravel(), return_index=True)[1]
    first_seen = m.faces.ravel()[np.sort(order)]
    relabel = np.empty(m.n_vertices, np.int64)
    relabel[first_seen] = np.arange(m.n_vertices)
    v32 = m.vertices[first_seen].astype(np.float32).astype(np.float64)
    mesh = Mesh(v32, relabel[m.faces])
    for name in ("s.stl", "s.stl.gz"):
        save(mesh, tmp_path / name)
        back = load_quiet(tmp_path / name)
        np.testing.assert_array_equal(back.vertices, mesh.vertices)
        np.testing.assert_array_equal(back.faces, mesh.faces)
    assert (tmp_path / "s.stl").stat().st_size == 84 + 50 * mesh.n_faces


def test_stl_of_arbitrary_mesh_same_triangles(tmp_path, sphere):
    save(sphere, tmp_path / "s.stl")
    back = load_quiet(tmp_path / "s.stl")
    assert back.n_vertices == sphere.n_vertices and back.n_faces == sphere.n_faces
    np.testing.assert_allclose(back.vertices[back.faces],
                               sphere.vertices[sphere.faces].astype(np.float32), rtol=0, atol=0)


@pytest.mark.parametrize("name", with_meshio(["p.off", "p.obj", "p.ply", "p.ply.gz", "p.off.gz",
                                              "p.mat", "p.mat.gz", "p.vtk", "p.vtu", "p.msh",
                                              "p.mesh", "p.msh.gz", "p.xyz", "p.xyz.gz"]))
def test_point_cloud_round_trip(tmp_path, name):
    pts = np.random.default_rng(0).normal(size=(50, 3))
    save(PointCloud(pts), tmp_path / name)
    back = load_quiet(tmp_path / name)
    assert type(back) is PointCloud
    np.testing.assert_array_equal(back.vertices, pts)


def test_file_type_overrides_extension(tmp_path, sphere):
    save(sphere, tmp_path / "mesh.dat", file_type="off.gz")
    assert (tmp_path / "mesh.dat").read_bytes()[:2] == b"\x1f\x8b"
    back = load_quiet(tmp_path / "mesh.dat", file_type="off.gz")
    np.testing.assert_array_equal(back.faces, sphere.faces)
    back = load_quiet(str(tmp_path / "mesh.dat"), file_type=".OFF.GZ")
    np.testing.assert_array_equal(back.vertices, sphere.vertices)


def test_extension_case_insensitive_and_str_path(tmp_path, sphere):
    save(sphere, str(tmp_path / "S.OFF"))
    np.testing.assert_array_equal(load_quiet(str(tmp_path / "S.OFF")).faces, sphere.faces)


def test_registry_covers_formats():
    assert {"off", "obj", "ply", "stl", "vert", "tri", "mat", "xyz", *MESHIO} <= set(FORMATS)
    for fmt in FORMATS.values():
        assert callable(fmt.read) and callable(fmt.write)


# --------------------------------------------------------------------------- interoperability
def test_files_we_write_read_identically_in_trimesh(tmp_path, sphere):
    trimesh = pytest.importorskip("trimesh")
    for ext in ("off", "obj", "ply"):
        save(sphere, tmp_path / f"s.{ext}")
        t = trimesh.load(tmp_path / f"s.{ext}", process=False, maintain_order=True)
        np.testing.assert_array_equal(t.faces, sphere.faces)
        np.testing.assert_allclose(t.vertices, sphere.vertices, rtol=1e-15, atol=0)


@pytest.mark.parametrize("kind", ["ply-binary", "ply-ascii", "stl-binary", "stl-ascii", "obj"])
def test_files_trimesh_writes_read_here(tmp_path, kind):
    trimesh = pytest.importorskip("trimesh")
    m = icosphere(1)
    t = trimesh.Trimesh(m.vertices, m.faces, process=False)
    fmt, _, enc = kind.partition("-")
    if fmt == "ply":
        data = trimesh.exchange.ply.export_ply(t, encoding=enc)
    elif fmt == "stl":
        data = trimesh.exchange.stl.export_stl(t) if enc == "binary" \
            else trimesh.exchange.stl.export_stl_ascii(t)
    else:
        data = trimesh.exchange.obj.export_obj(t, digits=17)
    path = write(tmp_path / f"t.{fmt}", data)
    back = load_quiet(path)
    ref = trimesh.load(path, process=False, maintain_order=True)
    if fmt == "stl":  # trimesh does not merge STL corners; compare triangle by triangle
        np.testing.assert_allclose(back.vertices[back.faces].reshape(-1, 3), ref.vertices, atol=0)
    else:
        np.testing.assert_array_equal(back.faces, m.faces)
        np.testing.assert_array_equal(back.vertices, ref.vertices)
        np.testing.assert_allclose(back.vertices, m.vertices, atol=1e-7)


# --------------------------------------------------------------------------- syntax variants
def test_off_counts_on_next_line_and_crlf(tmp_path):
    m = load_quiet(write(tmp_path / "a.off", TRI.replace("\n", "\r\n")))
    np.testing.assert_array_equal(m.faces, [[0, 1, 2]])


def test_off_hand_made_fixture_quads_comments_colours():
    path = FIXTURES / "square_quads.off"
    with pytest.warns(GromovWarning, match=r"square_quads\.off: triangulated 2 polygon"):
        m = load(path)
    np.testing.assert_array_equal(m.vertices[1], [1, 0, 0])  # trailing comment stripped
    # fan (p0, p1, p2), (p0, p2, p3), quads kept in file order
    np.testing.assert_array_equal(m.faces, [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    assert m.area == pytest.approx(2.0)
    assert len(m.boundary_loops) == 1 and m.euler_characteristic == 1


def test_coff_extra_vertex_values_ignored(tmp_path):
    text = "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n"
    m = load_quiet(write(tmp_path / "c.off", text))
    np.testing.assert_array_equal(m.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_mixed_polygons_keep_face_order(tmp_path):
    text = ("OFF\n6 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n2 1 0\n"
            "3 0 1 3\n4 1 4 5 2\n3 1 2 3\n")
    path = write(tmp_path / "mixed.off", text)
    with pytest.warns(GromovWarning, match=r"mixed\.off: triangulated 1 polygon.*3 faces -> 4"):
        m = load(path)
    np.testing.assert_array_equal(m.faces, [[0, 1, 3], [1, 4, 5], [1, 5, 2], [1, 2, 3]])


def test_pentagon_fan(tmp_path):
    path = write(tmp_path / "pent.obj", "v 1 0 0\nv 0.3 0.9 0\nv -0.8 0.6 0\nv -0.8 -0.6 0\n"
                                        "v 0.3 -0.9 0\nf 1 2 3 4 5\n")
    with pytest.warns(GromovWarning, match=str(path)):
        m = load(path)
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3], [0, 3, 4]])


def test_obj_fixture_quads_texture_normals_relative():
    with pytest.warns(GromovWarning, match=r"cube_quads\.obj: triangulated 6 polygon"):
        m = load(FIXTURES / "cube_quads.obj")
    assert m.n_vertices == 8 and m.n_faces == 12
    np.testing.assert_array_equal(m.faces[8:10], [[3, 7, 6], [3, 6, 2]])  # 'f -5 -1 -2 -6'
    assert m.boundary_loops == [] and m.euler_characteristic == 2  # closed cube
    assert m.area == pytest.approx(6.0)


def test_obj_vertices_only_is_point_cloud(tmp_path):
    pc = load_quiet(write(tmp_path / "p.obj", "# points\nv 0 0 0\nv 1 2 3\nvn 0 0 1\n"))
    assert type(pc) is PointCloud and pc.n_vertices == 2


def test_ply_fixture_ascii_mixed_with_face_colours():
    with pytest.warns(GromovWarning, match=r"mixed_ascii\.ply: triangulated 1 polygon"):
        m = load(FIXTURES / "mixed_ascii.ply")
    np.testing.assert_array_equal(m.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])


def test_ply_binary_big_endian_mixed_lists(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], ">f4")
    head = ("ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty float x\n"
            "property float y\nproperty float z\nelement face 2\n"
            "property list uchar uint vertex_indices\nend_header\n").encode()
    faces = struct.pack(">B3I", 3, 1, 4, 2) + struct.pack(">B4I", 4, 0, 1, 2, 3)
    path = write(tmp_path / "be.ply", head + v.tobytes() + faces)
    with pytest.warns(GromovWarning, match="triangulated 1 polygon"):
        m = load(path)
    np.testing.assert_array_equal(m.faces, [[1, 4, 2], [0, 1, 2], [0, 2, 3]])
    np.testing.assert_array_equal(m.vertices, v.astype(float))


def test_ply_vertex_only_is_point_cloud(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
            "property double z\nproperty uchar red\nend_header\n0.5 1 2 255\n3 4 5 0\n")
    pc = load_quiet(write(tmp_path / "p.ply", text))
    assert type(pc) is PointCloud
    np.testing.assert_array_equal(pc.vertices, [[0.5, 1, 2], [3, 4, 5]])


def test_stl_ascii_fixture_merges_corners():
    m = load_quiet(FIXTURES / "tetra_ascii.stl")
    assert m.n_vertices == 4 and m.n_faces == 4 and m.boundary_loops == []
    np.testing.assert_array_equal(m.vertices, [[0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 1]])


def test_tosca_fixture_one_based():
    m = load_quiet(FIXTURES / "tetra.tri")
    np.testing.assert_array_equal(m.faces[0], [0, 2, 1])
    assert m.boundary_loops == [] and m.euler_characteristic == 2
    assert m.area == pytest.approx(1.5 + np.sqrt(3) / 2)


@pytest.mark.parametrize("vert,tri", [("X.VERT", "X.TRI"), ("Y.Vert", "Y.tri"), ("Z.vert.gz", "Z.TRI")])
def test_tosca_pair_found_whatever_the_case_of_its_extensions(tmp_path, vert, tri):
    import gzip

    data = (FIXTURES / "tetra.vert").read_bytes()
    (tmp_path / vert).write_bytes(gzip.compress(data) if vert.endswith(".gz") else data)
    (tmp_path / tri).write_bytes((FIXTURES / "tetra.tri").read_bytes())
    for name in (vert, tri):
        m = load_quiet(tmp_path / name)
        assert m.n_vertices == 4 and m.n_faces == 4 and m.euler_characteristic == 2


# --------------------------------------------------------------------------- repair on load
def test_repair_on_load_keeps_file_ids(tmp_path):
    # vertex 4 duplicates vertex 1, vertex 2 is unused, face 2 is degenerate (repeated index)
    text = ("OFF\n6 4 0\n0 0 0\n1 0 0\n9 9 9\n0 1 0\n1 0 0\n1 1 0\n"
            "3 0 1 3\n3 4 5 3\n3 0 0 1\n3 1 5 3\n")
    path = write(tmp_path / "dirty.off", text)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        m = load(path)
    msgs = [str(w.message) for w in rec if issubclass(w.category, GromovWarning)]
    assert any("duplicate vertices" in s and str(path) in s for s in msgs), msgs
    assert any("degenerate" in s for s in msgs) and any("unreferenced" in s for s in msgs)
    file_v = np.array([[0, 0, 0], [1, 0, 0], [9, 9, 9], [0, 1, 0], [1, 0, 0], [1, 1, 0]], float)
    np.testing.assert_array_equal(m.input_ids, [0, 1, 3, 5])
    np.testing.assert_array_equal(m.vertices, file_v[m.input_ids])
    # every face, mapped back to file ids, is one of the file's non-degenerate faces (4 -> 1)
    file_faces = {(0, 1, 3), (1, 5, 3)}
    assert {tuple(m.input_ids[f]) for f in m.faces} == file_faces
    assert m.n_faces == 2  # face "4 5 3" became a repeat of "1 5 3"


def test_repair_false_keeps_everything(tmp_path):
    text = "OFF\n5 2 0\n0 0 0\n1 0 0\n0 1 0\n7 7 7\n1 0 0\n3 0 1 2\n3 0 0 1\n"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = load(write(tmp_path / "raw.off", text), repair=False)
    assert m.n_vertices == 5 and m.n_faces == 2


def test_nonmanifold_and_components_logged_not_raised(tmp_path, caplog):
    # three triangles on one edge (non-manifold) plus a separate triangle
    text = ("OFF\n8 4 0\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n5 5 5\n6 5 5\n5 6 5\n"
            "3 0 1 2\n3 1 0 3\n3 0 1 4\n3 5 6 7\n")
    path = write(tmp_path / "nm.off", text)
    with caplog.at_level(logging.INFO, logger="gromov.io"):
        m = load_quiet(path)
    assert m.n_faces == 4
    info = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
    assert any("1 non-manifold edges" in s and str(path) in s for s in info), info
    assert any("2 connected components" in s for s in info), info


# --------------------------------------------------------------------------- error paths
def test_missing_file(tmp_path):
    path = tmp_path / "nope.off"
    with raises_naming(path, MeshFileNotFoundError, "no such file") as info:
        load(path)
    assert isinstance(info.value, FileNotFoundError) and isinstance(info.value, MeshFormatError)


def test_directory(tmp_path):
    d = tmp_path / "dir.off"
    d.mkdir()
    with raises_naming(d, MeshFormatError, "is a directory"):
        load(d)


def test_unknown_extension_lists_supported(tmp_path):
    path = write(tmp_path / "mesh.abc", "1 2 3\n")
    with raises_naming(path, match=r"unknown mesh format \(extension '\.abc'\).*\.off.*\.obj"
                                   r".*\.ply.*\.stl.*\.vert.*\.tri.*\.xyz.*\.mat.*\.vtk.*\.vtu.*\.msh"
                                   r".*\.mesh \(each optionally followed by \.gz\)"):
        load(path)
    with raises_naming(tmp_path / "noext", match="no extension"):
        load(tmp_path / "noext")
    with raises_naming(path, match="unknown file_type 'abc'"):
        load(path, file_type="abc")


@pytest.mark.parametrize("name,text", [("e.off", ""), ("e.off", "  \n\n"), ("e.obj", ""),
                                       ("e.ply", ""), ("e.stl", ""), ("e.vert", ""), ("e.mat", ""),
                                       ("e.xyz", ""), ("e.xyz", "# only a comment\n"),
                                       *[pytest.param(f"e.{e}", "", marks=needs_meshio)
                                         for e in MESHIO]])
def test_empty_file(tmp_path, name, text):
    path = write(tmp_path / name, text)
    write(tmp_path / "e.tri", "1 2 3\n")
    with raises_naming(path, match="empty"):
        load(path)


def test_empty_after_comments_and_empty_gzip(tmp_path):
    path = write(tmp_path / "c.off", "# only a comment\n\n")
    with raises_naming(path, match="empty"):
        load(path)
    path = write(tmp_path / "z.off.gz", gzip.compress(b""))
    with raises_naming(path, match="empty after decompression"):
        load(path)


@pytest.mark.parametrize("text,match", [
    ("OOF\n3 1 0\n", "bad header: expected 'OFF' on line 1"),
    ("ply\nformat ascii 1.0\n", "bad header: expected 'OFF'"),
    ("3 1 0\n0 0 0\n", "bad header: expected 'OFF'"),
    ("OFF\n", "counts are missing"),
    ("OFF\n3 one 0\n0 0 0\n", r"bad header: line 2 should hold 'n_vertices n_faces"),
    ("OFF 3\n0 0 0\n", "bad header: line 1"),
    ("OFF\n3 -1 0\n", "bad header"),
    ("OFF\n0 0 0\n", "0 vertices"),
    ("OFF BINARY\n", "binary OFF is not supported"),
    ("4OFF\n3 1 0\n", "unsupported OFF variant '4OFF'"),
])
def test_off_bad_header(tmp_path, text, match):
    path = write(tmp_path / "h.off", text)
    with raises_naming(path, match=match):
        load(path)


def test_off_truncated_vertices_and_faces(tmp_path, sphere):
    save(sphere, tmp_path / "s.off")
    lines = (tmp_path / "s.off").read_text().splitlines(keepends=True)
    path = write(tmp_path / "tv.off", "".join(lines[:20]))
    with raises_naming(path, match=r"truncated: the header announces 42 vertices and 80 faces "
                                   r"but only 18 of the 42 vertex lines"):
        load(path)
    path = write(tmp_path / "tf.off", "".join(lines[:-5]))
    with raises_naming(path, match=r"truncated.*only 75 of the 80 face lines"):
        load(path)
    # a gzip file cut short is bad gzip data
    gz = gzip.compress("".join(lines).encode())
    path = write(tmp_path / "cut.off.gz", gz[: len(gz) // 2])
    with raises_naming(path, match="bad gzip data"):
        load(path)


def test_off_extra_lines(tmp_path):
    path = write(tmp_path / "x.off", TRI + "3 0 2 1\n")
    with raises_naming(path, match=r"1 more non-comment lines \(first at line 7\)"):
        load(path)


@pytest.mark.parametrize("text,match", [
    (TRI.replace("1 0 0\n", "1 x 0\n"), r"line 4: non-numeric value 'x' in vertex"),
    (TRI.replace("1 0 0\n", "1 0\n"), r"line 4: vertex needs 3 values, found 2"),
    (TRI.replace("3 0 1 2", "3 0 a 2"), r"line 6: vertex index 'a' is not an integer"),
    (TRI.replace("3 0 1 2", "3 0 1.5 2"), r"line 6: vertex index '1.5' is not an integer"),
    (TRI.replace("3 0 1 2", "three 0 1 2"), r"line 6: face vertex count 'three'"),
    (TRI.replace("3 0 1 2", "2 0 1"), r"line 6: a face needs at least 3 vertices, found 2"),
    (TRI.replace("3 0 1 2", "4 0 1 2"), r"line 6: face announces 4 vertices but lists only 3"),
])
def test_off_malformed_lines(tmp_path, text, match):
    path = write(tmp_path / "m.off", text)
    with raises_naming(path, match=match):
        load(path)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "NaN"])
def test_non_finite_coordinates(tmp_path, value):
    path = write(tmp_path / "n.off", TRI.replace("1 0 0\n", f"1 {value} 0\n"))
    with raises_naming(path, match=r"1 vertices have NaN or infinite coordinates, first vertex 1 "
                                   r"\(line 4\)"):
        load(path)


def test_negative_and_out_of_range_indices(tmp_path):
    path = write(tmp_path / "neg.off", TRI.replace("3 0 1 2", "3 0 -1 2"))
    with raises_naming(path, match=r"face 0 \(line 6\) has negative vertex index -1"):
        load(path)
    # 1-based indices in an OFF file: the largest is out of range
    path = write(tmp_path / "one.off", TRI.replace("3 0 1 2", "3 1 2 3"))
    with raises_naming(path, match=r"out-of-range vertex index 3: valid indices are 0\.\.2 "
                                   r"\(3 vertices, 0-based\)"):
        load(path)


def test_bad_gzip(tmp_path):
    path = write(tmp_path / "plain.off.gz", TRI)
    with raises_naming(path, match="bad gzip data: the name ends in .gz but the file is not"):
        load(path)
    path = write(tmp_path / "junk.off.gz", b"\x1f\x8b" + b"\x00garbage" * 5)
    with raises_naming(path, match="bad gzip data"):
        load(path)


def test_vert_without_tri_and_tri_without_vert(tmp_path):
    v = write(tmp_path / "a.vert", "0 0 0\n1 0 0\n0 1 0\n")
    with raises_naming(v, MeshFileNotFoundError, r"partner file .*a\.tri not found") as info:
        load(v)
    assert isinstance(info.value, FileNotFoundError)
    t = write(tmp_path / "b.tri", "1 2 3\n")
    with raises_naming(t, MeshFileNotFoundError, r"partner file .*b\.vert not found"):
        load(t)


def test_tosca_errors_name_the_right_file(tmp_path):
    write(tmp_path / "c.vert", "0 0 0\n1 0 0\n0 1 0\n")
    t = write(tmp_path / "c.tri", "1 2 3\n0 1 2\n")
    with raises_naming(t, match=r"c\.tri: face 1 \(line 2\) has negative vertex index 0: "
                                r"valid indices are 1\.\.3 \(3 vertices, 1-based\)"):
        load(tmp_path / "c.vert")
    write(t, "1 2 3 4\n")
    with raises_naming(t, match="line 1: a triangle needs exactly 3 vertex indices, found 4"):
        load(tmp_path / "c.vert")
    v = write(tmp_path / "c.vert", "0 0 0\n1 0 0 7\n0 1 0\n")
    with raises_naming(v, match=r"c\.vert: line 2: vertex needs exactly 3 values, found 4"):
        load(tmp_path / "c.tri")


def test_mesh_validation_error_becomes_format_error(tmp_path):
    # every face is degenerate: repair leaves no triangle (a MeshError), re-raised with the name
    path = write(tmp_path / "deg.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        with raises_naming(path, MeshFormatError, "no valid triangle left") as info:
            load(path)
    assert isinstance(info.value, MeshError)


@pytest.mark.parametrize("text,match", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", r"line 4: vertex index 0 is invalid \(OBJ indices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", r"line 4: a face needs at least 3 vertices, found 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", r"line 4: vertex reference 'x' is not an integer"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", r"relative vertex index -4 points before"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", r"face 0 \(line 4\) has out-of-range vertex index "
                                             r"4: valid indices are 1\.\.3"),
    ("v 0 0 0\nv 1 0 z\n", r"line 2: non-numeric value 'z'"),
    ("hello world\n", r"no vertices: the file has no 'v' lines"),
])
def test_obj_errors(tmp_path, text, match):
    path = write(tmp_path / "bad.obj", text)
    with raises_naming(path, match=match):
        load(path)


PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n")


@pytest.mark.parametrize("text,match", [
    ("solid x\n", "bad header: a PLY file starts with 'ply'"),
    ("ply\nformat ascii 1.0\nelement vertex 3\n", "no 'end_header' line"),
    ("ply\nformat zip 1.0\nend_header\n", "bad header line 2"),
    ("ply\nelement vertex 1\nproperty float x\nend_header\n0\n", "no 'format' line"),
    (PLY_HEAD + "0 0 0\n1 0 0\n", r"truncated.*only 2 of the 3 'vertex' lines"),
    (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n", r"truncated.*only 0 of the 1 'face' lines"),
    (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n", r"1 more lines"),
    (PLY_HEAD + "0 0 0\n1 q 0\n0 1 0\n3 0 1 2\n", r"line 11: non-numeric value 'q'"),
    (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", r"face 0 \(line 13\) has out-of-range vertex "
                                                  r"index 7"),
    (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n", r"line 13: a face needs at least 3 vertices"),
    (PLY_HEAD.replace("property float z\n", "") + "0 0\n1 0\n0 1\n3 0 1 2\n",
     r"lacks x, y, z"),
])
def test_ply_errors(tmp_path, text, match):
    path = write(tmp_path / "bad.ply", text)
    with raises_naming(path, match=match):
        load(path)


def test_ply_binary_truncated_and_padded(tmp_path, sphere):
    save(sphere, tmp_path / "s.ply")
    data = (tmp_path / "s.ply").read_bytes()
    path = write(tmp_path / "t.ply", data[:-7])
    with raises_naming(path, match="truncated: the header announces 42 vertex, 80 face records"):
        load(path)
    path = write(tmp_path / "t2.ply", data[:300])
    with raises_naming(path, match="truncated"):
        load(path)
    path = write(tmp_path / "extra.ply", data + b"\x01\x02\x03")
    with raises_naming(path, match="3 bytes of data follow them"):
        load(path)


def test_stl_errors(tmp_path, sphere):
    save(sphere, tmp_path / "s.stl")
    data = (tmp_path / "s.stl").read_bytes()
    path = write(tmp_path / "t.stl", data[:-30])
    with raises_naming(path, match=r"binary STL of wrong size: the header announces 80 triangles"):
        load(path)
    path = write(tmp_path / "short.stl", b"not an stl")
    with raises_naming(path, match="not an STL file"):
        load(path)
    text = (FIXTURES / "tetra_ascii.stl").read_text()
    path = write(tmp_path / "ta.stl", text[: text.rindex("endfacet")])
    with raises_naming(path, match="ASCII STL is truncated or malformed: 4 'facet', 3 'endfacet'"):
        load(path)
    path = write(tmp_path / "ta2.stl", text.replace("vertex 1 0 0", "vertex 1 O 0", 1))
    with raises_naming(path, match="non-numeric vertex coordinate"):
        load(path)
    path = write(tmp_path / "empty.stl", "solid empty\nendsolid empty\n")
    with raises_naming(path, match="holds no triangles"):
        load(path)


@pytest.mark.parametrize("source", with_meshio(
    ["s.off", "s.obj", "s.ply", "s.stl", "s.mat", "s.vtk", "s.vtu", "s.msh", "s.mesh",
     "square_quads.off", "cube_quads.obj", "mixed_ascii.ply", "tetra_ascii.stl",
     "square_2d.mesh"]))
def test_damaged_files_raise_only_mesh_format_error(tmp_path, source):
    """Cut or corrupt a valid file anywhere: load works or raises MeshFormatError, nothing else."""
    if source.startswith("s."):
        save(icosphere(1), tmp_path / source)
        data = (tmp_path / source).read_bytes()
    else:
        data = (FIXTURES / source).read_bytes()
    rng = np.random.default_rng(0)
    path = tmp_path / ("damaged" + Path(source).suffix)
    variants = [data[:i] for i in np.linspace(0, len(data) - 1, 25).astype(int)]
    for _ in range(40):
        b = bytearray(data)
        for i in rng.integers(len(b), size=rng.integers(1, 4)):
            b[i] = int(rng.choice(list(b" 0123456789.-eq\n#/\x00\xff")))
        variants.append(bytes(b))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)
        for v in variants:
            path.write_bytes(v)
            try:
                load(path)
            except MeshFormatError as exc:
                assert str(path) in str(exc)


def test_path_type_error():
    with pytest.raises(TypeError, match="path must be a str or os.PathLike, got int"):
        load(3)


def test_save_errors(tmp_path, sphere):
    pc = PointCloud(sphere.vertices)
    for name in ("p.stl", "p.vert", "p.tri.gz"):
        with raises_naming(tmp_path / name, match="point cloud"):
            save(pc, tmp_path / name)
    with raises_naming(tmp_path / "m.abc", match="unknown mesh format.*supported: .off"):
        save(sphere, tmp_path / "m.abc")
    with pytest.raises(TypeError, match="shape must be a gromov Mesh or PointCloud, got ndarray"):
        save(sphere.vertices, tmp_path / "m.off")


# --------------------------------------------------------------------------- MATLAB .mat
# a tetrahedron in the TOSCA layout: column vectors X, Y, Z and 1-based TRIV stored as doubles
TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TET_TRIV = np.array([[1, 3, 2], [1, 2, 4], [2, 3, 4], [1, 4, 3]], float)


def tosca_struct(**fields):
    """TOSCA's ``surface`` struct for the tetrahedron; a field given as ``None`` is left out."""
    out = {"X": TET_V[:, :1], "Y": TET_V[:, 1:2], "Z": TET_V[:, 2:], "TRIV": TET_TRIV}
    out.update(fields)
    return {k: v for k, v in out.items() if v is not None}


def savemat(path: Path, variables: dict) -> Path:
    from scipy.io import savemat as _savemat

    _savemat(path, variables)
    return path


@pytest.mark.parametrize("variables", [
    {"surface": tosca_struct()},           # TOSCA
    {"shape": tosca_struct(), "n": 4.0},   # another struct name, other variables ignored
    tosca_struct(),                        # X, Y, Z, TRIV at the top level
])
def test_mat_tosca_layout_one_based(tmp_path, variables):
    m = load_quiet(savemat(tmp_path / "tet.mat", variables))
    np.testing.assert_array_equal(m.vertices, TET_V)
    # TRIV row (1, 3, 2) is the triangle of vertices 0, 2, 1: (0,0,0), (0,1,0), (1,0,0)
    np.testing.assert_array_equal(m.faces[0], [0, 2, 1])
    np.testing.assert_array_equal(m.vertices[m.faces[0]], [[0, 0, 0], [0, 1, 0], [1, 0, 0]])
    np.testing.assert_array_equal(m.faces, TET_TRIV.astype(int) - 1)
    assert m.boundary_loops == [] and m.euler_characteristic == 2
    assert m.area == pytest.approx(1.5 + np.sqrt(3) / 2)


def test_mat_integer_triv_and_row_vectors(tmp_path):
    # MATLAB code also stores TRIV as int32 and coordinates as row vectors
    variables = {"surface": tosca_struct(X=TET_V[:, 0][None], TRIV=TET_TRIV.astype(np.int32))}
    m = load_quiet(savemat(tmp_path / "int.mat", variables))
    np.testing.assert_array_equal(m.faces, TET_TRIV.astype(int) - 1)
    np.testing.assert_array_equal(m.vertices, TET_V)


@pytest.mark.parametrize("triv", [None, np.zeros((0, 0))])
def test_mat_point_cloud(tmp_path, triv):
    pc = load_quiet(savemat(tmp_path / "pc.mat", {"surface": tosca_struct(TRIV=triv)}))
    assert type(pc) is PointCloud
    np.testing.assert_array_equal(pc.vertices, TET_V)


def test_mat_written_in_tosca_layout(tmp_path, sphere):
    from scipy.io import loadmat

    save(sphere, tmp_path / "s.mat")
    data = (tmp_path / "s.mat").read_bytes()
    assert data.startswith(b"MATLAB 5.0 MAT-file, written by gromov")
    surface = loadmat(tmp_path / "s.mat")["surface"]  # as MATLAB users read it
    assert surface.dtype.names == ("X", "Y", "Z", "TRIV") and surface.shape == (1, 1)
    for j, c in enumerate("XYZ"):
        col = surface[c][0, 0]
        assert col.shape == (sphere.n_vertices, 1) and col.dtype == np.float64
        np.testing.assert_array_equal(col[:, 0], sphere.vertices[:, j])
    triv = surface["TRIV"][0, 0]
    assert triv.dtype == np.float64 and triv.shape == (sphere.n_faces, 3)
    np.testing.assert_array_equal(triv, sphere.faces + 1)  # 1-based
    save(sphere, tmp_path / "again.mat")  # no time stamp in the header: same bytes
    assert (tmp_path / "again.mat").read_bytes() == data


def _cell_column():
    cell = np.empty((4, 1), object)
    for i in range(4):
        cell[i, 0] = np.array([[float(i)]])
    return cell


def _struct_array():
    a = np.zeros((1, 2), dtype=[("X", "O"), ("Y", "O"), ("Z", "O")])
    for i in range(2):
        a[0, i] = (TET_V[:, :1], TET_V[:, 1:2], TET_V[:, 2:])
    return a


@pytest.mark.parametrize("variables,match", [
    ({"foo": np.eye(3)}, r"no mesh found: expected a struct \(such as TOSCA's 'surface'\) with "
                         r"fields X, Y, Z.*the file holds 'foo'"),
    ({"surface": tosca_struct(Z=None)}, r"struct 'surface' lacks Z \(found X, Y, TRIV\)"),
    ({"X": TET_V[:, 0], "Y": TET_V[:, 1]}, r"top-level variables lack Z \(found X, Y\)"),
    ({"surface": tosca_struct(), "shape": tosca_struct()},
     r"2 meshes in one file \(struct 'surface', struct 'shape'\); keep only one"),
    ({"surface": tosca_struct(), **tosca_struct()},
     r"2 meshes in one file \(struct 'surface', top-level variables\)"),
    ({"surface": _struct_array()}, r"variable 'surface' is a 1 x 2 struct array"),
    ({"surface": tosca_struct(Z=TET_V[:3, 2:])},
     r"X, Y and Z of struct 'surface' have different lengths \(4, 4, 3\)"),
    ({"surface": tosca_struct(X="abcd")}, r"field 'X' of struct 'surface' holds text, not real"),
    ({"surface": tosca_struct(Y=_cell_column())}, r"field 'Y' of struct 'surface' holds a cell "
                                                  r"array or struct"),
    ({"surface": tosca_struct(Z=TET_V[:, 2:] + 1j)}, r"field 'Z' .* holds complex numbers"),
    ({"X": TET_V[:, 0], "Y": TET_V[:, 1], "Z": TET_V[:, 2], "TRIV": "1 2 3"},
     r"variable 'TRIV' holds text"),
    ({"surface": tosca_struct(X=TET_V[:, :2])},
     r"field 'X' of struct 'surface' must be a vector \(one coordinate per vertex\), got a 4 x 2"),
    ({"surface": tosca_struct(TRIV=np.ones((4, 4)))},
     r"field 'TRIV' of struct 'surface' must be an m x 3 matrix of 1-based vertex indices, got "
     r"a 4 x 4 array$"),
    ({"surface": tosca_struct(TRIV=TET_TRIV.T)}, r"got a 3 x 4 array \(transposed\?"),
    ({"surface": tosca_struct(TRIV=TET_TRIV + [[0, 0, 0], [0, 0.5, 0], [0, 0, 0], [0, 0, 0]])},
     r"non-integer vertex indices in 1 triangle, first triangle 1: \[1\.0, 2\.5, 4\.0\]"),
    ({"surface": tosca_struct(TRIV=TET_TRIV - 1)},
     r"face 0 has negative vertex index 0: valid indices are 1\.\.4 \(4 vertices, 1-based\)"),
    ({"surface": tosca_struct(TRIV=TET_TRIV + 1)},
     r"face 1 has out-of-range vertex index 5: valid indices are 1\.\.4 \(4 vertices, "
     r"1-based\)"),
    ({"surface": tosca_struct(X=TET_V[:, :1] * np.nan)}, r"4 vertices have NaN or infinite"),
])
def test_mat_errors(tmp_path, variables, match):
    path = savemat(tmp_path / "bad.mat", variables)
    with raises_naming(path, match=match):
        load(path)


def _v73_header() -> bytes:
    # what MATLAB's save -v7.3 writes: a 128-byte MAT header with version 0x0200, then HDF5
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116)
    return text + bytes(8) + struct.pack("<H", 0x0200) + b"IM"


@pytest.mark.parametrize("data", [
    _v73_header().ljust(512, b"\0") + b"\x89HDF\r\n\x1a\n" + bytes(64),  # signature found
    _v73_header() + bytes(64),                                          # scipy refuses it
    b"\x89HDF\r\n\x1a\n" + bytes(64),                                   # a bare HDF5 file
])
def test_mat_v73_hdf5_rejected(tmp_path, data):
    path = write(tmp_path / "v73.mat", data)
    with raises_naming(path, match=r"MATLAB v7\.3 MAT-file \(HDF5\), which scipy\.io\.loadmat "
                                   r"cannot read; re-save it in MATLAB with save\(\.\.\., '-v7'\)"):
        load(path)


def test_mat_not_a_mat_file(tmp_path):
    path = write(tmp_path / "text.mat", "hello, this is not a MAT-file\n" * 10)
    with raises_naming(path, match="not a readable MATLAB MAT-file"):
        load(path)
    path = write(tmp_path / "plain.mat.gz", "hello")
    with raises_naming(path, match="bad gzip data: the name ends in .gz"):
        load(path)


# --------------------------------------------------------------------------- meshio formats
PTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [0, 0, 1]], float)


def meshio_write(path: Path, cells, points=PTS, **kw) -> Path:
    meshio = pytest.importorskip("meshio")
    module = {"vtk": meshio.vtk, "vtu": meshio.vtu, "msh": meshio.gmsh, "mesh": meshio.medit}
    module[path.suffix[1:]].write(str(path), meshio.Mesh(points, cells), **kw)
    return path


@needs_meshio
def test_meshio_files_written_as_documented(tmp_path, sphere):
    for ext in MESHIO:
        save(sphere, tmp_path / f"s.{ext}")
    assert (tmp_path / "s.vtk").read_bytes().startswith(
        b"# vtk DataFile Version 4.2\nwritten by meshio")
    assert b"\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 42 double\n" in \
        (tmp_path / "s.vtk").read_bytes()
    vtu = (tmp_path / "s.vtu").read_bytes()
    assert b'compressor="vtkZLibDataCompressor"' in vtu and b'type="Float64"' in vtu
    assert (tmp_path / "s.msh").read_bytes().startswith(b"$MeshFormat\n4.1 1 8\n")
    medit = (tmp_path / "s.mesh").read_text()
    assert medit.startswith("MeshVersionFormatted 2\nDimension 3\n")
    assert f"{sphere.vertices[0, 0]:.16e}" in medit  # 17 significant digits: exact


@needs_meshio
@pytest.mark.parametrize("ext", ["vtk", "vtu"])
def test_meshio_quads_fan_triangulated_in_block_order(tmp_path, ext):
    # a triangle block, a quad block and a line block (ignored); vertex 5 is used by no face
    path = meshio_write(tmp_path / f"q.{ext}", [("triangle", [[1, 4, 2]]),
                                                ("quad", [[0, 1, 2, 3]]), ("line", [[0, 5]])])
    with pytest.warns(GromovWarning, match=rf"q\.{ext}: triangulated 1 polygon.*2 faces -> 3"):
        m = load(path, repair=False)
    np.testing.assert_array_equal(m.vertices, PTS)
    np.testing.assert_array_equal(m.faces, [[1, 4, 2], [0, 1, 2], [0, 2, 3]])


def test_medit_fixture_2d_points_quads_edges():
    pytest.importorskip("meshio")
    with pytest.warns(GromovWarning, match=r"square_2d\.mesh: triangulated 1 polygon"):
        m = load(FIXTURES / "square_2d.mesh")
    # Dimension 2: z = 0 added; the Edges block is ignored; blocks in file order
    np.testing.assert_array_equal(m.vertices, [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0],
                                               [1, 1, 0], [2, 1, 0]])
    np.testing.assert_array_equal(m.faces, [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    assert m.area == pytest.approx(2.0)
    assert len(m.boundary_loops) == 1 and m.euler_characteristic == 1


@needs_meshio
def test_meshio_triangles_beside_tetrahedra_are_read(tmp_path):
    path = meshio_write(tmp_path / "mixed.msh", [("tetra", [[0, 1, 3, 5]]),
                                                 ("triangle", [[0, 1, 3]])], fmt_version="2.2",
                        binary=False)
    m = load(path, repair=False)
    np.testing.assert_array_equal(m.faces, [[0, 1, 3]])
    assert m.n_vertices == 6


@needs_meshio
@pytest.mark.parametrize("ext", ["vtk", "vtu", "mesh"])
def test_meshio_volume_mesh_rejected(tmp_path, ext):
    path = meshio_write(tmp_path / f"tet.{ext}", [("tetra", [[0, 1, 3, 5], [1, 2, 3, 5]])])
    with raises_naming(path, match=r"volume meshes are not supported \(the file has 2 tetra "
                                   r"cells and no triangles\): extract the boundary surface "
                                   r"first"):
        load(path)


@needs_meshio
def test_meshio_second_order_only_rejected(tmp_path):
    path = meshio_write(tmp_path / "t6.vtk", [("triangle6", [[0, 1, 2, 3, 4, 5]])])
    with raises_naming(path, match=r"second-order surface cells \(triangle6\) are not supported"):
        load(path)


@needs_meshio
def test_meshio_no_faces_is_point_cloud(tmp_path):
    path = meshio_write(tmp_path / "ln.vtk", [("line", [[0, 1]]), ("vertex", [[2]])])
    pc = load_quiet(path)
    assert type(pc) is PointCloud
    np.testing.assert_array_equal(pc.vertices, PTS)


MEDIT_TRI = "MeshVersionFormatted 2\nDimension 3\nVertices\n3\n0 0 0 0\n1 0 0 0\n0 1 0 0\n" \
            "Triangles\n1\n{}\nEnd\n"


@needs_meshio
@pytest.mark.parametrize("name,text,match", [
    ("g.vtk", "hello\n", r"cannot read as legacy VTK with meshio \(ReadError: Illegal VTK header"),
    ("g.vtu", "hello\n", r"cannot read as VTK XML \(\.vtu\) with meshio \(ReadError"),
    ("g.msh", "hello\n", r"cannot read as Gmsh with meshio \(ReadError"),
    ("g.mesh", "hello\n", r"cannot read as Medit with meshio \(ReadError: Unknown keyword 'hello'"),
    ("pd.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n"
               "0 0 0\n1 0 0\n0 1 0\nPOLYGONS 1 4\n3 0 1 2\n", r"not POLYDATA"),
    ("oor.mesh", MEDIT_TRI.format("1 2 4 0"), r"face 0 has out-of-range vertex index 4: valid "
                                              r"indices are 1\.\.3 \(3 vertices, 1-based\)"),
    ("zero.mesh", MEDIT_TRI.format("0 1 2 0"), r"face 0 has negative vertex index 0"),
    ("nan.mesh", MEDIT_TRI.format("1 2 3 0").replace("1 0 0 0", "nan 0 0 0"),
     r"1 vertices have NaN or infinite coordinates, first vertex 1"),
])
def test_meshio_errors(tmp_path, name, text, match):
    path = write(tmp_path / name, text)
    with raises_naming(path, match=match):
        load(path)


@needs_meshio
@pytest.mark.parametrize("ext", MESHIO)
def test_meshio_gzip_errors_name_the_gz_file(tmp_path, ext):
    path = write(tmp_path / f"g.{ext}.gz", gzip.compress(b"hello\n"))
    with raises_naming(path, match="cannot read as .* with meshio") as info:
        load(path)
    assert "gromov-" not in str(info.value)  # not the temporary file's name
    path = write(tmp_path / f"plain.{ext}.gz", b"hello")
    with raises_naming(path, match="bad gzip data: the name ends in .gz"):
        load(path)


@pytest.mark.parametrize("name", ["m.vtk", "m.vtu.gz", "m.msh", "m.mesh"])
def test_meshio_missing_says_what_to_install(tmp_path, monkeypatch, sphere, name):
    monkeypatch.setitem(sys.modules, "meshio", None)  # `import meshio` raises ImportError
    path = write(tmp_path / name, "anything")
    ext = name.split(".")[1]
    install = re.escape('needs meshio, an optional dependency: pip install "gromov[formats]"')
    with raises_naming(path, MissingDependencyError, rf"reading \.{ext} files {install}") as info:
        load(path)
    assert isinstance(info.value, ImportError) and isinstance(info.value, MeshFormatError)
    out = tmp_path / f"out.{ext}"
    with raises_naming(out, MissingDependencyError, rf"writing \.{ext} files {install}"):
        save(sphere, out)
    assert not out.exists()


# --------------------------------------------------------------------------- real data
def test_tosca_cat(data_dir, tmp_path):
    cat = load_quiet(data_dir / "tosca" / "cat0.off.gz")  # no repair needed: no warning
    assert (cat.n_vertices, cat.n_faces) == (27894, 55712)  # README: cat has 27894 vertices
    np.testing.assert_array_equal(cat.input_ids, np.arange(27894))
    assert cat.n_components == 1 and cat.is_edge_manifold
    # the scan is open: a sphere with two holes (chi = 2 - 2g - b, g = 0, b = 2)
    assert len(cat.boundary_loops) == 2 and cat.euler_characteristic == 0 and cat.genus == 0
    assert 150 < np.ptp(cat.bbox[:, 1]) < 250  # about 200 units long
    # another pose shares the vertex numbering and (for the cat) the triangulation
    cat1 = load_quiet(data_dir / "tosca" / "cat1.off.gz")
    np.testing.assert_array_equal(cat1.faces, cat.faces)
    assert not np.allclose(cat1.vertices, cat.vertices)
    # exact round trip of real data through PLY and compressed OFF
    for name in ("cat0.ply", "cat0.off.gz"):
        save(cat, tmp_path / name)
        back = load_quiet(tmp_path / name)
        np.testing.assert_array_equal(back.vertices, cat.vertices)
        np.testing.assert_array_equal(back.faces, cat.faces)


def test_tosca_truncated_copy_detected(data_dir, tmp_path):
    raw = gzip.decompress((data_dir / "tosca" / "wolf0.off.gz").read_bytes())
    cut = raw[: raw.rindex(b"\n", 0, len(raw) - 1000) + 1]  # drop the last few faces
    path = write(tmp_path / "wolf0_cut.off.gz", gzip.compress(cut))
    with raises_naming(path, match=r"truncated: the header announces 4344 vertices"):
        load(path)


def test_topkids_have_handles(data_dir):
    kid = load_quiet(data_dir / "topkids" / "kid01.off.gz")
    info = (data_dir / "topkids" / "kid01_info.txt").read_text()
    n = int(re.search(r"Number of vertices:\s*(\d+)", info).group(1))
    nf = int(re.search(r"Number of faces:\s*(\d+)", info).group(1))
    assert (kid.n_vertices, kid.n_faces) == (n, nf) == (8608, 17150)
    assert kid.n_components == 1
    assert kid.euler_characteristic <= 0  # merged self-contacts: handles
    assert kid.euler_characteristic == -7


def test_tosca_cat_mat_round_trip(data_dir, tmp_path):
    from scipy.io import loadmat

    cat = load_quiet(data_dir / "tosca" / "cat0.off.gz")
    for name in ("cat0.mat", "cat0.mat.gz"):
        save(cat, tmp_path / name)
        back = load_quiet(tmp_path / name)
        np.testing.assert_array_equal(back.vertices, cat.vertices)
        np.testing.assert_array_equal(back.faces, cat.faces)
    triv = loadmat(tmp_path / "cat0.mat")["surface"]["TRIV"][0, 0]
    assert triv.shape == (55712, 3) and (triv.min(), triv.max()) == (1, 27894)  # 1-based


@needs_meshio
@pytest.mark.parametrize("ext", MESHIO)
def test_tosca_cat_meshio_round_trip(data_dir, tmp_path, ext):
    cat = load_quiet(data_dir / "tosca" / "cat0.off.gz")
    save(cat, tmp_path / f"cat0.{ext}")
    back = load_quiet(tmp_path / f"cat0.{ext}")
    np.testing.assert_array_equal(back.vertices, cat.vertices)
    np.testing.assert_array_equal(back.faces, cat.faces)


@needs_meshio
def test_meshio_warnings_become_gromov_warnings_naming_the_file(tmp_path, capfd):
    import threading

    import meshio

    def open_msh(path):   # a Gmsh 2.2 file whose last section is never closed: meshio warns
        path.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n"
                        "$EndNodes\n$Elements\n1\n1 2 2 0 0 1 2 3\n$EndElements\n$Comments\nnot closed\n")
        return path

    p = open_msh(tmp_path / "open.msh")
    with pytest.warns(GromovWarning, match=r"open\.msh: meshio: \$Comments not closed"):
        m = load(p)
    assert m.n_faces == 1
    assert capfd.readouterr().err == ""               # nothing printed behind the warnings' back
    # outside our reads meshio's own behaviour is kept: it prints, and no GromovWarning
    with warnings.catch_warnings():
        warnings.simplefilter("error", GromovWarning)
        meshio.gmsh.common.warn("from elsewhere")
    assert "from elsewhere" in capfd.readouterr().err
    # several threads inside at once: each warning names its own thread's file
    from gromov.io import _meshio_warnings

    barrier = threading.Barrier(6)

    def inside(k):
        with _meshio_warnings(meshio, f"file{k}"):
            barrier.wait()
            meshio.gmsh.common.warn(f"from {k}")
            barrier.wait()

    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        threads = [threading.Thread(target=inside, args=(k,)) for k in range(6)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    msgs = sorted(str(w.message) for w in got if issubclass(w.category, GromovWarning))
    assert msgs == sorted(f"file{k}: meshio: from {k}" for k in range(6))
    meshio.gmsh.common.warn("after the threads")    # and none of them left its name behind
    assert "after the threads" in capfd.readouterr().err


def test_xyz_point_clouds(tmp_path, sphere):
    p = tmp_path / "scan.xyz"
    # blanks or commas, extra values per point ignored, comments and blank lines skipped
    p.write_text("# a scan\n0 0 0 0.1 0.2 0.3\n1.5,0,0\n\n0 1 -2e-3 255 0 0  # red\n")
    cloud = load(p)
    assert type(cloud) is PointCloud
    np.testing.assert_array_equal(cloud.vertices, [[0, 0, 0], [1.5, 0, 0], [0, 1, -2e-3]])
    with pytest.raises(MeshFormatError, match=r"bad\.xyz: line 2: point needs 3 values, found 2"):
        (tmp_path / "bad.xyz").write_text("0 0 0\n1 2\n")
        load(tmp_path / "bad.xyz")
    with pytest.raises(MeshFormatError, match=r"word\.xyz: line 1: non-numeric value 'x'"):
        (tmp_path / "word.xyz").write_text("x y z\n")
        load(tmp_path / "word.xyz")
    with pytest.raises(MeshFormatError, match="empty"):
        (tmp_path / "empty.xyz").write_text("# nothing\n")
        load(tmp_path / "empty.xyz")
    (tmp_path / "csv.xyz").write_text("1.5, 2, 3\n4,5,6,7\n")   # comma-separated, blanks beside commas
    np.testing.assert_array_equal(load(tmp_path / "csv.xyz").vertices, [[1.5, 2, 3], [4, 5, 6]])
    with pytest.raises(MeshFormatError, match=r"dec\.xyz: line 2: both commas and blanks.*decimal commas"):
        (tmp_path / "dec.xyz").write_text("1 2 3\n1,5 2,25 3,0\n")
        load(tmp_path / "dec.xyz")
    with pytest.raises(MeshFormatError, match="would lose the mesh's faces"):
        save(sphere, tmp_path / "mesh.xyz")
    assert not (tmp_path / "mesh.xyz").exists()
