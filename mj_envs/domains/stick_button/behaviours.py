"""Stick Button's motion behaviours, shared by the scripted demonstrator and oracle skills.

First every unpressed button within the fingertips' reach is pressed with the closed
fingers (in a random order). If buttons remain, the stick is picked up by its free part, at a
grasp point drawn so that the tip reaches every remaining button with the hand inside
its comfortable reach (grasping nearer the holder reaches further), and each remaining
button is pressed with the tip. A press moves the pusher (fingertips or tip, whose offset
from the hand is re-measured every step) above the cap and lowers it toward a point 11 mm
below the cap's rest top, slowing to 6 mm per step in the last 6 cm, until the joint
reading says Pressed.
"""

from __future__ import annotations

import numpy as np

from bpns.structs import Object, State
from mj_envs.domains.stick_button.rules import (
    CAP_REST_TOP,
    HOLDER_LENGTH,
    ROBOT,
    STICK,
    STICK_LENGTH,
    STICK_WIDTH,
    TIP_INSET,
)
from mj_envs.oracles import motions
from mj_envs.oracles.motions import POS_TOL, at
from mj_envs.oracles.phases import DemonstrationFailed, Phase
from mj_envs.robots.panda import FINGERTIP_DROP

SAFE_Z = 0.15  # hand height for travel: the held stick clears every cap
PRESS_DEPTH = 0.011  # the pusher aims this far below the cap's rest top (latch: 8 mm)
FINGER_REACH = 0.80  # buttons closer than this (xy, from the base) are pressed by hand
HAND_REACH = 0.76  # where the hand may go while pressing with the stick
GRASP_Z_ABOVE_CENTRE = 0.005
GRASP_MIN = HOLDER_LENGTH + 0.018  # grasp offsets from the back end: the free part only
GRASP_MAX = STICK_LENGTH - 0.04
TIP_FROM_BACK = STICK_LENGTH - TIP_INSET
SLOW_ZONE, SLOW_STEP = 0.06, 0.006  # last 6 cm of a descent at <= 6 mm per step
MAX_PRESS_STEPS = 80
MAX_CLOSE_STEPS = 20
EXTRA_CLOSE_STEPS = 3
MAX_PHASE_STEPS = 150


def move_action(state: State, robot: Object, goal_xyz: np.ndarray, grip: float) -> np.ndarray:
    """Proportional step toward ``goal_xyz`` (:func:`mj_envs.oracles.motions.move_action`)."""
    return motions.move_action(state, robot, goal_xyz, grip)


def slow_near(state: State, robot: Object, goal_xyz: np.ndarray, grip: float) -> np.ndarray:
    """Like :func:`move_action`, but at most ``SLOW_STEP`` per step down near the goal."""
    action = move_action(state, robot, goal_xyz, grip)
    height = state.get(robot, "z") - goal_xyz[2]
    return motions.limit_descent(action, height, SLOW_ZONE, SLOW_STEP)


def reachable_by_hand(state: State, button: Object) -> bool:
    return float(np.hypot(state.get(button, "x"), state.get(button, "y"))) <= FINGER_REACH


def pusher(state: State, robot: Object, stick: Object | None) -> np.ndarray:
    """Lowest point that presses: the closed fingertips, or the held stick's tip."""
    if stick is None:
        return state.data[robot][:3] - np.array([0.0, 0.0, FINGERTIP_DROP])
    return np.array(
        [state.get(stick, "tip_x"), state.get(stick, "tip_y"), state.get(stick, "tip_z")]
    )


def hand_goal_for_pusher(
    state: State, robot: Object, stick: Object | None, pusher_goal: np.ndarray
) -> np.ndarray:
    """Hand position that puts the pusher at ``pusher_goal`` (offset measured now)."""
    return state.data[robot][:3] + pusher_goal - pusher(state, robot, stick)


def stick_axis(state: State, stick: Object) -> tuple[np.ndarray, np.ndarray]:
    """(back end xy, unit direction toward the tip) of the stick, from its features."""
    centre = np.array([state.get(stick, "x"), state.get(stick, "y")])
    tip = np.array([state.get(stick, "tip_x"), state.get(stick, "tip_y")])
    axis = (tip - centre) / max(float(np.linalg.norm(tip - centre)), 1e-9)
    return centre - axis * STICK_LENGTH / 2, axis


def grasp_limit_for(state: State, buttons: list[Object]) -> float:
    """Largest grasp offset (from the back end) whose tip reaches every button in ``buttons``.

    With the stick along +x the hand sits ``TIP_FROM_BACK - g`` behind the button; that
    point must lie within ``HAND_REACH`` of the base.
    """
    limit = GRASP_MAX
    for b in buttons:
        bx, by = state.get(b, "x"), state.get(b, "y")
        if abs(by) >= HAND_REACH:
            return -np.inf
        limit = min(limit, TIP_FROM_BACK - bx + float(np.sqrt(HAND_REACH**2 - by**2)))
    return limit


def sample_grasp_offset(state: State, buttons: list[Object], rng: np.random.Generator) -> float:
    hi = grasp_limit_for(state, buttons)
    if hi < GRASP_MIN:
        raise DemonstrationFailed("no grasp on the stick's free part reaches every button")
    return float(rng.uniform(GRASP_MIN, hi))


def grasp_point(state: State, stick: Object, offset: float) -> np.ndarray:
    back, axis = stick_axis(state, stick)
    xy = back + axis * offset
    return np.array([xy[0], xy[1], state.get(stick, "z") + GRASP_Z_ABOVE_CENTRE])


def press_phases(robot: Object, button: Object, stick: Object | None, grip: float) -> list[Phase]:
    """Rise, travel above ``button``, then lower the pusher in one proportional descent
    (slowed near the cap) toward a point below the latch depth until the cap latches.

    One smooth descent rather than "stop above the cap, then push at 3 mm per step": a
    cloned policy learns it well, whereas the stop-then-creep switch taught skills to
    hover a centimetre above the cap."""
    count = {"press": 0}

    def target_xy(s: State) -> np.ndarray:
        return np.array([s.get(button, "x"), s.get(button, "y")])

    def rise(s: State) -> np.ndarray | None:
        goal = np.array([s.get(robot, "x"), s.get(robot, "y"), SAFE_Z])
        return None if at(s, robot, goal, 0.01) else move_action(s, robot, goal, grip)

    def travel(s: State) -> np.ndarray | None:
        goal = hand_goal_for_pusher(s, robot, stick, np.array([*target_xy(s), 0.0]))
        goal[2] = SAFE_Z
        return None if at(s, robot, goal, 2 * POS_TOL) else move_action(s, robot, goal, grip)

    def press(s: State) -> np.ndarray | None:
        if s.get(button, "pressed") > 0.5:
            return None
        count["press"] += 1
        if count["press"] > MAX_PRESS_STEPS:
            raise DemonstrationFailed(f"could not press {button.name}")
        z = CAP_REST_TOP - PRESS_DEPTH
        goal = hand_goal_for_pusher(s, robot, stick, np.array([*target_xy(s), z]))
        return slow_near(s, robot, goal, grip)

    return [rise, travel, press, rise]


def pick_phases(robot: Object, stick: Object, offset: float) -> list[Phase]:
    """Open and rise, go above the grasp point, descend, close until both pads touch, lift."""
    closing = {"steps": 0, "extra": 0}

    def rise(s: State) -> np.ndarray | None:
        goal = np.array([s.get(robot, "x"), s.get(robot, "y"), SAFE_Z])
        return None if at(s, robot, goal, 0.01) else move_action(s, robot, goal, 1.0)

    def travel(s: State) -> np.ndarray | None:
        goal = grasp_point(s, stick, offset)
        goal[2] = SAFE_Z
        return None if at(s, robot, goal, 2 * POS_TOL) else move_action(s, robot, goal, 1.0)

    def descend(s: State) -> np.ndarray | None:
        goal = grasp_point(s, stick, offset)
        if at(s, robot, goal) and s.get(robot, "fingers") > 0.035:
            return None
        return slow_near(s, robot, goal, 1.0)

    def close(s: State) -> np.ndarray | None:
        closing["steps"] += 1
        if closing["steps"] > MAX_CLOSE_STEPS:
            raise DemonstrationFailed(f"could not grasp {stick.name}")
        if s.get(stick, "grasped") > 0.5:
            closing["extra"] += 1
            if closing["extra"] > EXTRA_CLOSE_STEPS:
                return None
        return move_action(s, robot, grasp_point(s, stick, offset), -1.0)

    def lift(s: State) -> np.ndarray | None:
        if s.get(stick, "grasped") < 0.5:
            raise DemonstrationFailed(f"dropped {stick.name}")
        goal = np.array([s.get(robot, "x"), s.get(robot, "y"), SAFE_Z])
        if at(s, robot, goal, 0.01):
            return None
        action = move_action(s, robot, goal, -1.0)
        if s.get(robot, "z") < SAFE_Z / 2:  # ease the stick out of the holder
            action[2] = min(action[2], SLOW_STEP)
        return action

    return [rise, travel, descend, close, lift]


# A stick still in the hand after a pad slipped off it: the hand's grip site lies over
# the stick's footprint, between its top and a little below its centre, and the fingers
# are neither closed past the stick nor opened off it (fingers: per finger, metres). The
# test reads the *observed* state, whose every feature a `hard` world blurs by 5 mm, so
# each band is that much wider than the geometry: closing once over nothing costs a
# back-off less than dropping a stick (and once the pads close on it, `grasped` holds).
IN_HAND_LATERAL = 0.022  # grip site to the stick's centre line, across it (m)
IN_HAND_DZ = (-0.035, 0.040)  # grip site above the stick's centre (m): grasps seen -0.02..+0.02
IN_HAND_FINGERS = (STICK_WIDTH / 2 - 0.009, STICK_WIDTH / 2 + 0.017)


def stick_in_hand(state: State) -> bool:
    """Is a stick between the fingers, though perhaps not touched by both pads?

    What the back-off keeps (:class:`mj_envs.oracles.motions.BackOffToStart` ``holds``):
    under two steps of latency a press can shake one pad off the stick while the hand
    still lifts it; reading ``grasped`` alone, the back-off opened the hand and dropped it.
    """
    (robot,) = state.objects_of_type(ROBOT)
    fingers = state.get(robot, "fingers")
    if not IN_HAND_FINGERS[0] <= fingers <= IN_HAND_FINGERS[1]:
        return False
    hand = np.array([state.get(robot, "x"), state.get(robot, "y")])
    for stick in state.objects_of_type(STICK):
        centre = np.array([state.get(stick, "x"), state.get(stick, "y")])
        axis = np.array([state.get(stick, "tip_x"), state.get(stick, "tip_y")]) - centre
        length = float(np.linalg.norm(axis))
        if length < 1e-9:
            continue
        d = hand - centre
        along = float(d @ axis) / length  # along the stick, from its centre
        across = float(d[0] * axis[1] - d[1] * axis[0]) / length
        dz = state.get(robot, "z") - state.get(stick, "z")
        if (
            abs(along) <= STICK_LENGTH / 2
            and abs(across) <= IN_HAND_LATERAL
            and IN_HAND_DZ[0] <= dz <= IN_HAND_DZ[1]
        ):
            return True
    return False
