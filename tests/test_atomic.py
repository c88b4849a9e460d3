"""Atomic writes: a target is the previous complete file or the new one, never a torn one."""

import contextlib
import fcntl
import json
import os
import re
import shutil
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
from gromov.shapes import grid, icosphere, rolled_grid

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


def _hold(path: Path) -> int:
    """Lock ``path`` as its running writer does (another open file: flock locks conflict
    between open files, in one process as in two)."""
    fd = os.open(path, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    return fd


def test_stale_temporaries_are_deleted_held_ones_kept(tmp_path):
    """The next write deletes the temporaries of its target that no writer holds (a killed
    writer's); a running writer's, another target's and other names stay."""
    (tmp_path / "out").mkdir()
    stale = [".a.0123abcd.tmp.npz", ".out.0123abcd.tmp"]
    held = [".a.89abcdef.tmp.npz", ".out.89abcdef.tmp"]
    others = [".b.0123abcd.tmp.npz", ".a.0123abcd.tmp.txt", ".a.0123abcz.tmp.npz",
              ".a.0123abcd.old.npz", "a.npz.bak", ".out.01234567.old", ".out.fedcba98.tmp"]
    for name in stale[:1] + held[:1] + others[:-2] + others[-1:]:  # .out.fedcba98.tmp: a file
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / stale[0]).chmod(0o444)     # given the mode of a read-only target
    for name in stale[1:] + held[1:] + others[-2:-1]:
        (tmp_path / name).mkdir()
        (tmp_path / name / "f.png").write_bytes(b"x")
    fds = [_hold(tmp_path / name) for name in held]
    try:
        atomic_write_bytes(tmp_path / "a.npz", b"new")
        with atomic_folder(tmp_path / "out") as work:
            (work / "r.json").write_text("{}")
        assert sorted(os.listdir(tmp_path)) == sorted(["a.npz", "out"] + held + others)
        assert (tmp_path / "a.npz").read_bytes() == b"new" and os.listdir(tmp_path / "out") == ["r.json"]
        assert os.listdir(tmp_path / held[1]) == ["f.png"]
    finally:
        for fd in fds:
            os.close(fd)
    atomic_write_bytes(tmp_path / "a.npz", b"newer")       # their writers are gone now
    with atomic_folder(tmp_path / "out"):
        pass
    assert sorted(os.listdir(tmp_path)) == sorted(["a.npz", "out"] + others)


_WRITER = """
import os, sys, time
from pathlib import Path
from gromov._atomic import atomic_folder, atomic_path

folder, file = Path(sys.argv[1]), Path(sys.argv[2])
with atomic_folder(folder) as work, atomic_path(file) as tmp:
    (work / "new.txt").write_text("new")
    tmp.write_text("new")
    child = os.fork() if sys.argv[3] == "fork" else -1   # a worker, as a process pool forks
    if child == 0:
        time.sleep(60)
        os._exit(0)
    print("writing", child, flush=True)
    sys.stdin.readline()
"""


def test_sigkilled_writer_leaves_temporaries_the_next_write_deletes(tmp_path):
    """A writer killed by SIGKILL leaves its temporary file and folder (the targets untouched);
    the next write deletes them, even while a process the writer forked lives on. While a
    writer runs, another write leaves its temporaries alone, and both complete."""
    folder, file = tmp_path / "out", tmp_path / "f.txt"
    folder.mkdir()
    (folder / "old.txt").write_text("old")
    file.write_text("old")

    def writer(mode):
        proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(folder), str(file), mode],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        word, child = proc.stdout.readline().split()
        assert word == "writing"
        return proc, int(child)

    def temps():
        return sorted(n for n in os.listdir(tmp_path) if n not in ("out", "f.txt"))

    proc, child = writer("fork")
    try:
        proc.kill()
        proc.wait()
        os.kill(child, 0)                  # the forked process lives on
        left = temps()
        assert len(left) == 2 and re.fullmatch(r"\.f\.[0-9a-f]{8}\.tmp\.txt", left[0]), left
        assert re.fullmatch(r"\.out\.[0-9a-f]{8}\.tmp", left[1])
        assert os.listdir(tmp_path / left[1]) == ["new.txt"]
        assert file.read_text() == "old" and os.listdir(folder) == ["old.txt"]

        proc, _ = writer("")               # the next writer deletes them; its own stay while it runs
        running = temps()
        assert len(running) == 2 and not set(left) & set(running)
        atomic_write_text(file, "mine")
        with atomic_folder(folder) as work:
            (work / "mine.txt").write_text("mine")
        assert temps() == running
        assert file.read_text() == "mine" and os.listdir(folder) == ["mine.txt"]
        proc.communicate("go\n", timeout=60)
        assert proc.returncode == 0 and temps() == []
        assert file.read_text() == "new" and os.listdir(folder) == ["new.txt"]
    finally:
        os.kill(child, signal.SIGKILL)


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
    t = time.perf_counter()
    subprocess.run(_distances(mesh, out), check=True)   # its duration; a 28 MB archive
    duration = time.perf_counter() - t
    seen = {_complete(out, old)}
    # a moment early in the run, one near its end, and (None) as soon as the archive's
    # temporary file appears: while it is written
    for moment in [*np.random.default_rng(7).uniform([0, 0.75], [1, 1]) * duration, None]:
        out.write_bytes(old)
        stale = set(_hidden(tmp_path))

        def stop(s, moment=moment, stale=stale):
            return s >= moment if moment is not None else bool(set(_hidden(tmp_path)) - stale)

        _run_until(_distances(mesh, out), stop, poll=0.001)
        seen.add(_complete(out, old))
        # nothing but the target and, after SIGKILL, possibly one hidden temporary file: the
        # one a killed run left is deleted by the next run's write
        others = sorted(set(os.listdir(tmp_path)) - {"out.npz"})
        assert len(others) <= 1 and all(n.startswith(".out.") and n.endswith(".tmp.npz")
                                        for n in others), others
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


# --------------------------------------------------------------------------- pairwise and reproduce
def _run_until(cmd, stop, poll: float = 0.002) -> bool:
    """Run ``cmd``; SIGKILL its process group the first time ``stop(seconds)`` is true.
    Returns whether it was killed before it ended."""
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    t = time.perf_counter()
    while proc.poll() is None:
        if stop(time.perf_counter() - t):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            return True
        time.sleep(poll)
    assert proc.returncode == 0
    return False


def _hidden(folder: Path) -> list[str]:
    return sorted(n for n in os.listdir(folder) if n.startswith("."))


@pytest.fixture(scope="module")
def sheets(tmp_path_factory):
    """Three sheets of 325 vertices: flat, rolled, and one twice as long."""
    folder = tmp_path_factory.mktemp("sheets")
    files = []
    for i, m in enumerate([grid(25, 13), rolled_grid(25, 13), grid(25, 13, width=2 * np.pi, height=0.5)]):
        files.append(str(folder / f"sheet{i}.off"))
        gromov.save(m, files[-1])
    return files


def _pairwise(files, out, seed=0):
    return GROMOV + ["pairwise", *files, "--metric", "geodesic", "--samples", "10", "--seed", str(seed),
                     "--jobs", "1", "--out", str(out), "-q"]


_PAIRWISE_KEYS = ("distance", "relative_distance", "relative_trimmed_distance")


def _pairwise_result(path: Path) -> dict:
    with np.load(path) as z:                 # a complete, valid archive
        assert z["files"].shape == (3,)
        return {k: z[k] for k in (*_PAIRWISE_KEYS, "seed")}


def test_pairwise_killed_leaves_old_or_new(tmp_path, sheets):
    """``gromov pairwise --out`` killed at random moments, and as soon as its temporary file
    appears: the old complete archive or the new one, and at most one hidden temporary."""
    out = tmp_path / "out.npz"
    np.savez_compressed(out, distance=np.zeros((2, 2)), marker="old")
    old = out.read_bytes()
    t = time.perf_counter()
    subprocess.run(_pairwise(sheets, out), check=True)     # its duration (and a first run's compiling)
    duration = time.perf_counter() - t
    new = _pairwise_result(out)
    assert new["distance"].shape == (3, 3) and new["distance"][0, 2] > 0
    seen = set()
    # two moments, the second near the end; None: once its temporary file is there (it writes)
    for moment in [*np.random.default_rng(3).uniform([0, 0.8], 1.0) * duration, None]:
        out.write_bytes(old)
        stale = set(_hidden(tmp_path))

        def stop(s, moment=moment, stale=stale):
            return s >= moment if moment is not None else bool(set(_hidden(tmp_path)) - stale)

        _run_until(_pairwise(sheets, out), stop, poll=0.001)
        if out.read_bytes() == old:
            seen.add("old")
        else:
            got = _pairwise_result(out)
            for k, v in new.items():
                np.testing.assert_array_equal(got[k], v, err_msg=k)
            seen.add("new")
        others = _hidden(tmp_path)
        assert len(others) <= 1, others
        assert all(re.fullmatch(r"\.out\.[0-9a-f]{8}\.tmp\.npz", n) for n in others), others
        assert sorted(set(os.listdir(tmp_path)) - set(others)) == ["out.npz"]
    assert "old" in seen


def test_two_pairwise_writers_leave_one_result(tmp_path, sheets):
    from gromov.experiments.pairwise import gh_matrix

    out = tmp_path / "same.npz"
    procs = [subprocess.Popen(_pairwise(sheets, out, seed)) for seed in (1, 2)]
    assert [p.wait(timeout=120) for p in procs] == [0, 0]
    refs = {seed: gh_matrix(sheets, "geodesic", n_samples=10, metric_options={}, seed=seed)
            for seed in (1, 2)}
    assert not np.array_equal(refs[1].trimmed, refs[2].trimmed)
    got = _pairwise_result(out)
    ref = refs[int(got["seed"])]             # one writer's archive, whole
    for k, v in zip(_PAIRWISE_KEYS, (ref.distance, ref.relative, ref.trimmed), strict=True):
        np.testing.assert_array_equal(got[k], v, err_msg=k)
    assert os.listdir(tmp_path) == ["same.npz"]


# ``gromov reproduce --quick`` takes about two minutes on one core; the command runs here with the
# settings of a smaller run (two classes, 300 vertices, 10 samples, the same diffusion metric for recognition
# and correspondence), everything else -- the folder it fills and swaps in -- its own.
_REPRODUCE = """
import sys
from dataclasses import replace
import gromov.experiments.reproduce as rp
from gromov.cli import main

full = rp.settings_for
two = {"cat": 1, "dog": 1}
rp.settings_for = lambda *a, **k: replace(full(*a, **k), resolution=300, n_samples=10,
                                          experiment1=two, experiment2=two)
sys.exit(main(["reproduce", "--quick", "--units", "raw", "--jobs", "1", "-q", "--out", sys.argv[1]]))
"""


def test_reproduce_killed_leaves_old_or_new_folder(tmp_path):
    """``gromov reproduce --out`` run to its end, then killed at a random moment early in its
    computation and at a random moment after its results.json is written (the report, the
    swap, the old folder's deletion): the old folder file for file, or a complete new one. A
    killed run leaves its hidden temporary folder; the next run deletes it."""
    from gromov.experiments.reproduce import RESULT_KEYS

    runs, ref = tmp_path / "runs", tmp_path / "old"
    out = runs / "out"
    ref.mkdir()
    (ref / "results.json").write_text('{"dataset": "old"}')
    (ref / "index.html").write_text("<p>old</p>")
    (ref / "only_old.png").write_bytes(b"\x89PNG old")
    old = {p.name: p.read_bytes() for p in ref.iterdir()}
    cmd = [sys.executable, "-c", _REPRODUCE, str(out)]

    def watch(event="results", delay=None, *, stale=()):
        """A stop condition: ``delay`` seconds after the folder being filled appears (``event``
        "tmp") or results.json in it ("results"); None: never. ``seen``: when each appeared."""
        seen = {}

        def stop(s):
            if "results" not in seen:
                tmps = [p for p in runs.glob(".out.*.tmp") if p.name not in stale]
                if tmps:
                    seen.setdefault("tmp", s)
                if any((p / "results.json").is_file() for p in tmps):
                    seen["results"] = s
            return delay is not None and event in seen and s >= seen[event] + delay
        return stop, seen

    def state() -> str:
        names = sorted(os.listdir(out))
        if names == sorted(old) and all((out / n).read_bytes() == b for n, b in old.items()):
            return "old"
        r = json.loads((out / "results.json").read_text())
        assert r["dataset"] == "synthetic" and all(0 <= r[k] <= 1 for k in RESULT_KEYS)
        assert r["params"]["n_samples"] == 10 and r["params"]["experiment1"] == {"cat": 1, "dog": 1}
        assert names == sorted([*r["figures"].values(), "results.json", "index.html"])
        assert all((out / n).stat().st_size > 0 for n in names)
        return "new"

    shutil.copytree(ref, out)
    stop, seen = watch()
    t, wall = time.perf_counter(), time.time()
    assert not _run_until(cmd, stop, poll=0.01)             # (and a first run's compiling)
    # when results.json was written: as polled, or (a fast run's short-lived folder missed by
    # the polling) from its modification time
    seen.setdefault("results", (out / "results.json").stat().st_mtime - wall)
    seen.setdefault("tmp", 0.0)
    tail = time.perf_counter() - t - seen["results"]        # report, swap, deletion of the old
    states = [state()]
    assert _hidden(runs) == []
    rng = np.random.default_rng(5)
    shutil.rmtree(out)
    shutil.copytree(ref, out)
    # any moment of the computation is alike (the folder being filled is partial, out untouched)
    stop, _ = watch("tmp", rng.uniform(0, 0.25) * (seen["results"] - seen["tmp"]))
    assert _run_until(cmd, stop, poll=0.01)
    states.append(state())
    stale = _hidden(runs)                                   # the killed run's folder, left
    assert len(stale) == 1 and re.fullmatch(r"\.out\.[0-9a-f]{8}\.tmp", stale[0]), stale
    shutil.rmtree(out)
    shutil.copytree(ref, out)
    _run_until(cmd, watch("results", rng.uniform(0, tail), stale=stale)[0], poll=0.01)
    states.append(state())
    others = _hidden(runs)
    assert len(others) <= 1 and all(re.fullmatch(r"\.out\.[0-9a-f]{8}\.tmp", n) for n in others)
    assert stale[0] not in others                           # deleted by the next run
    assert states[:2] == ["new", "old"], states
