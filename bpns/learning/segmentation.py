"""Temporal segmentation of demonstrations at contact switch points (paper §4.1).

A switch point is a state whose contact-related ground atoms differ from the previous
state's. In physics one event rarely flips its atoms in a single step: a released block
bounces back against a pad for a step, or settles onto the table a step after the pads
let go. Changes closer together than ``settle_steps`` are therefore one event, cut at
its last change, and an event that restores the atoms it started from (a flicker) is
no switch at all. ``settle_steps=1`` is the literal, every-change segmentation.

Only contact atoms are needed at every state; the full abstraction is computed
once per segment boundary, since evaluating every predicate on every state is the
costly part of preprocessing.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable

from bpns.env.abstraction import ground_atoms, true_atoms
from bpns.structs import Demonstration, GroundAtom, Predicate, Segment


def switch_points(contact_atoms: list[frozenset[GroundAtom]], settle_steps: int = 1) -> list[int]:
    """Indices at which the contact atoms change, with changes less than ``settle_steps``
    apart merged into their last one and net-zero events (flickers) dropped."""
    if settle_steps < 1:
        raise ValueError(f"settle_steps must be >= 1, got {settle_steps}")
    changes = [i for i in range(1, len(contact_atoms)) if contact_atoms[i] != contact_atoms[i - 1]]
    cuts: list[int] = []
    for i in changes:
        if cuts and i - cuts[-1] < settle_steps:
            cuts[-1] = i
        else:
            cuts.append(i)
    out, last = [], contact_atoms[0] if contact_atoms else frozenset()
    for i in cuts:
        if contact_atoms[i] != last:
            out.append(i)
            last = contact_atoms[i]
    return out


def segment_demonstration(
    demo: Demonstration,
    predicates: Collection[Predicate],
    contact_predicates: Collection[Predicate],
    settle_steps: int = 1,
) -> list[Segment]:
    """Split ``demo`` into segments ending at the first state after each contact change.

    Segment k spans states[start..end] (inclusive) and the demo's labels[start:end] (the
    demonstrator's commands; the executed actions unless noise was injected). The tail after
    the last switch point is kept only if it has effects; effect-free segments are dropped.
    """
    unknown = set(contact_predicates) - set(predicates)
    if unknown:
        raise ValueError(
            f"contact predicates {sorted(p.name for p in unknown)} are not among the predicates"
        )
    states = demo.states
    labels = demo.labels  # the demonstrator's commands: what a skill's policy imitates
    objects, keys = states[0].objects, states[0].data.keys()
    if any(s.data.keys() != keys for s in states):
        raise ValueError("a demonstration's states must all hold the same objects")
    watched = ground_atoms(objects, contact_predicates)
    contact = [true_atoms(s, watched) for s in states]
    boundaries = [0, *switch_points(contact, settle_steps)]
    if boundaries[-1] != len(states) - 1:
        boundaries.append(len(states) - 1)
    every = ground_atoms(objects, predicates)
    full: dict[int, frozenset[GroundAtom]] = {i: true_atoms(states[i], every) for i in boundaries}
    segments = []
    for start, end in zip(boundaries[:-1], boundaries[1:], strict=True):
        init, final = full[start], full[end]
        if init == final:
            continue
        segments.append(Segment(states[start : end + 1], labels[start:end], init, final))
    return segments


def segment_demonstrations(
    demos: Iterable[Demonstration],
    predicates: Collection[Predicate],
    contact_predicates: Collection[Predicate],
    settle_steps: int = 1,
) -> list[Segment]:
    """All segments of all demos, in demo order (the order later stages rely on)."""
    return [
        seg
        for demo in demos
        for seg in segment_demonstration(demo, predicates, contact_predicates, settle_steps)
    ]
