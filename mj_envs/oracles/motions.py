"""Motion primitives the scripted demonstrators and oracle skills are built from.

Every primitive maps the current state (and a goal) to the next end-effector delta; none
keeps state, so a demonstrator stays a closed-loop policy that a small network can
imitate. The arm lags its command, so the gains are below 1 and descents slow down near
their goal.
"""

from __future__ import annotations

import numpy as np

from bpns.structs import Object, State

GAIN = 0.7  # proportional gain < 1 absorbs the arm's tracking lag
POS_TOL = 0.003  # "at a point": every axis within 3 mm


def hand(state: State, robot: Object) -> np.ndarray:
    """The grip site's (x, y, z): the first three robot features by convention."""
    return state.data[robot][:3]


def move_action(state: State, robot: Object, goal_xyz: np.ndarray, grip: float = 0.0) -> np.ndarray:
    """Proportional step toward ``goal_xyz`` with a finger command: (dx, dy, dz, grip)."""
    return np.array([*(GAIN * (goal_xyz - hand(state, robot))), grip])


def at(state: State, robot: Object, goal_xyz: np.ndarray, tol: float = POS_TOL) -> bool:
    return bool(np.all(np.abs(hand(state, robot) - goal_xyz) <= tol))


def limit_descent(
    action: np.ndarray, height_above_goal: float, slow_zone: float, slow_step: float
) -> np.ndarray:
    """Within ``slow_zone`` above the goal, descend at most ``slow_step`` per step.

    A full-speed descent overshoots by several millimetres (the arm lags its command):
    enough to put the fingertips on the table. Edits ``action`` in place and returns it.
    """
    if height_above_goal < slow_zone:
        action[2] = max(action[2], -slow_step)
    return action


def funnel_action(
    state: State,
    robot: Object,
    goal_xyz: np.ndarray,
    grip: float,
    safe_z: float,
    slope: float,
    band: float,
    deadzone: float = 0.0,
) -> np.ndarray:
    """Step toward ``goal_xyz`` along a funnel: rise, travel and descend in one motion.

    The hand must be at least ``goal_z + min(safe_z - goal_z, slope * d)`` high, where d is
    the horizontal distance to the goal (less ``deadzone``, inside which the funnel is
    flat), and it moves sideways only as far as that height is reached (fading in over
    ``band``). No phase switches: a continuous function of the state, easy to imitate.
    """
    pos = hand(state, robot)
    d = max(0.0, float(np.hypot(*(goal_xyz[:2] - pos[:2]))) - deadzone)
    z_req = goal_xyz[2] + min(max(safe_z - goal_xyz[2], 0.0), slope * d)
    sideways = float(np.clip(1.0 - (z_req - pos[2]) / band, 0.0, 1.0))
    return np.array(
        [
            GAIN * (goal_xyz[0] - pos[0]) * sideways,
            GAIN * (goal_xyz[1] - pos[1]) * sideways,
            GAIN * (z_req - pos[2]),
            grip,
        ]
    )
