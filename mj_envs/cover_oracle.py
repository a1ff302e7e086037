"""Scripted Cover demonstrator: closed-loop on features, acting only through actions.

For each unsatisfied goal atom Covers(b, t): choose a grasp offset along the block that
leaves room to release over the target inside its allowed region, move above the grasp
point, descend, close until both pads touch, lift, carry so that the *measured* offset
puts the block over the target while the hand stays in the target's region, lower until
the block touches the table, open, lift.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bpns.structs import GroundAtom, Object, State, Task
from mj_envs.cover import BLOCK, LINE_X, ROBOT, TARGET, TARGET_REGION_HALF

SAFE_Z = 0.12
GAIN = 0.7
GRASP_Z_ABOVE_CENTRE = 0.006  # keeps the fingertips off the table
MAX_CLOSE_STEPS = 20
RELEASE_LIFT = 0.004
POS_TOL = 0.003
REGION_MARGIN = 0.005
COVER_MARGIN = 0.004
PAD_CLEARANCE = 0.014  # keep both pads fully on the block
EXTRA_CLOSE_STEPS = 3


def move_action(state: State, robot: Object, goal_xyz: np.ndarray, grip: float = 0.0) -> np.ndarray:
    """Proportional step toward ``goal_xyz``; the gain < 1 absorbs the arm's tracking lag."""
    pos = state.data[robot][:3]
    return np.array([*(GAIN * (goal_xyz - pos)), grip])


def at(state: State, robot: Object, goal_xyz: np.ndarray, tol: float = POS_TOL) -> bool:
    return bool(np.all(np.abs(state.data[robot][:3] - goal_xyz) <= tol))


def sample_grasp_offset(
    state: State, block: Object, target: Object, rng: np.random.Generator
) -> float:
    """A hand-minus-block y offset from which a release in the target region covers it."""
    bw = state.get(block, "width")
    tw = state.get(target, "width")
    slack = (bw - tw) / 2 - COVER_MARGIN
    reach = TARGET_REGION_HALF - REGION_MARGIN + slack
    lim = min(reach, bw / 2 - PAD_CLEARANCE)
    return float(rng.uniform(-lim, lim))


def release_hand_y(state: State, robot: Object, block: Object, target: Object) -> float:
    """Hand y that covers the target with the block's measured offset, within the region."""
    offset = state.get(robot, "y") - state.get(block, "y")
    r = TARGET_REGION_HALF - REGION_MARGIN
    return state.get(target, "y") + float(np.clip(offset, -r, r))


class DemonstrationFailed(RuntimeError):
    """The scripted demonstrator could not carry on (reported, never silent)."""


class CoverDemonstrator:
    """A stateful closed-loop oracle policy for one task (call it once per step)."""

    def __init__(self, task: Task, rng: np.random.Generator) -> None:
        self.task = task
        self.rng = rng
        self.robot = next(o for o in task.objects if o.type == ROBOT)
        self.pending = sorted(task.goal, key=str)
        self._phases: list[Callable[[State], np.ndarray | None]] = []

    def __call__(self, state: State) -> np.ndarray:
        while True:
            if not self._phases:
                atom = self._next_atom(state)
                if atom is None:
                    return np.zeros(4)
                self._phases = self._plan_atom(state, atom)
            action = self._phases[0](state)
            if action is not None:
                return action
            self._phases.pop(0)

    def _next_atom(self, state: State) -> GroundAtom | None:
        while self.pending:
            atom = self.pending.pop(0)
            if not atom.holds(state):
                return atom
        return None

    def _plan_atom(
        self, state: State, atom: GroundAtom
    ) -> list[Callable[[State], np.ndarray | None]]:
        block, target = atom.objects
        assert block.type == BLOCK and target.type == TARGET
        robot = self.robot
        offset = sample_grasp_offset(state, block, target, self.rng)
        grasp_y = state.get(block, "y") + offset
        bx = state.get(block, "x")
        grasp_z = state.get(block, "height") / 2 + GRASP_Z_ABOVE_CENTRE
        above_grasp = np.array([bx, grasp_y, SAFE_Z])
        grasp_point = np.array([bx, grasp_y, grasp_z])
        closing = {"extra": 0, "steps": 0}

        def lift(s: State) -> np.ndarray | None:
            goal = np.array([s.get(robot, "x"), s.get(robot, "y"), SAFE_Z])
            return None if at(s, robot, goal, 0.01) else move_action(s, robot, goal)

        def go(goal: np.ndarray, grip: float = 0.0) -> Callable[[State], np.ndarray | None]:
            return lambda s: None if at(s, robot, goal) else move_action(s, robot, goal, grip)

        def close(s: State) -> np.ndarray | None:
            closing["steps"] += 1
            if closing["steps"] > MAX_CLOSE_STEPS:
                raise DemonstrationFailed(f"could not grasp {block.name}")
            if s.get(block, "grasped") > 0.5:
                closing["extra"] += 1
                if closing["extra"] > EXTRA_CLOSE_STEPS:
                    return None
            # keep correcting toward the grasp point while the fingers close
            return move_action(s, robot, grasp_point, grip=-1.0)

        def carry(s: State) -> np.ndarray | None:
            goal = np.array([LINE_X, release_hand_y(s, robot, block, target), SAFE_Z])
            return go(goal)(s)

        def lower(s: State) -> np.ndarray | None:
            if s.get(block, "on_table") > 0.5:
                closing["release"] = np.array(
                    [
                        LINE_X,
                        release_hand_y(s, robot, block, target),
                        s.get(robot, "z") + RELEASE_LIFT,
                    ]
                )
                return None
            # hand height that puts the block's bottom 1 mm into the table
            drop = s.get(block, "z") - s.get(block, "height") / 2 + 0.001
            goal = np.array(
                [LINE_X, release_hand_y(s, robot, block, target), s.get(robot, "z") - drop]
            )
            return move_action(s, robot, goal)

        def open_(s: State) -> np.ndarray | None:
            if s.get(block, "grasped") < 0.5 and s.get(robot, "fingers") > 0.035:
                return None
            # hold the hand just above where the block touched down: the commanded pose
            # leads the measured one, and pushing on would slide the block up the pads
            return move_action(s, robot, closing["release"], grip=1.0)

        return [lift, go(above_grasp), go(grasp_point), close, lift, carry, lower, open_, lift]


def demonstrator(task: Task, rng: np.random.Generator) -> CoverDemonstrator:
    return CoverDemonstrator(task, rng)
