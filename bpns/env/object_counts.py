"""How many objects of each kind eval tasks hold: named eval sets and ``--objects``.

An environment's own eval distribution is the ``paper`` set. It may declare more named
sets (``Capabilities.eval_sets``, e.g. ``large``), the range each kind of object can take
(``Capabilities.object_limits``: what its scenes can hold) and how to draw eval tasks with
other counts (``Capabilities.with_objects``). bpns only carries the counts; the
environment decides what a kind means (a type's objects, or e.g. a floor plan's side).

Texts: ``KIND=N`` or ``KIND=LO:HI`` (inclusive), several separated by commas or given as
separate arguments, e.g. ``button=6`` or ``cup=4:6,pot=1``.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from bpns.errors import BpnsError

PAPER = "paper"  # every environment's own eval distribution


class ObjectCountError(BpnsError, ValueError):
    """A malformed count text, an unknown set or kind, or a count the scene cannot hold."""


@dataclass(frozen=True)
class ObjectCounts:
    """Inclusive (lo, hi) object counts per kind, sorted by kind (hashable, comparable)."""

    ranges: tuple[tuple[str, int, int], ...] = ()

    def __post_init__(self) -> None:
        kinds = [k for k, _, _ in self.ranges]
        if len(set(kinds)) != len(kinds):
            raise ObjectCountError(f"a kind is given twice: {', '.join(kinds)}")
        for kind, lo, hi in self.ranges:
            if not kind:
                raise ObjectCountError("a count names no kind")
            if lo < 0 or hi < lo:
                raise ObjectCountError(f"{kind}: expected 0 <= low <= high, got {lo}:{hi}")
        object.__setattr__(self, "ranges", tuple(sorted(self.ranges)))

    @classmethod
    def of(cls, ranges: Mapping[str, tuple[int, int] | int]) -> ObjectCounts:
        """From ``{kind: (lo, hi)}`` (or ``{kind: n}``)."""
        items = []
        for kind, r in ranges.items():
            lo, hi = (r, r) if isinstance(r, int) else r
            items.append((kind, int(lo), int(hi)))
        return cls(tuple(items))

    @classmethod
    def parse(cls, texts: str | Iterable[str]) -> ObjectCounts:
        """``KIND=N`` / ``KIND=LO:HI`` items, comma separated or one per text."""
        parts = [texts] if isinstance(texts, str) else list(texts)
        items = [p.strip() for text in parts for p in text.split(",") if p.strip()]
        return cls(tuple(_parse_item(item) for item in items))

    def as_dict(self) -> dict[str, tuple[int, int]]:
        return {k: (lo, hi) for k, lo, hi in self.ranges}

    def get(self, kind: str) -> tuple[int, int] | None:
        return self.as_dict().get(kind)

    def updated(self, other: ObjectCounts) -> ObjectCounts:
        """These counts with ``other``'s kinds replaced or added."""
        return ObjectCounts.of({**self.as_dict(), **other.as_dict()})

    def __bool__(self) -> bool:
        return bool(self.ranges)

    def text(self) -> str:
        """The parseable form, e.g. ``button=5:8,stick=1`` ("" when empty)."""
        return ",".join(f"{k}={lo}" if lo == hi else f"{k}={lo}:{hi}" for k, lo, hi in self.ranges)


def _parse_item(item: str) -> tuple[str, int, int]:
    kind, sep, value = item.partition("=")
    kind = kind.strip()
    if not sep or not kind:
        raise ObjectCountError(f"expected KIND=N or KIND=LO:HI, got {item!r}")
    lo_text, colon, hi_text = value.partition(":")
    try:
        lo = int(lo_text)
        hi = int(hi_text) if colon else lo
    except ValueError:
        raise ObjectCountError(
            f"{kind}: expected a whole number N or LO:HI, got {value.strip()!r}"
        ) from None
    if lo < 0:
        raise ObjectCountError(f"{kind}: counts must be >= 0, got {lo}")
    if hi < lo:
        raise ObjectCountError(f"{kind}: low {lo} exceeds high {hi}")
    return kind, lo, hi


@dataclass(frozen=True)
class EvalSet:
    """Which eval distribution tasks come from: a named set and counts overriding it."""

    name: str = PAPER
    objects: ObjectCounts = ObjectCounts()

    @property
    def is_paper(self) -> bool:
        """The environment's own eval distribution (nothing to change)."""
        return self.name == PAPER and not self.objects

    def label(self) -> str:
        """``paper``, ``large`` or ``large, button=6``."""
        return self.name + (f", {self.objects.text()}" if self.objects else "")

    def to_json(self) -> str:
        return json.dumps({"name": self.name, "objects": self.objects.text()})

    @classmethod
    def from_json(cls, text: str) -> EvalSet:
        d = json.loads(text)
        return cls(str(d.get("name", PAPER)), ObjectCounts.parse(str(d.get("objects", ""))))


PAPER_SET = EvalSet()
