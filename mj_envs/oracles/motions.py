"""Motion primitives the scripted demonstrators and oracle skills are built from.

Every primitive maps the current state (and a goal) to the next end-effector delta; none
keeps state, so a demonstrator stays a closed-loop policy that a small network can
imitate. The arm lags its command, so the gains are below 1 and descents slow down near
their goal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpns.structs import Object, State

# Proportional gain of every approach law. A law x <- x + k (goal - x) whose command takes
# effect d control steps late is stable only for k < 2 sin(pi / (2 (2d + 1))): 1.0 at
# d = 1 (the arm's own tracking lag), 0.62 at d = 2, 0.45 at d = 3. 0.4 keeps the laws
# stable under 100 ms of latency on top of the arm's lag (the `hard` worlds), and damps
# observation noise (a steady-state jitter of sqrt(k / (2 - k)) = 0.5 of the noise).
GAIN = 0.4
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


# -- pick and place -------------------------------------------------------------------
# Built on the funnel, so each is one continuous law of the state (saturated gripper), the
# form a small MLP imitates. A skill ends the instant its atoms flip: a pick when both
# pads touch (Holding), a place when the pads let go. So a pick first finishes opening
# where it stands (``open_first``) instead of dragging the object just released.

OPEN_FINGERS = 0.035  # finger opening (m) from which the hand may move: clear of a 4.5 cm object


@dataclass(frozen=True)
class Funnel:
    """A funnel's shape (see :func:`funnel_action`): travel height, slope and fade band."""

    safe_z: float = 0.12
    slope: float = 4.0
    band: float = 0.02
    deadzone: float = 0.005


def fingers(state: State, robot: Object) -> float:
    """The finger opening: the fourth robot feature by convention."""
    return float(state.data[robot][3])


def open_first(state: State, robot: Object, action: np.ndarray) -> np.ndarray:
    """Hold the hand still and open while the fingers are narrower than OPEN_FINGERS.

    Used at the start of any skill that may begin with an object between the fingers.
    Edits ``action`` in place and returns it.
    """
    if fingers(state, robot) < OPEN_FINGERS:
        action[:3] = 0.0
        action[3] = 1.0
    return action


def grasp_action(
    state: State, robot: Object, grasp_xyz: np.ndarray, funnel: Funnel, close_tol: float = 0.006
) -> np.ndarray:
    """Go above, descend (funnel) with the fingers open and close once within
    ``close_tol`` of ``grasp_xyz``. The pick is over when both pads touch."""
    near = np.linalg.norm(hand(state, robot) - grasp_xyz) <= close_tol
    action = funnel_action(
        state,
        robot,
        grasp_xyz,
        -1.0 if near else 1.0,
        funnel.safe_z,
        funnel.slope,
        funnel.band,
        funnel.deadzone,
    )
    return action if near else open_first(state, robot, action)


def release_action(
    state: State,
    robot: Object,
    release_xyz: np.ndarray,
    landed: bool,
    funnel: Funnel,
    release_tol: float = 0.006,
) -> np.ndarray:
    """Carry (closed) along the funnel to ``release_xyz``, the hand position that sets the
    object down; once it has ``landed`` with the hand within ``release_tol`` horizontally,
    hold still and open (pushing on would slide the object up the pads)."""
    pos = hand(state, robot)
    if landed and np.hypot(*(release_xyz[:2] - pos[:2])) <= release_tol:
        return move_action(state, robot, np.array([release_xyz[0], release_xyz[1], pos[2]]), 1.0)
    return funnel_action(state, robot, release_xyz, -1.0, funnel.safe_z, funnel.slope, funnel.band)
