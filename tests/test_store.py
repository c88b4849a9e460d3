"""The shape store: stored shapes match bit for bit, entries are verified, pairwise resumes."""

import dataclasses
import hashlib
import json
import logging
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import gromov
from gromov import MatchResult, Mesh, PointCloud, ShapeMetric, match
from gromov.cli import main
from gromov.experiments import pairwise
from gromov.experiments.pairwise import gh_matrix
from gromov.metrics import GeodesicSolver
from gromov.shapes import grid, icosphere, rolled_grid
from gromov.store import PAIR_ARRAYS, ShapeStore, StoreError, _arrays_sha256, match_options_key


def _sheets():
    """Two classes of sheets (2:1 and 4:1), each flat, rolled and gently waved: 325 vertices."""
    out = []
    for w, h in [(np.pi, 1.0), (2 * np.pi, 0.5)]:
        out += [grid(25, 13, width=w, height=h), rolled_grid(25, 13, width=w, height=h)]
        g = grid(25, 13, width=w, height=h)
        v = g.vertices.copy()
        v[:, 2] = 0.05 * np.sin(v[:, 0] * 2)
        out.append(Mesh(v, g.faces))
    return out


@pytest.fixture(scope="module")
def sheet_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sheets")
    files = []
    for i, m in enumerate(_sheets()):
        files.append(str(folder / f"sheet{i}.off"))
        gromov.save(m, files[-1])
    return files


def _assert_same_result(a: MatchResult, b: MatchResult) -> None:
    for f in dataclasses.fields(MatchResult):
        if f.name == "seconds":
            continue
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, tuple):
            for u, v in zip(x, y):
                np.testing.assert_array_equal(u, v, err_msg=f.name)
        else:
            np.testing.assert_array_equal(x, y, err_msg=f.name)


def test_a_stored_shape_matches_bit_for_bit(tmp_path, monkeypatch):
    """Simplified meshes (their maps to the input used by every correspondence), the heat
    metric with its ranking scale, the orientation preference and the dense maps: the same
    MatchResult from shapes read back from the store as from fresh ones."""
    x, y = grid(31, 16), rolled_grid(31, 16)
    opts = {"n_samples": 15, "rank_tau_scale": 0.5, "rank_residual": "log", "dense": True}
    store = ShapeStore(tmp_path / "s")
    fresh = store.shapes([x, y], "diffusion", resolution=200, rank_tau_scale=0.5)   # computed here
    assert store.computed == 2 and store.reused == 0
    again = ShapeStore(tmp_path / "s")
    stored = again.shapes([x, y], "diffusion", resolution=200, rank_tau_scale=0.5)
    assert again.computed == 0 and again.reused == 2
    assert stored[0] is not fresh[0] and stored[0].mesh.n_vertices < x.n_vertices
    # nothing of the metric is computed again: no eigenpairs, no rows
    from gromov.metrics.diffusion import _SpectralDiffusion

    def refuse(*a, **k):
        raise AssertionError("a metric was computed")

    monkeypatch.setattr(_SpectralDiffusion, "_spectral", refuse)
    monkeypatch.setattr(_SpectralDiffusion, "_rows", refuse)
    from gromov.gh import _match   # recognition's match: the shapes in their own (raw) units

    got = _match(*stored, "diffusion", as_prepared=True, **opts)
    monkeypatch.undo()
    _assert_same_result(got, _match(*fresh, "diffusion", as_prepared=True, **opts))
    assert np.isfinite(got.ranking_distance) and got.has_dense
    # the dense maps' Laplace-Beltrami basis is the heat kernel's own eigenpairs, read back
    from gromov.dense import _basis

    for a, b in zip(stored, fresh):
        np.testing.assert_array_equal(_basis(a, 40)[0], _basis(b, 40)[0])
        np.testing.assert_array_equal(a.ranking_surface(0.25)[0].embedding, b.ranking_surface(0.25)[0].embedding)


def test_a_stored_point_cloud_matches_bit_for_bit(tmp_path):
    a = PointCloud(icosphere(2).vertices)
    b = PointCloud(icosphere(2).vertices * [1.0, 1.0, 1.2])
    store = ShapeStore(tmp_path)
    store.shapes([a, b], "geodesic", resolution=120)
    stored = ShapeStore(tmp_path).shapes([a, b], "geodesic", resolution=120)
    fresh = [ShapeMetric(s, "geodesic", resolution=120) for s in (a, b)]
    _assert_same_result(match(*stored, "geodesic", n_samples=15), match(*fresh, "geodesic", n_samples=15))


def test_the_catalogue_and_entries_are_readable_without_gromov(tmp_path, sheet_files):
    store = ShapeStore(tmp_path)
    store.shape(sheet_files[0], "geodesic", resolution=100)
    with sqlite3.connect(tmp_path / "catalogue.sqlite") as db:
        (path, content, options, version, name, checksum) = db.execute(
            "SELECT path, content_hash, options, version, file, checksum FROM entries").fetchone()
    import hashlib

    assert path == os.path.realpath(sheet_files[0])
    assert content == hashlib.sha256(Path(sheet_files[0]).read_bytes()).hexdigest()
    assert checksum == hashlib.sha256((tmp_path / name).read_bytes()).hexdigest()
    assert version == gromov.__version__
    assert json.loads(options) == {"metric": "geodesic", "metric_options": {}, "resolution": 100,
                                   "rank_tau_scale": None}
    with np.load(tmp_path / name) as z:
        n = len(z["vertex_ids"])
        assert z["distances"].shape == (n, n) and z["distances"].dtype == np.float64
        np.testing.assert_array_equal(z["working_vertices"], z["input_vertices"][z["vertex_ids"]])
        assert float(z["diameter"]) == z["distances"].max()


def test_options_and_contents_make_separate_entries(tmp_path, sheet_files):
    store = ShapeStore(tmp_path)
    f = sheet_files[0]
    keys = set()
    for metric, res in [("geodesic", 100), ("geodesic", 200), ("diffusion", 100)]:
        keys.add(store.key_of(store.shape(f, metric, resolution=res)))
    store.shape(f, "geodesic", resolution=100)
    assert len(keys) == 3 and store.computed == 3 and store.reused == 1
    # a mesh given as arrays is keyed by its arrays, not by a file
    m = gromov.load(f)
    s = store.shape(m, "geodesic", resolution=100)
    assert store.key_of(s) not in keys and store.computed == 4
    # the heat kernel's ranking scale is part of its key; it does not apply to geodesic distances
    opt = ShapeStore.shape_options
    assert opt("geodesic", rank_tau_scale=0.5)["rank_tau_scale"] is None
    assert opt("diffusion", rank_tau_scale=0.5)["rank_tau_scale"] == 0.5
    assert opt("diffusion", metric_options={"kernel": "biharmonic"}, rank_tau_scale=0.5)["rank_tau_scale"] is None
    # the CLI's explicit defaults and the library's implicit ones are the same entry
    assert opt("diffusion") == opt("diffusion", metric_options={"kernel": "heat", "fill_holes": 0.5})
    # ... the heat kernel's units and diffusion time too; another value is another entry
    def heat(**o):
        return opt("diffusion", metric_options=o)

    assert heat() == heat(units="raw") == heat(tau=0.005) == heat(units="raw", tau=0.005)
    assert heat(units="normalized") == heat(units="normalized", tau=0.01) != heat()
    assert heat(tau=0.01) != heat()


def test_a_prepared_shape_metric_is_keyed_by_its_arrays(tmp_path):
    """A ShapeMetric (e.g. with a working mesh transferred from another pose) is stored with
    what it computed, and found again from an equal one."""
    ref = ShapeMetric(grid(13, 7), "geodesic")
    store = ShapeStore(tmp_path)
    assert store.shape(ref, "geodesic") is ref and store.computed == 1
    again = ShapeStore(tmp_path)
    s = again.shape(ShapeMetric(grid(13, 7), "geodesic"), "geodesic")
    assert again.reused == 1 and s.solver._pairwise is not None
    np.testing.assert_array_equal(s.distances, ref.distances)
    # another working mesh of the same input is another entry
    other = ShapeMetric(grid(13, 7), "geodesic", resolution=40)
    again.shape(other, "geodesic")
    assert again.computed == 1 and len(again.entries()) == 2



def test_shapes_that_differ_only_in_their_file_numbering_are_separate_entries(tmp_path):
    """Two arrays-given meshes alike but for the file vertices loading dropped give their
    per-vertex results in different file numberings: separate entries; a mesh without dropped
    or merged vertices keeps the key it had (its file index is the identity, not hashed)."""
    g = grid(9, 5)
    n = g.n_vertices
    plain = gromov.Mesh(g.vertices, g.faces)
    last = gromov.Mesh(g.vertices, g.faces, file_index=np.r_[np.arange(n), -1])    # a dropped last vertex
    first = gromov.Mesh(g.vertices, g.faces, file_index=np.r_[-1, np.arange(n)])   # ... or first
    store = ShapeStore(tmp_path)
    keys = [store.key_for(m, "geodesic") for m in (plain, last, first)]
    assert len(set(keys)) == 3
    h = hashlib.sha256()   # the identity file index is left out of the hash
    for name, a in sorted({"kind": np.array("mesh"), "vertices": plain.vertices, "input_ids": plain.input_ids,
                           "faces": plain.faces}.items()):
        a = np.ascontiguousarray(a)
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    assert _arrays_sha256(plain) == h.hexdigest()

def _entry_file(store: ShapeStore):
    (e,) = store.entries()
    return store.root / e.file


@pytest.mark.parametrize("damage", ["truncated", "altered", "missing"])
def test_a_damaged_entry_is_reported_and_recomputed(tmp_path, sheet_files, damage, caplog):
    store = ShapeStore(tmp_path)
    first = store.shape(sheet_files[0], "geodesic")
    path = _entry_file(store)
    data = path.read_bytes()
    if damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "altered":   # one byte of the distances, same size
        path.write_bytes(data[:-5000] + bytes([data[-5000] ^ 1]) + data[-4999:])
    else:
        path.unlink()
    assert len(ShapeStore(tmp_path).verify()) == 1
    again = ShapeStore(tmp_path)
    with caplog.at_level(logging.WARNING, logger="gromov.store"):
        s = again.shape(sheet_files[0], "geodesic")
    assert again.computed == 1 and again.reused == 0 and len(again.problems) == 1
    reason = {"truncated": "does not match its checksum", "altered": "does not match its checksum",
              "missing": "is missing"}[damage]
    assert [r.levelname for r in caplog.records] == ["WARNING"] and reason in caplog.text
    np.testing.assert_array_equal(s.distances, first.distances)
    assert again.verify() == [] and len(os.listdir(tmp_path / "entries")) == 1


def test_a_file_changed_since_indexing_is_recomputed(tmp_path, caplog):
    f = tmp_path / "shape.off"
    gromov.save(grid(25, 13), f)
    store = ShapeStore(tmp_path / "s")
    before = store.shape(f, "geodesic")
    gromov.save(grid(25, 13, width=2.0), f)   # another shape under the same name
    with caplog.at_level(logging.WARNING, logger="gromov.store"):
        after = store.shape(f, "geodesic")
    assert "changed since it was indexed" in caplog.text and store.computed == 2
    assert after.diameter != before.diameter
    assert after.diameter == ShapeMetric(str(f), "geodesic").diameter
    (e,) = store.entries()   # the stale entry is gone
    assert e.path == str(f.resolve()) and store.verify() == []


def test_cli_prints_one_line_per_damaged_entry(tmp_path, sheet_files, capsys):
    d = str(tmp_path / "s")
    files = sheet_files[:2]
    assert main(["index", *files, "--store", d, "--metric", "geodesic"]) == 0
    assert "2 files in" in capsys.readouterr().out
    store = ShapeStore(d)
    e = next(e for e in store.entries() if e.path == os.path.realpath(files[1]))
    (store.root / e.file).write_bytes(b"not an archive")
    assert main(["index", *files, "--store", d, "--metric", "geodesic"]) == 0
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if "gromov:" in line]
    assert len(lines) == 1 and lines[0].startswith("gromov: warning: ") and files[1].split("/")[-1] in lines[0]
    assert "does not match its checksum" in lines[0] and "1 computed, 1 read back" in out
    assert ShapeStore(d).verify() == []
    assert logging.getLogger("gromov.store").propagate   # the CLI's printer is removed again


def test_errors(tmp_path, sheet_files):
    (tmp_path / "file").write_text("x")
    with pytest.raises(StoreError, match="is not a folder"):
        ShapeStore(tmp_path / "file")
    store = ShapeStore(tmp_path / "s")
    with pytest.raises(FileNotFoundError, match="no such file"):
        store.shape(tmp_path / "missing.off", "geodesic")
    with pytest.raises(ValueError, match="prepared for 'geodesic'"):
        store.shape(ShapeMetric(grid(9, 5), "geodesic"), "diffusion")
    with pytest.raises(TypeError, match="unknown match options"):
        match_options_key(20, 0, {"n_sample": 3})
    store.close()
    with sqlite3.connect(tmp_path / "s" / "catalogue.sqlite") as db:
        db.execute("UPDATE meta SET value = '99' WHERE name = 'format'")
    with pytest.raises(StoreError, match="format 99"):
        ShapeStore(tmp_path / "s")


def test_gh_matrix_reuses_shapes_and_pairs_and_adds_only_new_pairs(tmp_path, sheet_files, monkeypatch):
    files = sheet_files[:4]
    opts = {"n_samples": 20, "resolution": None}
    ref = gh_matrix(files, "geodesic", jobs=1, **opts)
    calls = []
    real = pairwise._match

    def counted(x, y, *a, **k):
        calls.append(1)
        return real(x, y, *a, **k)

    monkeypatch.setattr(pairwise, "_match", counted)
    first = gh_matrix(files[:3], "geodesic", jobs=1, store=tmp_path, **opts)
    assert len(calls) == 3
    store = ShapeStore(tmp_path)
    grown = gh_matrix(files, "geodesic", jobs=1, store=store, **opts)
    assert len(calls) == 3 + 3 and store.computed == 1 and store.reused == 3 and store.pairs_reused == 3
    for a in ("distance", "relative", "trimmed"):
        np.testing.assert_array_equal(getattr(grown, a), getattr(ref, a))
        np.testing.assert_array_equal(getattr(first, a), getattr(ref, a)[:3, :3])
    # a second run computes no metric and no pair
    monkeypatch.setattr(GeodesicSolver, "_rows", lambda *a, **k: pytest.fail("a metric was computed"))
    monkeypatch.setattr(ShapeStore, "_compute", lambda *a, **k: pytest.fail("an entry was computed"))
    again = gh_matrix(files, "geodesic", jobs=2, store=tmp_path, **opts)
    assert len(calls) == 6
    np.testing.assert_array_equal(again.trimmed, ref.trimmed)
    # other match options are other pairs
    monkeypatch.undo()
    records = ShapeStore(tmp_path).pairs()
    assert len(records) == 6 and {r.options["n_samples"] for r in records} == {20}
    r = next(r for r in records if r.x == store.key_of(grown_shape(store, files[0]))
             and r.y == store.key_of(grown_shape(store, files[3])))
    from gromov.gh import _match   # what gh_matrix runs per pair

    one = _match(files[0], files[3], "geodesic", orientation="ignore", rank_tau_scale=0.5, rank_residual="log",
                 **opts)
    assert (r.distance, r.relative_distance, r.ranking_distance) == (one.distance, one.relative_distance,
                                                                     one.ranking_distance)
    assert r.distortion_trimmed == one.distortion_trimmed and r.relative_trimmed == one.relative_trimmed
    for k in PAIR_ARRAYS:
        np.testing.assert_array_equal(r.arrays[k], getattr(one, k))


def grown_shape(store, f):
    return store.shape(f, "geodesic", resolution=None)


def _cli(files, store, out, *extra):
    return [sys.executable, "-m", "gromov", "pairwise", *files, "--metric", "geodesic", "--samples", "20",
            "--jobs", "2", "--store", str(store), "--out", str(out), "-q", *extra]


def _n_pairs(store) -> int:
    if not (store / "catalogue.sqlite").exists():
        return 0
    try:
        with sqlite3.connect(store / "catalogue.sqlite", timeout=60) as db:
            return db.execute("SELECT count(*) FROM pairs").fetchone()[0]
    except sqlite3.OperationalError:   # created, its tables not yet
        return 0


def test_pairwise_killed_at_random_moments_resumes_to_the_same_matrix(tmp_path, sheet_files):
    """SIGKILL (the whole process group): twice when a random number of pairs is recorded, then
    once at a random moment (which may come after the run has finished: a fast machine does the
    10 pairs in under 2 s); every run continues from the pairs recorded before, and the last one
    gives the uninterrupted run's matrices bit for bit."""
    files = sheet_files[:5]   # 10 pairs
    ref = gh_matrix(files, "geodesic", n_samples=20, metric_options={}, jobs=2)
    store = tmp_path / "store"
    rng = np.random.default_rng(11)
    counts = [0]
    targets = sorted(rng.choice(np.arange(1, 10), 2, replace=False))
    for when in [("pairs", k) for k in targets] + [("seconds", rng.uniform(0.2, 2.0))]:
        proc = subprocess.Popen(_cli(files, store, tmp_path / "x.npz"), start_new_session=True,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t = time.perf_counter()
        while proc.poll() is None:
            if (time.perf_counter() - t > when[1]) if when[0] == "seconds" else _n_pairs(store) >= when[1]:
                os.killpg(proc.pid, signal.SIGKILL)
                break
            time.sleep(0.01)
        proc.wait()
        assert ShapeStore(store).verify() == []
        counts.append(_n_pairs(store))
        assert counts[-1] >= counts[-2]
    assert any(0 < c < 10 for c in counts), counts   # some run was killed half-way through the pairs
    out = tmp_path / "final.npz"
    r = subprocess.run(_cli(files, store, out, "--json"), capture_output=True, text=True, check=True)
    info = json.loads(r.stdout)["store"]
    assert info["pairs_read"] == counts[-1] and _n_pairs(store) == 10   # nothing finished ran again
    with np.load(out) as b:
        for k, a in (("distance", ref.distance), ("relative_distance", ref.relative),
                     ("relative_trimmed_distance", ref.trimmed)):
            np.testing.assert_array_equal(b[k], a)


def test_two_processes_index_one_store_at_once(tmp_path, sheet_files):
    store = tmp_path / "store"
    files = sheet_files[:3]
    cmd = [sys.executable, "-m", "gromov", "index", *files, "--store", str(store), "--metric", "geodesic"]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], results
    assert all(f"{len(files)} files in" in out for out, _ in results)
    s = ShapeStore(store)
    assert s.verify() == [] and len(s.entries()) == len(files)
    # every entry file is catalogued, and no temporary file is left
    assert sorted(os.listdir(store / "entries")) == sorted(e.file.split("/")[1] for e in s.entries())
    s.shapes(files, "geodesic", metric_options={}, rank_tau_scale=0.5)
    assert s.computed == 0 and s.reused == len(files)


# --------------------------------------------------------------------------- gromov match --store
def _refuse_metrics(monkeypatch):
    """Make computing any dense metric, or any store entry, fail the test."""
    from gromov.metrics.diffusion import _SpectralDiffusion

    def refuse(*a, **k):
        pytest.fail("a metric was computed")

    for cls, name in ((_SpectralDiffusion, "_spectral"), (_SpectralDiffusion, "_rows"), (GeodesicSolver, "_rows"),
                      (ShapeStore, "_compute")):
        monkeypatch.setattr(cls, name, refuse)


def test_match_with_a_store_reads_both_shapes_back_and_matches_bit_for_bit(tmp_path, sheet_files, capsys,
                                                                            monkeypatch):
    """``gromov match --store``: the first run computes both shapes in the correspondence's metric
    options (normalised heat units) and adds them, the second reads both back and computes no
    metric; the correspondence and the dense maps are those without a store, array for array."""
    x, y = sheet_files[:2]
    d = str(tmp_path / "s")

    def run(name, *extra):
        out = tmp_path / f"{name}.npz"
        assert main(["match", x, y, "--samples", "15", "--dense", "--out", str(out), "--json", *extra]) == 0
        r = json.loads(capsys.readouterr().out)
        with np.load(out) as z:
            return r, {k: z[k] for k in z.files}

    ref, ref_arrays = run("plain")
    first, a = run("first", "--store", d)
    assert first.pop("store") == {"path": d, "shapes_read": 0, "shapes_computed": 2}
    entries = ShapeStore(d).entries()
    assert len(entries) == 2 and all(e.options["metric_options"]["units"] == "normalized" for e in entries)
    _refuse_metrics(monkeypatch)
    second, b = run("second", "--store", d)
    monkeypatch.undo()
    assert second.pop("store") == {"path": d, "shapes_read": 2, "shapes_computed": 0}
    for r in (first, second):
        assert {k: v for k, v in r.items() if k != "seconds"} == {k: v for k, v in ref.items() if k != "seconds"}
    assert "x_to_y_dense_vertex" in ref_arrays
    for arrays in (a, b):
        assert arrays.keys() == ref_arrays.keys()
        for k, v in ref_arrays.items():
            np.testing.assert_array_equal(arrays[k], v, err_msg=k)


def test_match_with_a_store_recomputes_a_file_changed_since_indexing(tmp_path, capsys):
    """The geodesic entries of ``gromov index`` serve ``gromov match`` (a correspondence measures
    geodesic distances as recognition does); a file changed since is computed again, with one
    warning, and matched as it is now."""
    x, y = tmp_path / "x.off", tmp_path / "y.off"
    gromov.save(grid(25, 13), x)
    gromov.save(rolled_grid(25, 13), y)
    d = str(tmp_path / "s")
    assert main(["index", str(x), str(y), "--store", d, "--metric", "geodesic", "-q"]) == 0
    cmd = ["match", str(x), str(y), "--metric", "geodesic", "--samples", "15", "--json"]
    assert main([*cmd, "--store", d]) == 0
    assert json.loads(capsys.readouterr().out)["store"] == {"path": d, "shapes_read": 2, "shapes_computed": 0}
    gromov.save(rolled_grid(25, 13, width=2.5), y)   # another shape under the same name
    assert main([*cmd, "--store", d]) == 0
    out, err = capsys.readouterr()
    r = json.loads(out)
    assert r.pop("store") == {"path": d, "shapes_read": 1, "shapes_computed": 1}
    lines = [line for line in err.splitlines() if line.startswith("gromov: warning: ")]
    assert len(lines) == 1 and "y.off changed since it was indexed" in lines[0]
    assert main(cmd) == 0   # the changed file's match, not the stored shape's
    ref = json.loads(capsys.readouterr().out)
    assert {k: v for k, v in r.items() if k != "seconds"} == {k: v for k, v in ref.items() if k != "seconds"}
    assert len(ShapeStore(d).entries()) == 2 and ShapeStore(d).verify() == []


# --------------------------------------------------------------------------- gromov reproduce --store
def _tiny_reproduce(monkeypatch):
    """``reproduce`` on the synthetic set at its smallest: two classes, 300 vertices, 8 samples
    (about 8 s a run; the recognition's raw heat units and the correspondence's normalised
    ones, so both variants of every shape are stored)."""
    from dataclasses import replace

    from gromov.experiments import reproduce as rp

    full = rp.settings_for
    two = {"cat": 1, "dog": 1}
    monkeypatch.setattr(rp, "settings_for", lambda *a, **k: replace(full(*a, **k), resolution=300, n_samples=8,
                                                                      experiment1=two, experiment2=two))
    return rp.reproduce


def _same_results(a: dict, b: dict) -> None:
    skip = {"timings", "seconds_total", "date", "store"}
    assert a.keys() == b.keys()
    for k in a.keys() - skip:
        if k == "recognition":
            for exp in a[k]:
                for m in a[k][exp]:
                    x, y = a[k][exp][m], b[k][exp][m]
                    if isinstance(x, dict):
                        x, y = ({n: v for n, v in z.items() if n != "seconds"} for z in (x, y))
                    assert x == y, (exp, m)
        else:
            assert a[k] == b[k], k


def test_reproduce_with_a_store_computes_no_metric_twice(tmp_path, monkeypatch):
    """A second ``reproduce`` with the store reads every shape's metrics (clean, welded and
    holed shapes; recognition and correspondence options), the recognition's pairs and the
    ground truth's geodesic rows back, computes none of them, and gives the results of a
    run without a store."""
    reproduce = _tiny_reproduce(monkeypatch)
    store = tmp_path / "store"
    ref = reproduce(None, tmp_path / "plain", quick=True, jobs=1, quiet=True)
    first = reproduce(None, tmp_path / "first", quick=True, jobs=1, quiet=True, store=store)
    # 10 shapes (6 per experiment, the 2 references in both): geodesic and raw heat for
    # recognition, normalised heat for the correspondence (the references' read back for the
    # second experiment's correspondence)
    assert first["store"]["shapes_computed"] == 30 and first["store"]["shapes_read"] == 2 and ref["store"] is None
    n_pairs = len(ShapeStore(store).pairs())
    _refuse_metrics(monkeypatch)
    second = reproduce(None, tmp_path / "second", quick=True, jobs=1, quiet=True, store=store)
    monkeypatch.undo()
    assert second["store"]["shapes_computed"] == 0 and second["store"]["shapes_read"] == 32
    # every pair recorded but those whose full correspondence is kept (4 per experiment and metric)
    assert second["store"]["pairs_read"] == n_pairs - 16 > 0
    for r in (first, second):
        _same_results(r, ref)
        assert json.loads((tmp_path / "second" / "results.json").read_text())["store"] == second["store"]
    s = ShapeStore(store)
    assert s.verify() == [] and len(s.entries()) == 30 and len(s.pairs()) == n_pairs
    with pytest.raises(ValueError, match="inside out"):
        reproduce(None, tmp_path / "second", quick=True, jobs=1, quiet=True, store=tmp_path / "second" / "s")
    assert main(["reproduce", "--out", str(tmp_path / "o"), "--store", str(tmp_path / "o" / "s"), "-q"]) == 2
    assert not (tmp_path / "o").exists()


def test_damaged_ground_truth_rows_are_reported_and_computed_again(tmp_path, caplog):
    from gromov.experiments.reproduce import ROWS_EXTRA, _save_rows, _stored_rows
    from gromov.metrics import metric_solver

    mesh = grid(13, 7)
    store = ShapeStore(tmp_path)
    rows = _stored_rows(store, mesh, metric_solver(mesh, "geodesic"))
    want = rows.from_sources([3, 50, 7])
    _save_rows(store, rows)
    kept = _stored_rows(store, mesh, metric_solver(mesh, "geodesic"))
    assert sorted(kept.rows) == [3, 7, 50] and kept.n_stored == 3
    kept.solver = None   # read back, not computed
    np.testing.assert_array_equal(kept.from_sources([3, 50, 7]), want)
    # another mesh: other rows
    assert _stored_rows(store, grid(13, 8), metric_solver(grid(13, 8), "geodesic")).rows == {}
    arrays = store.extra(rows.key, ROWS_EXTRA)
    arrays["rows"][1, 5] += 1e-9   # altered: its checksum no longer matches
    store.put_extra(rows.key, ROWS_EXTRA, arrays)
    with caplog.at_level(logging.WARNING):
        again = _stored_rows(store, mesh, metric_solver(mesh, "geodesic"))
    assert "damaged" in caplog.text and again.rows == {}
    np.testing.assert_array_equal(again.from_sources([3, 50, 7]), want)
    _save_rows(store, again)
    assert _stored_rows(store, mesh, metric_solver(mesh, "geodesic")).n_stored == 3


def test_an_older_catalogue_gains_the_signature_column_and_its_pairs_are_rerun_only_where_needed(
        tmp_path, sheet_files, monkeypatch):
    files = sheet_files[:3]
    opts = {"n_samples": 20, "resolution": None}
    plain = gh_matrix(files, "geodesic", jobs=1, store=tmp_path, **opts)
    assert plain.signature is None
    assert all(np.isnan(r.signature_distortion) for r in ShapeStore(tmp_path).pairs())
    # a catalogue written before the column existed
    conn = sqlite3.connect(tmp_path / "catalogue.sqlite")
    conn.execute("ALTER TABLE pairs DROP COLUMN signature_distortion")
    conn.commit()
    conn.close()
    calls = []
    real = pairwise._match

    def counted(x, y, *a, **k):
        calls.append(k.get("signature"))
        return real(x, y, *a, **k)

    monkeypatch.setattr(pairwise, "_match", counted)
    store = ShapeStore(tmp_path)
    again = gh_matrix(files, "geodesic", jobs=1, store=store, **opts)   # nothing to rerun
    assert calls == [] and store.pairs_reused == 3
    np.testing.assert_array_equal(again.trimmed, plain.trimmed)
    # the combined ranking needs each pair's signature distortion: the pairs run again, once
    store = ShapeStore(tmp_path)
    spec = gh_matrix(files, "geodesic", jobs=1, store=store, spectral=True, **opts)
    assert calls == [True] * 3 and store.pairs_reused == 0
    np.testing.assert_array_equal(spec.trimmed, plain.trimmed)
    off = ~np.eye(3, dtype=bool)
    assert np.all(np.isfinite(spec.signature)) and np.all(spec.signature[off] > 0)
    records = ShapeStore(tmp_path).pairs()
    assert len(records) == 3 and all(np.isfinite(r.signature_distortion) for r in records)
    store = ShapeStore(tmp_path)
    last = gh_matrix(files, "geodesic", jobs=1, store=store, spectral=True, **opts)
    assert len(calls) == 3 and store.pairs_reused == 3
    np.testing.assert_array_equal(last.signature, spec.signature)
    np.testing.assert_array_equal(last.combined, spec.combined)
