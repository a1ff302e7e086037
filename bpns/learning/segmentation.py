"""Temporal segmentation of demonstrations at contact switch points (paper §4.1).

A switch point is a state whose contact-related ground atoms differ from the previous
state's. Only contact atoms are needed at every state; the full abstraction is computed
once per segment boundary, since evaluating every predicate on every state is the
costly part of preprocessing.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable

from bpns.abstraction import abstract
from bpns.structs import Demonstration, GroundAtom, Predicate, Segment


def switch_points(contact_atoms: list[frozenset[GroundAtom]]) -> list[int]:
    """Indices i with contact_atoms[i] != contact_atoms[i - 1]."""
    return [i for i in range(1, len(contact_atoms)) if contact_atoms[i] != contact_atoms[i - 1]]


def segment_demonstration(
    demo: Demonstration,
    predicates: Collection[Predicate],
    contact_predicates: Collection[Predicate],
) -> list[Segment]:
    """Split ``demo`` into segments ending at the first state after each contact change.

    Segment k spans states[start..end] (inclusive) and actions[start:end]. The tail after
    the last switch point is kept only if it has effects; effect-free segments are dropped.
    """
    unknown = set(contact_predicates) - set(predicates)
    if unknown:
        raise ValueError(
            f"contact predicates {sorted(p.name for p in unknown)} are not among the predicates"
        )
    states = demo.states
    contact = [abstract(s, contact_predicates) for s in states]
    boundaries = [0, *switch_points(contact)]
    if boundaries[-1] != len(states) - 1:
        boundaries.append(len(states) - 1)
    full: dict[int, frozenset[GroundAtom]] = {
        i: abstract(states[i], predicates) for i in boundaries
    }
    segments = []
    for start, end in zip(boundaries[:-1], boundaries[1:], strict=True):
        init, final = full[start], full[end]
        if init == final:
            continue
        segments.append(Segment(states[start : end + 1], demo.actions[start:end], init, final))
    return segments


def segment_demonstrations(
    demos: Iterable[Demonstration],
    predicates: Collection[Predicate],
    contact_predicates: Collection[Predicate],
) -> list[Segment]:
    """All segments of all demos, in demo order (the order later stages rely on)."""
    return [
        seg for demo in demos for seg in segment_demonstration(demo, predicates, contact_predicates)
    ]
