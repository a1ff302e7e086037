"""Run a sweep's cells on a backend as their dependencies finish, storing each finished
cell at once; reuse the cells a previous run finished.

The scheduler is the only writer of cell files. Workers write their own artifacts
(atomically); a cell file is written after its artifacts, so a cell file always points
at complete artifacts, and an interrupted sweep loses at most the cells that were running.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import sys
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from bpns.atomic import atomic_path, storage_problem
from bpns.env.environment import Environment
from bpns.env.registry import make_environment
from bpns.experiments import approach_info
from bpns.experiments.backends import Backend
from bpns.experiments.cells import DEMOS, EVAL, SKILLS, Cell, plan_cells
from bpns.experiments.presets import SweepConfig
from bpns.experiments.store import FORMAT, CellStore, CellStoreError
from bpns.experiments.work import CellJob, CellOutcome


@dataclass
class SweepSummary:
    total: int
    reused: list[str] = field(default_factory=list)  # keys of cells finished before
    computed: list[str] = field(default_factory=list)  # keys of cells finished now
    failed: dict[str, str] = field(default_factory=dict)  # key -> error (traceback)
    blocked: list[str] = field(default_factory=list)  # keys depending on a failed cell
    seconds: float = 0.0

    @property
    def complete(self) -> bool:
        return len(self.reused) + len(self.computed) == self.total


def make_environments(names: Sequence[str]) -> dict[str, Environment]:
    return {name: make_environment(name) for name in names}


def sweep_cells(config: SweepConfig, envs: Mapping[str, Environment] | None = None) -> list[Cell]:
    return plan_cells(config, envs if envs is not None else make_environments(config.envs))


def run_sweep(
    cells: Sequence[Cell],
    store: CellStore,
    backend: Backend,
    on_finished: Callable[[dict[str, Any]], None] | None = None,
    log: Callable[[str], None] | None = None,
    show_progress: bool | None = None,
) -> SweepSummary:
    """Run every cell of ``cells`` not already stored in ``store``; returns what happened.

    ``on_finished`` sees each record right after it is stored. Raises
    :class:`CellStoreError` before running anything if a stored cell cannot be reused
    or another sweep is running in the same directory.
    """
    finished = False
    try:
        with store.exclusive():
            store.remove_partial_artifacts()
            summary = _run_locked(cells, store, backend, on_finished, log, show_progress)
        finished = True
        return summary
    finally:  # an interruption stops the cells still running
        backend.close(cancel=not finished)


def _run_locked(
    cells: Sequence[Cell],
    store: CellStore,
    backend: Backend,
    on_finished: Callable[[dict[str, Any]], None] | None,
    log: Callable[[str], None] | None,
    show_progress: bool | None,
) -> SweepSummary:
    t0 = time.perf_counter()
    by_key = {c.key: c for c in cells}
    missing = sorted({d for c in cells for d in c.deps} - set(by_key))
    if missing:
        raise ValueError(f"cells depend on cells not in the sweep: {missing}")
    done = load_finished(cells, store)
    summary = SweepSummary(total=len(cells), reused=list(done))
    waiting = [c for c in cells if c.key not in done]
    check_inputs_present(waiting, by_key, done, store)
    running: dict[int, Cell] = {}
    bar = _progress_bar(len(cells), len(done), show_progress)
    say = log or (lambda line: bar.write(line, file=sys.stdout))
    try:
        while waiting or running:
            still_waiting = []
            for cell in waiting:
                if any(d in summary.failed or d in summary.blocked for d in cell.deps):
                    summary.blocked.append(cell.key)
                    bar.update(1)
                elif all(d in done for d in cell.deps):
                    running[backend.submit(_job(cell, by_key, done, store))] = cell
                else:
                    still_waiting.append(cell)
            waiting = still_waiting
            if not running:
                continue
            token, outcome = backend.next_finished()
            cell = running.pop(token)
            bar.update(1)
            if outcome.storage_problem is not None:
                raise CellStoreError(
                    f"{cell.describe()}: {outcome.storage_problem}; the cells finished so "
                    "far are stored"
                )
            if outcome.result is None:
                summary.failed[cell.key] = outcome.error or "unknown error"
                last = (outcome.error or "").strip().splitlines()[-1:] or ["unknown error"]
                say(f"FAILED {cell.describe()}: {last[0]}")
                continue
            record = _record(cell, outcome, done)
            try:
                store.save(record)
            except OSError as err:
                problem = storage_problem(err, store.record_path(cell.key))
                if problem is None:
                    raise
                raise CellStoreError(f"{problem}; the cells finished before are stored") from None
            done[cell.key] = record
            summary.computed.append(cell.key)
            say(f"[{len(done)}/{len(cells)}] {describe_result(cell, record)}")
            if on_finished is not None:
                on_finished(record)
    finally:
        bar.close()
        summary.seconds = time.perf_counter() - t0
    return summary


def load_finished(cells: Sequence[Cell], store: CellStore) -> dict[str, dict[str, Any]]:
    """Stored records of ``cells`` (key -> record), checked: settings equal, and each one
    computed from the stored records of its dependencies (not from an earlier run of them)."""
    done = {c.key: r for c in cells if (r := store.load(c)) is not None}
    for key, record in done.items():
        for dep, dep_id in record.get("inputs", {}).items():
            if dep not in done or done[dep]["id"] != dep_id:
                raise CellStoreError(
                    f"{store.record_path(key)} was computed from a run of {dep} that is no "
                    "longer stored; delete it to recompute it"
                )
    return done


def check_inputs_present(
    waiting: Sequence[Cell], cells: Mapping[str, Cell], done: Mapping[str, dict], store: CellStore
) -> None:
    """:class:`CellStoreError` if a finished cell that a cell still to run reads has lost
    its artifact (deleted by hand): found before any work, not by a worker's traceback."""
    for cell in waiting:
        for dep in cell.deps:
            if dep in done and not os.path.exists(store.artifact_path(cells[dep])):
                raise CellStoreError(
                    f"{store.artifact_path(cells[dep])}: the artifact of finished cell {dep} "
                    f"is missing, and {cell.key} needs it; delete {store.record_path(dep)} "
                    "(and the cells computed from it) to recompute it"
                )


def _job(
    cell: Cell, cells: Mapping[str, Cell], done: Mapping[str, dict], store: CellStore
) -> CellJob:
    inputs = tuple(str(store.artifact_path(cells[d])) for d in cell.deps)
    output = str(store.artifact_path(cell))
    if cell.kind == SKILLS:
        solved = done[cell.deps[0]]["result"]["solved_tasks"]
        num_demos = sum(1 for i in solved if i < (cell.count or 0))
        return CellJob(cell, output, inputs, num_demos=num_demos)
    if cell.kind == EVAL and cell.deps:
        assert cell.approach is not None
        skills = done[cell.deps[0]]["result"]
        return CellJob(
            cell,
            output,
            inputs,
            num_demos=skills["num_demos"],
            learning_seconds=approach_info.learning_seconds(cell.approach, skills),
        )
    return CellJob(cell, output, inputs)


def _record(cell: Cell, outcome: CellOutcome, done: Mapping[str, dict]) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "id": uuid.uuid4().hex,
        "key": cell.key,
        "kind": cell.kind,
        "settings": cell.settings,
        "inputs": {d: done[d]["id"] for d in cell.deps},
        "result": outcome.result,
        "seconds": outcome.seconds,
        "host": outcome.host,
        "scheduler_host": platform.node(),
        "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def describe_result(cell: Cell, record: dict[str, Any]) -> str:
    r = record["result"]
    if cell.kind == DEMOS:
        what = f"{r['num_demos']}/{cell.count} demonstrations"
    elif cell.kind == SKILLS:
        what = f"{r['num_skills']} skills from {r['num_demos']} demos"
    else:
        median = r.get("median_seconds")
        what = f"solved {r['num_solved']}/{r['num_tasks']}" + (
            f" (median {median:.2f} s)" if median is not None else ""
        )
    return f"{cell.describe()}: {what} in {record['seconds']:.1f} s"


def progress_enabled() -> bool:
    """BPNS_PROGRESS=0 hides the bar, =1 shows it; otherwise only on a terminal."""
    setting = os.environ.get("BPNS_PROGRESS")
    if setting in ("0", "1"):
        return setting == "1"
    return sys.stderr.isatty()


def _progress_bar(total: int, initial: int, show: bool | None):
    return tqdm(
        total=total,
        initial=initial,
        desc="sweep",
        unit="cell",
        disable=not (progress_enabled() if show is None else show),
        dynamic_ncols=True,
    )


def write_sweep_file(path: Path, config: SweepConfig, command: str, summary: SweepSummary) -> None:
    """What was asked for and how the last run went (for the record; results are in cells)."""
    data = {
        "config": config.to_json(),
        "command": command,
        "cells": summary.total,
        "reused": len(summary.reused),
        "computed": len(summary.computed),
        "failed": sorted(summary.failed),
        "blocked": sorted(summary.blocked),
        "seconds": summary.seconds,
    }
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1) + "\n")
