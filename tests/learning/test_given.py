"""Given skills (bpns.learning.given): operators are learned for every segment group, and
a group that a declared given skill produces keeps that skill's policy and sampler."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from bpns.learning.artifacts.skills_dir import ArtifactError, load_skills, save_skills
from bpns.learning.given import BoundPolicy, BoundSampler, GivenSkill, binding_for
from bpns.learning.pipeline import learn_skills
from bpns.learning.policies import LearnedPolicy
from bpns.structs import LiftedAtom, STRIPSOperator, Variable
from tests import toy_learning as toy

_R, _B = Variable("?r", toy.ROBOT), Variable("?b", toy.BLOCK)


class _PickPolicy:
    """Move to the block and grasp it (the toy's pick, written by hand)."""

    def __call__(self, state, objects, subgoal):
        block, robot = objects[1], objects[0]
        dx = state.get(block, "x") - state.get(robot, "x")
        return np.array([np.clip(dx, -toy.SPEED, toy.SPEED), 1.0 if abs(dx) < 0.1 else 0.0])


class _NoSubgoal:
    def __call__(self, state, objects, rng):
        return state.vec(objects).copy()


PICK = GivenSkill(
    "Pick",
    STRIPSOperator(
        "Pick",
        (_R, _B),
        frozenset(),
        frozenset({LiftedAtom(toy.HOLDING, (_R, _B))}),
        frozenset({LiftedAtom(toy.HAND_EMPTY, (_R,))}),
    ),
    _PickPolicy(),
    _NoSubgoal(),
)


@pytest.fixture(scope="module")
def learned():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return learn_skills(
            toy.demos(12, seed=3),
            toy.PREDICATES,
            toy.CONTACT_PREDICATES,
            toy.fast_config(0, 300),
            given=(PICK,),
        )
    finally:
        torch.set_num_threads(before)


def test_operators_are_learned_and_the_given_group_keeps_the_given_skill(learned):
    assert len(learned.skills) == 2  # both operators are still learned from the data
    pick = next(
        s for s in learned.skills if any(a.predicate == toy.HOLDING for a in s.operator.add_effects)
    )
    place = next(s for s in learned.skills if s is not pick)
    assert isinstance(pick.policy, BoundPolicy) and pick.policy.given is PICK
    assert isinstance(pick.sampler, BoundSampler)
    assert isinstance(place.policy, LearnedPolicy)  # the rest is trained as before
    # the binding puts the robot first and the block second, whatever the learned order
    params = pick.operator.parameters
    assert [params[i].type for i in pick.policy.binding] == [toy.ROBOT, toy.BLOCK]


def test_the_bound_policy_runs_the_given_policy_on_reordered_objects(learned):
    pick = next(s for s in learned.skills if isinstance(s.policy, BoundPolicy))
    task = toy.sample_task(np.random.default_rng(0))
    state = task.init
    block = state.objects_of_type(toy.BLOCK)[0]
    robot = state.objects_of_type(toy.ROBOT)[0]
    objs = [block if v.type == toy.BLOCK else robot for v in pick.operator.parameters]
    sub = pick.sampler(state, objs, np.random.default_rng(0))
    assert np.array_equal(pick.policy(state, objs, sub), _PickPolicy()(state, [robot, block], sub))


def test_given_skills_save_by_name_and_need_the_environments_skills_to_load(learned, tmp_path):
    path = save_skills(learned, tmp_path / "skills")
    loaded = load_skills(path, toy.PREDICATES, toy.TYPES, given=(PICK,))
    kinds = sorted(type(s.policy).__name__ for s in loaded.skills)
    assert kinds == ["BoundPolicy", "LearnedPolicy"]
    with pytest.raises(ArtifactError, match="given skill 'Pick'"):
        load_skills(path, toy.PREDICATES, toy.TYPES)


def test_a_signature_that_does_not_fit_binds_nothing():
    place_like = STRIPSOperator(
        "X", (_R, _B), frozenset(), frozenset({LiftedAtom(toy.HAND_EMPTY, (_R,))}), frozenset()
    )
    assert binding_for(PICK.signature, place_like) is None
