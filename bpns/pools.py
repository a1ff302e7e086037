"""Worker process pools that start small, stay bounded and die with their parent.

* Workers are started by a ``forkserver`` (``spawn`` where there is none), never forked
  from the caller: a parent that has loaded and learned from 1000 demonstrations holds
  gigabytes, and forking it can fail with ENOMEM under strict overcommit accounting.
* Worker counts are capped at the machine's CPU count (callers may print a note).
* Jobs are submitted lazily with a bounded number in flight, so an enormous job stream
  (10**22 tasks) costs constant memory.
* A worker exits when the process that created the pool dies: ``PR_SET_PDEATHSIG`` on
  Linux, plus a watchdog thread that polls the creator's pid everywhere.
* A worker that dies itself (killed by the kernel's OOM killer, a segfault in native
  code) is a :class:`WorkerDiedError` naming the likely cause and the fix, not a
  ``BrokenProcessPool`` traceback (:func:`result_of`, :func:`pool_map`).
"""

from __future__ import annotations

import collections
import ctypes
import ctypes.util
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from bpns.errors import BpnsError

T = TypeVar("T")
R = TypeVar("R")

PR_SET_PDEATHSIG = 1
WATCHDOG_SECONDS = 1.0


class WorkerDiedError(BpnsError, RuntimeError):
    """A worker process ended abruptly, taking its job with it. ``unfinished``: the
    items :func:`bounded_map` had submitted and not yet yielded, in order."""

    def __init__(self, message: str, unfinished: tuple[Any, ...] = ()) -> None:
        super().__init__(message)
        self.unfinished = unfinished


WORKER_DIED = (
    "a worker process died abruptly (killed, most often by the kernel's out-of-memory "
    "killer, or crashed in native code); no half-written output is left. Rerun with "
    "fewer --workers, or look for 'Out of memory' in `dmesg`"
)


#: a job's failure when its worker died twice (:func:`surviving_map`)
WORKER_DIED_ALONE = (
    "the worker process died, also when the job ran again alone (killed, most often by "
    "the kernel's out-of-memory killer, or crashed in native code)"
)


def worker_died(job: str | None = None) -> WorkerDiedError:
    """The error for a dead worker; ``job`` names what was unfinished (e.g. "task 3")."""
    if job is None:
        return WorkerDiedError(WORKER_DIED)
    return WorkerDiedError(
        WORKER_DIED.replace("abruptly", f"abruptly while {job} was unfinished", 1)
    )


#: what starting a worker raises when the pool is broken, or when the forkserver that
#: starts workers was killed while starting one
_START_FAILED = (BrokenProcessPool, EOFError, ConnectionError)


def submit(pool: Executor, fn: Callable[[T], R], item: T, job: str | None = None) -> Future[R]:
    """``pool.submit(fn, item)``, a worker that could not start because a worker or the
    forkserver died reported as :class:`WorkerDiedError` (naming ``job``)."""
    try:
        return pool.submit(fn, item)
    except _START_FAILED:
        raise worker_died(job) from None


def result_of(future: Future[R], job: str | None = None) -> R:
    """``future.result()``, a dead worker reported as :class:`WorkerDiedError`."""
    try:
        return future.result()
    except BrokenProcessPool:
        raise worker_died(job) from None


def pool_map(
    pool: Executor,
    fn: Callable[[T], R],
    items: Iterable[T],
    name: Callable[[T], str] | None = None,
) -> Iterator[R]:
    """``pool.map(fn, items)`` in order, a dead worker reported as
    :class:`WorkerDiedError` naming (``name(item)``) the first item not yet returned."""
    items = list(items)
    done = 0
    try:
        results = pool.map(fn, items)  # submits them all: starts the workers
    except _START_FAILED:
        raise worker_died(name(items[0]) if name is not None and items else None) from None
    try:
        for out in results:
            yield out
            done += 1
    except BrokenProcessPool:
        job = name(items[done]) if name is not None and done < len(items) else None
        raise worker_died(job) from None


def max_workers() -> int:
    """How many worker processes this machine can run at once."""
    return max(1, os.cpu_count() or 1)


def capped_workers(requested: int) -> int:
    """``requested`` workers, at least 1 and at most :func:`max_workers`."""
    return max(1, min(int(requested), max_workers()))


def worker_context() -> multiprocessing.context.BaseContext:
    """A start method that does not copy the caller's memory: forkserver, else spawn."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    # before its first worker (later calls change nothing): bpns.worker_start keeps a
    # worker that could not start because its pool was shut down from printing a traceback
    context.set_forkserver_preload(["__main__", "bpns.worker_start"])
    return context


def make_pool(
    workers: int,
    initializer: Callable[..., None] | None = None,
    initargs: tuple[Any, ...] = (),
) -> ProcessPoolExecutor:
    """A process pool of at most :func:`capped_workers` workers started by
    :func:`worker_context`, whose workers exit when the calling process dies."""
    return ProcessPoolExecutor(
        max_workers=capped_workers(workers),
        mp_context=worker_context(),
        initializer=_init_worker,
        initargs=(os.getpid(), initializer, initargs),
    )


def _init_worker(
    creator: int, initializer: Callable[..., None] | None, initargs: tuple[Any, ...]
) -> None:
    die_with(creator)
    if initializer is not None:
        initializer(*initargs)


def die_with(creator: int) -> None:
    """Make this process exit when process ``creator`` (its pool's owner) dies."""
    if sys.platform.startswith("linux"):
        # the signal fires when the *parent* dies: the forkserver, which itself exits
        # when the creator does
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if not _alive(creator):
        os._exit(1)
    threading.Thread(target=_watch, args=(creator,), daemon=True, name="die-with").start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else (pid reused): treat as gone
        return False
    return True


def _watch(creator: int) -> None:
    event = threading.Event()
    while not event.wait(WATCHDOG_SECONDS):
        if not _alive(creator) or os.getppid() == 1:
            os._exit(1)


def bounded_map(
    pool: Executor, fn: Callable[[T], R], items: Iterable[T], in_flight: int
) -> Iterator[R]:
    """``map(fn, items)`` on ``pool`` in order, with at most ``in_flight`` jobs submitted
    and not yet yielded: ``items`` is consumed lazily. A dead worker is a
    :class:`WorkerDiedError` whose ``unfinished`` are the items taken from ``items`` and
    not yielded."""
    pending: collections.deque[tuple[T, Future[R]]] = collections.deque()
    try:
        for item in items:
            try:
                pending.append((item, submit(pool, fn, item)))
            except WorkerDiedError as err:
                err.unfinished = (*(i for i, _ in pending), item)
                raise
            if len(pending) >= max(1, in_flight):
                yield _first_result(pending)
        while pending:
            yield _first_result(pending)
    finally:  # a consumer that stops early (Ctrl-C) waits for no queued job
        for _, future in pending:
            future.cancel()


def _first_result(pending: collections.deque[tuple[T, Future[R]]]) -> R:
    try:
        out = result_of(pending[0][1])
    except WorkerDiedError as err:
        err.unfinished = tuple(i for i, _ in pending)
        raise
    pending.popleft()
    return out


def surviving_map(
    new_pool: Callable[[int | None], Executor],
    fn: Callable[[T], R],
    items: Iterable[T],
    in_flight: int,
    died: Callable[[T], R],
) -> Iterator[R]:
    """:func:`bounded_map` that outlives its workers: ``map(fn, items)`` in order, in pools
    made by ``new_pool(None)``. A worker that dies (the kernel's out-of-memory killer, a
    crash in native code, a stray ``kill``) breaks its pool and every unfinished job
    with it; those (at most ``in_flight``) run again one at a time, each alone in
    ``new_pool(1)``, and ``died(item)`` stands for the result of one whose lone worker
    dies too; the rest of ``items`` go on in a fresh pool. For jobs whose result depends
    on the item alone (a task index and its seeds), a job run again gives what it would
    have given. A job that kills every worker it runs in breaks one pool at most."""
    rest = iter(items)  # shared by every pool: each takes up where the last stopped
    while True:
        try:
            with new_pool(None) as pool:
                yield from bounded_map(pool, fn, rest, in_flight)
            return
        except WorkerDiedError as err:
            unfinished = err.unfinished
        for item in unfinished:  # which one's worker died is unknown: each alone, in turn
            yield _alone(new_pool, fn, item, died)


def _alone(
    new_pool: Callable[[int | None], Executor],
    fn: Callable[[T], R],
    item: T,
    died: Callable[[T], R],
) -> R:
    try:
        with new_pool(1) as pool:
            return result_of(submit(pool, fn, item))
    except WorkerDiedError:
        return died(item)
