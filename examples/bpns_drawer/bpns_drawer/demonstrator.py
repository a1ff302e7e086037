"""Drawer's scripted demonstrator: the oracle skills' own policies, one phase each.

The plan is always the same six steps: grasp the handle, pull the drawer open (letting go
at the end), pick the cube, place it in the drawer, grasp the handle again, push the
drawer closed. Each phase samples its skill's subgoal from the state it starts in (a
random grasp point along the handle, a random spot in the drawer) and runs the skill's
policy until the operator's add effects hold, so the segments a demonstration is cut
into are exactly the skills' behaviours. ``mj_envs.oracles.phases.PhasedDemonstrator``
bounds every phase and names the one that stalls.
"""

from __future__ import annotations

import numpy as np

from bpns.structs import GroundOperator, Object, State, Task
from bpns_drawer.rules import CUBE, DRAWER, ROBOT
from bpns_drawer.skills import CLOSE, GRASP_HANDLE, OPEN, PICK, PLACE, SKILLS
from mj_envs.oracles.phases import Phase, PhasedDemonstrator


class DrawerDemonstrator(PhasedDemonstrator):
    """A closed-loop oracle policy for one task: call it once per step."""

    def __init__(self, task: Task, rng: np.random.Generator) -> None:
        super().__init__()
        self.rng = rng
        self.robot, self.drawer, self.cube = (
            next(o for o in task.objects if o.type == t) for t in (ROBOT, DRAWER, CUBE)
        )
        self.done = False

    def plan(self, state: State) -> list[Phase]:
        if self.done:
            return []
        self.done = True
        r, d, c = self.robot, self.drawer, self.cube
        steps = [
            GRASP_HANDLE.ground((r, d)),
            OPEN.ground((r, d)),
            PICK.ground((r, c)),
            PLACE.ground((r, c, d)),
            GRASP_HANDLE.ground((r, d)),
            CLOSE.ground((r, d)),
        ]
        return [self._phase(step) for step in steps]

    def idle_action(self, state: State) -> np.ndarray:
        return np.zeros(4)

    def _phase(self, step: GroundOperator) -> Phase:
        """Run ``step``'s skill with a subgoal sampled when the phase starts, until the
        step's add effects hold."""
        policy, sampler = SKILLS[step.operator]
        objects: tuple[Object, ...] = step.objects
        subgoal: list[np.ndarray] = []

        def phase(state: State) -> np.ndarray | None:
            if all(atom.holds(state) for atom in step.add_effects):
                return None
            if not subgoal:
                subgoal.append(sampler(state, objects, self.rng))
            return policy(state, objects, subgoal[0])

        phase.__qualname__ = str(step)  # what a stalled phase's error names
        return phase
