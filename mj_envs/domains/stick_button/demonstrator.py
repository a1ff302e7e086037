"""Scripted Stick Button demonstrator: closed-loop on features, acting only through actions.

Buttons within the fingertips' reach are pressed by hand in a random order; if buttons
remain, the stick is picked at a grasp point from which its tip reaches all of them, and
each is pressed with the tip (behaviours in :mod:`.behaviours`, shared with the oracle
skills).
"""

from __future__ import annotations

import numpy as np

from bpns.structs import State, Task
from mj_envs.domains.stick_button.behaviours import (
    MAX_PHASE_STEPS,
    pick_phases,
    press_phases,
    reachable_by_hand,
    sample_grasp_offset,
)
from mj_envs.domains.stick_button.rules import BUTTON, ROBOT, STICK
from mj_envs.oracles.phases import DemonstrationFailed, Phase, PhasedDemonstrator


class StickButtonDemonstrator(PhasedDemonstrator):
    """A stateful closed-loop oracle policy for one task (call it once per step)."""

    max_phase_steps = MAX_PHASE_STEPS

    def __init__(self, task: Task, rng: np.random.Generator) -> None:
        self.task = task
        self.rng = rng
        self.robot = next(o for o in task.objects if o.type == ROBOT)
        self.stick = next(o for o in task.objects if o.type == STICK)
        self.buttons = [o for o in task.objects if o.type == BUTTON]
        super().__init__()
        self._holding = False

    def idle_action(self, state: State) -> np.ndarray:
        return np.array([0.0, 0.0, 0.0, -1.0 if self._holding else 0.0])

    def plan(self, state: State) -> list[Phase]:
        """Phases for the next button (or for picking the stick first)."""
        todo = [b for b in self.buttons if state.get(b, "pressed") < 0.5]
        if not todo:
            return []
        # Buttons in a random order, not nearest first: the planner tries every order, and
        # skills learned from one systematic order fail on the others.
        if not self._holding:
            by_hand = [b for b in todo if reachable_by_hand(state, b)]
            if by_hand:
                b = by_hand[int(self.rng.integers(len(by_hand)))]
                return press_phases(self.robot, b, None, grip=-1.0)
            offset = sample_grasp_offset(state, todo, self.rng)
            self._holding = True
            return pick_phases(self.robot, self.stick, offset)
        if state.get(self.stick, "grasped") < 0.5:
            raise DemonstrationFailed(f"lost {self.stick.name}")
        b = todo[int(self.rng.integers(len(todo)))]
        return press_phases(self.robot, b, self.stick, grip=-1.0)
