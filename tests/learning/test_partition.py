"""Partitioning groups segments whose effects match under an injective, typed renaming."""

import numpy as np

from bpns.learning.partition import effect_mapping, make_parameters, partition_segments
from bpns.structs import GroundAtom, Object, Predicate, Segment, State, Type, Variable

ROBOT = Type("robot", ("x",))
BLOCK = Type("block", ("x",))
R = Object("robot", ROBOT)
B = [Object(f"b{i}", BLOCK) for i in range(5)]

HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), lambda s, o: True)
HOLDING = Predicate("Holding", (ROBOT, BLOCK), lambda s, o: True)
ON = Predicate("On", (BLOCK, BLOCK), lambda s, o: True)
CLEAR = Predicate("Clear", (BLOCK,), lambda s, o: True)
TOUCHED_R = Predicate("Touched", (ROBOT,), lambda s, o: True)
TOUCHED_B = Predicate("Touched", (BLOCK,), lambda s, o: True)
DUMMY = State({R: np.zeros(1)})


def seg(init=(), final=()):
    return Segment((DUMMY, DUMMY), np.zeros((1, 1)), frozenset(init), frozenset(final))


def pick(b):
    return seg([GroundAtom(HAND_EMPTY, (R,))], [GroundAtom(HOLDING, (R, b))])


def stack(top, bottom):
    return seg([GroundAtom(CLEAR, (bottom,))], [GroundAtom(ON, (top, bottom))])


def test_segments_differing_only_by_object_names_share_a_group():
    groups = partition_segments([pick(B[0]), pick(B[3]), pick(B[1])])
    assert len(groups) == 1
    g = groups[0]
    assert [v.name for v in g.parameters] == ["?block0", "?robot0"]
    vb, vr = g.parameters
    assert [dict(s) for s in g.substitutions] == [
        {B[0]: vb, R: vr},
        {B[3]: vb, R: vr},
        {B[1]: vb, R: vr},
    ]
    assert {str(a) for a in g.add_effects} == {"Holding(?robot0, ?block0)"}
    assert {str(a) for a in g.delete_effects} == {"HandEmpty(?robot0)"}


def test_mappings_keep_roles_of_objects_of_the_same_type():
    groups = partition_segments([stack(B[1], B[2]), stack(B[3], B[0])])
    assert len(groups) == 1
    top, bottom = Variable("?block0", BLOCK), Variable("?block1", BLOCK)
    assert groups[0].parameters == (top, bottom)
    assert dict(groups[0].substitutions[1]) == {B[3]: top, B[0]: bottom}


def test_different_effects_are_separated():
    place = seg([GroundAtom(HOLDING, (R, B[0]))], [GroundAtom(HAND_EMPTY, (R,))])
    groups = partition_segments([pick(B[0]), place, pick(B[1]), stack(B[0], B[1])])
    assert [len(g) for g in groups] == [2, 1, 1]


def test_same_predicate_name_with_other_types_is_not_merged():
    a = seg(final=[GroundAtom(TOUCHED_R, (R,))])
    b = seg(final=[GroundAtom(TOUCHED_B, (B[0],))])
    assert effect_mapping(a, b) is None
    assert len(partition_segments([a, b])) == 2


def test_non_injective_matches_are_rejected():
    # A match would need both b0 and b2 to map onto b3.
    src = seg(final=[GroundAtom(ON, (B[0], B[1])), GroundAtom(CLEAR, (B[2],))])
    dst = seg(final=[GroundAtom(ON, (B[3], B[4])), GroundAtom(CLEAR, (B[3],))])
    assert effect_mapping(src, dst) is None
    assert len(partition_segments([src, dst])) == 2


def test_effect_mapping_requires_both_add_and_delete_effects_to_match():
    add_only = seg([], [GroundAtom(HOLDING, (R, B[0]))])
    assert effect_mapping(pick(B[1]), add_only) is None
    assert effect_mapping(pick(B[1]), pick(B[2])) == {R: R, B[1]: B[2]}


def test_parameters_are_ordered_by_type_then_object_name():
    sub = make_parameters([B[2], R, B[0]])
    assert [(o.name, v.name) for o, v in sub.items()] == [
        ("b0", "?block0"),
        ("b2", "?block1"),
        ("robot", "?robot0"),
    ]
