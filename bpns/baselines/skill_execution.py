"""Execute one ground skill for one subgoal in the exact simulator.

TO BE REPLACED BY THE SHARED SKILL ROLLOUT: this is a minimal local stand-in for the
rollout that ``bpns.planning.refinement._Rollout.sample`` implements and that the
architecture work makes public. It keeps the same success test (every expected atom
holds and no deleted atom does, checked after every step) and the same failure reasons
(strings from ``bpns.planning.refinement``), but not the refinement's extras (contact-
change ending, nogood memo). Swap :func:`execute_skill` for the shared rollout at merge.
"""

from __future__ import annotations

import time
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from bpns.environment import Environment
from bpns.planning.refinement import (
    POLICY_ERROR,
    POLICY_NONFINITE,
    SKILL_HORIZON,
    STUCK,
    TASK_HORIZON,
    TIMEOUT,
)
from bpns.structs import GroundAtom, GroundOperator, Skill, State


@dataclass(frozen=True)
class RolloutLimits:
    """max_skill_horizon, stuck_steps and stuck_atol as in ``PlanningConfig``."""

    max_skill_horizon: int = 200
    stuck_steps: int = 10
    stuck_atol: float = 1e-3


@dataclass(frozen=True, eq=False)
class SkillRun:
    """``states`` are the states after each of ``actions``; ``reason`` is None on success."""

    success: bool
    actions: tuple[np.ndarray, ...]
    states: tuple[State, ...]
    reason: str | None


def _flat(state: State) -> np.ndarray:
    return np.concatenate([state.data[o] for o in state.objects]) if state.data else np.zeros(0)


def execute_skill(
    env: Environment,
    skill: Skill,
    ground: GroundOperator,
    subgoal: np.ndarray,
    state: State,
    must_hold: Collection[GroundAtom],
    must_not_hold: Collection[GroundAtom],
    steps_left: int,
    deadline: float | None,
    limits: RolloutLimits,
) -> SkillRun:
    """Roll ``skill``'s policy out from ``state`` towards ``subgoal`` until the atoms
    test passes (success) or the skill horizon, the task's remaining ``steps_left``,
    the deadline (``time.monotonic()``) or a stuck world ends it."""
    low = np.asarray(env.action_low, dtype=np.float64)
    high = np.asarray(env.action_high, dtype=np.float64)
    hold = [(a.predicate.classifier, a.objects) for a in must_hold]
    hold_not = [(a.predicate.classifier, a.objects) for a in must_not_hold]
    limit = limits.max_skill_horizon
    if skill.horizon is not None:
        limit = min(limit, skill.horizon)
    actions: list[np.ndarray] = []
    states: list[State] = []
    anchor, unchanged = _flat(state), 0

    def fail(reason: str) -> SkillRun:
        return SkillRun(False, tuple(actions), tuple(states), reason)

    for t in range(limit):
        if deadline is not None and time.monotonic() >= deadline:
            return fail(TIMEOUT)
        if t >= steps_left:
            return fail(TASK_HORIZON)
        try:
            action = np.asarray(skill.policy(state, ground.objects, subgoal), dtype=np.float64)
        except Exception:  # a learned network must never crash solving  # noqa: BLE001
            return fail(POLICY_ERROR)
        if action.shape != low.shape:
            return fail(POLICY_ERROR)
        if not np.isfinite(action).all():
            return fail(POLICY_NONFINITE)
        action = np.minimum(np.maximum(action, low), high)
        state = env.simulate(state, action)
        actions.append(action)
        states.append(state)
        if all(c(state, o) for c, o in hold) and not any(c(state, o) for c, o in hold_not):
            return SkillRun(True, tuple(actions), tuple(states), None)
        flat = _flat(state)
        if flat.shape == anchor.shape and np.max(np.abs(flat - anchor), initial=0.0) <= (
            limits.stuck_atol
        ):
            unchanged += 1
            if unchanged >= limits.stuck_steps:
                return fail(STUCK)
        else:
            anchor, unchanged = flat, 0
    return fail(SKILL_HORIZON)
