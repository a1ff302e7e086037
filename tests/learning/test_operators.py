"""Operators: lifted effects, intersected preconditions, filtering of rare skills."""

import re

import pytest

from bpns.learning.operators import anchor_parameters, applicable_bindings, learn_operators
from bpns.learning.partition import partition_segments
from bpns.structs import GroundAtom, Object, Type
from tests.learning.test_partition import (
    CLEAR,
    HAND_EMPTY,
    HOLDING,
    ON,
    B,
    R,
    pick,
    seg,
    stack,
)

TARGET = Type("target", ("x",))
T0 = Object("t0", TARGET)


def _pick_with(b, *extra):
    """A pick whose initial (and final) state also holds ``extra``: not effects."""
    s = pick(b)
    return seg(s.init_atoms | frozenset(extra), s.final_atoms | frozenset(extra))


def test_preconditions_are_the_intersection_of_lifted_initial_atoms():
    segs = [
        _pick_with(B[0], GroundAtom(CLEAR, (B[0],)), GroundAtom(ON, (B[0], B[1]))),
        _pick_with(B[2], GroundAtom(CLEAR, (B[2],)), GroundAtom(CLEAR, (B[4],))),
        _pick_with(B[3], GroundAtom(CLEAR, (B[3],))),
    ]
    (dataset,) = learn_operators(partition_segments(segs))
    assert {str(a) for a in dataset.operator.preconditions} == {
        "HandEmpty(?robot0)",
        "Clear(?block0)",
    }
    assert dataset.bindings == ((B[0], R), (B[2], R), (B[3], R))


def test_atoms_over_objects_outside_the_scope_are_discarded_without_anchoring():
    # On(b0, b1) holds in both segments but b1 is not an affected object.
    segs = [_pick_with(b, GroundAtom(ON, (b, B[1]))) for b in (B[0], B[2])]
    (dataset,) = learn_operators(partition_segments(segs), anchor=False)
    assert {str(a) for a in dataset.operator.preconditions} == {"HandEmpty(?robot0)"}
    assert dataset.scope_size is None


def test_an_object_related_to_the_parameters_in_every_segment_becomes_a_parameter():
    # Each picked block sits on some other block (a different one each time): the block
    # underneath is anchored by On(picked, under) and the relation becomes a precondition.
    segs = [
        _pick_with(top, GroundAtom(ON, (top, under))) for top, under in ((B[0], B[1]), (B[2], B[3]))
    ]
    (dataset,) = learn_operators(partition_segments(segs))
    op = dataset.operator
    assert [v.name for v in op.parameters] == ["?block0", "?robot0", "?block1"]
    assert {str(a) for a in op.preconditions} == {"HandEmpty(?robot0)", "On(?block0, ?block1)"}
    assert dataset.bindings == ((B[0], R, B[1]), (B[2], R, B[3]))
    assert dataset.scope_size == 2  # the skill's networks see the affected objects only


def test_anchoring_needs_the_relation_in_every_segment_and_one_object_each():
    on = [_pick_with(B[0], GroundAtom(ON, (B[0], B[1]))), pick(B[2])]  # not in every segment
    ambiguous = [
        _pick_with(B[0], GroundAtom(ON, (B[0], B[1])), GroundAtom(ON, (B[0], B[3]))),
        _pick_with(B[2], GroundAtom(ON, (B[2], B[4]))),
    ]
    unary = [_pick_with(b, GroundAtom(CLEAR, (B[4],))) for b in (B[0], B[2])]
    for segs in (on, ambiguous, unary):
        (group,) = partition_segments(segs)
        assert anchor_parameters(group) is group


def _mixed(n_common, n_rare):
    return [pick(B[i % 5]) for i in range(n_common)] + [stack(B[0], B[1])] * n_rare


def test_rare_skills_are_dropped_with_the_default_one_percent_threshold():
    datasets = learn_operators(partition_segments(_mixed(200, 1)))
    assert [len(d) for d in datasets] == [200]


def test_the_filtering_threshold_is_configurable():
    groups = partition_segments(_mixed(99, 1))  # 1 of 100 segments: exactly 1%
    assert [len(d) for d in learn_operators(groups)] == [99, 1]
    assert [len(d) for d in learn_operators(groups, min_segment_fraction=0.02)] == [99]
    assert [len(d) for d in learn_operators(partition_segments(_mixed(200, 1)), 0.0)] == [200, 1]


def test_operators_are_indexed_by_decreasing_dataset_size_and_named_after_their_effects():
    datasets = learn_operators(partition_segments(_mixed(3, 5)), 0.0)
    assert [d.operator.name for d in datasets] == ["On", "Holding"]
    assert [d.operator.order_key for d in datasets] == ["Op0", "Op1"]
    assert [len(d) for d in datasets] == [5, 3]
    assert {str(a) for a in datasets[0].operator.add_effects} == {"On(?block0, ?block1)"}
    indexed = learn_operators(partition_segments(_mixed(3, 5)), 0.0, index_names=True)
    assert [d.operator.name for d in indexed] == ["Op0", "Op1"]
    assert [d.operator.sort_name for d in indexed] == ["Op0", "Op1"]
    assert [d.operator for d in indexed] != [d.operator for d in datasets]


def _op(name, adds=(), dels=()):
    from bpns.structs import LiftedAtom, Predicate, STRIPSOperator, Variable

    block = Type("block", ("x",))
    v = Variable("?b", block)
    pred = {n: Predicate(n, (block,), lambda s, o: True) for n in {*adds, *dels}}
    atoms = lambda names: frozenset(LiftedAtom(pred[n], (v,)) for n in names)  # noqa: E731
    return STRIPSOperator(name, (v,), frozenset(), atoms(adds), atoms(dels))


def test_readable_names_break_ties_in_index_order_and_are_pddl_identifiers():
    from bpns.learning.naming import readable_names

    ops = [
        _op("Op0", adds=("Pressed", "Above")),
        _op("Op1", adds=("Holding",)),
        _op("Op2", adds=("Above", "Pressed")),
        _op("Op3", dels=("HandEmpty",)),
        _op("Op4"),
        _op("Op5", adds=("hot water",)),
        _op("Op6", adds=("Above_Pressed_1",)),  # a base name that equals a tie-break
    ]
    names = readable_names(ops)
    assert names == [
        "Above_Pressed_2",
        "Holding",
        "Above_Pressed_3",
        "NotHandEmpty",
        "Noop",
        "hot_water",
        "Above_Pressed_1",
    ]
    assert len(set(names)) == len(names)
    assert all(re.fullmatch(r"[A-Za-z][A-Za-z0-9_-]*", n) for n in names)


def test_applicable_bindings_match_preconditions_and_enumerate_free_parameters():
    segs = [_pick_with(b, GroundAtom(CLEAR, (b,))) for b in (B[0], B[1])]
    (dataset,) = learn_operators(partition_segments(segs))
    op = dataset.operator
    atoms = {GroundAtom(HAND_EMPTY, (R,)), GroundAtom(CLEAR, (B[2],)), GroundAtom(CLEAR, (B[4],))}
    assert applicable_bindings(op, atoms, [R, *B]) == [(B[2], R), (B[4], R)]
    assert applicable_bindings(op, atoms - {GroundAtom(HAND_EMPTY, (R,))}, [R, *B]) == []
    free = op.__class__(op.name, op.parameters, frozenset(), op.add_effects, op.delete_effects)
    assert applicable_bindings(free, set(), [R, B[0], B[1]]) == [(B[0], R), (B[1], R)]


def test_applicable_bindings_use_distinct_objects():
    segs = [stack(B[0], B[1])]
    (dataset,) = learn_operators(partition_segments(segs))
    atoms = {GroundAtom(CLEAR, (B[2],)), GroundAtom(HOLDING, (R, B[2]))}
    bindings = applicable_bindings(dataset.operator, atoms, [R, B[2], B[3]])
    assert bindings == [(B[3], B[2])]
    with pytest.raises(TypeError):
        dataset.operator.ground((B[3], R))
