"""Scripted Coffee demonstrator: closed-loop on features, acting only through actions.

Twist the pot by its knob if its handle faces away, pick it by the handle, put it on the
plate, press the plate's switch, pick it again once hot, and pour into every cup in a
random order (behaviours in :mod:`.behaviours`, shared with the oracle skills).
"""

from __future__ import annotations

import numpy as np

from bpns.structs import State, Task
from mj_envs.domains.coffee.behaviours import (
    MAX_PHASE_STEPS,
    TWIST_TARGET,
    needs_twist,
    pick_phases,
    place_phases,
    pour_phases,
    press_phases,
    twist_phases,
)
from mj_envs.domains.coffee.rules import CUP, PLATE, POT, ROBOT
from mj_envs.oracles.phases import DemonstrationFailed, Phase, PhasedDemonstrator


class CoffeeDemonstrator(PhasedDemonstrator):
    """A stateful closed-loop oracle policy for one task (call it once per step)."""

    max_phase_steps = MAX_PHASE_STEPS

    def __init__(self, task: Task, rng: np.random.Generator) -> None:
        self.task = task
        self.rng = rng
        objs = task.init.objects
        self.robot = next(o for o in objs if o.type == ROBOT)
        self.pot = next(o for o in objs if o.type == POT)
        self.plate = next(o for o in objs if o.type == PLATE)
        self.cups = [o for o in objs if o.type == CUP]
        super().__init__()
        self._stage = "start"

    def idle_action(self, state: State) -> np.ndarray:
        return np.zeros(6)

    # -- stages ---------------------------------------------------------------------
    def plan(self, s: State) -> list[Phase]:
        r, p = self.robot, self.pot
        if s.get(p, "spilled") > 0.5:
            raise DemonstrationFailed("spilled")
        if self._stage == "start":
            self._stage = "picked"
            phases: list[Phase] = []
            if needs_twist(s, p):
                side = float(np.sign(s.get(p, "rotation")))
                target = side * float(self.rng.uniform(*TWIST_TARGET))
                phases += twist_phases(r, p, target)
            return phases + pick_phases(r, p)
        if self._stage == "picked":
            self._stage = "placed"
            return place_phases(r, p, self.plate)
        if self._stage == "placed":
            self._stage = "pressed"
            return press_phases(r, self.plate)
        if self._stage == "pressed":
            self._stage = "pouring"
            return pick_phases(r, p, wait_hot=True)
        todo = [c for c in self.cups if s.get(c, "liquid") < s.get(c, "target")]
        if not todo:
            return []
        if s.get(p, "held") < 0.5:
            raise DemonstrationFailed("lost the pot")
        # A random order, not nearest first: the planner tries cups in every order, and
        # skills learned from one systematic order fail on the others (out of distribution).
        cup = todo[int(self.rng.integers(len(todo)))]
        return pour_phases(r, p, cup)
