"""Skills whose add effects another operator also achieves learn from its segments too."""

from __future__ import annotations

import numpy as np

from bpns.learning.operators import SkillDataset
from bpns.learning.pipeline import learn_skills
from bpns.learning.policies import ScopeDims
from bpns.learning.sharing import effect_scope, embed_effects, shared_data
from bpns.structs import (
    LiftedAtom,
    Object,
    Predicate,
    Segment,
    State,
    STRIPSOperator,
    Type,
    Variable,
)
from tests import toy_learning as toy

BUTTON = Type("button", ("x", "pressed"))
STICK = Type("stick", ("x",))
PRESSED = Predicate("Pressed", (BUTTON,), lambda s, o: True)
ABOVE = Predicate("Above", (STICK, BUTTON), lambda s, o: True)
NOWHERE = Predicate("AboveNone", (), lambda s, o: True)
B0, B1 = Variable("?button0", BUTTON), Variable("?button1", BUTTON)
ROBOT_T, BLOCK_T, TARGET_T = Type("robot", ("x",)), Type("block", ("x",)), Type("target", ("x",))
EMPTY = Predicate("HandEmpty", (ROBOT_T,), lambda s, o: True)
ON_T = Predicate("On", (BLOCK_T, TARGET_T), lambda s, o: True)
S0 = Variable("?stick0", STICK)


def _op(name, params, pre, add, delete):
    return STRIPSOperator(name, params, frozenset(pre), frozenset(add), frozenset(delete))


# press from above no button / from above the button just pressed: one motion, two operators
PRESS_1 = _op(
    "Press1",
    (B0, S0),
    [LiftedAtom(NOWHERE, ())],
    [LiftedAtom(PRESSED, (B0,)), LiftedAtom(ABOVE, (S0, B0))],
    [LiftedAtom(NOWHERE, ())],
)
PRESS_2 = _op(
    "Press2",
    (B0, B1, S0),
    [LiftedAtom(ABOVE, (S0, B1)), LiftedAtom(PRESSED, (B1,))],
    [LiftedAtom(PRESSED, (B0,)), LiftedAtom(ABOVE, (S0, B0))],
    [LiftedAtom(ABOVE, (S0, B1))],
)
# reaches only part of what the presses reach
TOUCH = _op("Touch", (S0, B0), [], [LiftedAtom(ABOVE, (S0, B0))], [])


def test_effect_scope_is_the_parameters_of_the_add_effects_in_order():
    assert effect_scope(PRESS_1) == (0, 1)
    assert effect_scope(PRESS_2) == (0, 2)  # ?button1 is only deleted: not in the scope


def test_variants_with_equal_add_effects_lend_to_each_other():
    assert embed_effects(PRESS_2, PRESS_1) == {B0: B0, S0: S0}
    assert embed_effects(PRESS_1, PRESS_2) == {B0: B0, S0: S0}


def test_a_donor_must_reach_all_of_the_skills_add_effects():
    # every press reaches Above(stick, button): a press may teach Touch ...
    assert embed_effects(TOUCH, PRESS_1) == {S0: S0, B0: B0}
    # ... but a touch never pressed anything, so it teaches no press
    assert embed_effects(PRESS_1, TOUCH) is None


def test_a_donor_may_end_in_an_effect_it_kept_from_its_preconditions():
    # a press from above no button that keeps AboveNone() ends where a skill that
    # *adds* AboveNone() and Pressed must end
    keeps = _op("PressKeeping", (B0,), [LiftedAtom(NOWHERE, ())], [LiftedAtom(PRESSED, (B0,))], [])
    leaves = _op(
        "PressLeaving",
        (B0, S0),
        [LiftedAtom(ABOVE, (S0, B0))],
        [LiftedAtom(PRESSED, (B0,)), LiftedAtom(NOWHERE, ())],
        [LiftedAtom(ABOVE, (S0, B0))],
    )
    assert embed_effects(leaves, keeps) == {B0: B0}
    # ... but a donor must have reached something itself: one that only kept the
    # atoms never moved towards them
    idle = _op("Idle", (B0,), [LiftedAtom(NOWHERE, ()), LiftedAtom(PRESSED, (B0,))], [], [])
    assert embed_effects(leaves, idle) is None
    # a precondition the donor deletes does not hold at its end
    assert embed_effects(TOUCH, PRESS_2) == {S0: S0, B0: B0}  # via its add Above(s, b0)


def test_a_donor_whose_motion_was_about_objects_the_skill_cannot_see_lends_nothing():
    # "let go" (scope: the robot) must not learn from "carry the block onto the target and
    # let go": where that one ended was decided by the target, which "let go" cannot see
    robot, block, target = (
        Variable("?robot0", ROBOT_T),
        Variable("?block0", BLOCK_T),
        Variable("?target0", TARGET_T),
    )
    let_go = _op("LetGo", (robot,), [], [LiftedAtom(EMPTY, (robot,))], [])
    place = _op(
        "Place",
        (block, robot, target),
        [],
        [LiftedAtom(EMPTY, (robot,)), LiftedAtom(ON_T, (block, target))],
        [],
    )
    seg = _segment([[[0.0, 0], [0.0, 0], [0.0]], [[0.0, 0], [0.0, 0], [0.0]]])
    mine = SkillDataset(let_go, (seg,), ((b0,),))
    theirs = SkillDataset(place, (seg,), ((b0, b1, s0),))
    assert embed_effects(let_go, place) is not None  # it does end where LetGo must end ...
    assert shared_data([mine, theirs], 0) is None  # ... but its motion was about the target
    # the other way round the whole motion is visible: Place may learn from nothing here,
    # since LetGo never reached On(block, target)
    assert shared_data([mine, theirs], 1) is None


def _segment(xs: list[float]) -> Segment:
    states = tuple(State({o: np.array(v) for o, v in zip(OBJS, row, strict=True)}) for row in xs)
    return Segment(states, np.zeros((len(xs) - 1, 1)), frozenset(), frozenset())


b0, b1, s0 = Object("b0", BUTTON), Object("b1", BUTTON), Object("s", STICK)
OBJS = (b0, b1, s0)


def test_shared_data_maps_donor_segments_onto_the_skills_effect_scope():
    seg1 = _segment([[[0.5, 0], [0.9, 0], [0.0]], [[0.5, 1], [0.9, 0], [0.5]]])
    seg2 = _segment([[[0.9, 0], [0.5, 1], [0.5]], [[0.9, 1], [0.5, 1], [0.9]]])
    d1 = SkillDataset(PRESS_1, (seg1,), ((b0, s0),))
    d2 = SkillDataset(PRESS_2, (seg2,), ((b0, b1, s0),))
    shared = shared_data([d1, d2], 1)
    assert shared is not None and shared.scope == (0, 2)
    assert shared.segments == (seg2, seg1)  # own first
    assert shared.objects == ((b0, s0), (b0, s0))
    assert shared.donors == (("Press1", 1),)
    assert shared_data([d1], 0) is None  # nobody to learn from: unchanged


def test_scope_dims_with_chosen_objects_select_them_and_round_trip():
    dims = ScopeDims(3, np.array([0, 1]), np.array([1, 2]), objects=(0, 2))
    assert tuple(dims.scope(OBJS)) == (b0, s0)
    back = ScopeDims.from_arrays(dims.to_arrays("dims/"), "dims/")
    assert back.objects == (0, 2) and back.scope_indices(3) == (0, 2)
    plain = ScopeDims(3, np.array([0]), np.array([0]), num_objects=2)
    assert "dims/objects" not in plain.to_arrays("dims/") and plain.scope_indices(3) == (0, 1)


def test_domains_without_shared_effects_learn_bit_identical_skills():
    demos = toy.demos(12, seed=3)
    config = toy.fast_config(0, 200)
    on = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    off = learn_skills(
        demos,
        toy.PREDICATES,
        toy.CONTACT_PREDICATES,
        toy.fast_config(0, 200, share_effect_data=False),
    )
    assert [s.name for s in on.skills] == [s.name for s in off.skills]
    for a, b in zip(on.skills, off.skills, strict=True):
        for key, value in a.policy.to_arrays().items():
            assert np.array_equal(value, b.policy.to_arrays()[key], equal_nan=True)
