"""A sweep's output directory: one small JSON file per finished cell, plus artifacts.

Layout under the root::

    cells/<kind>/<name>.json      one finished cell (written atomically when it finishes)
    artifacts/demos/<name>.h5     demonstrations of a demos cell
    artifacts/skills/<name>/      skills directory of a skills cell
    artifacts/eval/<name>.npz     solved plans of an eval cell

A cell file exists only once its cell has finished, and holds the settings that made
it: a rerun reuses it only if they equal the sweep's. One sweep at a time may run in a
directory (a lock file says so); it starts by removing the temporary files that cells
interrupted last time left behind (artifacts are written to hidden temporaries first).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from bpns.atomic import atomic_path
from bpns.errors import BpnsError
from bpns.experiments.cells import DEMOS, EVAL, SKILLS, Cell

FORMAT = "bpns-experiment-cell-1"

#: what readers of a finished cell's result use, by kind (the scheduler, the report)
RESULT_KEYS = {
    DEMOS: ("num_demos", "solved_tasks"),
    SKILLS: ("num_demos", "num_skills"),
    EVAL: (
        "num_tasks",
        "num_solved",
        "solved_percent",
        "median_seconds",
        "mean_seconds",
        "mean_nodes_created",
        "tasks",
    ),
}


class CellStoreError(BpnsError, ValueError):
    """A stored cell that cannot be reused: unreadable, or made with other settings."""


class CellStore:
    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root).resolve()

    def record_path(self, key: str) -> Path:
        return self.root / "cells" / f"{key}.json"

    def artifact_path(self, cell: Cell) -> Path:
        kind, name = cell.key.split("/", 1)
        suffix = {DEMOS: ".h5", SKILLS: "", EVAL: ".npz"}[kind]
        return self.root / "artifacts" / kind / f"{name}{suffix}"

    def load(self, cell: Cell) -> dict[str, Any] | None:
        """The stored record of ``cell``, None if it has not finished; raises
        :class:`CellStoreError` if the file is corrupt or was made with other settings."""
        path = self.record_path(cell.key)
        if not path.is_file():
            return None
        try:
            record = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise CellStoreError(
                f"{path}: unreadable cell file ({err}); delete it to redo the cell"
            ) from None
        if not isinstance(record, dict) or record.get("format") != FORMAT:
            raise CellStoreError(f"{path}: not a bpns experiment cell file")
        missing = _missing_fields(record, cell.kind)
        if missing:
            raise CellStoreError(
                f"{path}: incomplete cell file (no {', '.join(missing)}); delete it to "
                "redo the cell"
            )
        if record.get("settings") != cell.settings:
            raise CellStoreError(
                f"{path} was computed with other settings than this sweep's "
                f"({_differences(record.get('settings'), cell.settings)}); "
                "use another --out directory, or delete the stored cells to recompute them"
            )
        return record

    @contextlib.contextmanager
    def exclusive(self) -> Iterator[None]:
        """Hold the directory's lock; :class:`CellStoreError` if another sweep holds it."""
        self.root.mkdir(parents=True, exist_ok=True)
        with open(self.root / ".lock", "w") as lock:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise CellStoreError(f"{self.root} is in use by another running sweep") from None
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def remove_partial_artifacts(self) -> list[Path]:
        """Delete the hidden temporaries of interrupted cells (call with the lock held)."""
        removed = []
        for path in sorted((self.root / "artifacts").glob("*/.*")):
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed.append(path)
        return removed

    def save(self, record: dict[str, Any]) -> Path:
        path = self.record_path(record["key"])
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(record, indent=1, allow_nan=False) + "\n")
        return path


def _missing_fields(record: dict[str, Any], kind: str) -> list[str]:
    top = {"id": str, "settings": dict, "inputs": dict, "result": dict, "seconds": (int, float)}
    missing = [repr(k) for k, t in top.items() if not isinstance(record.get(k), t)]
    if not missing:
        result = record["result"]
        missing = [f"result {k!r}" for k in RESULT_KEYS.get(kind, ()) if k not in result]
    return missing


def _differences(stored: Any, wanted: dict[str, Any], prefix: str = "") -> str:
    """Readable list of the settings that differ, e.g. ``planning.timeout: 60.0 != 10.0``."""
    if not isinstance(stored, dict):
        return "no settings stored"
    out = []
    for key in sorted(set(stored) | set(wanted)):
        a, b = stored.get(key), wanted.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            inner = _differences(a, b, f"{prefix}{key}.")
            if inner:
                out.append(inner)
        elif a != b:
            out.append(f"{prefix}{key}: stored {a!r}, wanted {b!r}")
    return "; ".join(out)
