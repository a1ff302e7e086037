"""Scripted Cover demonstrator: closed-loop on features, acting only through actions.

For each unsatisfied goal atom Covers(b, t) it picks b at a sampled grasp offset and
places it over t (the behaviours are in :mod:`.behaviours`, shared with the oracle skills).
"""

from __future__ import annotations

import numpy as np

from bpns.structs import GroundAtom, State, Task
from mj_envs.domains.cover.behaviours import (
    MAX_SKILL_STEPS,
    pick_action,
    place_action,
    release_hand_y,
    sample_grasp_offset,
)
from mj_envs.domains.cover.rules import BLOCK, ROBOT, TARGET
from mj_envs.oracles.phases import DemonstrationFailed


class CoverDemonstrator:
    """A stateful closed-loop oracle policy for one task (call it once per step).

    State kept between calls: the goal atom being achieved and, for it,
    the sampled grasp offset and a step budget.
    """

    def __init__(self, task: Task, rng: np.random.Generator) -> None:
        self.task = task
        self.rng = rng
        self.robot = next(o for o in task.objects if o.type == ROBOT)
        self.goal = sorted(task.goal, key=str)
        self.atom: GroundAtom | None = None
        self.grasp_offset = 0.0
        self.steps = 0

    def __call__(self, state: State) -> np.ndarray:
        if self.atom is None or self.atom.holds(state):
            self.atom = self._next_atom(state)
            if self.atom is None:
                return np.zeros(4)
            block, target = self.atom.objects
            assert block.type == BLOCK and target.type == TARGET
            self.grasp_offset = sample_grasp_offset(state, block, target, self.rng)
            self.steps = 0
        self.steps += 1
        if self.steps > 2 * MAX_SKILL_STEPS:
            raise DemonstrationFailed(f"could not achieve {self.atom}")
        block, target = self.atom.objects
        robot = self.robot
        if state.get(block, "grasped") > 0.5:
            action = place_action(state, robot, block, release_hand_y(state, robot, block, target))
        else:
            hand_y = state.get(block, "y") + self.grasp_offset
            action = pick_action(state, robot, block, hand_y)
        return action

    def _next_atom(self, state: State) -> GroundAtom | None:
        """The first goal atom that does not hold (an achieved one may be undone later,
        e.g. by the pads nudging a released block, and is then redone)."""
        return next((a for a in self.goal if not a.holds(state)), None)
