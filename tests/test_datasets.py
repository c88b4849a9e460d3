"""Dataset readers on the real data: TOSCA discovery, the paper's subsets, TopKids ground truth.

Facts checked: the TOSCA classes and pose counts of the data README; the experiment subsets
have the stated sizes, every perturbed pose also appears clean (experiment 1), seeds are
stable CRC-32s and distinct; TopKids ground truth maps every kid vertex into kid00, kid00's
is the identity, and the symmetry map is (almost) an involution.
"""

import zlib
from collections import Counter

import numpy as np
import pytest

from gromov.experiments.datasets import (
    HOLE_COUNTS,
    TOSCA,
    WELD_COUNT,
    DatasetError,
    TopKids,
    data_root,
    experiment1,
    experiment2,
)

POSES = {"cat": 11, "dog": 9, "david": 7, "michael": 20, "victoria": 12, "centaur": 6,
         "horse": 8, "gorilla": 4, "wolf": 3}


@pytest.fixture(scope="module")
def tosca(data_dir):
    return TOSCA(data_dir / "tosca")


@pytest.fixture(scope="module")
def kids(data_dir):
    if not (data_dir / "topkids").is_dir():
        pytest.skip("topkids data not found")
    return TopKids(data_dir / "topkids")


# ---------------------------------------------------------------------------- data_root
def test_data_root_explicit_and_env(data_dir, monkeypatch, tmp_path):
    assert data_root(data_dir) == data_dir
    monkeypatch.setenv("GROMOV_DATA", str(tmp_path))
    assert data_root() == tmp_path
    assert data_root(data_dir) == data_dir  # an explicit path wins over the env


def test_data_root_errors(monkeypatch, tmp_path):
    missing = tmp_path / "nowhere"
    with pytest.raises(FileNotFoundError, match="nowhere"):
        data_root(missing)
    monkeypatch.setenv("GROMOV_DATA", str(missing))
    with pytest.raises(FileNotFoundError, match="GROMOV_DATA.*nowhere"):
        data_root()
    monkeypatch.delenv("GROMOV_DATA")
    with pytest.raises(FileNotFoundError, match="--data.*GROMOV_DATA"):
        data_root()
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileNotFoundError, match="not a directory"):
        data_root(tmp_path / "file")


# -------------------------------------------------------------------------------- TOSCA
def test_tosca_discovery(tosca, data_dir):
    assert tosca.classes == sorted(POSES)
    assert {c: len(tosca.poses(c)) for c in tosca.classes} == POSES
    assert tosca.poses("dog") == [0, 1, 2, 3, 5, 6, 7, 8, 10]
    assert tosca.poses("david") == [0, 1, 6, 10, 11, 12, 13]
    assert tosca.poses("gorilla") == [1, 5, 8, 14]
    assert len(tosca.shapes()) == 80 and tosca.shapes()[0] == ("cat", 0)
    assert tosca.path("david", 10).name == "david10.off.gz"
    assert TOSCA(data_dir).root == tosca.root  # a data root holding tosca/ works too


def test_tosca_load_wolf(tosca):
    a, b = tosca.load("wolf", 0), tosca.load("wolf", 2)
    assert a.n_vertices == b.n_vertices == 4344  # same vertices: identity ground truth
    assert not np.allclose(a.vertices, b.vertices)


def test_tosca_errors(tosca, tmp_path):
    with pytest.raises(KeyError, match=r"pose 4 .*dog.*0, 1, 2, 3, 5"):
        tosca.path("dog", 4)
    with pytest.raises(KeyError, match="pose 0 .*gorilla"):
        tosca.load("gorilla", 0)
    with pytest.raises(KeyError, match="zebra.*cat, centaur"):
        tosca.poses("zebra")
    with pytest.raises(FileNotFoundError, match="no <class><pose>"):
        TOSCA(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        TOSCA(tmp_path / "nowhere")
    (tmp_path / "cat0.off").write_text("OFF\n")
    (tmp_path / "cat0.off.gz").write_bytes(b"")
    with pytest.raises(DatasetError, match="cat0"):
        TOSCA(tmp_path)


# -------------------------------------------------------------------------- experiments
def test_experiment1(tosca):
    entries = experiment1(tosca)
    per_class = Counter(e.cls for e in entries)
    # reference + N deformations, each clean and welded
    assert per_class == {"cat": 1 + 2 * 2, "dog": 1 + 2 * 4, "david": 1 + 2 * 6,
                         "victoria": 1 + 2 * 6}
    clean = {(e.cls, e.pose) for e in entries if e.perturbation is None}
    welded = [e for e in entries if e.perturbation is not None]
    assert all(e.perturbation == ("weld", WELD_COUNT) for e in welded)
    assert all((e.cls, e.pose) in clean for e in welded)
    assert all(e.pose != 0 for e in welded)
    assert {p for c, p in clean if c == "dog"} == {0, 1, 2, 3, 5}
    assert {p for c, p in clean if c == "david"} == set(tosca.poses("david"))
    assert {p for c, p in clean if c == "victoria"} == {0, 1, 2, 4, 7, 10, 12}
    assert "dog5+weld3" in {e.label for e in entries}


def test_experiment2(tosca):
    entries = experiment2(tosca)
    assert Counter(e.cls for e in entries) == {c: 1 + 2 * len(HOLE_COUNTS)
                                               for c in ("cat", "dog", "david", "victoria")}
    for cls in ("cat", "dog", "david", "victoria"):
        mine = [e for e in entries if e.cls == cls]
        assert [e.pose for e in mine if e.perturbation is None] == [0]
        holed = Counter(e.pose for e in mine if e.perturbation is not None)
        assert holed == dict.fromkeys(tosca.poses(cls)[1:3], 2)
        assert {e.perturbation for e in mine} == {None, ("holes", 10), ("holes", 20)}


@pytest.mark.parametrize("make", [experiment1, experiment2])
def test_seeds_deterministic_and_distinct(tosca, make):
    entries = make(tosca)
    assert make(tosca) == entries
    seeds = [e.seed for e in entries]
    assert len(set(seeds)) == len(seeds)
    e = entries[0]
    assert e.seed == zlib.crc32(f"{e.experiment}/{e.cls}/{e.pose}/clean".encode())


def test_experiments_need_reference_pose(tmp_path):
    for name in ("cat0", "cat1", "dog1", "dog2"):
        (tmp_path / f"{name}.off.gz").write_bytes(b"")
    with pytest.raises(DatasetError, match="cat.*needs 2 poses"):
        experiment2(TOSCA(tmp_path))
    (tmp_path / "cat2.off.gz").write_bytes(b"")
    with pytest.raises(DatasetError, match="dog.*no reference pose 0"):
        experiment2(TOSCA(tmp_path))


# ------------------------------------------------------------------------------ TopKids
def test_topkids_names(kids):
    assert kids.names == [f"kid{i:02d}" for i in range(26)]
    assert kids.n_vertices("kid00") == 12000


def test_topkids_ground_truth(kids):
    n0 = kids.n_vertices("kid00")
    assert np.array_equal(kids.ground_truth("kid00"), np.arange(n0))
    gt = kids.ground_truth("kid01")
    mesh = kids.load("kid01")
    assert gt.shape == (mesh.n_vertices,) == (8608,)
    assert gt.dtype == np.int64 and gt.min() >= 0 and gt.max() < n0
    # first rows of kid01_ref.txt: "1 3", "2 2", "3 10725" (1-based)
    assert gt[:3].tolist() == [2, 1, 10724]


@pytest.mark.parametrize("name", ["kid00", "kid01", "kid15"])
def test_topkids_symmetry_nearly_involution(kids, name):
    sym = kids.symmetry(name)
    n = kids.n_vertices(name)
    assert sym.shape == (n,) and sym.min() >= -1 and sym.max() < n
    defined = np.flatnonzero(sym >= 0)
    assert len(defined) > 0.85 * n
    # not exact on the data: 98.2-99.3 % of defined entries map back
    assert np.mean(sym[sym[defined]] == defined) > 0.98


def test_topkids_errors(kids, tmp_path):
    with pytest.raises(KeyError, match="kid99.*kid00, kid01"):
        kids.ground_truth("kid99")
    src = kids.root
    for name in ("kid00", "kid01"):
        (tmp_path / f"{name}.off.gz").write_bytes((src / f"{name}.off.gz").read_bytes())
    bad = TopKids(tmp_path)
    with pytest.raises(FileNotFoundError, match="kid01_ref.txt"):
        bad.ground_truth("kid01")
    rows = np.loadtxt(src / "kid01_ref.txt", dtype=np.int64)
    np.savetxt(tmp_path / "kid01_ref.txt", rows[:-1], fmt="%d")
    with pytest.raises(DatasetError, match="8607 rows for 8608 vertices"):
        bad.ground_truth("kid01")
    rows[0, 1] = 12001
    np.savetxt(tmp_path / "kid01_ref.txt", rows, fmt="%d")
    with pytest.raises(DatasetError, match="second column .*1..12000"):
        bad.ground_truth("kid01")
    np.savetxt(tmp_path / "kid01_ref.txt", rows[:, :1], fmt="%d")
    with pytest.raises(DatasetError, match="expected 2 columns"):
        bad.ground_truth("kid01")
    np.savetxt(tmp_path / "kid00_sym.txt", np.arange(1, 11), fmt="%d")
    with pytest.raises(DatasetError, match="10 rows, but kid00 has 12000"):
        bad.symmetry("kid00")
