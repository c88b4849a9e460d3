"""The command line: `gromov info`, `gromov distances` (a contract other tools read), errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

import gromov
from gromov.cli import main
from gromov.errors import GromovWarning
from gromov.metrics import GeodesicSolver, metric_solver
from gromov.shapes import icosphere, torus


@pytest.fixture
def torus_file(tmp_path):
    path = tmp_path / "torus.off"
    gromov.save(torus(), path)
    return path


def test_info_reports_topology(torus_file, capsys):
    assert main(["info", str(torus_file), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["euler_characteristic"] == 0 and info["genus"] == 1
    assert info["components"] == 1 and info["boundary_loops"] == 0
    assert info["vertices"] == torus().n_vertices
    # the double sweep finds the largest distance of the all-pairs matrix
    exact = GeodesicSolver(torus()).diameter(exact=True)
    assert info["geodesic_diameter"] == pytest.approx(exact, rel=0.01)
    assert main(["info", str(torus_file)]) == 0
    assert "euler characteristic" in capsys.readouterr().out


@pytest.mark.parametrize("metric", ["geodesic", "diffusion", "euclidean"])
def test_distances_all_vertices(tmp_path, metric):
    mesh = icosphere(2)
    src = tmp_path / "s.ply"
    gromov.save(mesh, src)
    out = tmp_path / "d.npz"
    assert main(["distances", str(src), "--metric", metric, "--out", str(out), "-q"]) == 0
    z = np.load(out)
    np.testing.assert_array_equal(z["samples"], np.arange(mesh.n_vertices))
    np.testing.assert_allclose(z["distances"], metric_solver(mesh, metric).pairwise(), atol=1e-12)


def test_distances_samples_refer_to_the_input_file(tmp_path):
    mesh = icosphere(4)  # 2562 vertices, simplified to 500
    src = tmp_path / "sphere.obj.gz"
    gromov.save(mesh, src)
    out = tmp_path / "d.npz"
    rc = main(["distances", str(src), "--metric", "geodesic", "--resolution", "500",
               "--samples", "25", "--seed", "3", "--out", str(out), "-q"])
    assert rc == 0
    z = np.load(out)
    d, s = z["distances"], z["samples"]
    assert d.shape == (25, 25) and s.shape == (25,) and s.dtype == np.int64
    assert np.allclose(d, d.T) and np.all(np.diag(d) == 0)
    assert len(np.unique(s)) == 25 and s.max() < mesh.n_vertices
    # distances between the input vertices, measured on the full mesh, agree to discretisation
    full = GeodesicSolver(mesh).submatrix(s)
    assert np.abs(d - full).max() < 0.05 * full.max()
    # same seed, same samples
    out2 = tmp_path / "d2.npz"
    main(["distances", str(src), "--metric", "geodesic", "--resolution", "500",
          "--samples", "25", "--seed", "3", "--out", str(out2), "-q"])
    np.testing.assert_array_equal(np.load(out2)["samples"], s)


def test_distances_on_tosca_ids_are_input_vertices(data_dir, tmp_path):
    src = data_dir / "tosca" / "cat0.off.gz"
    out = tmp_path / "cat.npz"
    assert main(["distances", str(src), "--metric", "diffusion", "--samples", "50",
                 "--out", str(out), "-q"]) == 0
    z = np.load(out)
    cat = gromov.load(src)
    work = gromov.simplify(cat, 3000)
    assert z["samples"].max() < cat.n_vertices
    # every sample is a working vertex, i.e. an input vertex of the working mesh
    assert np.isin(z["samples"], work.mesh.input_ids).all()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["info", "/no/such/file.off"], "/no/such/file.off"),
        (["info", "{fixtures}/../test_cli.py"], "test_cli.py"),
        (["distances", "{sphere}", "--samples", "1000", "--out", "{tmp}/x.npz"], "more than the 162"),
        (["distances", "{sphere}", "--out", "{tmp}/missing/x.npz"], "does not exist"),
        (["distances", "{sphere}", "--metric", "diffusion", "--steps", "0", "--out", "x.npz"],
         "positive integer"),
        (["distances", "{sphere}", "--metric", "diffusion", "--kernel", "biharmonic", "--tau", "0.1",
          "--out", "{tmp}/x.npz"], "--tau is the heat kernel's"),
        (["distances", "{sphere}", "--metric", "diffusion", "--steps", "20", "--out", "{tmp}/x.npz"],
         "--steps is the graph kernels'"),
        (["distances", "{sphere}", "--metric", "diffusion", "--refine", "1", "--out", "{tmp}/x.npz"],
         "--refine applies to --metric geodesic"),
        (["distances", "{sphere}", "--metric", "geodesic", "--geodesic-method", "heat", "--refine", "1",
          "--out", "{tmp}/x.npz"], "--refine applies to --metric geodesic"),
        (["distances", "{sphere}", "--metric", "geodesic", "--tau", "0.5", "--out", "{tmp}/x.npz"],
         "--tau applies to --metric diffusion"),
        (["distances", "{sphere}", "--metric", "euclidean", "--kernel", "biharmonic", "--out", "{tmp}/x.npz"],
         "--kernel applies to --metric diffusion"),
        (["distances", "{sphere}", "--metric", "geodesic", "--steps", "5", "--out", "{tmp}/x.npz"],
         "--steps applies to --metric diffusion"),
        (["distances", "{sphere}", "--geodesic-method", "exact", "--out", "{tmp}/x.npz"],
         "--geodesic-method applies to --metric geodesic"),
        (["match", "{sphere}", "{sphere}", "--metric", "euclidean", "--geodesic-method", "heat"],
         "--geodesic-method applies to --metric geodesic"),
        (["match", "{sphere}", "{sphere}", "--seed", "-1"], "argument --seed: expected an integer >= 0, got -1"),
        (["match", "{sphere}", "{sphere}", "--samples", "2"], "argument --samples: expected an integer >= 3"),
        (["pairwise", "{sphere}", "{sphere}", "--resolution", "3"], "argument --resolution: expected an integer >= 4"),
        (["pairwise", "{sphere}"], "at least two meshes"),
        (["pairwise", "{sphere}", "{sphere}"], "a file is given twice"),
        (["pairwise", "{sphere}", "{tmp}/./s.off"], "a file is given twice"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "{fixtures}/tetra_ascii.stl",
          "--mds", "{tmp}/m.svg"], "--mds writes a PNG image"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "--out", "{tmp}/d.csv/x.npz"],
         "does not exist"),
        (["match", "{sphere}", "{sphere}", "--plot", "{tmp}/c.jpg"], "--plot writes a PNG image"),
        (["match", "{sphere}", "{sphere}", "--map", "{tmp}/missing/m.txt"], "--map: output folder"),
        (["match", "{sphere}", "{sphere}", "--dense", "--out", "{tmp}/missing/m.npz"], "--out: output folder"),
        (["match", "{sphere}", "{sphere}", "--html", "{tmp}/missing/m.html"], "--html: output folder"),
        (["match", "{sphere}", "{sphere}", "--out", "{tmp}/m.txt"],
         "--out writes a NumPy archive: give a file name ending in .npz, got"),
        (["distances", "{sphere}", "--out", "{tmp}/d.txt"], "--out writes a NumPy archive"),
        (["perturb", "holes", "{sphere}", "{tmp}/./s.off", "--count", "2"], "is the input mesh"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "--labels", "a"],
         "one non-empty label per file (2), got 1"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "--labels", "a,b",
          "--labels-from-names"], "either --labels or --labels-from-names"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "--out", "{tmp}/x.txt"],
         "--out must end in .npz or .csv"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "--mds", "{tmp}/m.png"],
         "--mds needs at least three shapes"),
        (["pairwise", "{sphere}", "{fixtures}/cube_quads.obj", "--samples", "100"],
         "more than the 8 vertices"),
    ],
)
def test_user_errors_are_one_line_without_traceback(tmp_path, capsys, argv, message):
    """Run in this process (``main`` as ``python -m gromov`` calls it; argparse's own errors
    exit); ``test_a_user_error_in_its_own_process`` checks the process's exit code and stderr."""
    sphere = tmp_path / "s.off"
    gromov.save(icosphere(2), sphere)
    fixtures = str(__import__("pathlib").Path(__file__).parent / "fixtures")
    argv = [a.format(sphere=sphere, tmp=tmp_path, fixtures=fixtures) for a in argv]
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    _one_error_line(capsys.readouterr().err, message)


def _one_error_line(stderr: str, message: str) -> None:
    assert "Traceback" not in stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    # one error line (argparse adds a usage line before its own errors)
    assert [ln for ln in lines if "error:" in ln] == [lines[-1]]
    assert lines[-1].startswith("gromov") and message in lines[-1]


@pytest.mark.parametrize("argv, message", [
    (["info", "/no/such/file.off"], "/no/such/file.off"),                          # gromov's error
    (["distances", "x.off", "--metric", "diffusion", "--steps", "0"], "positive integer"),   # argparse's
])
def test_a_user_error_in_its_own_process(argv, message):
    r = subprocess.run([sys.executable, "-m", "gromov", *argv], capture_output=True, text=True)
    assert r.returncode == 2
    _one_error_line(r.stderr, message)


def test_a_reader_that_stops_early_ends_the_command_quietly(torus_file):
    """``gromov info FILE | head -0``: stdout's reader is gone before anything is written; the
    command stops with status 141 (128 + SIGPIPE) and no traceback."""
    import os

    r, w = os.pipe()
    os.close(r)   # the reader has gone
    try:
        p = subprocess.run([sys.executable, "-m", "gromov", "info", str(torus_file)], stdout=w,
                           stderr=subprocess.PIPE, text=True)
    finally:
        os.close(w)
    assert p.returncode == 141 and "Traceback" not in p.stderr and "Error" not in p.stderr, p.stderr


def test_demo_runs(capsys):
    assert main(["demo", "--samples", "5"]) == 0
    out = capsys.readouterr().out
    assert "geodesic" in out and "diffusion" in out and "covering radius" in out


def test_match_json_and_out(tmp_path, capsys):
    from gromov.shapes import grid, rolled_grid

    x, y = tmp_path / "flat.off", tmp_path / "rolled.ply"
    gromov.save(grid(21, 11), x)
    gromov.save(rolled_grid(21, 11), y)
    out = tmp_path / "m.npz"
    rc = main(["match", str(x), str(y), "--metric", "geodesic", "--samples", "20", "--json",
               "--out", str(out), "--seed", "1"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    for key in ("distance", "relative_distance", "metric", "solver", "n_samples", "seconds"):
        assert key in res
    assert set(res["distortion"]) >= {"l2", "linf", "trimmed"}
    assert res["distortion"]["trimmed"] <= res["distortion"]["l2"]
    assert res["relative_trimmed_distance"] <= res["relative_distance"]
    assert res["metric"] == "geodesic" and res["solver"] == "gmds" and res["n_samples"] == 20
    assert res["distance"] == pytest.approx(0.5 * res["distortion"]["l2"])
    assert res["relative_distance"] < 0.01  # isometric shapes
    assert 0.0 <= res["orientation"] <= 1.0  # a fraction of sample triangles (both sheets orientable)
    assert res["metric_options"] == {}
    z = np.load(out)
    for side, other in (("x", "y"), ("y", "x")):
        assert z[f"{side}_samples"].shape == (20,)
        assert z[f"{side}_to_{other}_face"].shape == (20,)
        assert z[f"{side}_to_{other}_bary"].shape == (20, 3)
        assert z[f"{side}_to_{other}_vertex"].shape == (20,)
        assert z[f"{side}_distortion"].shape == (20,) and np.all(z[f"{side}_distortion"] >= 0)
    # same vertex numbering and isometric: each image is the sample itself or one of its
    # images under the sheet's symmetries (mirror in u, in v, or both), the same for all
    u, w = np.divmod(z["x_samples"], 11)
    img = z["x_to_y_vertex"]
    candidates = [u * 11 + w, (20 - u) * 11 + w, u * 11 + (10 - w), (20 - u) * 11 + (10 - w)]
    assert max(np.mean(img == c) for c in candidates) >= 0.9
    # the search on a subset of vertices, and the search on distances only, find the isometry
    # too; a value out of range is a usage error
    for option, good, bad in (("--search-vertices", "60", "0"), ("--signature-weight", "0", "-1")):
        rc = main(["match", str(x), str(y), "--metric", "geodesic", "--samples", "20", "--json",
                   option, good])
        assert rc == 0
        assert json.loads(capsys.readouterr().out)["relative_distance"] < 0.01
        with pytest.raises(SystemExit):
            main(["match", str(x), str(y), option, bad])


def test_match_summary_for_people(tmp_path, capsys):
    x = tmp_path / "s.off"
    gromov.save(icosphere(2), x)
    assert main(["match", str(x), str(x), "--metric", "euclidean", "--samples", "15"]) == 0
    out = capsys.readouterr().out
    assert "Gromov-Hausdorff distance" in out and "euclidean metric" in out
    assert "rms" in out and "max" in out and "best-fitting 80% of pairs" in out


def test_match_gw_solver_and_errors(tmp_path, capsys):
    x = tmp_path / "s.off"
    gromov.save(icosphere(2), x)
    assert main(["match", str(x), str(x), "--metric", "euclidean", "--samples", "15",
                 "--solver", "gw", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["solver"] == "gw" and np.isfinite(res["distance"]) and res["n_iter"] == 0
    r = subprocess.run([sys.executable, "-m", "gromov", "match", str(x), str(x), "--samples", "500"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "more than the 162" in r.stderr
    r = subprocess.run([sys.executable, "-m", "gromov", "match", str(x), str(x), "--norm", "l7x"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "norm" in r.stderr.splitlines()[-1]


def test_perturb_writes_mesh_and_ground_truth(tmp_path, capsys):
    src = tmp_path / "sphere.off"
    gromov.save(icosphere(4), src)
    out = tmp_path / "holed.ply"
    assert main(["perturb", "holes", str(src), str(out), "--count", "5", "--seed", "2"]) == 0
    assert "boundary loops 0 -> 5" in capsys.readouterr().out
    holed = gromov.load(out)
    z = np.load(tmp_path / "holed.map.npz")
    assert len(holed.boundary_loops) == 5 and holed.euler_characteristic == 2 - 5
    # output vertex i is input vertex vertex_map[i]
    np.testing.assert_array_equal(holed.vertices, icosphere(4).vertices[z["vertex_map"]])
    r = subprocess.run([sys.executable, "-m", "gromov", "perturb", "weld", str(src), str(out),
                        "--count", "2"], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "weld site" in r.stderr
    assert main(["perturb", "holes", str(src), str(out), "--count", "2", "--join", "pinch"]) == 2
    assert "--join applies to weld" in capsys.readouterr().err


def test_refine_option(tmp_path):
    from gromov.metrics import GeodesicSolver

    src = tmp_path / "s.off"
    gromov.save(icosphere(2), src)
    out = tmp_path / "d.npz"
    assert main(["distances", str(src), "--metric", "geodesic", "--refine", "1", "--samples", "20",
                 "--out", str(out), "-q"]) == 0
    z = np.load(out)
    assert json.loads(str(z["options"])) == {"refine": 1}
    mesh = gromov.load(src)
    s = mesh.from_input_ids(z["samples"])
    fine = GeodesicSolver(mesh, refine=1).submatrix(s)
    np.testing.assert_allclose(z["distances"], fine, rtol=1e-12)
    assert np.abs(GeodesicSolver(mesh).submatrix(s) - fine).max() > 1e-6  # it did refine
    # --refine 0 is the default, with any metric
    assert main(["distances", str(src), "--metric", "diffusion", "--refine", "0", "--out", str(out), "-q"]) == 0


def test_fill_holes_option(tmp_path, capsys):
    from gromov.perturb import holes

    src = tmp_path / "holed.off"
    gromov.save(holes(icosphere(3), 4, radius=0.15, seed=0).mesh, src)
    out = tmp_path / "d.npz"
    assert main(["distances", str(src), "--metric", "geodesic", "--fill-holes", "0.5", "--out", str(out)]) == 2
    assert "--fill-holes applies to --metric diffusion" in capsys.readouterr().err
    for bad in ("-1", "inf", "nan"):
        assert main(["distances", str(src), "--fill-holes", bad, "--out", str(out)]) == 2
        assert "--fill-holes must be a finite number >= 0" in capsys.readouterr().err
    runs = {}
    for fill in ("0", None):
        assert main(["distances", str(src), "--samples", "6", "--out", str(out)]
                    + ([] if fill is None else ["--fill-holes", fill])) == 0
        z = np.load(out)
        runs[fill] = (z["distances"], json.loads(str(z["options"])))
    # the default closes the 4 holes (recorded as 0.5); 0 leaves them open (recorded as None)
    assert runs[None][1] == {"kernel": "heat", "fill_holes": 0.5}
    assert runs["0"][1] == {"kernel": "heat", "fill_holes": None}
    assert not np.allclose(runs[None][0], runs["0"][0])


def test_units_option(tmp_path, capsys):
    src = tmp_path / "sphere.off"
    gromov.save(icosphere(2), src)
    out = tmp_path / "d.npz"
    assert main(["distances", str(src), "--metric", "geodesic", "--units", "length", "--out", str(out)]) == 2
    assert "--units applies to --metric diffusion" in capsys.readouterr().err
    assert main(["distances", str(src), "--kernel", "biharmonic", "--units", "length", "--out", str(out)]) == 2
    assert "--units applies to the heat kernel" in capsys.readouterr().err
    runs = {}
    for units in ("raw", "length", "normalized"):
        assert main(["distances", str(src), "--samples", "6", "--units", units, "--out", str(out), "-q"]) == 0
        z = np.load(out)
        runs[units] = z["distances"]
        assert json.loads(str(z["options"]))["units"] == units
    assert main(["match", str(src), str(src), "--samples", "6", "--units", "length", "--json"]) == 0
    opts = json.loads(capsys.readouterr().out)["metric_options"]
    assert opts == {"kernel": "heat", "units": "length", "fill_holes": 0.5}
    # a correspondence defaults to normalised heat distributions, unless units or tau are given
    assert main(["match", str(src), str(src), "--samples", "6", "--json"]) == 0
    opts = json.loads(capsys.readouterr().out)["metric_options"]
    assert opts == {"kernel": "heat", "units": "normalized", "fill_holes": 0.5}
    assert main(["match", str(src), str(src), "--samples", "6", "--tau", "0.01", "--json"]) == 0
    opts = json.loads(capsys.readouterr().out)["metric_options"]
    assert opts == {"kernel": "heat", "tau": 0.01, "fill_holes": 0.5}   # the solver's raw default
    # a constant factor, sqrt(32 pi) tau area (HeatDiffusionSolver)
    area = icosphere(2).area
    np.testing.assert_allclose(runs["length"], runs["raw"] * np.sqrt(32 * np.pi) * 0.005 * area, rtol=1e-9)
    # normalised heat distributions: dimensionless, at most 2 (HeatDiffusionSolver)
    assert 0 < runs["normalized"].max() <= 2


def test_class_from_name():
    from gromov.cli.collection import class_from_name

    assert class_from_name("data/tosca/cat0.off.gz") == "cat"
    assert class_from_name("david12.off") == "david"
    assert class_from_name("/x/kid_12.PLY") == "kid"
    assert class_from_name("shape.obj") == "shape"
    assert class_from_name("123.off") == "123"   # nothing left: the whole stem
    assert class_from_name("ball,1.off") == "ball"


def test_short_names_tell_equal_stems_apart():
    from gromov.cli.collection import _short_names

    assert _short_names(["a/cat0.off", "b/cat1.ply"]) == ["cat0", "cat1"]
    assert _short_names(["x/a/long1.off", "x/b/long1.off", "c/dog.off"]) == ["a/long1", "b/long1", "dog"]


def test_pairwise_recognises_isometric_shapes(tmp_path, capsys):
    """Two classes: a sheet and the same sheet rolled into a half-cylinder (isometric), and
    a sheet twice as long and a rigidly moved, renumbered copy of it. With the geodesic
    metric each shape's nearest neighbour is the other of its class, the EER is 0, and the
    files written agree with the printed JSON."""
    from gromov.mesh import Mesh
    from gromov.shapes import grid, rolled_grid

    long = grid(31, 11, width=2 * np.pi)
    perm = np.random.default_rng(0).permutation(long.n_vertices)
    inv = np.argsort(perm)
    c, s_ = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
    moved = Mesh(long.vertices[perm] @ rot.T + [1.0, -2.0, 0.5], inv[long.faces])
    files = [tmp_path / "sheet0.off", tmp_path / "long0.off", tmp_path / "sheet1.ply",
             tmp_path / "long1.obj"]
    for f, m in zip(files, (grid(21, 11), long, rolled_grid(21, 11), moved)):
        gromov.save(m, f)
    npz, csv_path, png = tmp_path / "d.npz", tmp_path / "d.csv", tmp_path / "mds.png"
    base = ["pairwise", *map(str, files), "--metric", "geodesic", "--samples", "20", "--jobs", "1"]
    argv = [*base, "--labels-from-names"]
    # classes of 2: k = 4 is capped at n - 1 = 3, which takes scales from the other class: said
    with pytest.warns(GromovWarning, match=r"not below the smallest class \(2 shapes\)") as caught:
        assert main([*argv, "--json", "--out", str(npz), "--mds", str(png)]) == 0
    assert {str(w.message).split(" with")[0] for w in caught} >= {"local scaling", "diffusion re-ranking"}
    res = json.loads(capsys.readouterr().out)
    names = [str(f) for f in files]
    assert res["files"] == names and res["labels"] == ["sheet", "long", "sheet", "long"]
    assert res["nearest"] == [names[2], names[3], names[0], names[1]]
    assert res["eer"] == 0.0 and res["eer_gh"] == 0.0 and res["nn_accuracy"] == 1.0
    assert res["local_scaling_k"] == 3 and res["eer_local"] == 0.0     # k = 4 capped at n - 1
    assert res["errors_at_eer_local"]["false_accept"] == {} and res["errors_at_eer_local"]["false_reject"] == {}
    rel = np.array(res["relative_distance"])
    trim = np.array(res["relative_trimmed_distance"])
    from gromov.experiments.recognition import diffusion_roc

    assert res["diffusion_rerank_k"] == 3    # k = 8 capped at n - 1
    assert res["eer_diffusion"] == diffusion_roc(trim, res["labels"], 3)[0].eer
    assert np.array_equal(rel, rel.T) and np.all(np.diag(rel) == 0)
    assert res["rank_residual"] == "log" and np.array_equal(trim, trim.T)   # log distance ratios
    assert main([*argv, "--json", "--rank-residual", "difference", "--local-scaling", "1"]) == 0   # differences
    diff = json.loads(capsys.readouterr().out)
    assert diff["rank_residual"] == "difference" and diff["relative_distance"] == res["relative_distance"]
    assert np.all(np.array(diff["relative_trimmed_distance"]) <= rel + 1e-15)   # trimmed <= RMS
    assert not np.allclose(diff["relative_trimmed_distance"], trim)
    assert rel[0, 2] < 0.01 and rel[1, 3] < 1e-3     # isometric; rigid copy
    assert min(rel[0, 1], rel[0, 3], rel[2, 1], rel[2, 3]) > 5 * max(rel[0, 2], rel[1, 3])
    z = np.load(npz)
    assert list(z["files"]) == names and list(z["labels"]) == res["labels"]
    np.testing.assert_array_equal(z["relative_distance"], rel)
    np.testing.assert_array_equal(z["relative_trimmed_distance"], trim)
    np.testing.assert_array_equal(z["distance"], np.array(res["distance"]))
    assert str(z["metric"]) == "geodesic" and int(z["n_samples"]) == 20
    assert str(z["ranked_by"]) == "trimmed" and list(z["nearest"]) == res["nearest"]
    assert float(z["eer"]) == 0.0 and float(z["eer_local"]) == res["eer_local"]
    assert int(z["local_scaling_k"]) == res["local_scaling_k"] == 3
    assert float(z["eer_diffusion"]) == res["eer_diffusion"] and int(z["diffusion_rerank_k"]) == 3
    assert main([*base, "--local-scaling", "2"]) == 2          # no labels: nothing to scale an EER of
    assert "--local-scaling sets the neighbour" in capsys.readouterr().err
    assert main([*base, "--diffusion-rerank", "2"]) == 2
    assert "--diffusion-rerank sets the neighbours" in capsys.readouterr().err
    assert png.stat().st_size > 1000
    # the same run (deterministic) as CSV, and the summary for people
    assert main([*argv, "--out", str(csv_path), "--local-scaling", "1"]) == 0
    out = capsys.readouterr().out
    assert "4 shapes, 6 pairs, geodesic metric" in out and "equal error rate 0.00%" in out
    assert "locally scaled, k = 1: 0.00%; diffusion re-ranked, k = 3: " in out
    assert "another class" not in out
    assert "false acceptances (pairs of classes): none; false rejections (within a class): none" in out
    assert res["errors_at_eer"]["false_accept"] == {} and res["errors_at_eer"]["far"] == 0.0
    import csv

    with open(csv_path, newline="") as fh:
        rows = list(csv.reader(fh))
    # the CSV holds the matrix the results rank by (trimmed by default), named in its corner
    assert rows[0] == ["relative_trimmed_distance"] + names and [r[0] for r in rows[1:]] == names
    np.testing.assert_array_equal(np.array([r[1:] for r in rows[1:]], dtype=float), trim)
    # labels given by hand; one label per class only: no EER, said so
    assert main([*base, "--labels", "a,b,c,d"]) == 0
    assert "no equal error rate" in capsys.readouterr().out


def test_match_plot_draws_the_correspondence(tmp_path, capsys, monkeypatch):
    """--plot colours X's sample cells and the cells around their images on Y alike: on a
    sheet and its isometric roll, each image's cell is (nearly) the sample's own cell."""
    from gromov.experiments import report
    from gromov.shapes import grid, rolled_grid

    x, y = tmp_path / "flat.off", tmp_path / "rolled.off"
    gromov.save(grid(21, 11), x)
    gromov.save(rolled_grid(21, 11), y)
    seen = {}
    draw = report.plot_correspondence
    monkeypatch.setattr(report, "plot_correspondence",
                        lambda xm, ym, xl, yl, path, **kw: seen.update(xl=xl, yl=yl) or draw(
                            xm, ym, xl, yl, path, **kw))
    png = tmp_path / "c.png"
    assert main(["match", str(x), str(y), "--metric", "geodesic", "--samples", "20", "-q",
                 "--plot", str(png), "--seed", "1", "--resolution", "1000"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    xl, yl = seen["xl"], seen["yl"]
    assert set(xl) == set(range(20)) == set(yl)          # every sample has a cell on both
    # same numbering, isometric: up to the sheet's symmetries the cells agree vertex by vertex
    u, w = np.divmod(np.arange(231), 11)
    best = max(np.mean(xl[(a * 11 + b)] == yl) for a, b in
               ((u, w), (20 - u, w), (u, 10 - w), (20 - u, 10 - w)))
    assert best > 0.8
    r = subprocess.run([sys.executable, "-m", "gromov", "match", str(x), str(y), "--plot",
                        str(tmp_path / "no" / "c.png")], capture_output=True, text=True)
    assert r.returncode == 2 and "does not exist" in r.stderr.splitlines()[-1]
