"""Worker pools start small, stay bounded, consume jobs lazily and die with their parent."""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from bpns.data.demos import collect_demonstrations
from bpns.pools import (
    WorkerDiedError,
    bounded_map,
    capped_workers,
    make_pool,
    max_workers,
    pool_map,
    result_of,
    submit,
    surviving_map,
)


def _die_on_two(x: int) -> int:
    if x == 2:
        os.kill(os.getpid(), signal.SIGKILL)  # what the kernel's OOM killer does
    return x


@pytest.mark.parametrize("how", ["bounded_map", "pool_map", "result_of"])
def test_a_worker_killed_mid_job_is_one_clear_error_naming_the_fix(how):
    with make_pool(1) as pool:
        with pytest.raises(WorkerDiedError, match="fewer --workers") as err:
            if how == "bounded_map":
                list(bounded_map(pool, _die_on_two, range(5), in_flight=1))
            elif how == "pool_map":
                list(pool_map(pool, _die_on_two, range(5), name=lambda i: f"task {i}"))
            else:
                result_of(pool.submit(_die_on_two, 2))
    assert "Traceback" not in str(err.value) and "\n" not in str(err.value)
    if how == "pool_map":
        assert "while task 2 was unfinished" in str(err.value)


class _ForkserverKilledMidStart(ThreadPoolExecutor):
    def submit(self, fn, /, *args, **kwargs):
        raise EOFError("unexpected EOF")  # multiprocessing's, reading the new worker's pid


@pytest.mark.parametrize("how", ["bounded_map", "pool_map", "submit"])
def test_a_worker_that_cannot_start_because_the_forkserver_died_is_one_clear_error(how):
    with _ForkserverKilledMidStart(1) as pool:
        with pytest.raises(WorkerDiedError, match="fewer --workers") as err:
            if how == "bounded_map":
                list(bounded_map(pool, abs, range(3), in_flight=1))
            elif how == "pool_map":
                list(pool_map(pool, abs, range(3), name=lambda i: f"task {i}"))
            else:
                submit(pool, abs, -1, "network 1 (policies)")
    if how == "submit":
        assert "while network 1 (policies) was unfinished" in str(err.value)


def test_worker_counts_are_capped_at_the_cpu_count():
    assert capped_workers(1000) == max_workers() == max(1, os.cpu_count() or 1)
    assert capped_workers(0) == 1


def test_bounded_map_consumes_an_endless_job_stream_lazily():
    consumed = []

    def jobs():
        for i in itertools.count():
            consumed.append(i)
            yield i

    with ThreadPoolExecutor(2) as pool:
        out = list(itertools.islice(bounded_map(pool, lambda x: x * x, jobs(), in_flight=3), 5))
    assert out == [0, 1, 4, 9, 16]
    assert len(consumed) <= 5 + 3


def test_collecting_an_astronomical_number_of_demos_starts_at_once():
    stream = collect_demonstrations("cover", 10**22, seed=3, workers=1)
    index, demo = next(stream)
    stream.close()
    assert index == 0 and demo is not None


def _rss_bytes(status: str) -> int:
    line = next(x for x in status.splitlines() if x.startswith("VmRSS:"))
    return int(line.split()[1]) * 1024


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
def test_workers_do_not_inherit_a_large_parent_memory():
    """`bpns run` forks workers after learning from 1000 demos; a forked worker maps the
    parent's gigabytes and fork() itself can fail with ENOMEM. Workers must start from
    the small forkserver instead."""
    ballast = np.ones(400 * 2**20 // 8)  # 400 MB, touched
    parent_rss = _rss_bytes(Path("/proc/self/status").read_text())
    assert parent_rss > ballast.nbytes
    with make_pool(1) as pool:
        worker_status = pool.submit(Path("/proc/self/status").read_text).result()
    assert _rss_bytes(worker_status) < ballast.nbytes / 2
    del ballast


_PARENT = textwrap.dedent(
    """
    import os, sys, time
    from bpns.pools import make_pool
    pool = make_pool(1)
    print(pool.submit(os.getpid).result(), flush=True)
    time.sleep(600)
    """
)


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    # a zombie counts as gone: it has exited and waits for its reaper
    stat = Path(f"/proc/{pid}/stat")
    return stat.exists() and stat.read_text().split(")")[-1].split()[0] == "Z"


@pytest.mark.skipif(sys.platform != "linux", reason="Linux process semantics")
def test_workers_exit_when_their_parent_is_killed():
    parent = subprocess.Popen([sys.executable, "-c", _PARENT], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(parent.stdout.readline())
        assert not _gone(worker)
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        for _ in range(300):  # bounded wait, not a timing assertion
            if _gone(worker):
                break
            time.sleep(0.1)
        assert _gone(worker), "the worker outlived its killed parent"
    finally:
        parent.kill()
        parent.wait()


def _die_once_on_two(job: tuple[str, int]) -> int:
    """Item 2 kills its worker the first time only (a marker file remembers)."""
    marker, x = job
    if x == 2 and not os.path.exists(marker):
        Path(marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return x * 10


def _always_die_on_two(job: tuple[str, int]) -> int:
    if job[1] == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return job[1] * 10


@pytest.mark.parametrize("fn", [_die_once_on_two, _always_die_on_two])
def test_surviving_map_runs_an_unfinished_job_again_alone_and_goes_on(tmp_path, fn):
    pools: list[int | None] = []

    def new_pool(n):
        pools.append(n)
        return make_pool(n or 2)

    jobs = [(str(tmp_path / "died"), x) for x in range(6)]
    out = list(surviving_map(new_pool, fn, jobs, in_flight=3, died=lambda job: -job[1]))
    again = 20 if fn is _die_once_on_two else -2  # run alone: its result, or died()'s
    assert out == [0, 10, again, 30, 40, 50]
    # the unfinished jobs ran again alone, one pool each; the rest in one fresh pool
    assert pools[0] is None and pools[-1] is None and pools.count(None) == 2
    assert 1 <= pools.count(1) <= 3
