"""Reading a recording back with Rerun's own reader (``rerun.chunk.RrdReader``)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np
from rerun.chunk import RrdReader


class Recording:
    """A .rrd file's chunks by entity path: the tuple of its parts, unescaped."""

    def __init__(self, path: Path) -> None:
        self.temporal: dict[tuple[str, ...], list] = defaultdict(list)
        self.static: dict[tuple[str, ...], list] = defaultdict(list)
        for chunk in RrdReader(path).stream().to_chunks():
            entity = _unescape(chunk.entity_path.lstrip("/"))
            (self.static if chunk.is_static else self.temporal)[entity].append(
                chunk.to_record_batch()
            )

    def children(self, *prefix: str) -> set[str]:
        """The names of the entities right below ``prefix``."""
        n = len(prefix)
        return {e[n] for e in {*self.temporal, *self.static} if e[:n] == prefix and len(e) > n}

    def series(self, entity: tuple[str, ...], component: str) -> tuple[np.ndarray, list]:
        """(steps, values) of ``component`` on ``entity``, in step order."""
        steps, values = [], []
        for batch in self.temporal[entity]:
            if component not in batch.schema.names:
                continue
            steps += batch.column("step").to_pylist()
            values += batch.column(component).to_pylist()
        order = np.argsort(steps, kind="stable")
        return np.asarray(steps)[order], [values[i] for i in order]

    def static_values(self, entity: tuple[str, ...], component: str) -> list:
        return [
            v
            for batch in self.static[entity]
            if component in batch.schema.names
            for v in batch.column(component).to_pylist()
        ]

    def components(self, entity: tuple[str, ...]) -> set[str]:
        batches = self.temporal[entity] + self.static[entity]
        return {n for b in batches for n in b.schema.names}


def _unescape(path: str) -> tuple[str, ...]:
    """Entity path parts as logged (Rerun escapes '/', spaces, commas ... with '\\')."""
    parts, part, escaped = [], "", False
    for ch in path:
        if escaped:
            part += ch
            escaped = False
        elif ch == "\\":
            escaped = True
        elif ch == "/":
            parts.append(part)
            part = ""
        else:
            part += ch
    parts.append(part)
    return tuple(parts)
