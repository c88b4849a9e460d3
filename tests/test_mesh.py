"""Facts about meshes: topology invariants, areas, immutability, validation, repair."""

import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

import gromov
from gromov import GromovWarning, Mesh, MeshError, PointCloud, repair
from gromov.shapes import grid, icosphere, rolled_grid, torus


def test_sphere_invariants():
    m = icosphere(4)
    assert m.n_vertices == 2562 and m.n_faces == 5120
    assert m.euler_characteristic == 2 and m.genus == 0
    assert m.boundary_loops == [] and m.is_edge_manifold and m.n_components == 1
    assert abs(m.area - 4 * np.pi) / (4 * np.pi) < 0.01
    np.testing.assert_allclose(m.vertex_areas.sum(), m.area)


def test_grid_boundary_and_torus_genus():
    g = grid(11, 6)
    assert g.euler_characteristic == 1 and g.genus == 0
    (loop,) = g.boundary_loops
    assert len(loop) == 2 * (11 + 6) - 4
    # consecutive loop vertices are boundary edges
    be = {tuple(e) for e in g.boundary_edges.tolist()}
    for a, b in zip(loop, np.roll(loop, -1)):
        assert (min(a, b), max(a, b)) in be
    t = torus()
    assert t.euler_characteristic == 0 and t.genus == 1 and t.boundary_loops == []


def test_rolled_grid_keeps_edge_lengths_nearly():
    # chords of a circle are shorter than arcs, by at most (h/r)^2/24 relatively
    f, r = grid(), rolled_grid()
    np.testing.assert_array_equal(f.edges, r.edges)
    rel = (f.edge_lengths - r.edge_lengths) / f.edge_lengths
    assert rel.min() >= -1e-12 and rel.max() < 1e-3


def test_adjacency_symmetric_with_edge_lengths():
    m = icosphere(2)
    a = m.adjacency
    assert (a != a.T).nnz == 0
    e = m.edges[5]
    assert a[e[0], e[1]] == pytest.approx(np.linalg.norm(m.vertices[e[0]] - m.vertices[e[1]]))


def test_arrays_are_immutable_copies():
    v = icosphere(1).vertices.copy()
    f = icosphere(1).faces.copy()
    m = Mesh(v, f)
    v[0] = 100.0  # the mesh holds its own copy
    assert m.vertices[0, 0] != 100.0
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 1.0
    with pytest.raises(ValueError):
        m.faces[0, 0] = 1
    with pytest.raises(ValueError):
        m.vertex_areas[0] = 1.0


@pytest.mark.parametrize(
    "vertices, faces, match",
    [
        (np.zeros((3, 2)), [[0, 1, 2]], r"shape \(n, 3\)"),
        (np.zeros((0, 3)), [[0, 1, 2]], "empty"),
        ([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], [[0, 1, 2]], "non-finite"),
        ([[0, 0, 0], [1, 0, np.inf], [0, 1, 0]], [[0, 1, 2]], "non-finite"),
        (np.eye(3), [[0, 1, -1]], "negative vertex index -1"),
        (np.eye(3), [[0, 1, 3]], "refers to vertex 3 but the mesh has only 3"),
        (np.eye(3), [[0, 1, 2, 0]], r"shape \(m, 3\)"),
        (np.eye(3), np.zeros((0, 3), int), "empty"),
        (np.eye(3), [[0, 1, 1.5]], "integer vertex indices"),
        ([["a", "b", "c"]], [[0, 0, 0]], "numeric"),
    ],
)
def test_validation_errors(vertices, faces, match):
    with pytest.raises(MeshError, match=match):
        Mesh(vertices, faces)


def test_point_cloud_validation():
    with pytest.raises(MeshError, match="points"):
        PointCloud(np.ones((4, 2)))
    pc = PointCloud(np.random.default_rng(0).normal(size=(50, 3)))
    g = pc.knn_graph(5)
    assert (g != g.T).nnz == 0 and g.nnz >= 50 * 5
    with pytest.raises(ValueError, match="k must be"):
        pc.knn_graph(50)


def test_repair_merges_duplicates_drops_degenerate_and_unreferenced():
    base = icosphere(1)
    v = np.vstack([base.vertices, base.vertices[3], [[9.0, 9.0, 9.0]]])  # dup of 3, unreferenced
    n = base.n_vertices
    f = base.faces.copy()
    f[f == 3] = n  # half the faces use the duplicate
    f[::2][f[::2] == n] = 3
    f = np.vstack([f, [[0, 0, 1]], f[:1, ::-1]])  # a degenerate face and a repeated face
    m = Mesh(v, f)
    with pytest.warns(GromovWarning) as rec:
        fixed, report = repair(m, source="x.off")
    text = " ".join(str(r.message) for r in rec)
    assert "x.off" in text and "duplicate" in text and "unreferenced" in text
    assert report.duplicate_vertices == 1 and report.unreferenced_vertices == 1
    assert report.degenerate_faces == 1 and report.duplicate_faces == 1
    assert fixed.n_vertices == n
    # input ids still point at the input vertex with the same coordinates
    np.testing.assert_array_equal(fixed.vertices, m.vertices[fixed.input_ids])
    assert fixed.euler_characteristic == 2  # the repaired sphere is closed again


def test_repair_noop_returns_same_object():
    m = icosphere(1)
    fixed, report = repair(m)
    assert fixed is m and not report.changed


def test_components_and_nonmanifold_reporting():
    a, b = icosphere(1), icosphere(0)
    m = Mesh(np.vstack([a.vertices, b.vertices + 5]), np.vstack([a.faces, b.faces + a.n_vertices]))
    assert m.n_components == 2 and m.euler_characteristic == 4
    big = m.largest_component()
    assert big.n_vertices == a.n_vertices
    np.testing.assert_array_equal(big.input_ids, np.arange(a.n_vertices))
    # three triangles on one edge
    nm = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]],
              [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert not nm.is_edge_manifold
    np.testing.assert_array_equal(nm.nonmanifold_edges, [[0, 1]])


def test_summary_and_top_level_api():
    s = torus().summary()
    assert s["euler_characteristic"] == 0 and s["genus"] == 1 and s["components"] == 1
    for name in ("load", "save", "simplify", "metric_solver", "farthest_point_sampling", "fill_holes"):
        assert hasattr(gromov, name)


def test_tosca_cat_is_a_closed_sphere(tosca_cat0):
    m = tosca_cat0
    assert m.n_vertices == 27894
    s = m.summary()
    assert s["components"] == 1
    # a closed genus-0 surface: chi = 2 - b
    assert m.euler_characteristic == 2 - len(m.boundary_loops)


def test_topkids_have_handles(data_dir):
    kid = gromov.load(data_dir / "topkids" / "kid05.off.gz")
    assert kid.euler_characteristic < 2
    assert kid.genus >= 1


def test_fill_holes_closes_small_loops_and_keeps_the_vertices():
    from gromov.mesh import fill_holes
    from gromov.perturb import holes

    sphere = icosphere(4)
    holed = holes(sphere, 5, radius=0.15, seed=0).mesh
    assert len(holed.boundary_loops) == 5 and holed.euler_characteristic == 2 - 5
    closed, k = fill_holes(holed, 10.0)
    # one centroid per loop; a closed, oriented sphere again (chi = 2, every directed edge once)
    assert k == 5 and closed.n_vertices == holed.n_vertices + 5
    assert closed.euler_characteristic == 2 and len(closed.boundary_loops) == 0
    f = closed.faces
    directed = np.r_[f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]
    assert len(np.unique(directed, axis=0)) == len(directed)
    np.testing.assert_array_equal(closed.vertices[: holed.n_vertices], holed.vertices)
    np.testing.assert_array_equal(closed.input_ids[: holed.n_vertices], holed.input_ids)
    assert closed.input_ids[holed.n_vertices:].min() > holed.input_ids.max()   # not in the file
    # the fan's area is close to the removed disks' (a cap of radius 0.15 on the unit sphere)
    assert abs(closed.area - sphere.area) < 0.02 * sphere.area
    # loops at least max_perimeter long stay open; nothing to fill -> the same mesh
    per = [np.linalg.norm(holed.vertices[np.roll(l, -1)] - holed.vertices[l], axis=1).sum()
           for l in holed.boundary_loops]
    part, k = fill_holes(holed, float(np.median(per)))
    assert k == sum(p < np.median(per) for p in per) and len(part.boundary_loops) == 5 - k
    assert fill_holes(sphere, 1.0) == (sphere, 0)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="max_perimeter must be a positive number"):
            fill_holes(holed, bad)
    with pytest.raises(TypeError, match="fill_holes needs a Mesh"):
        fill_holes(PointCloud(np.zeros((3, 3))), 1.0)
    with pytest.raises(ValueError, match="one per connected component"):
        fill_holes(holed, [1.0, 2.0])
    # the other orientation: every face flipped, the fans follow
    flipped = Mesh(holed.vertices, holed.faces[:, ::-1])
    closed, k = fill_holes(flipped, 10.0)
    f = closed.faces
    directed = np.r_[f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]
    assert k == 5 and len(np.unique(directed, axis=0)) == len(directed)
    # two holes touching at one vertex (faces 0 and 81 of icosphere(2) share only vertex 43):
    # two loops, each through 43 once, and both are filled
    ico = icosphere(2)
    keep = np.ones(ico.n_faces, bool)
    keep[[0, 81]] = False
    bowtie = Mesh(ico.vertices, ico.faces[keep])
    assert len(bowtie.boundary_loops) == 2 and all(len(np.unique(l)) == len(l) for l in bowtie.boundary_loops)
    closed, k = fill_holes(bowtie, 100.0)
    assert k == 2 and closed.euler_characteristic == 2 and len(closed.boundary_edges) == 0


def test_holes_are_small_or_not_relative_to_their_own_component():
    """A separate small open patch keeps its rim open: the rim is long for the patch's area,
    though short next to the whole mesh's. A small hole in the big part is filled."""
    from gromov.mesh import component_areas, fill_holes
    from gromov.metrics import metric_solver
    from gromov.perturb import holes

    big = holes(icosphere(4), 1, radius=0.15, seed=0).mesh        # area ~ 4 pi, one small hole
    patch = grid(5, 5, width=0.3, height=0.3)                    # a 0.3 x 0.3 open square
    v = np.vstack([big.vertices, np.asarray(patch.vertices) + [3.0, 0.0, 0.0]])
    two = Mesh(v, np.vstack([big.faces, np.asarray(patch.faces) + big.n_vertices]))
    areas = component_areas(two)
    assert two.n_components == 2 and areas.sum() == pytest.approx(two.area)
    np.testing.assert_allclose(np.sort(areas), [0.09, big.area], rtol=1e-9)
    rim = [l for l in two.boundary_loops if l.min() >= big.n_vertices][0]
    rim_length = np.linalg.norm(v[np.roll(rim, -1)] - v[rim], axis=1).sum()      # 1.2
    assert rim_length < 0.5 * np.sqrt(two.area)            # "small" against the whole mesh ...
    assert rim_length > 0.5 * np.sqrt(areas.min())          # ... not against its own piece
    closed, k = fill_holes(two, 0.5 * np.sqrt(areas))
    assert k == 1 and len(closed.boundary_loops) == 1      # the sphere's hole only
    # the diffusion metric's default filling judges each loop against its own component
    s = metric_solver(two, "diffusion")
    assert s.inner.n_vertices == two.n_vertices + 1


def test_as_mesh_takes_arrays_and_mesh_objects():
    import trimesh

    from gromov.mesh import as_mesh

    m = icosphere(1)
    assert as_mesh(m) is m
    for shape in ((m.vertices, m.faces), [m.vertices.tolist(), m.faces.tolist()],
                  trimesh.Trimesh(m.vertices, m.faces, process=False)):
        a = as_mesh(shape)
        np.testing.assert_array_equal(a.vertices, m.vertices)
        np.testing.assert_array_equal(a.faces, m.faces)
        np.testing.assert_array_equal(a.input_ids, np.arange(m.n_vertices))
    # repaired like a file: a duplicated vertex is merged, ids still index the given array
    v = np.vstack([m.vertices, m.vertices[:1]])
    f = m.faces.copy()
    f[f == 0] = m.n_vertices          # every face of vertex 0 uses the duplicate instead
    f[0, f[0] == m.n_vertices] = 0    # ... except the first: two copies in use
    with pytest.warns(gromov.GromovWarning, match="merged"):
        a = as_mesh((v, f), name="arrays")
    assert a.n_vertices == m.n_vertices and set(a.input_ids) <= set(range(len(v)))
    np.testing.assert_array_equal(v[a.input_ids], a.vertices)
    with pytest.raises(TypeError, match="point cloud"):
        as_mesh(gromov.PointCloud(m.vertices))
    with pytest.raises(TypeError, match=r"\(vertices, faces\) pair.*got ndarray"):
        as_mesh(m.vertices)
    with pytest.raises(gromov.MeshError):
        as_mesh((m.vertices, m.faces + 1000))
    with pytest.raises(gromov.MeshError, match="ragged: vertices and faces must be arrays"):
        as_mesh(([[0, 0, 0], [1, 0]], [[0, 1, 2]]), name="ragged")


def test_match_takes_arrays():
    from gromov.shapes import grid, rolled_grid

    x, y = grid(21, 11), rolled_grid(21, 11)
    a = gromov.match(x, y, "geodesic", n_samples=15, resolution=None)
    b = gromov.match((x.vertices, x.faces), (np.array(y.vertices), np.array(y.faces)), "geodesic",
                     n_samples=15, resolution=None)
    assert a.distance == b.distance
    np.testing.assert_array_equal(a.x_to_y_vertex, b.x_to_y_vertex)


def _two_sheet_fold():
    """A closed surface that touches itself: an icosphere whose upper half is pressed down onto
    its lower half over a patch, each touching vertex a separate vertex of its own sheet at the
    same coordinates as one of the other sheet (a thin fold, as in scanned animal legs)."""
    base = icosphere(2)
    v, f = np.array(base.vertices), np.array(base.faces)
    n = len(v)
    up = np.flatnonzero(v[:, 2] > 1e-12)
    mirror = cKDTree(v).query(v[up] * [1, 1, -1])[1]      # the vertex below each upper one
    patch = np.hypot(v[up, 0], v[up, 1]) < 0.6
    v[up[patch]] = v[mirror[patch]]   # press the top down onto the bottom: the same coordinates
    assert patch.sum() >= 3
    return Mesh(v, f), n, int(patch.sum())


def test_repair_keeps_a_closed_surface_touching_itself_as_it_is():
    m, n, touching = _two_sheet_fold()
    assert m.is_edge_manifold and len(m.boundary_edges) == 0
    assert len(np.unique(m.vertices, axis=0)) == n - touching   # coincident vertices, two sheets
    with warnings.catch_warnings():
        warnings.simplefilter("error", GromovWarning)   # nothing to repair: no warning
        fixed, report = repair(m)
    assert fixed is m and not report.changed
    assert report.coincident_vertices_kept == 2 * touching


def test_repair_zips_a_seam_and_a_polygon_soup():
    base = icosphere(2)
    # a polygon soup: every triangle with its own three corners
    soup = Mesh(base.vertices[base.faces.ravel()], np.arange(3 * base.n_faces).reshape(-1, 3))
    with pytest.warns(GromovWarning, match=f"merged {3 * base.n_faces - base.n_vertices} duplicate"):
        fixed, report = repair(soup)
    assert fixed.n_vertices == base.n_vertices and fixed.euler_characteristic == 2
    assert fixed.is_edge_manifold and len(fixed.boundary_edges) == 0
    # every corner of the file stands for the vertex at its coordinates
    np.testing.assert_array_equal(fixed.vertices[fixed.file_index], soup.vertices)


def test_file_numbering_kept_when_the_last_vertices_go():
    base = icosphere(1)
    n = base.n_vertices
    # a copy of vertex 5 and an unused vertex at the end of the file
    v = np.vstack([base.vertices, base.vertices[5], [[7.0, 7.0, 7.0]]])
    with pytest.warns(GromovWarning):
        fixed, report = repair(Mesh(v, base.faces))
    assert fixed.n_vertices == n and fixed.n_file_vertices == n + 2
    np.testing.assert_array_equal(fixed.file_index, np.r_[np.arange(n), 5, -1])
    vals = fixed.per_file_vertex(np.arange(n) * 10)
    np.testing.assert_array_equal(vals, np.r_[np.arange(n) * 10, 50, -1])
    xyz = fixed.per_file_vertex(fixed.vertices)
    assert xyz.shape == (n + 2, 3) and np.isnan(xyz[-1]).all()
    np.testing.assert_array_equal(xyz[:-1], v[:-1])
    np.testing.assert_array_equal(fixed.from_input_ids([n, 5]), [5, 5])   # the copy: its vertex
    with pytest.raises(ValueError, match="not a vertex"):
        fixed.from_input_ids([n + 1])
    with pytest.raises(ValueError, match=f"one row per vertex \\({n}\\)"):
        fixed.per_file_vertex(np.zeros(n + 2))
    # shapes derived from it keep the file's numbering
    assert fixed.submesh(np.ones(n, bool)).n_file_vertices == n + 2
    assert fixed.with_vertices(fixed.vertices * 2).n_file_vertices == n + 2


def test_repair_drops_vertices_of_removed_faces_only_with_their_file_ids():
    base = icosphere(1)
    n = base.n_vertices
    # a needle: a face whose third corner lies on its first edge, with its own vertex
    a, b = base.faces[0, :2]
    v = np.vstack([base.vertices, 0.5 * (base.vertices[a] + base.vertices[b])])
    f = np.vstack([base.faces, [[a, b, n]]])
    with pytest.warns(GromovWarning) as rec:
        fixed, _ = repair(Mesh(v, f), source="needle.off")
    text = " ".join(str(r.message) for r in rec)
    assert "removed 1 degenerate" in text and "dropped 1 unreferenced" in text and "-1 or NaN" in text
    assert fixed.file_index[n] == -1 and fixed.n_file_vertices == n + 1
    assert (fixed.vertex_areas > 0).all()
