"""Ranking parts against wholes (gromov.partial.partial_matrix, gromov.retrieval.nearest_wholes,
``gromov pairwise --partial``, ``gromov search --partial``) and the warning for a part too small
to place (gromov.partial.SMALL_PART)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import gromov
from gromov.errors import SmallPartWarning
from gromov.partial import PARTIAL_RANK_BRIDGE, SMALL_PART, match_partial, partial_matrix
from gromov.perturb import cut
from gromov.retrieval import nearest_wholes
from gromov.shapes import icosphere, rolled_grid, torus

N = 20   # samples per part: the shapes have 200-500 vertices


@pytest.fixture(scope="module")
def shapes():
    """A part cut from a torus A (60% of its area), A, A moved (rotated and its vertices
    permuted: the same surface), and three other wholes: a fatter torus, a sphere, a rolled
    grid (an open cylinder)."""
    a = torus(32, 16)
    p = cut(a, 0.6, kind="plane", seed=0).mesh
    rng = np.random.default_rng(5)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    perm = rng.permutation(a.n_vertices)
    moved = gromov.Mesh(a.vertices[perm] @ q.T, np.argsort(perm)[a.faces])
    wholes = {"A": a, "A_moved": moved, "fat": torus(32, 16, minor=0.6), "sphere": icosphere(2),
              "cylinder": rolled_grid(31, 16)}
    return p, wholes


@pytest.fixture(scope="module")
def matrix(shapes):
    part, wholes = shapes
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = partial_matrix([part, wholes["A"], wholes["fat"], wholes["sphere"], wholes["cylinder"]], n_samples=N,
                           resolution=None)
    return m, caught


def test_matrix_is_match_partial_pair_by_pair(shapes, matrix):
    part, wholes = shapes
    m, _ = matrix
    assert m.same and m.distance.shape == (5, 5)
    assert np.all(np.diag(m.distance) == 0) and np.all(np.diag(m.covered_fraction) == 1)
    for i, j in [(0, 1), (1, 0), (2, 3), (3, 2)]:
        x = [part, wholes["A"], wholes["fat"], wholes["sphere"]][i]
        y = [part, wholes["A"], wholes["fat"], wholes["sphere"]][j]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SmallPartWarning)
            r = match_partial(x, y, n_samples=N, resolution=None, bridge=PARTIAL_RANK_BRIDGE)
        assert m.distance[i, j] == r.distance
        assert m.relative_distance[i, j] == r.relative_distance
        assert m.covered_fraction[i, j] == r.covered_fraction
        assert m.ranking_distance[i, j] == r.ranking_distance
        assert m.area_ratio[i, j] == pytest.approx(x.area / y.area)
    # not symmetric: the part fits into its whole, the whole not into the part
    assert m.distance[0, 1] < 0.1 * m.distance[1, 0]


def test_a_part_finds_its_whole(shapes):
    part, wholes = shapes
    names = list(wholes)
    m = partial_matrix([part], list(wholes.values()), n_samples=N, resolution=None, names=names)
    assert m.distance.shape == (1, len(names)) and not m.same
    order = [names[j] for j in np.argsort(m.distance[0])]
    assert set(order[:2]) == {"A", "A_moved"}
    assert names[m.nearest[0]] in ("A", "A_moved")
    np.testing.assert_allclose(m.score, m.ranking_distance / m.covered_fraction)
    # the ranked objective adds the curvature term (>= 0) to the same weighted residuals
    assert np.all(m.ranking_distance >= m.relative_distance)
    # in its own whole the part covers about its own share of the area
    assert abs(m.covered_fraction[0, names.index("A")] - part.area / wholes["A"].area) < 0.3


@pytest.mark.parametrize("bridge", [False, "choose"])
def test_a_torus_part_fits_its_own_whole_exactly(shapes, bridge):
    """The plane cut through the torus leaves chords across its central hole, a loose bound:
    the bridged distances alone misfit the part's own whole (about 1e-3), and "choose" keeps
    the exact map of the part's own distances."""
    part, wholes = shapes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SmallPartWarning)
        r = match_partial(part, wholes["A"], n_samples=N, resolution=None, bridge=bridge)
        b = match_partial(part, wholes["A"], n_samples=N, resolution=None, bridge=True)
    assert r.relative_distance < 1e-4 < b.relative_distance
    assert abs(r.covered_fraction - part.area / wholes["A"].area) < 0.3


def test_the_score_is_the_relative_distance_per_share_covered():
    """A whole that the part fits slightly better but covers a third as much of is not the
    nearest; a whole with nothing covered never is; with ``same`` the diagonal is 0."""
    from gromov.partial import PartialMatrix

    rel = np.array([[0.020, 0.015, 0.001]])
    cover = np.array([[0.6, 0.2, 0.0]])
    m = PartialMatrix(rel * 10, rel, cover, np.full((1, 3), 0.5), False, ["p"], ["a", "b", "c"], "geodesic", 10, 0.0)
    np.testing.assert_allclose(m.score[0, :2], [0.020 / 0.6, 0.015 / 0.2])
    assert m.score[0, 2] == np.inf and m.nearest[0] == 0
    sq = PartialMatrix(np.zeros((2, 2)), np.array([[0.0, 0.01], [0.02, 0.0]]), np.array([[1.0, 0.5], [0.5, 1.0]]),
                       np.ones((2, 2)), True, ["a", "b"], ["a", "b"], "geodesic", 10, 0.0)
    np.testing.assert_allclose(sq.score, [[0.0, 0.02], [0.04, 0.0]])
    np.testing.assert_array_equal(sq.nearest, [1, 0])


def test_nearest_wholes_of_a_list(shapes):
    part, wholes = shapes
    r = nearest_wholes(part, list(wholes.values()), k=2, n_samples=N, resolution=None)
    assert r.rank_by == "partial" and r.exact and r.full_matches == len(wholes) and r.skipped == 0
    assert {n.index for n in r.neighbors} == {0, 1}
    d = r.to_dict()
    assert d["partial"] is True and 0 < d["neighbors"][0]["covered_fraction"] <= 1
    assert d["neighbors"][0]["distance"] <= d["neighbors"][1]["distance"]


def test_partial_matrix_checks_its_inputs(shapes):
    part, wholes = shapes
    with pytest.raises(ValueError, match="a part and a whole"):
        partial_matrix([part])
    with pytest.raises(ValueError, match="names needs one name per whole"):
        partial_matrix([part], [wholes["A"]], names=["a", "b"], n_samples=N, resolution=None)
    with pytest.raises(ValueError, match="dense"):
        partial_matrix([part], [wholes["A"]], dense=True)
    with pytest.raises(ValueError, match="part 0 as a part of whole 0: n_samples"):
        partial_matrix([part], [wholes["A"]], n_samples=10_000, resolution=None)


def test_a_point_cloud_whole_is_left_out(shapes):
    part, wholes = shapes
    cloud = gromov.PointCloud(wholes["A"].vertices)
    with pytest.warns(gromov.GromovWarning, match="point clouds"):
        m = partial_matrix([part], [wholes["A"], cloud], n_samples=N, resolution=None)
    assert np.isfinite(m.distance[0, 0]) and np.isnan(m.distance[0, 1]) and m.nearest[0] == 0


# ----------------------------------------------------------------------------- the small part
def test_small_part_warns_below_the_threshold():
    whole = torus(32, 16)
    small = cut(whole, 0.12, kind="plane", seed=0).mesh
    assert small.area / whole.area < SMALL_PART
    with pytest.warns(SmallPartWarning, match=r"keeps only 1\d\.\d% of the whole's area.*unreliable below 25%"):
        r = match_partial(small, whole, n_samples=N, resolution=None)
    assert np.isfinite(r.distance) and 0 < r.covered_fraction < 1   # matched all the same
    with pytest.warns(SmallPartWarning):   # through gromov.match too
        gromov.match(small, whole, partial=True, n_samples=N, resolution=None)


def test_no_warning_above_the_threshold(shapes):
    part, wholes = shapes   # 60% of A
    with warnings.catch_warnings():
        warnings.simplefilter("error", SmallPartWarning)
        match_partial(part, wholes["A"], n_samples=N, resolution=None)
        part35 = cut(wholes["A"], 0.35, kind="plane", seed=0).mesh
        assert part35.area / wholes["A"].area > SMALL_PART
        match_partial(part35, wholes["A"], n_samples=N, resolution=None)


def test_matrix_warns_once_for_its_small_pairs(matrix):
    m, caught = matrix
    small = [w for w in caught if issubclass(w.category, SmallPartWarning)]
    # the cylinder (area pi) into the tori (14 and 24): under a quarter of their area
    assert m.small[4, 1] and m.small[4, 2] and not m.small[0].any()
    assert np.array_equal(m.small, (m.area_ratio < SMALL_PART) & ~np.eye(5, dtype=bool))
    assert len(small) == 1 and f"{m.small.sum()} of 20 pairs" in str(small[0].message)
    assert "shape 4 in shape 1" in str(small[0].message)


def test_tiny_parts_do_not_crash():
    whole = torus(32, 16)
    for keep in (0.05, 0.1):
        tiny = cut(whole, keep, kind="plane", seed=1).mesh
        with pytest.warns(SmallPartWarning):
            r = match_partial(tiny, whole, n_samples=min(N, tiny.n_vertices), resolution=None)
        assert np.isfinite(r.distance) and r.covered_fraction < 0.5


# ----------------------------------------------------------------------------- command line
@pytest.fixture(scope="module")
def files(shapes, tmp_path_factory):
    part, wholes = shapes
    d = tmp_path_factory.mktemp("partial_rank")
    paths = [d / "part.off", d / "torus.off", d / "fat.off", d / "sphere.off"]
    for path, mesh in zip(paths, [part, wholes["A"], wholes["fat"], wholes["sphere"]]):
        gromov.save(mesh, path)
    return [str(p) for p in paths]


def test_cli_pairwise_partial_json(files, matrix, capsys, tmp_path):
    from gromov.cli import main

    m, _ = matrix
    keep = np.ix_(range(4), range(4))
    out = tmp_path / "m.npz"
    argv = ["pairwise", *files, "--partial", "--samples", str(N), "--resolution", "100000", "--json", "-q",
            "--out", str(out)]
    assert main(argv) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["partial"] is True and got["metric"] == "geodesic" and got["ranked_by"] == "ranking_distance/covered_fraction"
    assert np.allclose(got["distance"], m.distance[keep])
    assert np.allclose(got["covered_fraction"], m.covered_fraction[keep])
    assert np.allclose(got["area_ratio"], m.area_ratio[keep]) and got["small_part"] == SMALL_PART
    assert got["nearest"][0] == files[1]   # the part's whole
    z = np.load(out)
    assert np.allclose(z["distance"], m.distance[keep]) and np.allclose(z["covered_fraction"], m.covered_fraction[keep])
    assert list(z["files"]) == files and str(z["ranked_by"]) == "ranking_distance/covered_fraction"


def test_cli_pairwise_partial_text_and_csv(files, capsys, tmp_path):
    from gromov.cli import main

    out = tmp_path / "m.csv"
    argv = ["pairwise", *files[:2], "--partial", "--samples", str(N), "--resolution", "100000", "-q",
            "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "2 ordered pairs" in text and f"in {files[1]}" in text and "of it covered" in text
    rows = out.read_text().splitlines()
    assert rows[0].startswith("partial_distance,") and rows[1].split(",")[1] == "0.0"


@pytest.mark.parametrize("extra, option", [(["--candidates", "2"], "--candidates"), (["-k", "1"], "-k"),
                                           (["--rank-by", "gh"], "--rank-by"), (["--mds", "m.png"], "--mds"),
                                           (["--dask", "2"], "--dask"), (["--jobs", "2"], "--jobs"),
                                           (["--rank-tau-scale", "2"], "--rank-tau-scale")])
def test_cli_pairwise_partial_refuses(files, capsys, extra, option):
    from gromov.cli import main

    assert main(["pairwise", *files[:2], "--partial", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"gromov: error: {option} is not available with --partial") and err.count("\n") == 1


def test_cli_search_partial(files, capsys, tmp_path):
    from gromov.cli import main

    store = tmp_path / "store"
    # wholes indexed with the geodesic metric (read as they are) and the sphere with the diffusion
    # one (its mesh read, its geodesic metric computed)
    assert main(["index", *files[1:3], "--store", str(store), "--metric", "geodesic", "--resolution", "100000",
                 "-q"]) == 0
    assert main(["index", files[3], "--store", str(store), "-q"]) == 0
    argv = ["search", files[0], "--store", str(store), "--partial", "--samples", str(N), "--resolution", "100000"]
    assert main([*argv, "--json", "-k", "3"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["partial"] is True and got["full_matches"] == 3 and got["exact"] is True
    assert got["neighbors"][0]["file"].endswith("torus.off")
    assert all(0 < x["covered_fraction"] <= 1 and x["area_ratio"] > 0 for x in got["neighbors"])
    assert main([*argv, "-q"]) == 0
    assert "per share covered" in capsys.readouterr().out
    # the query's own file is left out
    assert main(["search", files[1], "--store", str(store), "--partial", "--samples", str(N), "--resolution",
                 "100000", "--json"]) == 0
    assert all(not x["file"].endswith("torus.off") for x in json.loads(capsys.readouterr().out)["neighbors"])
    assert main([*argv, "--prune", "none"]) == 2
    assert capsys.readouterr().err.startswith("gromov: error: --prune is not available with --partial")


def test_cli_match_prints_the_small_part_warning(tmp_path):
    import subprocess
    import sys

    whole = torus(32, 16)
    gromov.save(whole, tmp_path / "whole.off")
    gromov.save(cut(whole, 0.12, kind="plane", seed=0).mesh, tmp_path / "small.off")
    # in a process of its own: pytest records the warnings of the tests' own
    proc = subprocess.run([sys.executable, "-m", "gromov", "match", str(tmp_path / "small.off"),
                           str(tmp_path / "whole.off"), "--partial", "--samples", str(N), "-q"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("gromov: warning: the part keeps only 11.9% of the whole's area")
    assert "unreliable below 25%" in lines[0] and "as a part of" in proc.stdout
