"""Fault injection: a directory replacement killed at any step loses neither version.

Every filesystem step of :func:`bpns.atomic.replace_directory` (the renames, the atomic
exchange, the deletions) is made to fail at call k, for every k, with and without
``renameat2(RENAME_EXCHANGE)``; in-process (an exception, as from Ctrl-C) and in a
child process that dies on the spot (``os._exit``, as from SIGKILL). After the "crash"
the next run's recovery must find the complete old or the complete new directory under
its name.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from bpns import atomic
from bpns.learning.artifacts.skills_dir import load_skills, save_skills
from tests import toy_learning as toy

OLD = {"a.txt": "old a", "sub/b.txt": "old b", "c.txt": "old c"}
NEW = {"a.txt": "new a", "sub/b.txt": "new b", "d.txt": "new d"}


class Crash(BaseException):
    """Stands for the process dying at this point."""


def _write_tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def _tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): p.read_text() for p in sorted(root.rglob("*")) if p.is_file()}


class _Faults:
    """Counts filesystem steps; the step numbered ``crash_at`` and all later ones fail."""

    def __init__(self, monkeypatch, crash_at: int, exchange: bool) -> None:
        self.calls = 0
        self.crash_at = crash_at
        real_rename, real_rmtree, real_exchange = atomic.os.rename, shutil.rmtree, atomic._exchange

        def step(fn):
            def wrapped(*args, **kwargs):
                self.calls += 1
                if self.calls >= self.crash_at:
                    raise Crash(f"killed at step {self.calls}")
                return fn(*args, **kwargs)

            return wrapped

        monkeypatch.setattr(atomic.os, "rename", step(real_rename))
        monkeypatch.setattr(shutil, "rmtree", step(real_rmtree))
        monkeypatch.setattr(
            atomic, "_exchange", step(real_exchange if exchange else (lambda a, b: False))
        )


def _steps_without_faults(tmp_path: Path, exchange: bool, monkeypatch) -> int:
    with monkeypatch.context() as m:
        faults = _Faults(m, crash_at=10**9, exchange=exchange)
        target = _write_tree(tmp_path / "probe" / "skills", OLD)
        new = _write_tree(tmp_path / "probe" / "new", NEW)
        atomic.replace_directory(new, target)
        assert _tree(target) == NEW
        return faults.calls


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2", "two-renames"])
def test_replace_directory_killed_at_any_step_loses_nothing(tmp_path, monkeypatch, exchange):
    total = _steps_without_faults(tmp_path, exchange, monkeypatch)
    assert total >= 3
    for k in range(1, total + 2):
        root = tmp_path / f"k{k}"
        target = _write_tree(root / "skills", OLD)
        new = _write_tree(root / "new", NEW)
        with monkeypatch.context() as m:
            _Faults(m, crash_at=k, exchange=exchange)
            try:
                atomic.replace_directory(new, target)
            except Crash:
                pass
        atomic.recover_directory(target)  # the next run
        assert _tree(target) in (OLD, NEW), f"step {k}: {_tree(target)}"
        if k > total:
            assert _tree(target) == NEW
        leftovers = [p.name for p in root.iterdir() if ".old-" in p.name or ".trash-" in p.name]
        assert leftovers == [], f"step {k}: {leftovers}"


def test_recovery_restores_the_old_directory_hidden_by_an_interrupted_swap(tmp_path):
    target = tmp_path / "skills"
    aside = _write_tree(tmp_path / ".skills.old-123-4", OLD)
    assert atomic.recover_directory(target)
    assert _tree(target) == OLD and not aside.exists()
    assert not atomic.recover_directory(target)


def test_recovery_understands_the_leftover_of_the_earlier_two_rename_scheme(tmp_path):
    target = tmp_path / "skills"
    _write_tree(tmp_path / ".skills.old-k3j_x" / "skills", OLD)
    assert atomic.recover_directory(target)
    assert _tree(target) == OLD
    assert [p.name for p in tmp_path.iterdir()] == ["skills"]


_CHILD = textwrap.dedent(
    """
    import os, shutil, sys
    from bpns import atomic
    target, new, crash_at, exchange = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    calls = [0]
    def step(fn):
        def wrapped(*a, **k):
            calls[0] += 1
            if calls[0] == crash_at:
                os._exit(9)  # no cleanup, no finally: as SIGKILL
            return fn(*a, **k)
        return wrapped
    atomic.os.rename = step(os.rename)
    shutil.rmtree = step(shutil.rmtree)
    atomic._exchange = step(atomic._exchange if exchange == "1" else (lambda a, b: False))
    atomic.replace_directory(new, target)
    """
)


@pytest.mark.parametrize("exchange", ["1", "0"], ids=["renameat2", "two-renames"])
def test_replace_directory_in_a_killed_process_loses_nothing(tmp_path, exchange):
    for k in range(1, 6):
        root = tmp_path / f"k{k}"
        target = _write_tree(root / "skills", OLD)
        new = _write_tree(root / "new", NEW)
        run = subprocess.run(
            [sys.executable, "-c", _CHILD, str(target), str(new), str(k), exchange],
            capture_output=True,
            text=True,
        )
        assert run.returncode in (0, 9), run.stderr
        atomic.recover_directory(target)
        assert _tree(target) in (OLD, NEW), f"step {k}: {_tree(target)}"


def test_save_skills_killed_at_any_step_keeps_loadable_skills(tmp_path, monkeypatch):
    skills = toy.learned_toy_skills()
    target = save_skills(skills, tmp_path / "skills")
    for k in range(1, 6):
        with monkeypatch.context() as m:
            _Faults(m, crash_at=k, exchange=k % 2 == 0)
            try:
                save_skills(skills, target, overwrite=True)
            except Crash:
                pass
        loaded = load_skills(target, toy.PREDICATES, toy.TYPES)  # recovers if needed
        assert [s.name for s in loaded.skills] == [s.name for s in skills.skills]


def test_exchange_swaps_two_directories_where_the_kernel_supports_it(tmp_path):
    a = _write_tree(tmp_path / "a", OLD)
    b = _write_tree(tmp_path / "b", NEW)
    if not atomic._exchange(a, b):
        pytest.skip("renameat2(RENAME_EXCHANGE) is not available here")
    assert _tree(a) == NEW and _tree(b) == OLD
