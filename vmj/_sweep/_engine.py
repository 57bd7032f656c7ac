"""Running chunks of work: in threads of this process, or as Dask tasks on a cluster.

A *job* is a picklable object with a `token` (a digest of what it computes), a `chunk` size
and a method `compute(c)` that returns the result of chunk `c`. [`run_chunks`][] evaluates the
chunks still to do and hands each finished one, in this process, to a `sink`; chunk failures
are recorded and the run goes on, or (in-process without a store) the first is raised once the
chunks already running have ended. Dask is imported only when a client is asked for.

On a cluster the job is scattered to every worker once (`Client.scatter(broadcast=True)`), each
task carries only its chunk number, and each worker process keeps the first copy of a job it
receives ([`_worker_job`][]), so that the function it holds is compiled once per process and
reused for every chunk; it follows the client's float64 setting. A worker that dies has its tasks
rescheduled by Dask; a chunk whose result or whose job died with it is submitted again (the job
scattered again where its last copy was lost).
"""

from __future__ import annotations

import collections
import contextlib
import functools
import os
import queue
import re
import sys
import threading
import time
import uuid
from collections.abc import Callable

__all__ = ["run_chunks", "cluster", "Progress", "CORES", "failure_message"]

#: the cores this process may run on (threads evaluating chunks side by side)
CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


_IDLE: list[queue.SimpleQueue] = []  #: the inboxes of the kept threads waiting for work
_IDLE_LOCK = threading.Lock()
os.register_at_fork(after_in_child=_IDLE.clear)  # (threads do not survive a fork)


def _kept_thread(inbox: queue.SimpleQueue) -> None:
    while True:
        inbox.get()()


def _on_threads(task: Callable[[], None], n: int, inline: bool = False) -> Callable[[], None]:
    """Start `task()` on `n` threads and return a function that waits until all have
    returned, and raises what one of them raised. The threads are kept for the next sweep:
    starting two per sweep and joining them cost 0.5-1 ms, a tenth of a 4096-point sweep of
    exact turning points. A thread is started where none is idle (a sweep inside another's
    chunk never waits for a thread). With `inline`, the calling thread is one of the `n`: it
    runs `task()` itself when it first waits (what that raises is raised at once; a second
    call waits for the others)."""
    done = queue.SimpleQueue()  # None, or what a thread raised

    def run(inbox):
        raised = None
        try:
            task()
        except BaseException as e:  # (handed to the waiting thread: this one is kept)
            raised = e
        with _IDLE_LOCK:  # (idle again before the sweep goes on: its next one takes it)
            _IDLE.append(inbox)
        done.put(raised)

    for _ in range(n - inline):
        with _IDLE_LOCK:
            inbox = _IDLE.pop() if _IDLE else None
        if inbox is None:
            inbox = queue.SimpleQueue()
            threading.Thread(target=_kept_thread, args=(inbox,), daemon=True).start()
        inbox.put(functools.partial(run, inbox))

    left, first = n - inline, None  # threads not yet returned; what the first failing one raised

    def wait():  # (again after it returned or raised: at once)
        nonlocal left, first, inline
        if inline:
            inline = False
            task()
        while left:
            e = done.get()
            left -= 1
            first = first or e
        e, first = first, None  # (raised once)
        if e is not None:
            raise e

    return wait


class Progress:
    """Chunks done / total, rate and estimated time left, on stderr (or to a callable)."""

    def __init__(
        self,
        total: int,
        points: int,
        show,
        *,
        already: int = 0,
        label: str = "sweep",
        unit: str = "points",
        stream=None,
    ):
        self.total, self.points, self.label, self.unit = total, points, label, unit
        self.callback = show if callable(show) else None
        self.enabled = bool(show) and self.callback is None
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()
        self.already = self.done = already

    def update(self, k: int = 1) -> None:
        self.done += k
        if self.callback is not None:
            self.callback(self.done, self.total)
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        new = self.done - self.already
        rate = new / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        per_point = self.points / self.total
        bar = "#" * int(30 * self.done / self.total)
        self.stream.write(
            f"\r{self.label} [{bar:<30}] {self.done}/{self.total} chunks "
            f"{rate * per_point:9.3g} {self.unit}/s  {elapsed:6.1f} s  "
            f"ETA {left:6.1f} s"
        )
        if self.done == self.total:
            self.stream.write("\n")
        self.stream.flush()


def failure_message(exc: BaseException) -> str:
    """A one-line message for a failed chunk: the message of a check (returned by the chunk
    as a value, `vmj._checks.Failures`, or an `equinox.error_if` inside it) or a solver
    status, without the long stack text around it."""
    collected = getattr(exc, "check_message", None)
    if collected is not None:
        return collected
    text = str(exc)
    hit = re.search(r"EquinoxRuntimeError: (.*)", text)
    if hit:
        return hit.group(1).strip()
    first = text.strip().splitlines()[0] if text.strip() else ""
    return f"{type(exc).__name__}: {first}" if first else type(exc).__name__


# -- the worker side ---------------------------------------------------------------------------
#: the jobs this process has received, by token and chunk size (the first copy is kept, so that
#: its function's compiled code is reused for every chunk); at most a few are kept
_JOBS: collections.OrderedDict = collections.OrderedDict()
_JOBS_LOCK = threading.Lock()
_KEEP_JOBS = 4


def _worker_job(job):
    key = (job.token, job.chunk)
    with _JOBS_LOCK:
        kept = _JOBS.get(key)
        if kept is None:
            kept = _JOBS[key] = job
            while len(_JOBS) > _KEEP_JOBS:
                _JOBS.popitem(last=False)
        else:
            _JOBS.move_to_end(key)
    return kept


def _run_on_worker(job, c):
    return _worker_job(job).compute(c)


def _float64_plugin(x64: bool):
    """A Dask worker plugin that sets JAX's float64 mode on every worker (those running and
    those that join later) before any task's arguments are unpickled into arrays."""
    import distributed

    class Float64(distributed.WorkerPlugin):
        name = "vmj-float64"

        def __init__(self, x64):
            self.x64 = x64

        def setup(self, worker):
            import jax

            jax.config.update("jax_enable_x64", self.x64)

    return Float64(x64)


# -- clusters ----------------------------------------------------------------------------------
@contextlib.contextmanager
def cluster(client):
    """The `distributed.Client` for `client`: itself, a new one connected to a scheduler
    address (`"tcp://host:8786"`), or, for `"local"`, a `LocalCluster` on this machine with one
    single-threaded worker process per core (closed again at the end). The clients vmj makes
    are not the process's Dask scheduler (`set_as_default=False`): one whose address failed
    stayed it (Dask's constructor sets it first), and every later Dask computation of the
    process, a store's lazy results among them, failed with "Requested dask.distributed
    scheduler but no Client active"."""
    if client is None:
        yield None
        return
    try:
        import distributed
    except ImportError:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            "a Dask client needs the optional extra: pip install 'vmj[distributed]'"
        ) from None
    if isinstance(client, distributed.Client):
        yield client
        return
    if not isinstance(client, str):
        raise ValueError(
            f"client must be a dask.distributed.Client, a scheduler address such as "
            f"'tcp://host:8786', or 'local' (got {type(client).__name__})"
        )
    if client == "local":
        lc = distributed.LocalCluster(
            n_workers=CORES,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        )
        with lc, distributed.Client(lc, set_as_default=False) as c:
            yield c
        return
    try:
        connected = distributed.Client(client, set_as_default=False)
    except (ValueError, TypeError) as e:  # not an address: Dask's message names no argument
        raise ValueError(
            f"client {client!r} is not a scheduler address ({e}); give one such as "
            "'tcp://host:8786', or 'local'"
        ) from None
    with connected as c:
        yield c


def threads_of(client) -> int:
    """The number of chunks a cluster evaluates side by side (its workers' threads)."""
    workers = client.scheduler_info(n_workers=-1)["workers"].values()
    return max(1, sum(w["nthreads"] for w in workers))


def worker_memory(client) -> int | None:
    """The smallest memory limit per worker thread in bytes (None: no limits set)."""
    limits = [
        w["memory_limit"] / max(1, w["nthreads"])
        for w in client.scheduler_info(n_workers=-1)["workers"].values()
        if w.get("memory_limit")
    ]
    return int(min(limits)) if limits else None


# -- running -----------------------------------------------------------------------------------
LOST_RETRIES = 3  #: resubmissions of a chunk whose result died with its worker
#: chunks per thread (per worker thread of a cluster) computed ahead of the one `sink` takes,
#: at most, where results come back to this thread (a store): their memory stays bounded
BACKLOG = 2


class Interrupted(RuntimeError):
    """A run stopped before every chunk was done (its client closed, its tasks cancelled)."""


def run_chunks(
    job,
    todo,
    *,
    sink: Callable,
    fail: Callable | None,
    progress: Progress,
    client=None,
    threads: int = 1,
    sink_in_thread: bool = False,
    store=None,
) -> None:
    """Evaluate `job.compute(c)` for every chunk `c` in `todo` and pass each result to
    `sink(c, result)` as it arrives (in this process; with `sink_in_thread` and no client, in
    the thread that computed it, which also counts it on `progress`). A chunk that raises is
    passed to `fail(c, exception)` and the others go on; with `fail=None` the first failure is
    raised, no further chunk is started, and the running ones end first. Interrupted (Ctrl-C, the
    client closed), the chunks not started are cancelled and the exception is raised; chunks
    already handed to `sink` are complete, and what a `store` holds is said on stderr."""
    todo = list(todo)
    if not todo:
        return
    try:
        if client is None:
            _run_threads(job, todo, sink, fail, progress, threads, sink_in_thread)
        else:
            _run_dask(job, todo, sink, fail, progress, client, window=store is not None)
    except BaseException:
        if store is not None:
            done = int((store.status() == 1).sum())
            sys.stderr.write(
                f"\n{progress.label} stopped: {done} of {progress.total} chunks "
                f"are in the store {store.path!r}; rerun with resume=True to "
                f"compute only the others\n"
            )
        raise


def _run_threads(job, todo, sink, fail, progress, threads, sink_in_thread):
    """Threads that take chunk numbers from one queue until it is empty. With `sink_in_thread`
    each thread also hands its chunks to `sink` and counts them on the progress bar itself, and
    this thread only waits for the threads to end: waking it for every chunk cost a hand-over
    of Python's interpreter lock each time (a 10^6-point energy-balance sweep on two cores:
    66 -> 57 ms). Otherwise the results come back to this thread in the order they finish. On
    an exception here (the first failure without `fail`, Ctrl-C) the chunks not yet started
    are dropped and the running ones finish first. Results handed back are bounded: a thread
    starts a chunk only while fewer than `BACKLOG` per thread wait for `sink` (a store written
    more slowly than the chunks are computed would otherwise gather the whole result here)."""
    pending = queue.SimpleQueue()
    for c in todo:
        pending.put(c)
    finished = queue.SimpleQueue()  # (chunk, result, exception): results come back here
    failed = []  # (chunk, exception): with sink_in_thread
    stop = threading.Event()
    lock = threading.Lock()
    room = None if sink_in_thread else threading.Semaphore(BACKLOG * max(1, threads))

    def work():
        while not stop.is_set():
            if room is not None and not room.acquire(timeout=0.05):
                continue  # (the results handed back are not yet sunk: wait, or stop)
            try:
                c = pending.get_nowait()
            except queue.Empty:
                return
            try:
                out = job.compute(c)
                if sink_in_thread:
                    # sunk here, the chunk's buffers are freed at once and the next chunk
                    # reuses their memory (kept until the end, every chunk would be fresh
                    # memory, page-faulted into existence: one core, 155 -> 130 ms for the
                    # 10^6-point energy-balance sweep)
                    sink(c, out)
                    out = None
            except Exception as e:
                if not sink_in_thread:
                    finished.put((c, None, e))
                    continue
                with lock:
                    failed.append((c, e))
                if fail is None:
                    stop.set()
                continue
            if sink_in_thread:
                with lock:
                    progress.update()
            else:
                finished.put((c, out, None))

    # with sink_in_thread this thread is one of the threads (one fewer to wake and to wait for)
    wait = _on_threads(work, max(1, min(threads, len(todo))), inline=sink_in_thread)
    try:
        if sink_in_thread:
            wait()
            for c, exc in failed:
                if fail is None:
                    raise exc
                fail(c, exc)
                progress.update()
            return
        for _ in range(len(todo)):
            c, out, exc = finished.get()
            if exc is not None:
                if fail is None:
                    raise exc
                fail(c, exc)
            else:
                sink(c, out)
            out = None
            room.release()
            progress.update()
    finally:
        stop.set()
        wait()


def _held(client, future) -> bool:
    """Whether the scheduler knows a worker that holds `future`'s data."""
    if future.status != "finished":
        return False
    try:
        return bool(client.who_has([future]).get(future.key))
    except Exception:
        return False


def _run_dask(job, todo, sink, fail, progress, client, window=False):
    """The chunks as Dask tasks; their results are passed to `sink` here as they arrive. With
    `window`, at most `BACKLOG + 1` chunks per worker thread are submitted and not yet sunk
    (the next is submitted as each is sunk), so that neither the workers nor this process hold
    more than that of a result larger than memory; otherwise all are submitted at once."""
    import distributed
    import jax

    client.register_plugin(_float64_plugin(bool(jax.config.jax_enable_x64)))
    shared = [client.scatter(job, broadcast=True, hash=False)]
    run = uuid.uuid4().hex[:8]  # task keys of this run only
    tries = dict.fromkeys(todo, 0)
    needs = {}  # chunk future -> the scattered job it waits on

    def submit(c):
        f = client.submit(
            _run_on_worker,
            shared[0],
            c,
            pure=False,
            key=f"vmj-{job.token[:12]}-{run}-{c}-{tries[c]}",
        )
        needs[f] = shared[0]
        return f

    def lost(f, needed):
        """Whether the chunk of `f` died with a worker: its result (status "lost"), or the
        scattered job it waited on (whose last copy was on that worker: Dask then cancels the
        chunks that need it). A lost job is scattered again."""
        if f.status == "lost":
            return True
        if f.status != "cancelled" or client.status != "running":
            return False
        if needed is shared[0] and not _held(client, needed):
            with contextlib.suppress(Exception):
                shared[0].release()
            shared[0] = client.scatter(job, broadcast=True, hash=False)
        return needed is not shared[0]

    queued = collections.deque(todo)
    ahead = (BACKLOG + 1) * threads_of(client) if window else len(queued)
    futures = {submit(c): c for c in (queued.popleft() for _ in range(min(ahead, len(queued))))}
    try:
        # results are fetched in the client's event loop as tasks finish, side by side
        done = distributed.as_completed(list(futures), with_results=True, raise_errors=False)
        for f, value in done:
            c = futures.pop(f)
            needed = needs.pop(f)
            if f.status == "finished":
                sink(c, value)
            elif f.status == "error":
                exc = value[1] if isinstance(value, tuple) else value
                if fail is None:
                    raise exc
                fail(c, exc)
            elif tries[c] < LOST_RETRIES and lost(f, needed):
                # the chunk, or the job it needed, died with a worker
                tries[c] += 1
                again = submit(c)
                futures[again] = c
                done.add(again)
                continue
            else:  # cancelled: the client or the cluster went away
                raise Interrupted(f"the run was interrupted (chunk {c} {f.status})")
            f.release()
            progress.update()
            if queued:
                if client.status != "running":
                    raise Interrupted(f"the run was interrupted (client {client.status})")
                c = queued.popleft()
                nxt = submit(c)
                futures[nxt] = c
                done.add(nxt)
    finally:
        if futures:
            with contextlib.suppress(Exception):
                client.cancel(list(futures))
        with contextlib.suppress(Exception):
            shared[0].release()
