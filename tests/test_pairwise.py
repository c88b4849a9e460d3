"""Pairwise GH matrices: symmetric, zero diagonal, parallel equals serial, separates classes."""

import json

import numpy as np
import pytest

import gromov
from gromov import Mesh
from gromov.experiments.pairwise import gh_matrix
from gromov.experiments.recognition import equal_error_rate
from gromov.shapes import grid, rolled_grid


def _sheets():
    # two classes: sheets of aspect 2:1 and 4:1, each flat, rolled and sheared slightly
    out, labels = [], []
    for cls, (w, h) in enumerate([(np.pi, 1.0), (2 * np.pi, 0.5)]):
        for k in range(3):
            if k == 0:
                m = grid(25, 13, width=w, height=h)
            elif k == 1:
                m = rolled_grid(25, 13, width=w, height=h)
            else:
                g = grid(25, 13, width=w, height=h)
                v = g.vertices.copy()
                v[:, 2] = 0.05 * np.sin(v[:, 0] * 2)  # a gentle, nearly isometric wave
                m = Mesh(v, g.faces)
            out.append(m)
            labels.append(cls)
    return out, np.array(labels)


def test_gh_matrix_facts_and_parallel_equals_serial():
    shapes, labels = _sheets()
    serial = gh_matrix(shapes, "geodesic", n_samples=25, resolution=None, jobs=1)
    parallel = gh_matrix(shapes, "geodesic", n_samples=25, resolution=None, jobs=2)
    d = serial.distance
    assert d.shape == (6, 6) and np.array_equal(d, d.T) and np.all(np.diag(d) == 0)
    np.testing.assert_array_equal(parallel.distance, d)
    assert equal_error_rate(serial.relative, labels) == 0.0
    assert serial.seconds_prepare > 0 and serial.seconds_match > 0


def test_errors():
    with pytest.raises(ValueError, match="at least two shapes"):
        gh_matrix([grid()], "geodesic")
    with pytest.raises(ValueError, match="jobs must be"):
        gh_matrix([grid(), grid()], "geodesic", jobs=0)


def test_keep_returns_the_full_match_of_the_asked_pairs():
    shapes, _ = _sheets()
    r = gh_matrix(shapes[:3], "geodesic", n_samples=20, resolution=None, jobs=2, keep=[(0, 2)])
    assert set(r.results) == {(0, 2)}
    full = r.results[0, 2]
    assert full.distance == r.distance[0, 2] and len(full.x_to_y_vertex) == 20
    with pytest.raises(ValueError, match="keep needs pairs"):
        gh_matrix(shapes[:3], "geodesic", n_samples=20, resolution=None, keep=[(2, 0)])


def test_known_pairs_are_not_run_again():
    """Pairs computed before (a set sharing shapes) give the same matrix and are not re-run."""
    from gromov.experiments.pairwise import prepare

    shapes, _ = _sheets()
    prepared = prepare(shapes[:3], "geodesic", n_samples=20, resolution=None)
    full = gh_matrix(prepared, "geodesic", n_samples=20, jobs=1, keep=[(0, 1)])
    known = {(0, 1): (full.distance[0, 1], full.relative[0, 1], full.trimmed[0, 1], full.results[0, 1])}
    again = gh_matrix(prepared, "geodesic", n_samples=20, jobs=1, keep=[(0, 1)], known=known)
    for a in ("distance", "relative", "trimmed"):
        np.testing.assert_array_equal(getattr(again, a), getattr(full, a))
    assert again.results[0, 1] is full.results[0, 1]
    # a known value is taken as given, not recomputed
    fake = gh_matrix(prepared, "geodesic", n_samples=20, jobs=1, known={(1, 2): (7.0, 0.5, 0.25, None)})
    assert fake.distance[1, 2] == fake.distance[2, 1] == 7.0 and fake.trimmed[2, 1] == 0.25
    np.testing.assert_array_equal(fake.distance[0], full.distance[0])
    with pytest.raises(ValueError, match="need their MatchResult"):
        gh_matrix(prepared, "geodesic", n_samples=20, keep=[(1, 2)], known={(1, 2): (7.0, 0.5, 0.25, None)})
    with pytest.raises(ValueError, match="known needs pairs"):
        gh_matrix(prepared, "geodesic", n_samples=20, known={(2, 1): (7.0, 0.5, 0.25, None)})


def test_prepare_computes_the_search_subsets_once_per_shape():
    from gromov.experiments.pairwise import _subsets, prepare
    from gromov import SearchOptions
    from gromov.gh import DEFAULT_COARSE_STAGES, search_subsets

    shapes, _ = _sheets()
    # the default search's subsets, or the one of search_vertices
    assert _subsets({}) == [k for _, k in DEFAULT_COARSE_STAGES if k is not None]
    assert _subsets({"search": SearchOptions(search_vertices=40)}) == [40]
    assert search_subsets(((12, None),)) == []
    (s,) = prepare(shapes[:1], "geodesic", n_samples=10, resolution=None, subsets=[40])
    # the subset match will ask for is already there (no farthest point sampling per pair)
    assert (40, 0) in s._samples
    np.testing.assert_array_equal(s.subset(40), s._samples[40, 0])
    assert len(s.subset(10**6)) == s.mesh.n_vertices  # capped at the working vertices


def test_diffusion_shapes_prepared_in_workers_are_the_ones_prepared_here():
    """prepare(..., jobs=2) computes the diffusion shapes in forked workers: every number the
    matches read (distances, diameter, signatures, samples, subsets, the ranking scale) is
    the one-process value bit for bit, and the matrices stay read-only."""
    from gromov.experiments.pairwise import prepare
    from gromov.gh import ShapeMetric

    shapes, _ = _sheets()
    opts = {"units": "raw", "tau": 0.005}
    runs = []
    for jobs in (1, 2):
        ss = [ShapeMetric(m, "diffusion", resolution=None, metric_options=opts) for m in shapes]
        solvers = [s.solver for s in ss]
        out = prepare(ss, "diffusion", n_samples=20, subsets=[60], rank_tau_scale=0.5, jobs=jobs)
        assert all(a is b for a, b in zip(out, ss))   # the same objects, prepared
        # with two jobs every solver came back from a worker (a new object); with one, in place
        assert all((s.solver is old) == (jobs == 1) for s, old in zip(ss, solvers))
        runs.append(out)
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a.distances, b.distances)
        assert not b.distances.flags.writeable
        assert a.diameter == b.diameter
        np.testing.assert_array_equal(a.descriptors, b.descriptors)
        assert a._samples.keys() == b._samples.keys() and (60, 0) in b._samples
        for key in a._samples:
            np.testing.assert_array_equal(a._samples[key], b._samples[key])
        (ea, da), (eb, db) = a.ranking_surface(0.5), b.ranking_surface(0.5)
        assert da == db
        np.testing.assert_array_equal(ea.embedding, eb.embedding)


def test_matrix_holds_the_orientation_free_estimate_and_keep_the_default_map():
    """The GH estimate counts mirror images as correspondences (orientation="ignore"); a kept
    pair's map is ``match``'s default (orientation="prefer")."""
    from gromov import match

    shapes, _ = _sheets()
    r = gh_matrix(shapes[:3], "geodesic", n_samples=20, resolution=None, keep=[(0, 1), (1, 2)])
    for i, j in [(0, 1), (0, 2), (1, 2)]:
        plain = match(shapes[i], shapes[j], "geodesic", n_samples=20, resolution=None, orientation="ignore")
        assert r.distance[i, j] == plain.distance
    for i, j in [(0, 1), (1, 2)]:
        default = match(shapes[i], shapes[j], "geodesic", n_samples=20, resolution=None)
        np.testing.assert_array_equal(r.results[i, j].x_to_y_vertex, default.x_to_y_vertex)
        assert r.results[i, j].distance == default.distance


def test_prepare_warns_when_the_matrices_will_not_fit(monkeypatch):
    """The dense matrices (8 n^2 bytes per shape) are counted before any metric is computed."""
    import warnings

    from gromov import GromovWarning
    from gromov.experiments import pairwise

    shapes = [grid(21, 11), rolled_grid(21, 11)]   # 231 vertices each: 2 x 427 kB
    need = 2 * 8 * 231**2
    monkeypatch.setattr(pairwise, "_available_memory", lambda: need)  # 80% of it is too little
    with pytest.warns(GromovWarning, match=r"need about 0\.9 MB \(up to 231 working vertices.*"
                                          r"0\.9 MB are available: use a lower resolution"):
        out = pairwise.prepare(shapes, "geodesic", n_samples=10, resolution=None)
    assert all(s.solver._pairwise is not None for s in out)
    monkeypatch.setattr(pairwise, "_available_memory", lambda: 2 * need)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pairwise.prepare(shapes, "geodesic", n_samples=10, resolution=None)
        pairwise.prepare(out, "geodesic", n_samples=10)   # computed already: nothing to warn
    monkeypatch.setattr(pairwise, "_available_memory", lambda: None)   # unknown: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pairwise.prepare(shapes, "geodesic", n_samples=10, resolution=None)


def test_recognition_ranks_by_the_distortion_at_the_finer_scale():
    """gh_matrix's trimmed matrix holds each correspondence's ranking distance (heat kernel:
    measured at rank_tau_scale x tau, default RANK_TAU_SCALE, of the log distance ratios,
    default RANK_RESIDUAL); None and "difference" rank by relative_trimmed (the match's scale);
    the GH estimates are the same either way."""
    from gromov.gh import RANK_RESIDUAL, RANK_TAU_SCALE

    shapes, labels = _sheets()
    shapes = shapes[:2] + shapes[3:5]
    opts = {"units": "raw"}
    r = gh_matrix(shapes, "diffusion", n_samples=20, resolution=None, metric_options=opts,
                  jobs=2, keep=[(0, 2)])
    old = gh_matrix(shapes, "diffusion", n_samples=20, resolution=None, metric_options=opts,
                    jobs=1, rank_tau_scale=None, rank_residual="difference")
    assert r.rank_tau_scale == RANK_TAU_SCALE == 0.5 and old.rank_tau_scale is None
    assert r.rank_residual == RANK_RESIDUAL == "log" and old.rank_residual == "difference"
    np.testing.assert_array_equal(r.distance, old.distance)
    from gromov.gh import _match   # what gh_matrix runs per pair

    one = _match(shapes[0], shapes[2], "diffusion", n_samples=20, resolution=None, metric_options=opts,
                 orientation="ignore", rank_tau_scale=0.5, rank_residual="log")
    assert r.trimmed[0, 2] == one.ranking_distance and r.relative[0, 2] == one.relative_distance
    diff = _match(shapes[0], shapes[2], "diffusion", n_samples=20, resolution=None, metric_options=opts,
                  orientation="ignore", rank_tau_scale=0.5)   # match's default: differences
    assert diff.distance == one.distance and diff.ranking_distance != one.ranking_distance
    with pytest.raises(ValueError, match="rank_residual"):
        gh_matrix(shapes, "diffusion", n_samples=20, resolution=None, rank_residual="ratio")
    assert old.trimmed[0, 2] == one.relative_trimmed != one.ranking_distance
    kept = r.results[0, 2]          # the kept map is measured the same way
    assert kept.ranking_distance != kept.relative_trimmed
    off = ~np.eye(4, dtype=bool)
    assert np.all(r.trimmed[off] > 0) and not np.allclose(r.trimmed, old.trimmed)
    assert np.array_equal(r.trimmed, r.trimmed.T)


def test_main_names_import_from_the_experiments_package():
    import gromov.experiments as ex
    from gromov.experiments import gh_matrix, pairwise, roc
    from gromov.experiments import reproduce as module

    assert gh_matrix is pairwise.gh_matrix and roc is ex.recognition.roc
    assert module.__name__ == "gromov.experiments.reproduce"   # the submodule, not the function
    assert "gh_matrix" in dir(ex)


def _collection(tmp_path):
    """Two classes of two isometric sheets (flat and rolled) and a file with no surface."""
    files = [tmp_path / "sheet0.off", tmp_path / "long0.off", tmp_path / "sheet1.off",
             tmp_path / "long1.off"]
    for f, m in zip(files, (grid(21, 11), grid(31, 11, width=2 * np.pi), rolled_grid(21, 11),
                            rolled_grid(31, 11, width=2 * np.pi))):
        gromov.save(m, f)
    bad = tmp_path / "flat2.off"   # every face has zero area
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n")
    return [str(f) for f in files], str(bad)


def test_pairwise_goes_on_without_a_shape_it_cannot_use(tmp_path, capsys):
    """The unusable file is named on one line with its reason and left out of every result;
    the others are matched as without it; the exit status is 0, or 1 with --strict."""
    from gromov.cli import main

    files, bad = _collection(tmp_path)
    argv = ["pairwise", files[0], files[1], bad, files[2], files[3], "--metric", "geodesic",
            "--samples", "20", "--jobs", "1", "--labels-from-names", "--json"]
    csv_path = tmp_path / "d.csv"
    assert main([*argv, "--out", str(csv_path)]) == 0
    out, err = capsys.readouterr()
    res = json.loads(out)
    skipped = [line for line in err.splitlines() if line.startswith("gromov: skipped")]
    assert skipped == [f"gromov: skipped {bad}: " + res["skipped"][bad]]
    assert "no valid triangle" in res["skipped"][bad]
    assert res["files"] == files and res["labels"] == ["sheet", "long", "sheet", "long"]
    assert res["nearest"] == [files[2], files[3], files[0], files[1]] and res["eer"] == 0.0
    assert csv_path.read_text().splitlines()[0].split(",")[1:] == files
    assert main([*argv, "--strict"]) == 1
    assert bad in capsys.readouterr().err


def test_pairwise_leaves_out_a_shape_whose_metric_fails(tmp_path, capsys, monkeypatch):
    """A shape that loads but whose metric cannot be computed is found, named and left out."""
    import gromov.experiments.pairwise as pw
    from gromov.cli import main
    from gromov.errors import MetricError

    files, _ = _collection(tmp_path)
    real = pw._prepare_one

    def failing(s, *a):
        if s.input.n_vertices == 31 * 11:   # the long sheets
            raise MetricError("no metric on this one")
        return real(s, *a)

    monkeypatch.setattr(pw, "_prepare_one", failing)
    assert main(["pairwise", *files, "--metric", "geodesic", "--samples", "20", "--jobs", "1",
                 "--json"]) == 0
    out, err = capsys.readouterr()
    res = json.loads(out)
    assert res["files"] == [files[0], files[2]] and res["nearest"] == [files[2], files[0]]
    assert res["skipped"] == {files[1]: "no metric on this one", files[3]: "no metric on this one"}
    assert err.count("gromov: skipped") == 2


def test_pairwise_with_one_usable_shape_names_the_others(tmp_path, capsys):
    """With fewer than two usable shapes the run stops on one line naming each left-out file."""
    from gromov.cli import main

    files, bad = _collection(tmp_path)
    assert main(["pairwise", files[0], bad, "--metric", "geodesic", "--samples", "20", "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert "at least two usable shapes; 1 of 2 can be used" in err and bad in err and "Traceback" not in err


def test_known_pairs_take_four_or_five_values():
    shapes = [grid(8, 8), grid(9, 8)]
    with pytest.raises(ValueError, match="4 or 5 values"):
        gh_matrix(shapes, "geodesic", n_samples=10, resolution=None, known={(0, 1): (1.0, 0.1, 0.1)})
    four = gh_matrix(shapes, "geodesic", n_samples=10, resolution=None, known={(0, 1): (1.0, 0.1, 0.2, None)})
    assert (four.distance[0, 1], four.relative[1, 0], four.trimmed[0, 1]) == (1.0, 0.1, 0.2)
    assert four.signature is None
    # a known pair without its signature distortion is matched again where the combined ranking needs it
    five = gh_matrix(shapes, "geodesic", n_samples=10, resolution=None, spectral=True,
                     known={(0, 1): (1.0, 0.1, 0.2, float("nan"), None)})
    assert five.distance[0, 1] != 1.0 and np.isfinite(five.signature[0, 1])
    kept = gh_matrix(shapes, "geodesic", n_samples=10, resolution=None, spectral=True,
                     known={(0, 1): (1.0, 0.1, 0.2, 0.3, None)})
    assert kept.distance[0, 1] == 1.0 and kept.signature[0, 1] == 0.3
