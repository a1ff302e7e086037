"""`bpns experiment` on hostile ground (issue 24): a bad --out, a missing sweep, damaged
or incomplete cell files, a deleted artifact, a full disk, an unreachable Ray cluster,
a killed scheduler. Each is one ``bpns: error:`` line (exit 2) before any work where it
can be, and nothing finished is lost."""

from __future__ import annotations

import errno
import json
import os
import signal
import socket
import subprocess
import sys
import time

import pytest

from bpns.experiments import backends, work
from bpns.experiments.backends import BackendError, PoolBackend, check_reachable, host_and_port
from bpns.experiments.cells import DEMOS, EVAL
from bpns.experiments.presets import SweepConfig
from bpns.experiments.store import FORMAT, RESULT_KEYS, CellStore, CellStoreError
from bpns.experiments.sweep import run_sweep, sweep_cells
from tests.cli_probe import error_line

SWEEP = ["experiment", "--env", "cover", "--demos", "2", "--seeds", "0", "--tasks", "1"]
ORACLE = ["experiment", "--env", "cover", "--approach", "oracle", "--seeds", "0", "--tasks", "1"]
CONFIG = SweepConfig("tiny", ("cover",), (2,), (0,), ("bpns",), 1, 10.0)


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed again: nothing listens there


@pytest.mark.parametrize(
    "out, message",
    [
        ("{w}/file", "--out {w}/file: exists and is not a directory"),
        ("{w}/file/sweep", "--out {w}/file/sweep: {w}/file is not a directory"),
        ("/proc/sweep", "--out /proc/sweep: cannot write in /proc"),
    ],
)
def test_a_sweep_directory_that_cannot_be_one_is_refused_first(tmp_path, capsys, out, message):
    (tmp_path / "file").write_text("mine")
    line = error_line([*SWEEP, "--out", out.format(w=tmp_path)], capsys)
    assert line.startswith(f"bpns: error: {message.format(w=tmp_path)}")
    assert [p.name for p in tmp_path.iterdir()] == ["file"]
    assert (tmp_path / "file").read_text() == "mine"


def test_report_only_on_a_missing_sweep_creates_nothing(tmp_path, capsys):
    out = tmp_path / "nothing-here"
    line = error_line([*SWEEP, "--out", str(out), "--report-only"], capsys)
    assert line == (
        f"bpns: error: --report-only: {out} holds no sweep (no cells/ in it); run the sweep first"
    )
    assert not out.exists()


@pytest.mark.parametrize("drop", ["result", "id", "result.tasks"])
def test_an_incomplete_cell_file_is_one_line_naming_it(tmp_path, capsys, cover_env, drop):
    config = SweepConfig("tiny", ("cover",), (2,), (0,), ("oracle",), 1, 60.0)
    (cell,) = sweep_cells(config, {"cover": cover_env})
    record = {"format": FORMAT, "id": "x", "key": cell.key, "settings": cell.settings}
    record.update(inputs={}, seconds=1.0, result={"num_tasks": 1, "tasks": []})
    field, _, inner = drop.partition(".")
    if inner:
        del record[field][inner]
    else:
        del record[field]
    path = CellStore(tmp_path).record_path(cell.key)
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(record))
    line = error_line([*ORACLE, "--timeout", "60", "--out", str(tmp_path), "--dry-run"], capsys)
    assert line.startswith(f"bpns: error: {path}: incomplete cell file (no ")
    assert line.endswith("); delete it to redo the cell")


class _InlineBackend:
    """Runs each cell in this process when asked for the next finished one (so that a
    test can break a write the worker makes)."""

    def __init__(self) -> None:
        self._jobs: list[tuple[int, work.CellJob]] = []

    def submit(self, job):
        self._jobs.append((len(self._jobs), job))
        return self._jobs[-1][0]

    def next_finished(self):
        token, job = self._jobs.pop(0)
        return token, work.run_cell_safely(job)

    def close(self, cancel):
        self._jobs.clear()


def test_a_finished_cell_whose_artifact_was_deleted_is_refused_before_work(tmp_path, cover_env):
    cells = sweep_cells(CONFIG, {"cover": cover_env})
    store = CellStore(tmp_path)
    demos = [c for c in cells if c.kind == DEMOS]
    run_sweep(demos, store, _InlineBackend(), log=lambda line: None)
    store.artifact_path(demos[0]).unlink()
    backend = _InlineBackend()
    with pytest.raises(CellStoreError, match="the artifact of finished cell demos/cover-seed0 is"):
        run_sweep(cells, store, backend, log=lambda line: None)
    assert store.record_path(demos[0].key).is_file()  # nothing deleted for the user


def test_a_full_disk_stops_the_sweep_with_one_line_keeping_finished_cells(
    tmp_path, cover_env, monkeypatch
):
    import bpns.workflow.collect

    def no_space(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(bpns.workflow.collect, "write_demonstrations", no_space)
    cells = sweep_cells(CONFIG, {"cover": cover_env})
    store = CellStore(tmp_path)
    with pytest.raises(CellStoreError) as raised:
        run_sweep(cells, store, _InlineBackend(), log=lambda line: None)
    message = str(raised.value)
    assert message.startswith(
        "demos cover 2 tasks seed 0: cannot write "
        f"{store.artifact_path(cells[0])}: No space left on device"
    )
    assert "\n" not in message
    assert not (tmp_path / "cells").exists()


@pytest.mark.parametrize(
    "address, target",
    [
        ("auto", None),
        ("ray://head", ("head", 10001)),
        ("ray://head:1234", ("head", 1234)),
        ("10.0.0.1", ("10.0.0.1", 6379)),
        ("10.0.0.1:7000", ("10.0.0.1", 7000)),
        ("[::1]:7000", ("::1", 7000)),
    ],
)
def test_ray_addresses_name_the_host_and_port_to_reach(address, target):
    assert host_and_port(address) == target


def test_an_unreachable_ray_cluster_is_refused_before_any_work(tmp_path, capsys):
    port = _closed_port()
    out = tmp_path / "s"
    argv = [*SWEEP, "--out", str(out), "--backend", "ray", "--ray-address", f"127.0.0.1:{port}"]
    line = error_line(argv, capsys)
    assert line == f"bpns: error: cannot reach Ray at '127.0.0.1:{port}': Connection refused"
    assert not out.exists()


def test_a_ray_address_that_never_answers_times_out(monkeypatch):
    seen = []

    def silent(address, timeout):
        seen.append(timeout)
        raise TimeoutError("timed out")

    monkeypatch.setattr(backends.socket, "create_connection", silent)
    with pytest.raises(BackendError, match=r"no answer within 5 s"):
        check_reachable("10.0.0.1:6379")
    assert seen == [backends.CONNECT_TIMEOUT]


SLEEPER = """
import os, time
def sleep_here(path):
    with open(path, "w") as f:
        f.write(str(os.getpid()))
    time.sleep(120)
"""
SCHEDULER = """
import sys, time
from bpns.experiments.backends import PoolBackend
import h24_sleeper
PoolBackend(1, run=h24_sleeper.sleep_here).submit(sys.argv[1])
time.sleep(120)
"""


def test_a_killed_scheduler_leaves_no_worker_running(tmp_path):
    (tmp_path / "h24_sleeper.py").write_text(SLEEPER)
    pid_file = tmp_path / "worker.pid"
    path = os.pathsep.join([str(tmp_path), *sys.path])
    proc = subprocess.Popen(
        [sys.executable, "-c", SCHEDULER, str(pid_file)],
        env={**os.environ, "PYTHONPATH": path},
        stderr=subprocess.DEVNULL,  # the killed scheduler's resource tracker complains
    )
    for _ in range(1200):  # until the worker started its cell
        if pid_file.is_file() and pid_file.read_text():
            break
        time.sleep(0.05)
    worker = int(pid_file.read_text())
    os.kill(worker, 0)  # running its cell
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    for _ in range(600):  # the forkserver notices, then the kernel signals the worker
        if not _running(worker):
            break
        time.sleep(0.05)
    assert not _running(worker)


def test_a_cell_whose_process_is_killed_is_that_cells_failure_not_a_hang():
    backend = PoolBackend(1, run=signal.raise_signal)  # the cell kills its own process
    try:
        token = backend.submit(signal.SIGKILL)
        done, outcome = backend.next_finished()
    finally:
        backend.close(cancel=True)
    assert done == token
    assert outcome.result is None
    assert "WorkerDiedError" in outcome.error and "killed by signal 9" in outcome.error
    assert "fewer --workers" in outcome.error


def test_cells_beyond_the_worker_count_wait_and_all_finish():
    backend = PoolBackend(2, run=abs)
    try:
        tokens = {backend.submit(-k): k for k in range(1, 6)}
        finished = dict(backend.next_finished() for _ in tokens)
    finally:
        backend.close(cancel=False)
    assert finished == tokens  # each token's own answer, none lost
    with pytest.raises(RuntimeError, match="no cell is running"):
        backend.next_finished()


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie (exited, not yet reaped by init) is not running
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_a_sweep_whose_demonstrations_cannot_fit_is_refused_before_work(
    tmp_path, capsys, monkeypatch
):
    import shutil

    from bpns import atomic

    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(atomic.shutil, "disk_usage", lambda p: usage._replace(free=10_000))
    out = tmp_path / "s"
    line = error_line([*SWEEP, "--out", str(out)], capsys)
    assert line.startswith(f"bpns: error: --out {out}: 2 demonstrations need at least ")
    assert line.endswith("has 10 kB free")
    assert not out.exists()


def test_an_axis_level_colliding_with_a_stored_cell_is_one_line_with_the_fix(
    tmp_path, capsys, cover_env
):
    config = SweepConfig(
        "tiny", ("cover",), (2,), (0,), ("oracle",), 1, 10.0, ("friction_scale", (0.5,))
    )
    (cell,) = sweep_cells(config, {"cover": cover_env})
    record = {"format": FORMAT, "id": "x", "key": cell.key, "settings": cell.settings}
    result = dict.fromkeys(RESULT_KEYS[EVAL], 1) | {"tasks": []}
    record.update(inputs={}, seconds=1.0, result=result)
    path = CellStore(tmp_path).record_path(cell.key)
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(record))
    argv = [*ORACLE, "--timeout", "10", "--out", str(tmp_path)]
    line = error_line([*argv, "--perturb-axis", "friction_scale=0.5000001"], capsys)
    assert line.startswith(f"bpns: error: {path} was computed with other settings")
    assert "friction_scale: stored 0.5, wanted 0.5000001" in line
    assert "use another --out directory" in line


def test_axis_levels_that_would_share_one_cell_are_refused_before_work(tmp_path, capsys):
    out = tmp_path / "sweep"
    argv = [*ORACLE, "--timeout", "10", "--out", str(out)]
    line = error_line([*argv, "--perturb-axis", "friction_scale=0.5,0.5000001"], capsys)
    assert line == (
        "bpns: error: perturbation axis friction_scale: levels 0.5 and 0.5000001 would share "
        "the cell friction_scale=0.5 (cells are named to 6 significant digits); give levels "
        "that differ in their first 6 digits"
    )
    assert not out.exists()
