"""A command stopped by SIGTERM or Ctrl-C ends in one line and keeps every earlier output."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bpns import worker_start


def _as_from_a_terminal() -> None:
    """Ctrl-C's default action, as a shell in a terminal gives it.

    CI may start the suite with SIGINT ignored (a background job of a non-interactive
    shell); a child inherits that and, as Unix wants, would then never see Ctrl-C.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _bpns(*args: str) -> subprocess.Popen:
    env = {**os.environ, "BPNS_PROGRESS": "0"}
    return subprocess.Popen(
        [sys.executable, "-m", "bpns.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=_as_from_a_terminal,
    )


def _wait_for_workers(proc: subprocess.Popen, seconds: float = 300.0) -> None:
    """Until ``proc`` has started worker processes (a loaded machine starts them late)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
        if children.exists() and children.read_text().split():
            time.sleep(1.0)
            return
        time.sleep(0.2)
    raise AssertionError("the command started no worker process")


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize(
    ("sig", "code", "line"),
    [
        (signal.SIGTERM, 143, "bpns: terminated"),
        (signal.SIGINT, 130, "bpns: interrupted"),
    ],
)
def test_a_stopped_demos_run_says_so_in_one_line_and_keeps_the_old_file(
    cover_demo_file, tmp_path, sig, code, line
):
    old = tmp_path / "demos.h5"
    old.write_bytes(Path(cover_demo_file).read_bytes())
    before = _digest(old)
    proc = _bpns(
        "demos", "--env", "cover", "-n", "2000", "--workers", "2", "--out", str(old), "--overwrite"
    )
    _wait_for_workers(proc)  # the pool is up; 2000 demonstrations take minutes, not seconds
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == code, err
    assert err.strip().splitlines() == [line], err  # no worker's traceback beneath it
    assert _digest(old) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos.h5"]  # no temporary left


def _raise_in(filename: str, function: str, error: BaseException):
    namespace: dict = {}
    source = f"def {function}(error):\n    raise error\n"
    exec(compile(source, filename, "exec"), namespace)  # a frame named like the real one
    try:
        namespace[function](error)
    except BaseException as caught:  # noqa: BLE001 (handed to the hook as the forkserver does)
        return type(caught), caught, caught.__traceback__


def test_a_worker_whose_pool_is_gone_exits_without_a_traceback(capsys, monkeypatch):
    shown = []
    monkeypatch.setattr(worker_start, "_DEFAULT_HOOK", lambda *exc: shown.append(exc[0]))
    gone = _raise_in(
        "/usr/lib/python3/multiprocessing/synchronize.py",
        "__setstate__",
        FileNotFoundError(2, "No such file or directory"),
    )
    worker_start._quiet_when_the_pool_is_gone(*gone)
    assert shown == []
    for other in (
        _raise_in(
            "/usr/lib/python3/multiprocessing/synchronize.py", "__setstate__", ValueError("x")
        ),
        _raise_in("/work/plugin.py", "__setstate__", FileNotFoundError(2, "missing")),
        _raise_in(
            "/usr/lib/python3/multiprocessing/synchronize.py",
            "acquire",
            FileNotFoundError(2, "missing"),
        ),
    ):
        worker_start._quiet_when_the_pool_is_gone(*other)
    assert shown == [ValueError, FileNotFoundError, FileNotFoundError]


@pytest.mark.parametrize("stage", ["learn_baselines", "save_baselines"])
def test_learn_stopped_while_its_baselines_train_or_save_keeps_the_old_skills_whole(
    stage, cover_demo_file, tmp_path, monkeypatch, capsys
):
    from bpns.baselines import learn as baselines_learn
    from bpns.cli import main
    from bpns.workflow import learn as workflow_learn

    out = tmp_path / "skills"
    argv = ["learn", str(cover_demo_file), "--out", str(out), "--workers", "1", "--limit", "2"]
    assert main([*argv, "--baselines", "--baseline-steps", "5"]) == 0
    before = {p.name: _digest(p) for p in out.iterdir() if p.is_file()}
    assert {"gnn_bc.npz", "gnn_meta.npz", "skills.json"} <= before.keys()

    def stopped(*args, **kwargs):  # Ctrl-C while the GNNs train (the longest stage) or save
        raise KeyboardInterrupt

    for module in (baselines_learn, workflow_learn):
        monkeypatch.setattr(module, stage, stopped, raising=False)
    capsys.readouterr()
    code = main([*argv, "--baselines", "--baseline-steps", "5", "--overwrite", "--seed", "1"])
    assert (code, capsys.readouterr().err.strip()) == (130, "bpns: interrupted")
    assert {p.name: _digest(p) for p in out.iterdir() if p.is_file()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["skills"]  # no temporary left behind


def _tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): _digest(p) for p in sorted(root.rglob("*")) if p.is_file()}


def test_eval_stopped_while_it_renders_its_report_keeps_every_earlier_output(
    tmp_path, monkeypatch, capsys
):
    from bpns.cli import main
    from bpns.workflow import report_page

    out, video, rec = tmp_path / "ev", tmp_path / "solved.mp4", tmp_path / "rec"
    argv = ["eval", "--env", "cover", "--approach", "oracle", "-n", "1", "--workers", "1"]
    argv += ["--out", str(out), "--video", str(video), "--report-videos", "none"]
    argv += ["--rerun", str(rec)]
    assert main(argv) == 0
    before = {**_tree(out), "video": _digest(video), "png": _digest(video.with_suffix(".png"))}
    recordings = _tree(rec)
    assert list(recordings) == ["oracle_task0.rrd"]

    def stopped(*args, **kwargs):  # Ctrl-C after the results and the video were written
        raise KeyboardInterrupt

    monkeypatch.setattr(report_page, "write_page", stopped)
    capsys.readouterr()
    code = main([*argv, "--overwrite", "--seed", "1"])
    assert (code, capsys.readouterr().err.strip()) == (130, "bpns: interrupted")
    after = {**_tree(out), "video": _digest(video), "png": _digest(video.with_suffix(".png"))}
    assert after == before
    assert _tree(rec) == recordings  # the recordings too: put in place with the results
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ev", "rec", "solved.mp4", "solved.png"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no staging left
    assert not [p for p in rec.iterdir() if p.name.startswith(".")]


def test_deferred_signals_wait_for_the_end_of_the_block():
    from bpns.atomic import deferred_signals

    # Ctrl-C as a terminal gives it: CI may run the suite with SIGINT ignored, and an
    # ignored signal stays ignored after the block (as it would have been without it)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    seen = []
    try:
        with pytest.raises(KeyboardInterrupt):
            with deferred_signals():
                signal.raise_signal(signal.SIGINT)
                seen.append("after the signal, inside the block")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen == ["after the signal, inside the block"]


def test_a_deferred_signal_the_process_ignores_stays_ignored():
    from bpns.atomic import deferred_signals

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred_signals():
            signal.raise_signal(signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
