"""Hostile inputs: touching holes, extreme coordinates, degenerate shapes, resources, processes."""

import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import gromov
from gromov import GromovWarning, Mesh, MeshError, MetricError
from gromov.cli import main
from gromov.metrics import metric_solver
from gromov.shapes import icosphere

REPO = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------------- touching holes
def _disk_holes(mesh: Mesh, n_pairs: int, n_single: int, rho: float, seed: int, gap: float):
    """Remove the faces whose centroid lies within ``rho`` of a centre: ``n_pairs`` pairs of
    centres ``2 rho + gap`` apart (``gap=0``: tangent disks, whose holes touch at vertices) and
    ``n_single`` lone centres, all other centres at least ``4 rho`` apart. Returns the kept faces."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    V, F = mesh.vertices, mesh.faces
    centres: list = []
    for i in rng.permutation(len(V)):
        if len(centres) == 2 * n_pairs + n_single:
            break
        c1 = V[i]
        if centres and np.linalg.norm(np.array(centres) - c1, axis=1).min() < 4 * rho:
            continue
        if len(centres) < 2 * n_pairs:
            r = np.linalg.norm(V - c1, axis=1)
            near = np.flatnonzero(np.abs(r - (2 * rho + gap)) < 0.5 * rho)
            j = int(rng.choice(near))
            c2 = c1 + (2 * rho + gap) * (V[j] - c1) / r[j]
            if centres and np.linalg.norm(np.array(centres) - c2, axis=1).min() < 4 * rho:
                continue
            centres += [c1, c2]
        else:
            centres.append(c1)
    assert len(centres) == 2 * n_pairs + n_single
    return F[cKDTree(np.array(centres)).query(V[F].mean(axis=1))[0] >= rho]


def _write_split_off(vertices, faces, path, seed=0):
    """An OFF file in which every boundary vertex is stored twice, each face using either copy
    (as exporters that split a mesh along its boundaries write it); unused vertices left out."""
    used = np.unique(faces)
    new = np.full(len(vertices), -1)
    new[used] = np.arange(len(used))
    V, F = vertices[used], new[faces]
    m = Mesh(V, F)
    bv = np.unique(m.boundary_edges)
    copy = np.full(len(V), -1)
    copy[bv] = len(V) + np.arange(len(bv))
    pick = np.random.default_rng(seed).random(F.shape) < 0.5
    F = np.where(pick & (copy[F] >= 0), copy[F], F)
    V = np.vstack([V, V[bv]])
    with open(path, "w") as fh:
        fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
        np.savetxt(fh, V, fmt="%.17g")
        np.savetxt(fh, np.c_[np.full(len(F), 3), F], fmt="%d")


def _load_quietly(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GromovWarning)   # the duplicate vertices merged
        return gromov.load(path)


def _bowties(mesh: Mesh) -> int:
    """Vertices on more than two boundary edges: where two holes touch."""
    return int((np.bincount(mesh.boundary_edges.ravel(), minlength=mesh.n_vertices) > 2).sum())


def _working_vertices_in_no_face(w) -> int:
    return int((np.diff(w.mesh.vertex_faces[0]) == 0).sum())


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_touching_holes_simplify_to_a_surface(tmp_path, seed):
    """A 10k-vertex sphere with 41 holes, 15 pairs of which touch at vertices, stored with its
    boundary vertices duplicated: after the merge at loading, simplification to 3,000 keeps every
    working vertex in a face and the topology (Euler characteristic, components, the vertices
    where holes touch). Where the file splits a touching point into two whole fans, loading
    keeps them apart (merging would make the surface non-manifold there), which can cut off a
    piece: the working mesh then has the same pieces."""
    src = icosphere(5)
    faces = _disk_holes(src, 15, 11, 2.5 * src.mean_edge_length, seed, 0.0)
    _write_split_off(src.vertices, faces, tmp_path / "holes.off")
    mesh = _load_quietly(tmp_path / "holes.off")
    assert _bowties(mesh) >= 3   # holes do touch
    w = gromov.simplify(mesh, 3000)
    assert abs(w.n_vertices - 3000) <= 60
    assert _working_vertices_in_no_face(w) == 0
    assert w.mesh.euler_characteristic == mesh.euler_characteristic
    assert w.mesh.n_components == mesh.n_components
    assert _bowties(w.mesh) == _bowties(mesh)
    assert len(w.mesh.boundary_loops) == len(mesh.boundary_loops)
    assert w.mesh.is_edge_manifold


def test_boundary_loops_of_holes_touching_at_a_vertex():
    """Two triangles sharing one vertex (a bow-tie): two simple loops of three, each once."""
    m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.5]], [[0, 1, 2], [0, 3, 4]])
    loops = m.boundary_loops
    assert sorted(sorted(map(int, loop)) for loop in loops) == [[0, 1, 2], [0, 3, 4]]


def _star_pairs(mesh: Mesh, n_pairs: int, seed: int) -> np.ndarray:
    """Faces left after removing, ``n_pairs`` times, the faces around the two opposite
    neighbours ``c1``, ``c2`` of a valence-6 vertex ``w``: two hexagonal holes that share the
    vertex ``w`` and nothing else (a triangle of the surface on either side of ``w``)."""
    rng = np.random.default_rng(seed)
    F = mesh.faces
    indptr, incident = mesh.vertex_faces
    adj = mesh.adjacency
    removed = np.zeros(len(F), bool)
    used = np.zeros(mesh.n_vertices, bool)
    pairs = 0
    for w in rng.permutation(mesh.n_vertices):
        link = {}
        for f in incident[indptr[w]:indptr[w + 1]]:
            a, b = (int(v) for v in F[f] if v != w)
            link.setdefault(a, []).append(b)
            link.setdefault(b, []).append(a)
        if len(link) != 6 or used[list(link) + [w]].any():
            continue
        ring = [next(iter(link))]
        while len(ring) < 6:
            ring.append(next(v for v in link[ring[-1]] if v not in ring[-2:]))
        c1, c2 = ring[0], ring[3]
        common = set(adj.indices[adj.indptr[c1]:adj.indptr[c1 + 1]]) & set(
            adj.indices[adj.indptr[c2]:adj.indptr[c2 + 1]])
        if common != {int(w)}:
            continue
        around = np.isin(F, [c1, c2]).any(axis=1)
        removed |= around
        near = np.unique(F[around])
        used[np.unique(adj[near].indices)] = True   # the next pair's stars stay apart
        pairs += 1
        if pairs == n_pairs:
            break
    assert pairs == n_pairs
    return F[~removed]


def test_touching_holes_are_filled_each_on_its_own():
    """fill_holes closes holes that touch at a vertex, each on its own: the sphere is closed
    again, edge- and vertex-manifold, with Euler characteristic 2."""
    src = icosphere(3)
    m = Mesh(src.vertices, _star_pairs(src, 3, 0))
    m = m.submesh(m.referenced)
    assert _bowties(m) == 3 and len(m.boundary_loops) == 6 and m.euler_characteristic == -4
    closed, n = gromov.fill_holes(m, 10.0)
    assert n == 6 and len(closed.boundary_edges) == 0
    assert closed.is_edge_manifold and closed.euler_characteristic == 2
    # every vertex's faces form one fan closed around it (no bow-tie left)
    indptr, incident = closed.vertex_faces
    for v in range(closed.n_vertices):
        ring = closed.faces[incident[indptr[v]:indptr[v + 1]]]
        assert len(np.unique(ring[ring != v])) == len(ring)


def test_a_triangle_hanging_by_a_vertex_is_not_filled():
    """Two disks cut tangent to each other leave a triangle hanging by one vertex into the hole:
    the hole is filled, the triangle's own boundary is not (that would add a closed bubble)."""
    src = icosphere(4)
    m = Mesh(src.vertices, _disk_holes(src, 3, 0, 2.5 * src.mean_edge_length, 0, 0.0))
    m = m.submesh(m.referenced)
    hanging = (m.edge_face_count[m.face_edges] == 1).all(axis=1)
    assert hanging.sum() == 2
    closed, n = gromov.fill_holes(m, 10.0)
    assert n == len(m.boundary_loops) - 2
    assert len(closed.boundary_edges) == 6 and closed.euler_characteristic == 2


def test_collapses_that_would_break_the_surface_are_refused():
    """Facts on tiny meshes: contracting an edge of a tetrahedron (two copies of one triangle
    would remain), of a lone triangle (its third vertex would be left in no face) or at a vertex
    where two fans meet is refused; an interior edge of a flat grid is contracted."""
    from gromov._collapse import replay_collapses
    from gromov.shapes import grid

    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tet_faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    bowtie = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    bowtie_faces = np.array([[0, 1, 2], [0, 3, 4]])
    for V, F, pairs in ((tet, tet_faces, [[0, 1], [2, 3]]), (tet[:3], tet_faces[:1], [[0, 1], [1, 2]]),
                        (bowtie, bowtie_faces, [[1, 0], [0, 3], [1, 2]])):
        for pair in pairs:
            alive, faces, applied, owner = replay_collapses(V, F, np.array([pair]))
            assert not applied.any() and alive.all() and np.array_equal(faces, F)
    g = grid(5, 5)
    inner = int(np.flatnonzero(np.bincount(g.boundary_edges.ravel(), minlength=g.n_vertices) == 0)[0])
    nb = int(g.adjacency[inner].indices[0])
    alive, faces, applied, owner = replay_collapses(g.vertices, g.faces, np.array([[nb, inner]]))
    assert applied.all() and alive.sum() == g.n_vertices - 1 and len(faces) == g.n_faces - 2


def _holed_pair(tmp_path, gap_edges: float):
    """Two poses of the synthetic cat with the same holes (6 pairs and 4 lone ones), each written
    with duplicated boundary vertices and loaded: file vertex i of one is file vertex i of the other."""
    from gromov.experiments.synthetic import Synthetic

    data = Synthetic(n_vertices=4000)
    x0, y0 = data.load("cat", 0), data.load("cat", 1)
    e = x0.mean_edge_length
    faces = _disk_holes(x0, 6, 4, 2.5 * e, 0, gap_edges * e)
    out = []
    for pose, name in ((x0, "x"), (y0, "y")):
        _write_split_off(pose.vertices, faces, tmp_path / f"{name}.off")
        out.append(_load_quietly(tmp_path / f"{name}.off"))
    return out


@pytest.fixture(scope="module")
def holed_pairs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("holes")
    (tmp / "touching").mkdir()
    (tmp / "apart").mkdir()
    return {"touching": _holed_pair(tmp / "touching", 0.0), "apart": _holed_pair(tmp / "apart", 2.0)}


@pytest.mark.parametrize("metric", ["geodesic", "diffusion"])
def test_touching_holes_match_as_well_as_separate_holes(holed_pairs, metric):
    """Shapes whose holes touch match with both metrics, about as well as with the same holes
    kept apart (mean geodesic error of the sample images over the diameter)."""
    from gromov.evaluate import correspondence_error

    x, _ = holed_pairs["touching"]
    assert _bowties(x) >= 2 and _bowties(holed_pairs["apart"][0]) == 0
    errors = {}
    for kind, (x, y) in holed_pairs.items():
        sx, sy = (gromov.ShapeMetric(s, metric, resolution=1000) for s in (x, y))
        assert _working_vertices_in_no_face(sx.working) == 0
        r = gromov.match(sx, sy, metric, n_samples=40, search=gromov.SearchOptions(n_starts=32))
        truth = gromov.ShapeMetric(y, "geodesic", working=sy.working)
        errors[kind] = correspondence_error(r, truth).mean
    assert errors["apart"] < 0.02
    assert errors["touching"] < errors["apart"] + 0.01


# ----------------------------------------------------------------------------- processes
def _children(pid: int) -> list[int]:
    """Live (not zombie) processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        state, ppid = stat.rsplit(")", 1)[1].split()[:2]
        if int(ppid) == pid and state != "Z":
            out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc (Linux)")
def test_pairwise_workers_die_with_a_killed_parent(tmp_path):
    """SIGKILL to ``gromov pairwise --jobs 2`` ends its worker processes too."""
    from gromov.shapes import torus

    files = []
    for k in range(6):
        m = torus(36, 18, minor=0.25 + 0.03 * k)
        files.append(tmp_path / f"t{k}.off")
        gromov.save(m, files[-1])
    proc = subprocess.Popen([sys.executable, "-m", "gromov", "pairwise", *map(str, files), "--jobs", "2",
                             "--metric", "geodesic", "--samples", "60", "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        workers: list[int] = []
        while len(workers) < 2 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
            workers = _children(proc.pid)
        assert len(workers) == 2, "the workers did not start"
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + 5
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(_alive(w) for w in workers)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


# ----------------------------------------------------------------------------- read-only installs
def _read_only_tree(root: Path) -> None:
    for folder, _, files in os.walk(root):
        for f in files:
            os.chmod(os.path.join(folder, f), 0o444)
        os.chmod(folder, 0o555)


@pytest.mark.skipif(not hasattr(os, "geteuid"), reason="POSIX permissions")
def test_read_only_install_without_a_writable_home():
    """With the package folder read-only and no writable home, gromov imports and computes:
    numba's cache goes to the temporary folder."""
    import shutil
    import tempfile

    base = Path(tempfile.mkdtemp(prefix="gromov-ro-"))
    try:
        site, home, tmp = base / "site", base / "home", base / "tmp"
        shutil.copytree(REPO / "src" / "gromov", site / "gromov",
                        ignore=shutil.ignore_patterns("__pycache__"))
        home.mkdir()
        tmp.mkdir()
        os.chmod(tmp, 0o777)
        _read_only_tree(site)
        _read_only_tree(home)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "XDG_"))}
        env.update(PYTHONPATH=str(site), HOME=str(home), TMPDIR=str(tmp), PYTHONDONTWRITEBYTECODE="1")
        prefix = []
        if os.geteuid() == 0:   # root writes anywhere: drop the capabilities that let it
            if not shutil.which("setpriv"):
                pytest.skip("running as root without setpriv: permissions are not enforced")
            prefix = ["setpriv", "--inh-caps=-all", "--bounding-set=-all"]
        code = ("import os, gromov, gromov.gh\n"
                "from gromov.shapes import grid\n"
                "d = gromov.metric_solver(grid(8, 5), 'diffusion').pairwise()\n"
                "print(gromov.__file__, os.environ['NUMBA_CACHE_DIR'], float(d.max()))\n")
        out = subprocess.run([*prefix, sys.executable, "-c", code], env=env, cwd=base, capture_output=True,
                             text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        where, cache, top = out.stdout.split()
        assert where.startswith(str(site)) and float(top) > 0
        assert Path(cache).parent == tmp and any(Path(cache).rglob("*.nbi"))
    finally:
        for folder, _, _ in os.walk(base):
            os.chmod(folder, 0o755)
        shutil.rmtree(base, ignore_errors=True)


# ----------------------------------------------------------------------------- numerical range
def test_coordinates_beyond_double_precision_are_refused():
    t = icosphere(2)
    for scale in (1e80, 1e150, 1e200):
        with pytest.raises(MeshError, match="overflow there: scale the shape"):
            Mesh(t.vertices * scale, t.faces)
        with pytest.raises(MeshError, match="overflow there"):
            gromov.PointCloud(t.vertices * scale)
    for scale in (1e-80, 1e-150):
        with pytest.raises(MeshError, match="underflow there: scale the shape"):
            Mesh(t.vertices * scale, t.faces)
    gromov.PointCloud([[1e-300, 0, 0]])   # one point spans nothing: nothing to refuse


def test_metrics_scale_exactly_up_to_the_limit():
    """At the accepted extremes (coordinates near 1e75 and 1e-75) distances are the unit shape's
    times the scale (geodesic), or unchanged (normalised heat distances), and a match is exact."""
    from gromov.shapes import torus

    t = torus(24, 12)
    geo = metric_solver(t, "geodesic").pairwise()
    heat = metric_solver(t, "diffusion", units="normalized").pairwise()
    for scale in (2.0**-249, 2.0**247):   # about 1.1e-75 and 2.3e74: exact in binary
        m = Mesh(t.vertices * scale, t.faces)
        np.testing.assert_allclose(metric_solver(m, "geodesic").pairwise(), geo * scale, rtol=1e-12)
        np.testing.assert_allclose(metric_solver(m, "diffusion", units="normalized").pairwise(), heat,
                                   rtol=1e-6, atol=1e-9)
        r = gromov.match(m, m, "geodesic", n_samples=20)
        assert r.relative_distance == 0.0 and np.isfinite(r.distance)


def test_json_output_is_standard_json(tmp_path, capsys):
    """--json prints standard JSON only: a value that is not a number is null, never NaN."""
    from gromov.cli._common import _dumps
    from gromov.shapes import torus

    assert _dumps({"a": float("nan"), "b": [np.inf, np.float64(1.5)], "c": np.int64(2)}) == \
        '{"a": null, "b": [null, 1.5], "c": 2}'
    f = tmp_path / "t.off"
    gromov.save(torus(24, 12), f)
    assert main(["info", str(f), "--json"]) == 0

    def refuse(token):
        raise ValueError(f"non-standard JSON token {token}")

    info = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert info["vertices"] == 288
    big = tmp_path / "big.off"
    m = torus(24, 12)
    big.write_text("OFF\n288 576 0\n" + "\n".join(" ".join(f"{x:.17g}" for x in v * 1e200) for v in m.vertices)
                   + "\n" + "\n".join("3 " + " ".join(map(str, f)) for f in m.faces) + "\n")
    assert main(["info", str(big), "--json"]) == 2
    out = capsys.readouterr()
    assert out.out == "" and "scale" in out.err and len(out.err.strip().splitlines()) == 1


# ----------------------------------------------------------------------------- degenerate inputs
def _tetrahedra(n: int, same: bool = False) -> Mesh:
    """``n`` disjoint tetrahedra in a row, of different sizes or (``same``) all alike."""
    base = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    scale = np.ones(n) if same else 1.0 + 0.5 * np.sin(np.arange(n))
    V = np.concatenate([base * scale[i] + 3.0 * i * np.array([1, 0.1, 0.05]) for i in range(n)])
    return Mesh(V, np.concatenate([f + 4 * i for i in range(n)]))


def test_collinear_point_cloud_is_a_clear_error():
    pts = np.c_[np.linspace(0, 1, 200), np.zeros(200), np.zeros(200)]
    cloud = gromov.PointCloud(pts)
    with pytest.raises(MetricError, match=r"lie on a line.*--metric geodesic"):
        metric_solver(cloud, "diffusion").pairwise()
    # the metrics that need no surface work on it
    assert np.isfinite(metric_solver(cloud, "geodesic").pairwise()).all()
    assert np.isfinite(metric_solver(cloud, "diffusion", kernel="gaussian").pairwise()).all()


def test_heat_diffusion_on_many_components_is_exact():
    """200 equal disjoint tetrahedra (jointly, ARPACK stopped with error 3 on them): component
    by component, the distances equal those of a dense generalised eigendecomposition of the
    whole shape."""
    from scipy.linalg import eigh
    from threadpoolctl import threadpool_limits

    m = _tetrahedra(200, same=True)
    s = metric_solver(m, "diffusion", units="raw", fill_holes=None)
    d = s.pairwise()
    with threadpool_limits(limits=1):   # (threaded LAPACK on a busy machine: 50x slower)
        lam, phi = eigh(s.stiffness.toarray(), s.mass.toarray())
    psi = phi * np.exp(-np.maximum(lam, 0.0) * s.t)
    sq = (psi**2).sum(1)
    exact = np.sqrt(np.maximum(sq[:, None] + sq[None] - 2 * psi @ psi.T, 0.0))
    # (a distance of d^2 ~ 1e-16 is the cancellation's rounding: 1e-8 either way)
    np.testing.assert_allclose(d, exact, atol=1e-7 * exact.max())


def test_graph_diffusion_on_two_components_matches_the_dense_one():
    """The connectivity kernel on two spheres through the sparse eigensolver (more vertices than
    ``dense_below``): distances across the components as the dense decomposition has them
    (jointly, ARPACK found one of the two unit eigenvalues and put them at distance 0)."""
    from threadpoolctl import threadpool_limits

    from gromov.metrics import GraphDiffusionSolver

    a = icosphere(2)
    m = Mesh(np.vstack([a.vertices, 0.5 * a.vertices + [0, 5, 0]]),
             np.vstack([a.faces, a.faces + a.n_vertices]))
    sparse = GraphDiffusionSolver(m, dense_below=100).pairwise()
    with threadpool_limits(limits=1):
        psi = GraphDiffusionSolver(m)._dense()
    sq = (psi**2).sum(1)
    dense = np.sqrt(np.maximum(sq[:, None] + sq[None] - 2 * psi @ psi.T, 0.0))
    np.testing.assert_allclose(sparse, dense, atol=1e-6 * dense.max())
    assert sparse[0, a.n_vertices] > 0.01


def test_thousand_tetrahedra_distances_finish(tmp_path, capsys):
    f, out = tmp_path / "tets.off", tmp_path / "d.npz"
    gromov.save(_tetrahedra(1000), f)
    assert main(["distances", str(f), "--metric", "diffusion", "--out", str(out), "-q"]) == 0
    d = np.load(out)["distances"]
    assert d.shape == (4000, 4000) and np.isfinite(d).all() and np.array_equal(d, d.T)
    piece = np.arange(4000) // 4   # vertices of different tetrahedra are apart
    assert (d[piece[:, None] != piece[None, :]] > 0).all()


def test_geodesic_match_of_a_mesh_in_pieces_names_the_options(tmp_path, capsys):
    f = tmp_path / "tets.off"
    gromov.save(_tetrahedra(20), f)
    assert main(["match", str(f), str(f), "--metric", "geodesic", "--samples", "10", "-q"]) == 2
    err = capsys.readouterr().err
    assert "20 connected components" in err and "--metric diffusion" in err
    assert "largest_component()" not in err


def test_neighbors_message_names_the_option(tmp_path, capsys):
    f = tmp_path / "cloud.xyz"
    np.savetxt(f, np.random.default_rng(0).random((10, 3)))
    assert main(["distances", str(f), "--metric", "geodesic", "--neighbors", "50", "--out",
                 str(tmp_path / "d.npz"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "--neighbors" in err and "[1, 9]" in err


# ----------------------------------------------------------------------------- resources
def _no_work(*args, **kwargs):
    raise AssertionError("the work started")


def test_reproduce_checks_matplotlib_before_any_work(monkeypatch, tmp_path, capsys):
    import importlib.util

    from gromov.experiments import reproduce

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "matplotlib" else real(name, *a))
    monkeypatch.setattr(reproduce, "_collection", _no_work)
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "matplotlib" in err and "pip install" in err and not (tmp_path / "out").exists()
    with pytest.raises(ImportError, match="pip install"):   # the library says it as early
        reproduce.reproduce(out=tmp_path / "out", quick=True)


@pytest.mark.parametrize("command", ["distances", "match", "pairwise"])
def test_resolution_beyond_memory_is_refused_with_the_numbers(monkeypatch, tmp_path, capsys, command):
    """The dense matrices are counted before any distance is computed: 2 x 8 n^2 bytes per shape
    (1,152 vertices: 21 MB) against the memory available (here 10 MB)."""
    from gromov.experiments import pairwise
    from gromov.metrics import GeodesicSolver
    from gromov.shapes import torus

    f, g = tmp_path / "a.off", tmp_path / "b.off"
    gromov.save(torus(48, 24), f)
    gromov.save(torus(48, 24, minor=0.3), g)
    monkeypatch.setattr(pairwise, "_available_memory", lambda: 10_000_000)
    args = {"distances": ["distances", str(f), "--out", str(tmp_path / "d.npz")],
            "match": ["match", str(f), str(g)], "pairwise": ["pairwise", str(f), str(g)]}[command]
    with monkeypatch.context() as m:
        m.setattr(GeodesicSolver, "_rows", _no_work)
        assert main(args + ["-q", "--metric", "geodesic"]) == 2
    err = capsys.readouterr().err
    n = 1 if command == "distances" else 2
    assert f"{n} dense distance matri" in err
    assert f"of up to 1,152 working vertices need about {2 * 8 * 1152**2 * n / 1e6:.1f} MB" in err
    assert f"10.0 MB of memory are available; a --resolution of at most {700 if n == 1 else 500} fits" in err
    assert not (tmp_path / "d.npz").exists()
    if command == "distances":   # with the memory there (or unknown) it runs
        monkeypatch.setattr(pairwise, "_available_memory", lambda: None)
        assert main(args + ["-q", "--metric", "geodesic", "--resolution", "300"]) == 0
        d = np.load(tmp_path / "d.npz")["distances"]   # (about 300: simplification is within 2%)
        assert abs(len(d) - 300) <= 6 and np.isfinite(d).all()
