"""Hand-written ("oracle") Cover skills: operators, subgoal samplers and policies.

They run through exactly the same bilevel planner as learned skills and are the
reference point for planning speed. Subgoals are absolute scope vectors, as for learned
skills: Pick's scope is (robot, block), Place's is (robot, block, target); the policies
read the robot's target position from the subgoal's robot part.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import Object, Skill, State, Variable
from mj_envs.domains.cover.behaviours import (
    PAD_CLEARANCE,
    pick_action,
    place_action,
    release_hand_y,
)
from mj_envs.domains.cover.rules import (
    BLOCK,
    COVERS,
    HAND_EMPTY,
    HOLDING,
    IS_BLOCK,
    IS_TARGET,
    ROBOT,
    TARGET,
)
from mj_envs.oracles.operators import atom, make_operator

_R, _B, _T = Variable("?robot", ROBOT), Variable("?block", BLOCK), Variable("?target", TARGET)
PICK = make_operator(
    "Pick",
    (_R, _B),
    {atom(HAND_EMPTY, _R), atom(IS_BLOCK, _B)},
    {atom(HOLDING, _B)},
    {atom(HAND_EMPTY, _R)},
)
PLACE = make_operator(
    "Place",
    (_R, _B, _T),
    {atom(HOLDING, _B), atom(IS_BLOCK, _B), atom(IS_TARGET, _T)},
    {atom(HAND_EMPTY, _R), atom(COVERS, _B, _T)},
    {atom(HOLDING, _B)},
)


class PickPolicy:
    """The demonstrator's pick behaviour toward the grasp y in the subgoal's robot part."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, block = objects
        return pick_action(state, robot, block, float(subgoal[1]))


class PickSampler:
    """Grasp anywhere along the block's width (the pads fully on it)."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        robot, block = objects
        sub = state.vec(objects).copy()
        lim = state.get(block, "width") / 2 - PAD_CLEARANCE
        sub[1] = state.get(block, "y") + rng.uniform(-lim, lim)  # robot y
        return sub


class PlacePolicy:
    """The demonstrator's place behaviour toward the release y in the subgoal."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, block, _ = objects
        return place_action(state, robot, block, float(subgoal[1]))


class PlaceSampler:
    """Release with the hand inside the target's region so the held block covers it."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        robot, block, target = objects
        sub = state.vec(objects).copy()
        sub[1] = release_hand_y(state, robot, block, target) + rng.uniform(-0.002, 0.002)
        return sub


def oracle_skills() -> list[Skill]:
    return [Skill(PICK, PickPolicy(), PickSampler()), Skill(PLACE, PlacePolicy(), PlaceSampler())]
