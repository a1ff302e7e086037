"""Scripted Cover demonstrator: closed-loop on features, acting only through actions.

For each unsatisfied goal atom Covers(b, t) it picks b at a sampled grasp offset and
places it over t (the behaviours are in :mod:`.behaviours`, shared with the oracle skills),
one phase of :class:`mj_envs.oracles.phases.PhasedDemonstrator` per atom.
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
from mj_envs.oracles.phases import DemonstrationFailed, Phase, PhasedDemonstrator


class CoverDemonstrator(PhasedDemonstrator):
    """A stateful closed-loop oracle policy for one task (call it once per step).

    One phase per goal atom Covers(b, t) that does not hold: pick b at a grasp offset
    sampled when the phase is planned, then place it over t; the phase ends when the atom
    holds, and fails after ``2 * MAX_SKILL_STEPS`` actions (a pick and a place).
    """

    max_phase_steps = 2 * MAX_SKILL_STEPS

    def __init__(self, task: Task, rng: np.random.Generator) -> None:
        self.task = task
        self.rng = rng
        self.robot = next(o for o in task.objects if o.type == ROBOT)
        self.goal = sorted(task.goal, key=str)
        self.atom: GroundAtom | None = None  # the atom the current phase achieves
        super().__init__()

    def idle_action(self, state: State) -> np.ndarray:
        return np.zeros(4)

    def plan(self, state: State) -> list[Phase]:
        """A phase for the first goal atom that does not hold (an achieved one may be
        undone later, e.g. by the pads nudging a released block, and is then redone)."""
        self.atom = next((a for a in self.goal if not a.holds(state)), None)
        if self.atom is None:
            return []
        block, target = self.atom.objects
        assert block.type == BLOCK and target.type == TARGET
        offset = sample_grasp_offset(state, block, target, self.rng)
        return [self._cover(self.atom, offset)]

    def phase_failed(self) -> DemonstrationFailed:
        return DemonstrationFailed(f"could not achieve {self.atom}")

    def _cover(self, atom: GroundAtom, grasp_offset: float) -> Phase:
        """Pick the block at ``grasp_offset`` (hand minus block y) until it is grasped,
        then place it where it covers the target; done once ``atom`` holds."""
        block, target = atom.objects
        robot = self.robot

        def phase(state: State) -> np.ndarray | None:
            if atom.holds(state):
                return None
            if state.get(block, "grasped") > 0.5:
                hand_y = release_hand_y(state, robot, block, target)
                return place_action(state, robot, block, hand_y)
            return pick_action(state, robot, block, state.get(block, "y") + grasp_offset)

        return phase
