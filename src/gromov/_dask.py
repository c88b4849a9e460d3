"""Dask support: prepared shapes held by workers, and pairs placed where their shapes are.

Imported only when a Dask client is used (:func:`gromov.experiments.gh_matrix`'s ``client``,
``gromov pairwise --dask N`` or ``--scheduler ADDRESS``): ``import gromov`` never loads Dask.

Each shape is prepared on one worker, its *home* (shape i on worker i mod W), and stays there
as a Dask future. A pair whose two shapes share a home runs there. The pairs between two homes
A and B (A before B) are split in two halves of equal work: those whose shape on B is in the
first half of B's shapes run on A, which receives that half of B's shapes; the others run on
B, which receives A's shapes. Each worker's pairs are submitted grouped by the shape it
receives, and only ``2 x threads`` at a time, so a shape sent to a worker serves a run of
pairs there and is then dropped (Dask's active memory manager keeps the copy on the shape's
home, :class:`HomeReplicas`, in the clusters :func:`client_for` starts):
a worker holds its own shapes and the few it is receiving, never the whole collection. A
worker whose pairs are done takes the last ones of the longest list of another.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import os
import time

import numpy as np

try:
    import dask
    import distributed
    from dask.sizeof import sizeof
    from distributed.active_memory_manager import ActiveMemoryManagerPolicy, Suggestion
    from distributed.protocol.serialize import (
        dask_deserialize,
        dask_serialize,
        pickle_dumps,
        pickle_loads,
    )
except ImportError as exc:   # tests/test_dask.py hides distributed
    raise ImportError("gromov's Dask support needs dask.distributed: pip install 'gromov[dask]'") from exc

from .shape_metric import ShapeMetric

__all__ = ["LOCAL_CLUSTER_CONFIG", "HomeReplicas", "client_for", "one_thread", "plan", "prepare_workers",
           "reuse_freed_memory", "run_pinned", "spread", "worker_threads"]

#: Pairs submitted at a time per worker thread: one running, one whose shapes are on their way.
IN_FLIGHT_PER_THREAD = 2
#: Seconds between looks at the workers the scheduler knows (workers may come and go).
WORKER_REFRESH_S = 5.0
#: Seconds :func:`worker_threads` waits for a first worker.
WORKER_WAIT_S = 60.0


# ----------------------------------------------------------------------------- shapes on workers
def _nbytes(obj) -> int:
    """Bytes of the arrays reachable from ``obj`` (each buffer counted once): what a prepared
    shape holds (its distances, eigenpairs, meshes...)."""
    seen: set[int] = set()
    total = 0
    stack = [obj]
    while stack:
        o = stack.pop()
        if id(o) in seen:
            continue
        seen.add(id(o))
        if isinstance(o, np.ndarray):
            root = o
            while isinstance(root.base, np.ndarray):
                root = root.base
            if id(root) not in seen or root is o:
                seen.add(id(root))
                total += root.nbytes
        elif isinstance(o, dict):
            stack.extend(o.values())
        elif isinstance(o, (list, tuple, set, frozenset)):
            stack.extend(o)
        elif hasattr(o, "__dict__") and type(o).__module__.startswith(("gromov", "scipy.sparse")):
            stack.extend(vars(o).values())
    return total


@sizeof.register(ShapeMetric)
def _sizeof_shape(s: ShapeMetric) -> int:
    # Dask's memory accounting (spilling, pausing) and its transfer costs use this
    return 1000 + _nbytes(s)


@dask_serialize.register(ShapeMetric)
def _dumps_shape(s: ShapeMetric):
    """A shape as sent between workers (or spilled to disk): without GMDS's view of its surface
    (:attr:`ShapeMetric.surface`: the face adjacency), which the receiver builds again if it
    needs it."""
    light = copy.copy(s)
    light._surface = None
    return pickle_dumps(light)


@dask_deserialize.register(ShapeMetric)
def _loads_shape(header, frames) -> ShapeMetric:
    return pickle_loads(header, frames)


class _WorkerSetup(distributed.WorkerPlugin):
    """Sets up each worker, present or joining later, for gromov: imports this module, which
    registers how a :class:`ShapeMetric` is read (:func:`_loads_shape`; without it a worker that
    has run no gromov task yet cannot receive a prepared shape: "No dispatch for ShapeMetric"),
    and lets it reuse the memory its matches free (:func:`reuse_freed_memory`)."""

    def setup(self, worker) -> None:
        from gromov import _dask

        _dask.reuse_freed_memory()


def prepare_workers(client) -> None:
    """Register :class:`_WorkerSetup` on the client's cluster (registering it again replaces it)."""
    client.register_plugin(_WorkerSetup(), name="gromov-worker-setup")


#: glibc ``mallopt`` parameters (``malloc.h``).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Blocks up to this size come from malloc's heap, which keeps them for reuse once freed.
MMAP_THRESHOLD = 32 * 1024 * 1024
#: Freed memory at the top of the heap beyond this is given back to the system.
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD
_MALLOC_SET = False


def reuse_freed_memory() -> bool:
    """Let this worker process reuse the memory its matches free, as a plain Python process does.

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536`` (its setting
    ``distributed.nanny.pre-spawn-environ``), so that freed memory goes back to the system.
    Setting that threshold turns off glibc's sliding mmap threshold: every block over 128 kB is
    mapped afresh and unmapped when freed, and each match's few-megabyte work arrays are
    faulted in page by page again: 54,000 page faults and 0.73 s per match of two TOSCA
    centaurs in a worker against 17 faults and 0.53 s in this process (median of 15, the
    machine of the README's numbers). Setting both thresholds explicitly (:data:`MMAP_THRESHOLD`,
    :data:`TRIM_THRESHOLD`) brings it back to 0.50 s. Returns whether it could (glibc only;
    elsewhere nothing is changed).
    """
    global _MALLOC_SET
    if not _MALLOC_SET:
        try:
            import ctypes

            libc = ctypes.CDLL("libc.so.6")
            _MALLOC_SET = bool(libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
                               and libc.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
        except (OSError, AttributeError):   # not glibc
            return False
    return _MALLOC_SET


_BLAS_LIMITED = False


def one_thread() -> None:
    """Run this task on one thread: numba's parallel kernels (this thread's setting) and the
    BLAS pool (the worker process's); a worker runs as many tasks at once as it has threads."""
    global _BLAS_LIMITED
    import numba

    numba.set_num_threads(1)
    if not _BLAS_LIMITED:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1)
        _BLAS_LIMITED = True


# ----------------------------------------------------------------------------- the cluster
class HomeReplicas(ActiveMemoryManagerPolicy):
    """Dask's active memory manager policy that drops the extra copies of a result, keeping the
    copy on its home worker (the one its task was restricted to) and those that tasks queued
    or running on a worker still need.

    Dask's own policy (``ReduceReplicas``) keeps as many copies as there are workers with
    tasks waiting for the key, and drops the others from the workers using the most memory:
    a worker's own shapes once another worker has received a copy, whenever none of the few
    pairs submitted to it at that moment reads them; it then receives them back for its next
    pairs. On 14 TOSCA shapes and 2 workers, where :func:`plan` needs 11 shapes sent, 16-25
    were sent with that policy (six runs) and 12-14 with this one (four runs). A key without a
    worker restriction keeps, as with ``ReduceReplicas``, a copy on each worker running or
    queuing a task that reads it, and one spare copy while such tasks wait for a worker
    (``ReduceReplicas`` keeps one per waiting task). :func:`client_for` runs its
    ``LocalCluster`` with this policy instead of ``ReduceReplicas``; a scheduler of your own
    takes it in its Dask configuration (``distributed.scheduler.active-memory-manager.policies``),
    when it can import gromov.
    """

    def run(self):
        for ts in self.manager.scheduler.replicated_tasks:
            holders = ts.who_has or set()
            waiters = ts.waiters or ()
            needed = {w.processing_on for w in waiters if w.processing_on is not None}
            home = {ws for ws in holders if ts.worker_restrictions and ws.address in ts.worker_restrictions}
            keep = (needed & holders) | home
            spare = holders - keep
            # a waiter not yet on a worker may go to any holder: one spare copy stays for it
            n_keep = max(1, len(keep) + any(w.processing_on is None for w in waiters))
            for _ in range(min(len(spare), len(holders) - n_keep)):
                yield Suggestion("drop", ts, spare)


#: Dask settings of the ``LocalCluster`` that :func:`client_for` starts, for workers of one
#: thread each running long, compute-bound tasks on a machine they fill: the policy above, no
#: statistical profiler in the workers (it samples each worker's stack every 10 ms), no work
#: stealing (:func:`run_pinned` places every pair and balances the workers itself), and the
#: periodic checks of the event loop, of each worker's memory and of the machine every 1 s,
#: 1 s and 5 s instead of 20, 100 and 500 ms. Idle, the three processes of a 2-worker cluster
#: took 120 ms of CPU per second with Dask's defaults and 16 ms with these; what they take is
#: taken from the pairs.
LOCAL_CLUSTER_CONFIG = {
    "distributed.scheduler.active-memory-manager.policies": [{"class": "gromov._dask.HomeReplicas"}],
    "distributed.worker.profile.enabled": False,
    "distributed.scheduler.work-stealing": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
}


@contextlib.contextmanager
def client_for(*, scheduler: str | None = None, n_workers: int | None = None):
    """A :class:`distributed.Client` of the scheduler at ``scheduler``, or of a new
    ``LocalCluster`` of ``n_workers`` worker processes of one thread each (closed on exit).

    Raises
    ------
    ValueError
        Neither or both given, or the scheduler cannot be reached (the message names it).
    """
    if (scheduler is None) == (n_workers is None):
        raise ValueError("give either a scheduler address or a number of workers")
    if n_workers is not None and n_workers < 1:
        raise ValueError(f"n_workers must be >= 1, got {n_workers}")
    with contextlib.ExitStack() as stack:
        # Dask logs its cluster's life at INFO: shown only when this process logs INFO
        log = logging.getLogger("distributed")
        if logging.getLogger().getEffectiveLevel() > logging.INFO and log.level < logging.WARNING:
            stack.callback(log.setLevel, log.level)
            log.setLevel(logging.WARNING)
        if scheduler is not None:
            try:
                client = distributed.Client(scheduler, timeout="20s")
            except (OSError, TimeoutError) as exc:
                raise ValueError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        else:   # a free port for the scheduler's web pages: several runs at once do not collide
            saved = dict(os.environ)
            stack.callback(_restore_environ, saved)   # after the cluster closes (a restart sets them again)
            try:
                with dask.config.set(LOCAL_CLUSTER_CONFIG):   # read as the cluster starts
                    cluster = stack.enter_context(distributed.LocalCluster(
                        n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=":0"))
            finally:
                _restore_environ(saved)
            client = distributed.Client(cluster)
        yield stack.enter_context(client)


def _restore_environ(saved: dict) -> None:
    """Put this process's environment back as ``saved``.

    Dask's nanny writes its settings for new workers (``distributed.nanny.pre-spawn-environ``:
    ``OPENBLAS_NUM_THREADS=1``, ``OMP_NUM_THREADS=1``, ``MALLOC_TRIM_THRESHOLD_=65536``...) into
    the environment of the process that starts the cluster, where they stay: every process it
    started afterwards ran BLAS on one thread and mapped every block over 128 kB afresh (the
    ``gromov pairwise`` runs a benchmark started after a ``LocalCluster`` computed heat distances
    that differ from its earlier runs' in the last bits). The workers get the settings from the
    nanny itself, at every start.
    """
    for key in set(os.environ) - set(saved):
        del os.environ[key]
    for key, value in saved.items():
        if os.environ.get(key) != value:
            os.environ[key] = value


def worker_threads(client, wait: float = WORKER_WAIT_S) -> dict[str, int]:
    """``{address: threads}`` of the client's workers, waiting up to ``wait`` seconds for one."""
    try:
        client.wait_for_workers(1, timeout=wait)
    except TimeoutError:
        raise ValueError(f"no Dask worker joined the scheduler {client.scheduler.address} "
                         f"in {wait:g} s") from None
    import time

    deadline = time.monotonic() + wait
    while True:   # the client's view of the scheduler can lag the worker that joined
        try:
            info = client.scheduler_info(n_workers=-1)   # all of them (some versions list 5 by default)
        except TypeError:   # versions that list all and take no argument
            info = client.scheduler_info()
        workers = info["workers"]
        if workers or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    if not workers:
        raise ValueError(f"the Dask scheduler {client.scheduler.address} lists no worker")
    return {addr: int(w.get("nthreads", 1)) for addr, w in sorted(workers.items())}


def spread(n_items: int, n_workers: int) -> list[int]:
    """The home (worker index) of each of ``n_items``: item i on worker i mod ``n_workers``."""
    return [i % n_workers for i in range(n_items)]


def plan(pairs, homes, n_workers: int) -> list[np.ndarray]:
    """Each worker's pairs in the order they are submitted (see the module's description).

    Parameters
    ----------
    pairs : (m, 2) array_like of int
    homes : (n,) array_like of int
        The worker index of each shape.
    n_workers : int

    Returns
    -------
    list of (m_w, 2) int64 arrays
        Per worker: its pairs of two shapes it holds (in the given order), then the others,
        grouped by the shape it receives (in order of that shape's index).
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    homes = np.asarray(homes, dtype=np.int64)
    p, q = pairs[:, 0], pairs[:, 1]
    swap = homes[p] > homes[q]
    p, q = np.where(swap, q, p), np.where(swap, p, q)   # p on the earlier worker, q on the later
    a, b = homes[p], homes[q]
    order = np.argsort(homes, kind="stable")
    rank = np.empty_like(order)   # a shape's place among its worker's shapes
    counts = np.bincount(homes, minlength=n_workers)
    rank[order] = np.arange(len(homes)) - np.repeat(np.cumsum(counts) - counts, counts)
    # B's first half (rounded up or down by turns, so that odd halves even out) runs on A
    to_a = rank[q] < (counts[b] + (a + b) % 2) // 2
    runs_on = np.where(to_a, a, b)
    gets = np.where(a == b, -1, np.where(to_a, q, p))
    sort = np.lexsort((np.arange(len(pairs)), gets, runs_on))
    cuts = np.searchsorted(runs_on[sort], np.arange(1, n_workers))
    return [pairs[idx] for idx in np.split(sort, cuts)]


class _Queue:
    """A worker's pairs: taken from the front by the worker, from the back by others."""

    def __init__(self, items: np.ndarray):
        self.items, self.lo, self.hi = items, 0, len(items)

    def __len__(self) -> int:
        return self.hi - self.lo

    def popleft(self) -> tuple:
        self.lo += 1
        return tuple(int(v) for v in self.items[self.lo - 1])

    def pop(self) -> tuple:
        self.hi -= 1
        return tuple(int(v) for v in self.items[self.hi])


def run_pinned(client, queues: list[np.ndarray], addresses: list[str], submit, on_done) -> None:
    """Submit each worker's queued pairs to it, a few at a time, until all are done.

    ``queues``: :func:`plan`'s, one per address. ``submit(item, address)`` (``item`` a pair
    ``(i, j)``) returns a future of the item run on that worker (loosely: it
    may run elsewhere if the worker leaves); ``on_done(item, future)`` is called for each, in
    the order they finish. A worker with free threads and no items of its own takes the last
    ones of the longest queue (of a worker that left, or of a busy one); workers that join
    during the run take work the same way. On an error, or an interrupt, the futures still
    running are cancelled and the error raised.
    """
    queues = {a: _Queue(q) for a, q in zip(addresses, queues)}
    threads = worker_threads(client)
    in_flight = dict.fromkeys(queues, 0)
    running: dict = {}   # future key -> (item, address, future)
    done = distributed.as_completed()
    seen = time.monotonic()

    def fill():
        for addr, n in threads.items():
            own = queues.setdefault(addr, _Queue(np.zeros((0, 2), dtype=np.int64)))
            in_flight.setdefault(addr, 0)
            while in_flight[addr] < IN_FLIGHT_PER_THREAD * n:
                if own:
                    item = own.popleft()
                else:
                    longest = max(queues.values(), key=len)
                    if not longest:
                        break
                    item = longest.pop()
                fut = submit(item, addr)
                running[fut.key] = (item, addr, fut)
                in_flight[addr] += 1
                done.add(fut)

    try:
        fill()
        for fut in done:
            item, addr, _ = running.pop(fut.key)
            in_flight[addr] -= 1
            on_done(item, fut)
            if time.monotonic() - seen > WORKER_REFRESH_S:
                threads, seen = worker_threads(client), time.monotonic()
            fill()
    except BaseException:
        client.cancel([f for *_, f in running.values()])
        raise
