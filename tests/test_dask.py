"""Recognition matrices on a Dask cluster: the local pool's numbers, shapes kept by workers."""

import dataclasses
import json
import logging
import sys
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed", reason="the dask extra is not installed (make test installs it)")

from test_store import _sheets  # the same two classes of sheets

import gromov
from gromov import MatchResult
from gromov.cli import main
from gromov.experiments.pairwise import gh_matrix
from gromov.gh import RANK_TAU_SCALE
from gromov.store import ShapeStore

OPTS = {"n_samples": 15, "resolution": None}




@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def local():
    """The local process pool's matrix of the six sheets, with the full result of (0, 5)."""
    return gh_matrix(_sheets(), jobs=2, keep=[(0, 5)], **OPTS)


def _held(client) -> dict:
    """The keys of this module's shapes and pairs that each worker still holds."""
    return client.run(lambda dask_worker: sorted(k for k in dask_worker.data if str(k).startswith("gromov-")))


def _assert_same(a, b):
    for name in ("distance", "relative", "trimmed"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_a_dask_matrix_is_the_local_pools_bit_for_bit(client, local):
    r = gh_matrix(_sheets(), client=client, keep=[(0, 5)], **OPTS)
    _assert_same(r, local)
    assert set(r.results) == {(0, 5)}
    for f in dataclasses.fields(MatchResult):
        if f.name != "seconds":
            x, y = getattr(r.results[0, 5], f.name), getattr(local.results[0, 5], f.name)
            np.testing.assert_array_equal(x, y, err_msg=f.name)   # NaN equal to NaN
    deadline = time.monotonic() + 10
    while any(_held(client).values()) and time.monotonic() < deadline:   # released once done
        time.sleep(0.1)
    assert not any(_held(client).values())


def test_prepared_shapes_reach_workers_that_ran_no_gromov_task_yet(local):
    """Prepared ShapeMetric objects are sent with gromov's own serializer: a fresh cluster,
    whose workers have imported nothing of gromov, reads them."""
    shapes = [gromov.ShapeMetric(m, "diffusion", resolution=None) for m in _sheets()]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, distributed.Client(cluster) as c:
        assert not any(c.run(lambda: "gromov._dask" in sys.modules).values())
        r = gh_matrix(shapes, client=c, **OPTS)
    _assert_same(r, local)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_workers_reuse_the_memory_they_free(client, local):
    """Dask starts workers with MALLOC_TRIM_THRESHOLD_ set, which maps every block over 128 kB
    afresh; once gromov has run there, a freed work array is reused instead of faulted in again."""
    gh_matrix(_sheets()[:2], client=client, **OPTS)

    def faults():
        import resource

        blocks = []
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        for _ in range(20):
            blocks.append(np.ones(1 << 19))   # 4 MB
            blocks.pop()
        return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

    pages = (1 << 22) // 4096
    got = client.run(faults)
    assert all(f < 5 * pages for f in got.values()), got   # 20 blocks faulted afresh: 20,480 pages


def test_a_local_cluster_leaves_this_process_environment_as_it_was():
    """Dask's nanny writes its workers' settings (OPENBLAS_NUM_THREADS=1,
    MALLOC_TRIM_THRESHOLD_...) into the starting process's environment, where every process
    started later inherited them; the workers still get them."""
    import os

    from gromov._dask import client_for

    before = dict(os.environ)
    with client_for(n_workers=1) as c:
        assert dict(os.environ) == before
        assert set(c.run(lambda: os.environ.get("OPENBLAS_NUM_THREADS")).values()) == {"1"}
    assert dict(os.environ) == before


def test_the_local_cluster_keeps_each_result_on_its_home_worker():
    """Dask's ReduceReplicas drops the extra copy from the worker using the most memory, here
    the result's home (it also holds a larger block), which then receives it back for its next
    task; HomeReplicas drops the copy elsewhere. The cluster runs gromov's settings."""
    from gromov._dask import LOCAL_CLUSTER_CONFIG, client_for

    with client_for(n_workers=2) as c:
        a, b = sorted(c.scheduler_info(n_workers=-1)["workers"])
        ballast = c.submit(np.ones, 4_000_000, workers=[a], pure=False)   # 32 MB more on a
        x = c.submit(np.arange, 1000, workers=[a], allow_other_workers=True, pure=False)
        distributed.wait([ballast, x])
        c.replicate([x], n=2)
        assert set(c.who_has([x])[x.key]) == {a, b}
        c.amm.run_once()
        deadline = time.monotonic() + 30
        while len(c.who_has([x])[x.key]) > 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert set(c.who_has([x])[x.key]) == {a}
        policies = c.run_on_scheduler(lambda dask_scheduler: [type(p).__name__ for p in
                                                               dask_scheduler.extensions["amm"].policies])
        assert policies == ["HomeReplicas"]
        import dask

        names = [k for k in LOCAL_CLUSTER_CONFIG if k.startswith("distributed.worker.")]
        got = c.run(lambda: {k: dask.config.get(k) for k in names})
        assert all(v == {k: LOCAL_CLUSTER_CONFIG[k] for k in names} for v in got.values()), got
    assert dask.config.get("distributed.worker.profile.enabled") is True   # this process: as it was


def test_shapes_stay_on_their_workers_and_pairs_go_to_them(client, local):
    """A worker receives a shape for a run of pairs, not with each pair: fewer shapes cross
    between the two workers than there are pairs of shapes held by different workers."""
    client.run(lambda dask_worker: dask_worker.transfer_incoming_log.clear())
    r = gh_matrix(_sheets(), client=client, **OPTS)
    _assert_same(r, local)
    got = client.run(lambda dask_worker: [str(k) for e in dask_worker.transfer_incoming_log for k in e["keys"]])
    received = [k for keys in got.values() for k in keys]
    assert all(k.startswith("gromov-shape-") for k in received), received   # never a pair's result
    across = 3 * 3   # shapes i on worker i mod 2: the pairs of an even and an odd shape
    assert 0 < len(received) < across, got


def test_plan_runs_each_pair_once_where_its_shapes_are():
    from gromov._dask import plan, spread

    n, workers = 9, 3
    homes = spread(n, workers)
    assert homes == [0, 1, 2, 0, 1, 2, 0, 1, 2]
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    queues = [[tuple(ij) for ij in q.tolist()] for q in plan(pairs, homes, workers)]
    placed = [(ij, w) for w, q in enumerate(queues) for ij in q]
    assert sorted(ij for ij, _ in placed) == pairs
    for (i, j), w in placed:
        assert w in (homes[i], homes[j])   # where one of its shapes is, both if they share a home
    assert [len(q) for q in queues] == [12, 12, 12]
    for w, q in enumerate(queues):
        local = [ij for ij in q if homes[ij[0]] == homes[ij[1]] == w]
        assert q[:len(local)] == local and len(local) == 3   # its own pairs first
        # then one run of pairs per shape it receives: each shape comes once
        other = [ij[0] if homes[ij[0]] != w else ij[1] for ij in q[len(local):]]
        runs = [k for k, prev in zip(other, [None] + other) if k != prev]
        assert len(runs) == len(set(runs))
    # the pairs of workers 0 and 1: 0 receives the first half of 1's shapes, 1 all of 0's
    assert {ij[1] for ij in queues[0] if homes[ij[1]] == 1} == {1, 4}
    assert {ij[0] for ij in queues[1] if homes[ij[0]] == 0} == {0, 3, 6}


def test_a_store_read_and_written_by_workers_resumes_like_the_local_path(client, tmp_path, caplog):
    files = []
    for i, m in enumerate(_sheets()[:4]):
        files.append(str(tmp_path / f"sheet{i}.off"))
        gromov.save(m, files[-1])
    plain = gh_matrix(files, jobs=1, **OPTS)
    first = ShapeStore(tmp_path / "s")
    gh_matrix(files[:3], jobs=1, store=first, **OPTS)   # three shapes, three pairs, locally
    again = ShapeStore(tmp_path / "s")
    r = gh_matrix(files, client=client, store=again, **OPTS)   # the workers read three, add one
    assert (again.reused, again.computed, again.pairs_reused) == (3, 1, 3)
    _assert_same(r, plain)
    assert len(again.pairs()) == 6 and len(again.entries()) == 4 and again.verify() == []
    last = ShapeStore(tmp_path / "s")
    _assert_same(gh_matrix(files, jobs=1, store=last, **OPTS), plain)   # every pair read back
    assert (last.reused, last.pairs_reused) == (4, 6)
    # shapes the store returned keep their entries' keys on the workers
    shapes = last.shapes(files, resolution=None, rank_tau_scale=RANK_TAU_SCALE)
    _assert_same(gh_matrix(shapes, client=client, store=last, **OPTS), plain)
    assert (last.reused, last.computed, last.pairs_reused) == (8, 0, 12)
    # a damaged entry: the worker computes the shape again, this process says so
    entry = tmp_path / "s" / last.entries()[0].file
    entry.write_bytes(entry.read_bytes()[:1000])
    damaged = ShapeStore(tmp_path / "s")
    with caplog.at_level(logging.WARNING, logger="gromov.store"):
        _assert_same(gh_matrix(files, client=client, store=damaged, **OPTS), plain)
    assert (damaged.reused, damaged.computed, damaged.pairs_reused) == (3, 1, 6)
    assert len(damaged.problems) == 1 and "does not match its checksum" in damaged.problems[0]
    assert [r.getMessage() for r in caplog.records if r.name == "gromov.store"] == damaged.problems


def test_errors(client, monkeypatch):
    from gromov._dask import client_for

    with pytest.raises(ValueError, match="shape 0: 400 samples are more than the 325 vertices"):
        gh_matrix(_sheets()[:2], client=client, n_samples=400, resolution=None)
    with pytest.raises(ValueError, match="either a scheduler address or a number of workers"), client_for():
        pass
    with pytest.raises(ValueError, match="n_workers must be >= 1"), client_for(n_workers=0):
        pass
    monkeypatch.delitem(sys.modules, "gromov._dask")
    monkeypatch.delattr(gromov, "_dask")
    monkeypatch.setitem(sys.modules, "distributed", None)   # as if not installed
    with pytest.raises(ImportError, match=r"pip install 'gromov\[dask\]'"):
        gh_matrix(_sheets()[:2], client=client, **OPTS)


@pytest.fixture(scope="module")
def sheet_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sheets")
    files = []
    for i, m in enumerate(_sheets()[:3]):
        files.append(str(folder / f"sheet{i}.off"))
        gromov.save(m, files[-1])
    return files


def test_cli_runs_on_dask_with_the_numbers_of_jobs(client, sheet_files, tmp_path, capsys):
    args = ["pairwise", *sheet_files, "--samples", "15", "--resolution", "400", "--json"]
    assert main(args + ["--jobs", "2"]) == 0
    ref = json.loads(capsys.readouterr().out)
    assert main(args + ["--dask", "2"]) == 0   # a cluster of its own, closed at the end
    out = json.loads(capsys.readouterr().out)
    store = str(tmp_path / "s")
    assert main(args + ["--scheduler", client.scheduler.address, "--store", store]) == 0
    stored = json.loads(capsys.readouterr().out)
    for name in ("distance", "relative_distance", "relative_trimmed_distance"):
        assert out[name] == ref[name] == stored[name]
    assert stored["store"] == {"path": store, "shapes_read": 0, "pairs_read": 0}
    assert main(args + ["--store", store, "--jobs", "1"]) == 0   # the workers' store, read locally
    again = json.loads(capsys.readouterr().out)
    assert again["store"] == {"path": store, "shapes_read": 3, "pairs_read": 3}
    assert again["distance"] == ref["distance"]


def test_cli_refuses_jobs_with_dask_and_says_what_to_install(sheet_files, capsys, monkeypatch):
    with pytest.raises(SystemExit) as exc:
        main(["pairwise", *sheet_files, "--dask", "2", "--jobs", "2"])
    assert exc.value.code == 2
    assert "argument --jobs: not allowed with argument --dask" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["pairwise", *sheet_files, "--dask", "2", "--scheduler", "tcp://127.0.0.1:8786"])
    assert "not allowed with argument" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "distributed", None)
    assert main(["pairwise", *sheet_files, "--dask", "2"]) == 2
    assert capsys.readouterr().err == ("gromov: error: --dask needs dask.distributed: "
                                       "pip install 'gromov[dask]'\n")
