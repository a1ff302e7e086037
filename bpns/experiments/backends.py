"""Where cells run: a local process pool (default) or a Ray cluster.

Both run :func:`bpns.experiments.work.run_cell_safely` on a :class:`CellJob` and hand
back ``(token, CellOutcome)`` pairs as cells finish, in completion order. A cell runs
in a fresh worker process: the pool's workers start from a forkserver (not forked from
the scheduler, which may hold a large environment) and each is replaced after one cell,
so the memory of a learning cell goes back to the system before the next cell starts.
A worker exits when the scheduler dies (:func:`bpns.pools.die_with`), so a killed sweep
leaves no cell running.
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import os
import queue
import socket
import sys
import tempfile
from collections.abc import Iterator
from typing import Any, Protocol

from bpns.errors import BpnsError
from bpns.experiments.work import CellJob, CellOutcome, run_cell_safely
from bpns.pools import die_with


class BackendError(BpnsError, RuntimeError):
    """A backend that cannot start (Ray missing, cluster unreachable)."""


class Backend(Protocol):
    def submit(self, job: CellJob) -> int: ...

    def next_finished(self) -> tuple[int, CellOutcome]: ...

    def close(self, cancel: bool) -> None: ...


class PoolBackend:
    """``workers`` cells at a time in local processes."""

    def __init__(self, workers: int = 1, start_method: str = "forkserver") -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        ctx = multiprocessing.get_context(start_method)
        self._pool = ctx.Pool(
            processes=workers,
            maxtasksperchild=1,
            initializer=die_with,  # a killed sweep leaves no cell running
            initargs=(os.getpid(),),
        )
        self._finished: queue.Queue[tuple[int, CellOutcome | BaseException]] = queue.Queue()
        self._tokens = itertools.count()
        self._pending = 0

    def submit(self, job: CellJob) -> int:
        token = next(self._tokens)
        self._pool.apply_async(
            run_cell_safely,
            (job,),
            callback=lambda outcome: self._finished.put((token, outcome)),
            error_callback=lambda err: self._finished.put((token, err)),
        )
        self._pending += 1
        return token

    def next_finished(self) -> tuple[int, CellOutcome]:
        if self._pending == 0:
            raise RuntimeError("no cell is running")
        while True:
            try:  # a timeout keeps Ctrl-C responsive
                token, outcome = self._finished.get(timeout=0.5)
                break
            except queue.Empty:
                continue
        self._pending -= 1
        if isinstance(outcome, BaseException):  # the worker died or could not unpickle
            outcome = CellOutcome(None, f"{type(outcome).__name__}: {outcome}", 0.0, "")
        return token, outcome

    def close(self, cancel: bool) -> None:
        if cancel:
            self._pool.terminate()
        else:
            self._pool.close()
        self._pool.join()


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
            import ray
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
