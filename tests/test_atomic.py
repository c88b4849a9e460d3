"""Atomic writes: a target is the previous complete file or the new one, never a torn one."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import gromov
from gromov._atomic import (atomic_folder, atomic_path, atomic_savez_compressed,
                            atomic_write_bytes, atomic_write_text)
from gromov.shapes import icosphere

GROMOV = [sys.executable, "-m", "gromov"]


def _temps(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") and ".tmp" in p.name)


# --------------------------------------------------------------------------- the context manager
def test_success_replaces_the_target(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".a.") and tmp.name.endswith(".tmp.txt")
        assert tmp.exists() and target.read_text() == "old"   # untouched until the block ends
        tmp.write_text("new")
    assert target.read_text() == "new"
    assert sorted(os.listdir(tmp_path)) == ["a.txt"]


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_exception_keeps_the_old_file_and_no_temp(tmp_path, exc):
    target = tmp_path / "a.npz"
    atomic_savez_compressed(target, x=np.arange(3))
    before = target.read_bytes()
    with pytest.raises(exc):
        with atomic_path(target) as tmp:
            tmp.write_bytes(b"half a fi")
            raise exc()
    assert target.read_bytes() == before
    assert os.listdir(tmp_path) == ["a.npz"]


def test_savez_keeps_numpy_suffix_rule(tmp_path):
    """numpy appends .npz to a name without it; so does the atomic writer, and the temporary
    name ends in .npz so numpy writes it where asked."""
    assert atomic_savez_compressed(tmp_path / "d", x=np.ones(2)) == tmp_path / "d.npz"
    assert np.load(tmp_path / "d.npz")["x"].tolist() == [1.0, 1.0]
    assert sorted(os.listdir(tmp_path)) == ["d.npz"]


def test_matplotlib_png_through_temp_name(tmp_path):
    pytest.importorskip("matplotlib")
    from gromov.experiments.recognition import plot_mds

    path = plot_mds(np.random.default_rng(0).normal(size=(4, 2)), ["a", "a", "b", "b"],
                    tmp_path / "m.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert os.listdir(tmp_path) == ["m.png"]


def test_permissions_symlinks_and_errors(tmp_path):
    target = tmp_path / "t.txt"
    atomic_write_text(target, "x")
    umask = os.umask(0)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask     # not mkstemp's 0o600
    target.chmod(0o640)
    atomic_write_bytes(target, b"y")
    assert target.stat().st_mode & 0o777 == 0o640 and target.read_bytes() == b"y"
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    atomic_write_text(link, "z")                                # writes through the link
    assert link.is_symlink() and target.read_text() == "z"
    with pytest.raises(FileNotFoundError, match="no-such-folder"):
        atomic_write_text(tmp_path / "no-such-folder" / "x.txt", "x")
    with pytest.raises(IsADirectoryError):
        atomic_write_text(tmp_path, "x")
    assert sorted(os.listdir(tmp_path)) == ["link.txt", "t.txt"]


def test_mesh_save_is_atomic(tmp_path):
    m = icosphere(1)
    for name in ("s.off", "s.ply.gz", "s.vert"):
        gromov.save(m, tmp_path / name)
        assert np.array_equal(gromov.load(tmp_path / name).vertices, m.vertices)
    assert sorted(os.listdir(tmp_path)) == ["s.off", "s.ply.gz", "s.tri", "s.vert"]


def test_folder_swap(tmp_path):
    out = tmp_path / "out"
    with atomic_folder(out) as work:
        (work / "a").write_text("1")
        assert not out.exists()
    assert os.listdir(out) == ["a"]
    with pytest.raises(KeyboardInterrupt):
        with atomic_folder(out) as work:
            (work / "b").write_text("2")
            raise KeyboardInterrupt
    assert os.listdir(out) == ["a"] and os.listdir(tmp_path) == ["out"]
    with atomic_folder(out) as work:
        (work / "b").write_text("2")
    assert os.listdir(out) == ["b"] and os.listdir(tmp_path) == ["out"]


def test_reproduce_refuses_a_folder_it_would_wipe(tmp_path, monkeypatch):
    from gromov.experiments.reproduce import reproduce

    (tmp_path / "mine.txt").write_text("keep")
    with pytest.raises(ValueError, match="no results.json"):
        reproduce(None, tmp_path, quick=True)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results.json").write_text("{}")
    with pytest.raises(ValueError, match="current directory"):
        reproduce(None, tmp_path, quick=True)
    assert sorted(os.listdir(tmp_path)) == ["mine.txt", "results.json"]


# --------------------------------------------------------------------------- processes
@pytest.fixture(scope="module")
def mesh_and_old(tmp_path_factory):
    folder = tmp_path_factory.mktemp("kill")
    mesh = folder / "sphere.off"
    gromov.save(icosphere(4), mesh)
    old = folder / "old.npz"
    np.savez_compressed(old, distances=np.zeros((2, 2)), marker="old")
    return mesh, old.read_bytes()


def _distances(mesh, out, seed=0, samples=None):
    more = [] if samples is None else ["--samples", str(samples), "--seed", str(seed)]
    return GROMOV + ["distances", str(mesh), "--metric", "geodesic", *more, "--out", str(out), "-q"]


def _complete(path: Path, old: bytes) -> str:
    if path.read_bytes() == old:
        return "old"
    with np.load(path) as z:            # a complete, valid archive
        assert z["distances"].shape == (2562, 2562)   # the full matrix of icosphere(4)
    return "new"


def test_kill_leaves_old_or_new(tmp_path, mesh_and_old):
    mesh, old = mesh_and_old
    out = tmp_path / "out.npz"
    out.write_bytes(old)
    subprocess.run(_distances(mesh, out), check=True)   # compiles what a first run compiles
    t = time.perf_counter()
    subprocess.run(_distances(mesh, out), check=True)   # its normal duration; a 28 MB archive
    duration = time.perf_counter() - t
    seen = {_complete(out, old)}
    rng = np.random.default_rng(7)
    # three moments near the end of the run, while the archive is written
    moments = np.concatenate([rng.uniform(0, duration, 2), rng.uniform(0.75, 1.0, 3) * duration])
    for moment in moments:
        out.write_bytes(old)
        proc = subprocess.Popen(_distances(mesh, out), stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        try:
            proc.wait(timeout=moment)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
        seen.add(_complete(out, old))
        # nothing but the target and, after SIGKILL, possibly one hidden temporary file
        others = sorted(set(os.listdir(tmp_path)) - {"out.npz"})
        assert len(others) <= 1 and all(n.startswith(".out.") and n.endswith(".tmp.npz")
                                        for n in others), others
        for n in others:
            (tmp_path / n).unlink()
    assert "old" in seen and "new" in seen


def test_two_writers_last_rename_wins(tmp_path, mesh_and_old):
    mesh, _ = mesh_and_old
    out = tmp_path / "same.npz"
    procs = [subprocess.Popen(_distances(mesh, out, seed, 300)) for seed in (1, 2)]
    assert [p.wait(timeout=120) for p in procs] == [0, 0]
    singles = []
    for seed in (1, 2):
        subprocess.run(_distances(mesh, tmp_path / f"s{seed}.npz", seed, 300), check=True)
        with np.load(tmp_path / f"s{seed}.npz") as z:
            singles.append(z["distances"])
    assert not np.array_equal(*singles)
    with np.load(out) as z:
        got = z["distances"]
    assert any(np.array_equal(got, s) for s in singles)
    assert sorted(os.listdir(tmp_path)) == ["s1.npz", "s2.npz", "same.npz"]
