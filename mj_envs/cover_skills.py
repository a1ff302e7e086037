"""Hand-written ("oracle") Cover skills: operators, subgoal samplers and policies.

They run through exactly the same bilevel planner as learned skills and are the
reference point for planning speed. Subgoals are absolute scope vectors, as for learned
skills: Pick's scope is (robot, block), Place's is (robot, block, target); the policies
read the robot's target position from the subgoal's robot part.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import LiftedAtom, Object, Skill, State, STRIPSOperator, Variable
from mj_envs.cover import (
    BLOCK,
    COVERS,
    HAND_EMPTY,
    HOLDING,
    IS_BLOCK,
    IS_TARGET,
    LINE_X,
    ROBOT,
    TARGET,
)
from mj_envs.cover_oracle import (
    GAIN,
    GRASP_Z_ABOVE_CENTRE,
    PAD_CLEARANCE,
    POS_TOL,
    SAFE_Z,
    release_hand_y,
)

_R, _B, _T = Variable("?robot", ROBOT), Variable("?block", BLOCK), Variable("?target", TARGET)
PICK = STRIPSOperator(
    "Pick",
    (_R, _B),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,)), LiftedAtom(IS_BLOCK, (_B,))}),
    frozenset({LiftedAtom(HOLDING, (_B,))}),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,))}),
)
PLACE = STRIPSOperator(
    "Place",
    (_R, _B, _T),
    frozenset(
        {LiftedAtom(HOLDING, (_B,)), LiftedAtom(IS_BLOCK, (_B,)), LiftedAtom(IS_TARGET, (_T,))}
    ),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,)), LiftedAtom(COVERS, (_B, _T))}),
    frozenset({LiftedAtom(HOLDING, (_B,))}),
)


def _toward(state: State, robot: Object, goal: np.ndarray, grip: float) -> np.ndarray:
    return np.array([*(GAIN * (goal - state.data[robot][:3])), grip])


def _travel(state: State, robot: Object, xy: np.ndarray, grip: float) -> np.ndarray | None:
    """Rise to the safe height, then move in xy; None once above ``xy``."""
    pos = state.data[robot][:3]
    if np.all(np.abs(pos[:2] - xy) <= 2 * POS_TOL):
        return None
    if pos[2] < SAFE_Z - 0.01 and np.any(np.abs(pos[:2] - xy) > 0.01):
        return _toward(state, robot, np.array([pos[0], pos[1], SAFE_Z]), grip)
    return _toward(state, robot, np.array([xy[0], xy[1], SAFE_Z]), grip)


class PickPolicy:
    """Go above the grasp point in the subgoal, descend, close."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, block = objects
        grasp = np.array(
            [
                state.get(block, "x"),
                subgoal[1],
                state.get(block, "height") / 2 + GRASP_Z_ABOVE_CENTRE,
            ]
        )
        move = _travel(state, robot, grasp[:2], grip=1.0)
        if move is not None and state.get(robot, "fingers") > 0.03:
            return move
        if state.get(robot, "z") > grasp[2] + POS_TOL and state.get(robot, "fingers") > 0.03:
            return _toward(state, robot, grasp, grip=1.0)
        return _toward(state, robot, grasp, grip=-1.0)


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
    """Carry to the release point in the subgoal, lower until the block lands, open."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, block, _ = objects
        release = np.array([LINE_X, subgoal[1]])
        if state.get(block, "on_table") > 0.5 and state.get(robot, "z") < SAFE_Z - 0.04:
            pos = state.data[robot][:3]
            return _toward(state, robot, np.array([*release, pos[2] + 0.004]), grip=1.0)
        move = _travel(state, robot, release, grip=-1.0)
        if move is not None:
            return move
        drop = state.get(block, "z") - state.get(block, "height") / 2 + 0.001
        return _toward(state, robot, np.array([*release, state.get(robot, "z") - drop]), -1.0)


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
