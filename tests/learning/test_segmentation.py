"""Segmentation splits demonstrations exactly where contact-related atoms change."""

import numpy as np

from bpns.learning.segmentation import segment_demonstration, segment_demonstrations
from bpns.structs import Demonstration, GroundAtom, Object, Predicate, State, Task, Type

THING = Type("thing", ("contact", "near"))
OBJ = Object("a", THING)
calls = {"Touching": 0, "Near": 0}


def _touching(s, o):
    calls["Touching"] += 1
    return s.get(o[0], "contact") > 0.5


def _near(s, o):
    calls["Near"] += 1
    return s.get(o[0], "near") > 0.5


TOUCHING = Predicate("Touching", (THING,), _touching)
NEAR = Predicate("Near", (THING,), _near)
PREDICATES = {TOUCHING, NEAR}


def _demo(rows):
    states = tuple(State({OBJ: np.array(r, dtype=float)}) for r in rows)
    actions = np.arange(len(rows) - 1, dtype=float).reshape(-1, 1)
    return Demonstration(Task(states[0], frozenset(), 10), states, actions)


def _atoms(*names):
    preds = {"Touching": TOUCHING, "Near": NEAR}
    return frozenset(GroundAtom(preds[n], (OBJ,)) for n in names)


def test_splits_at_contact_changes_and_ignores_non_contact_changes():
    # contact changes entering states 3 and 6; "near" (non-contact) changes at 1, 4, 7.
    rows = [(0, 0), (0, 1), (0, 1), (1, 1), (1, 0), (1, 0), (0, 0), (0, 1)]
    demo = _demo(rows)
    segs = segment_demonstration(demo, PREDICATES, {TOUCHING})
    spans = [(demo.states.index(s.states[0]), demo.states.index(s.states[-1])) for s in segs]
    assert spans == [(0, 3), (3, 6), (6, 7)]
    for seg, (start, end) in zip(segs, spans, strict=True):
        assert seg.states == demo.states[start : end + 1]
        np.testing.assert_array_equal(seg.actions, demo.actions[start:end])
    assert segs[0].init_atoms == frozenset()
    assert segs[0].final_atoms == _atoms("Touching", "Near")
    assert segs[1].final_atoms == frozenset()
    assert segs[2].add_effects == _atoms("Near")  # the tail has effects, so it is kept


def test_tail_without_effects_is_dropped():
    rows = [(0, 0), (1, 0), (1, 1), (1, 0)]  # tail 1..3 changes "near" but ends as it began
    segs = segment_demonstration(_demo(rows), PREDICATES, {TOUCHING})
    assert len(segs) == 1
    assert segs[0].add_effects == _atoms("Touching")


def test_no_contact_change_gives_at_most_the_tail():
    assert segment_demonstration(_demo([(0, 0), (0, 0)]), PREDICATES, {TOUCHING}) == []
    segs = segment_demonstration(_demo([(0, 0), (0, 1)]), PREDICATES, {TOUCHING})
    assert len(segs) == 1 and segs[0].add_effects == _atoms("Near")


def test_contact_atoms_are_evaluated_once_per_state_and_the_rest_only_at_boundaries():
    rows = [(0, 0)] * 5 + [(1, 0)] * 5
    calls.update(Touching=0, Near=0)
    segment_demonstration(_demo(rows), PREDICATES, {TOUCHING})
    boundaries = 3  # states 0, 5 and the last one
    assert calls["Touching"] == len(rows) + boundaries
    assert calls["Near"] == boundaries


def test_segments_of_several_demos_keep_demo_order():
    d1, d2 = _demo([(0, 0), (1, 0)]), _demo([(0, 0), (0, 0), (1, 1)])
    segs = segment_demonstrations([d1, d2], PREDICATES, {TOUCHING})
    assert [s.states[0] for s in segs] == [d1.states[0], d2.states[0]]
