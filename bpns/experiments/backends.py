"""Where cells run: a local process pool (default) or a Ray cluster.

Both run :func:`bpns.experiments.work.run_cell_safely` on a :class:`CellJob` and hand
back ``(token, CellOutcome)`` pairs as cells finish, in completion order. A cell runs
in a fresh process started from a forkserver (not forked from the scheduler, which may
hold a large environment), so the memory of a learning cell goes back to the system
before the next cell starts. A cell process exits when the scheduler dies
(:func:`bpns.pools.die_with`), so a killed sweep leaves no cell running; a cell process
that dies (killed, crashed) is that cell's failure, never a hang.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import itertools
import multiprocessing
import multiprocessing.connection as mp_connection
import os
import socket
import sys
import tempfile
from collections.abc import Callable, Iterator
from typing import Any, Protocol

from bpns.errors import BpnsError
from bpns.experiments.work import CellJob, CellOutcome, run_cell_safely
from bpns.pools import WORKER_DIED, die_with, worker_context


class BackendError(BpnsError, RuntimeError):
    """A backend that cannot start (Ray missing, cluster unreachable)."""


class Backend(Protocol):
    def submit(self, job: CellJob) -> int: ...

    def next_finished(self) -> tuple[int, CellOutcome]: ...

    def close(self, cancel: bool) -> None: ...


class PoolBackend:
    """``workers`` cells at a time, each in a fresh local process.

    One process per cell (not a ``multiprocessing.Pool``): when a process dies without
    an answer (the OOM killer, a native crash, ``kill -9``) the backend knows exactly
    which cell it held and reports that cell as failed; a pool would lose the task and
    wait for it forever. Processes start from :func:`bpns.pools.worker_context`
    (forkserver), never forked from a scheduler that may hold a large environment.
    """

    def __init__(
        self,
        workers: int = 1,
        start_method: str | None = None,
        run: Callable[[CellJob], CellOutcome] = run_cell_safely,
    ) -> None:
        """``run`` is what a cell process calls on its job (a module-level function)."""
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self._ctx = multiprocessing.get_context(start_method) if start_method else worker_context()
        self._workers = workers
        self._run = run
        self._waiting: collections.deque[tuple[int, CellJob]] = collections.deque()
        self._running: dict[int, _Running] = {}
        self._tokens = itertools.count()

    def submit(self, job: CellJob) -> int:
        token = next(self._tokens)
        self._waiting.append((token, job))
        self._start_waiting()
        return token

    def _start_waiting(self) -> None:
        while self._waiting and len(self._running) < self._workers:
            token, job = self._waiting.popleft()
            receiver, sender = self._ctx.Pipe(duplex=False)
            process = self._ctx.Process(
                target=_run_cell_in_child,
                args=(self._run, job, sender, os.getpid()),
                name=f"bpns-cell-{token}",
                daemon=True,
            )
            process.start()
            sender.close()  # the child holds the only writing end: EOF when it dies
            self._running[token] = _Running(process, receiver)

    def next_finished(self) -> tuple[int, CellOutcome]:
        if not self._running:
            raise RuntimeError("no cell is running")
        while True:  # a timeout keeps Ctrl-C responsive
            ready = mp_connection.wait([r.receiver for r in self._running.values()], 0.5)
            if ready:
                break
        token = next(t for t, r in self._running.items() if r.receiver in ready)
        running = self._running.pop(token)
        try:
            outcome = running.receiver.recv()
        except (EOFError, OSError):  # it died before it could answer
            running.process.join()
            outcome = CellOutcome(None, _died(running.process.exitcode), 0.0, "")
        else:
            running.process.join()
        running.receiver.close()
        self._start_waiting()
        return token, outcome

    def close(self, cancel: bool) -> None:
        self._waiting.clear()
        for running in self._running.values():
            if cancel:
                running.process.kill()
            running.process.join()
            running.receiver.close()
        self._running.clear()


@dataclasses.dataclass
class _Running:
    process: multiprocessing.process.BaseProcess
    receiver: mp_connection.Connection


def _run_cell_in_child(
    run: Callable[[CellJob], CellOutcome],
    job: CellJob,
    sender: mp_connection.Connection,
    creator: int,
) -> None:
    die_with(creator)  # a killed sweep leaves no cell running
    outcome = run(job)
    sender.send(outcome)
    sender.close()


def _died(exitcode: int | None) -> str:
    """The error of a cell whose process ended without an answer."""
    how = (
        f"killed by signal {-exitcode}"
        if exitcode is not None and exitcode < 0
        else f"exit code {exitcode}"
    )
    return f"WorkerDiedError: the cell's process ended without a result ({how}); " + WORKER_DIED


#: seconds to wait for a Ray cluster's address to accept a connection
CONNECT_TIMEOUT = 5.0


def host_and_port(address: str) -> tuple[str, int] | None:
    """The (host, port) a Ray address names; None for ``auto``/``local`` (found on this
    node). ``ray://HOST[:10001]`` is Ray Client; ``HOST[:6379]`` a cluster's GCS."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "", address
    if rest in ("auto", "local", ""):
        return None
    default = 10001 if scheme == "ray" else 6379
    host, colon, port = rest.rpartition(":")
    if not colon or "]" in port:
        host, port = rest, str(default)
    host = host.strip("[]")
    if not port.isdigit():
        raise BackendError(f"--ray-address {address!r}: expected HOST:PORT or ray://HOST:PORT")
    return host, int(port)


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """:class:`BackendError` unless ``address`` accepts a TCP connection within
    ``timeout`` seconds (Ray itself would wait, and retry, far longer)."""
    target = host_and_port(address)
    if target is None:
        return
    try:
        with socket.create_connection(target, timeout=timeout):
            pass
    except TimeoutError:
        raise BackendError(
            f"cannot reach Ray at {address!r}: no answer within {timeout:g} s"
        ) from None
    except OSError as err:
        raise BackendError(f"cannot reach Ray at {address!r}: {err.strerror or err}") from None


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Hold what is written to file descriptor 2 meanwhile; replay it only on success."""
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (captured)
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), fd)
        ok = False
        try:
            yield
            ok = True
        finally:
            sys.stderr.flush()
            os.dup2(saved, fd)
            os.close(saved)
            if ok:
                held.seek(0)
                sys.stderr.write(held.read().decode(errors="replace"))


class RayBackend:
    """Cells as Ray tasks (one CPU each) on the cluster at ``address`` (``auto`` on a
    node of a running cluster, ``ray://head:10001`` from outside it), or on a local Ray
    instance with ``num_cpus`` CPUs when no address is given. Every node needs this
    package installed and the sweep's output directory at the same path."""

    def __init__(
        self,
        address: str | None = None,
        num_cpus: int | None = None,
        connect_timeout: float = CONNECT_TIMEOUT,
    ) -> None:
        try:
            import ray  # optional extra (bpns[ray]), only for this backend
        except ImportError:
            raise BackendError(
                "the ray backend needs Ray: pip install 'bpns[ray]' (or 'ray>=2.9')"
            ) from None
        self._ray = ray
        self._owns_ray = not ray.is_initialized()
        if self._owns_ray:
            try:
                if address is None:  # starts Ray's processes, which inherit our stderr
                    ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
                else:
                    check_reachable(address, connect_timeout)
                    with _quiet_stderr():  # Ray's C++ core logs each failed retry there
                        ray.init(address=address, log_to_driver=False)
            except (ConnectionError, RuntimeError, ValueError) as err:
                raise BackendError(f"cannot connect to Ray at {address!r}: {err}") from None
        self._remote = ray.remote(num_cpus=1, max_calls=1)(run_cell_safely)
        self._running: dict[Any, int] = {}
        self._tokens = itertools.count()

    def submit(self, job: CellJob) -> int:
        token = next(self._tokens)
        self._running[self._remote.remote(job)] = token
        return token

    def next_finished(self) -> tuple[int, CellOutcome]:
        if not self._running:
            raise RuntimeError("no cell is running")
        ready: list[Any] = []
        while not ready:  # a timeout keeps Ctrl-C responsive
            ready, _ = self._ray.wait(list(self._running), num_returns=1, timeout=0.5)
        ref = ready[0]
        token = self._running.pop(ref)
        try:
            outcome = self._ray.get(ref)
        except self._ray.exceptions.RayError as err:  # the worker or its node died
            outcome = CellOutcome(None, f"{type(err).__name__}: {err}", 0.0, "")
        return token, outcome

    def close(self, cancel: bool) -> None:
        if cancel:
            for ref in self._running:
                self._ray.cancel(ref, force=True)
        self._running.clear()
        if self._owns_ray:
            self._ray.shutdown()
