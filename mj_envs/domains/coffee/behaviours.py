"""Coffee's motion behaviours, shared by the scripted demonstrator and the oracle skills.

If the handle faces away from the robot by more than ``TWIST_ABOVE`` (50 deg, inside the
60 deg rule), the pot is first twisted: the knob is grasped from above with the wrist
aligned to its faces, the wrist turns until the pot's rotation reaches a drawn target
20-45 deg on the side it was turned to, and the knob is let go. Then the pot is picked by
the handle (wrist turned by the pot's rotation, fingers in the handle's finger slot), put
on the hot plate and let go, the closed fingertips press the plate's button, and the pot
is picked again and held until hot. The cups are filled in a random order (a systematic
one, e.g. nearest first, teaches skills only that order, and the planner tries all): the
measured spout tip is brought over the cup high enough for the hanging pot to clear every
cup nearby, the pot is tilted past the pouring angle while the hand keeps the tip over the
cup (and rises as the tip dips), and it is tilted back as soon as the cup holds its
target. With the pot in the hand, steps are shortened so it does not swing in the grasp.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bpns.structs import Object, State
from mj_envs.domains.coffee.rules import (
    CUP,
    FINGERTIP_DROP,
    GRIP_FROM_AXIS,
    HANDLE_Z,
    KNOB_HALF_HEIGHT,
    KNOB_Z,
    PLATE_TOP,
    POT,
    POUR_TILT,
    WRIST_LIMITS,
)
from mj_envs.oracles import motions
from mj_envs.oracles.motions import GAIN, POS_TOL, at, hand
from mj_envs.oracles.phases import DemonstrationFailed, Phase

SAFE_Z = 0.25  # hand height for travel with the pot: it clears every cup
FREE_Z = 0.22  # hand height for travel without the pot: the fingertips clear the knob
TURN_GAIN, ANGLE_TOL = GAIN, 0.03  # wrist and tilt laws: the same stability bound
CARRY_STEP = 0.012  # metres per step, per axis, with the pot in the hand
SUPPORT_SNAP = 0.01
KNOB_GRIP_BELOW_TOP = 0.009  # fingertips 9 mm above the lid
TWIST_ABOVE = np.deg2rad(50.0)
TWIST_TARGET = (np.deg2rad(20.0), np.deg2rad(45.0))  # on the side the pot is turned to;
# far enough from 0 that the turn, plus the ~25 % the knob slips in the fingers, ends
# >= 10 deg inside the wrist's limit
TWIST_TOL = np.deg2rad(3.0)
TWIST_TURN, MAX_KNOB_MISSES = 0.07, 5  # rad per step turning the knob
APPROACH_CLEARANCE, PRESS_SPEED = 0.008, 0.003
SLOW_ZONE, SLOW_STEP = 0.05, 0.006
BACK_OFF = 0.04  # after letting go, rise this far at SLOW_STEP
POUR_ABOVE_RIM = 0.025  # least spout tip height above the rim while pouring
UPRIGHT_CLEARANCE, CLEARANCE_SLOPE = 0.105, 0.12  # see spout_clearance
NEIGHBOUR_RANGE, NEIGHBOUR_CLEARANCE = 0.2, 0.012  # see spout_height
POUR_TILT_GOAL = POUR_TILT + 0.12
POUR_TURN = 0.05  # rad per step while pouring: the hand keeps up with the dipping spout
UNTILT_TURN = 0.06  # back up briskly: the flow stops within a few steps
MAX_CLOSE_STEPS, EXTRA_CLOSE_STEPS = 25, 3
PART_OF_FLAG = {"held": "handle", "twisted": "knob"}  # the pot feature a grasp sets
MAX_PHASE_STEPS = 200


def wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def move_action(
    state: State,
    robot: Object,
    goal: np.ndarray,
    grip: float,
    wrist: float | None = None,
    tilt: float = 0.0,
) -> np.ndarray:
    """Proportional step toward a hand position and (wrist, tilt); None keeps the wrist.

    With the pot in the hand, steps are shorter (``CARRY_STEP``) so it does not swing.
    """
    dpos = GAIN * (goal - hand(state, robot))
    if any(state.get(p, "held") > 0.5 for p in state.objects_of_type(POT)):
        dpos = np.clip(dpos, -CARRY_STEP, CARRY_STEP)
    dtilt = TURN_GAIN * (tilt - state.get(robot, "tilt"))
    dwrist = 0.0 if wrist is None else TURN_GAIN * (wrist - state.get(robot, "wrist"))
    return np.array([*dpos, dtilt, dwrist, grip])


def slow_near(state: State, robot: Object, goal: np.ndarray, grip: float, **kw) -> np.ndarray:
    """Like :func:`move_action`, but at most ``SLOW_STEP`` per step down near the goal."""
    action = move_action(state, robot, goal, grip, **kw)
    return motions.limit_descent(action, hand(state, robot)[2] - goal[2], SLOW_ZONE, SLOW_STEP)


def turned(state: State, robot: Object, wrist: float | None, tilt: float = 0.0) -> bool:
    ok = abs(state.get(robot, "tilt") - tilt) <= ANGLE_TOL
    return ok and (wrist is None or abs(state.get(robot, "wrist") - wrist) <= ANGLE_TOL)


def pot_xy(state: State, pot: Object) -> np.ndarray:
    return np.array([state.get(pot, "x"), state.get(pot, "y")])


def base_z(state: State, pot: Object) -> float:
    """Height of the pot's base, snapped to its support (table or plate) within 1 cm: a
    hand aiming at the measured height would chase a pot its fingers lift a little."""
    z = state.get(pot, "z")
    for support in (0.0, PLATE_TOP):
        if abs(z - support) < SUPPORT_SNAP:
            return support
    return z


def handle_grasp(state: State, pot: Object, along: float = GRIP_FROM_AXIS) -> np.ndarray:
    """Hand position that grasps the handle ``along`` metres from the pot's axis."""
    rot = state.get(pot, "rotation")
    xy = pot_xy(state, pot) - along * np.array([np.cos(rot), np.sin(rot)])
    return np.array([*xy, base_z(state, pot) + HANDLE_Z])


def knob_grasp(state: State, pot: Object) -> np.ndarray:
    z = base_z(state, pot) + KNOB_Z + KNOB_HALF_HEIGHT - KNOB_GRIP_BELOW_TOP
    return np.array([*pot_xy(state, pot), z])


def knob_wrist(rotation: float, target: float) -> float:
    """Wrist angle across two knob faces (pot rotation mod 90 deg) from which the pot is
    turned to ``target``: one quarter turn ahead of the pot, towards the turn.

    One rule for every pot turned to one side, so the grasp angle is a continuous function
    of the pot's rotation and a learned grasp sampler has a single mode to fit. (Choosing
    the face pair that centres the turn in the wrist's range jumps between pairs as the
    rotation varies; a Gaussian generator averaged those modes into grasps off the faces,
    and the turn then ran into the wrist's limit.)"""
    delta = wrap(target - rotation)
    w0 = rotation + np.sign(delta) * np.pi / 2
    if max(abs(w0), abs(w0 + delta)) > WRIST_LIMITS[1] - 0.1:
        raise DemonstrationFailed("no knob grasp turns the pot within the wrist's range")
    return float(w0)


def needs_twist(state: State, pot: Object) -> bool:
    return abs(state.get(pot, "rotation")) > TWIST_ABOVE


# -- phase builders ---------------------------------------------------------------------
def rise_phase(robot: Object, z: float, grip: float) -> Phase:
    def rise(s: State) -> np.ndarray | None:
        goal = np.array([*hand(s, robot)[:2], z])
        if at(s, robot, goal, 0.01) and turned(s, robot, None):
            return None
        return move_action(s, robot, goal, grip)

    return rise


def grasp_phases(
    robot: Object,
    pot: Object,
    target: Callable[[State], np.ndarray],
    wrist: Callable[[State], float],
    flag: str,
) -> list[Phase]:
    """Open, travel above the grasp point with the wrist turned, descend, close on it."""
    closing = {"steps": 0, "extra": 0}

    def travel(s: State) -> np.ndarray | None:
        goal = target(s).copy()
        goal[2] = max(goal[2], hand(s, robot)[2], FREE_Z)
        w = wrist(s)
        if at(s, robot, goal, 2 * POS_TOL) and turned(s, robot, w):
            return None
        return move_action(s, robot, goal, 1.0, wrist=w)

    def descend(s: State) -> np.ndarray | None:
        goal = target(s)
        w = wrist(s)
        if at(s, robot, goal) and s.get(robot, "fingers") > 0.035 and turned(s, robot, w):
            return None
        return slow_near(s, robot, goal, 1.0, wrist=w)

    def close(s: State) -> np.ndarray | None:
        closing["steps"] += 1
        if closing["steps"] > MAX_CLOSE_STEPS:
            raise DemonstrationFailed(
                f"could not grasp the pot by its {PART_OF_FLAG.get(flag, flag)} "
                f"within {MAX_CLOSE_STEPS} close steps"
            )
        if s.get(pot, flag) > 0.5:
            closing["extra"] += 1
            if closing["extra"] > EXTRA_CLOSE_STEPS:
                return None
        action = move_action(s, robot, target(s), -1.0, wrist=wrist(s))
        if closing["extra"]:
            action[2] = 0.0  # once held, no lifting before the lift phase
        return action

    return [travel, descend, close]


def release_phases(robot: Object, pot: Object, flag: str, rise_to: float) -> list[Phase]:
    """Open fully, then back straight up, slowly while the fingers are beside the pot."""
    start: dict[str, float] = {}

    def release(s: State) -> np.ndarray | None:
        if s.get(pot, flag) < 0.5 and s.get(robot, "fingers") > 0.038:
            return None
        return np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])

    def back_off(s: State) -> np.ndarray | None:
        z0 = start.setdefault("z", float(hand(s, robot)[2]))
        goal = np.array([*hand(s, robot)[:2], z0 + BACK_OFF])
        if hand(s, robot)[2] >= goal[2] - 0.003:
            return None
        action = move_action(s, robot, goal, 1.0)
        action[2] = min(action[2], SLOW_STEP)
        return action

    return [release, back_off, rise_phase(robot, rise_to, 1.0)]


def twist_phases(robot: Object, pot: Object, target: float) -> list[Phase]:
    """Grasp the knob, turn the wrist until the pot's rotation is ``target``, let go."""
    memo: dict[str, float] = {}

    def grasp_wrist(s: State) -> float:
        if "w0" not in memo:
            memo["w0"] = knob_wrist(s.get(pot, "rotation"), target)
        return memo["w0"]

    phases = [rise_phase(robot, FREE_Z, 1.0)]
    phases += grasp_phases(robot, pot, lambda s: knob_grasp(s, pot), grasp_wrist, "twisted")

    misses = {"n": 0}

    def turn(s: State) -> np.ndarray | None:
        action = move_action(s, robot, knob_grasp(s, pot), -1.0)
        if s.get(pot, "twisted") < 0.5:  # a pad slipped off a face for a moment: squeeze
            misses["n"] += 1
            if misses["n"] > MAX_KNOB_MISSES:
                raise DemonstrationFailed("lost the knob while twisting")
            return action
        err = wrap(target - s.get(pot, "rotation"))
        if abs(err) <= TWIST_TOL:
            return None
        action[4] = float(np.clip(TURN_GAIN * err, -TWIST_TURN, TWIST_TURN))
        return action

    return phases + [turn] + release_phases(robot, pot, "twisted", FREE_Z)


def pick_phases(robot: Object, pot: Object, wait_hot: bool = False) -> list[Phase]:
    """Grasp the handle (wrist turned by the pot's rotation) and lift the pot."""
    phases = [rise_phase(robot, FREE_Z, 1.0)]
    phases += grasp_phases(
        robot, pot, lambda s: handle_grasp(s, pot), lambda s: s.get(pot, "rotation"), "held"
    )

    def wait(s: State) -> np.ndarray | None:
        if s.get(pot, "heat") >= 1.0:
            return None
        return np.array([0.0, 0.0, 0.0, 0.0, 0.0, -1.0])

    def lift(s: State) -> np.ndarray | None:
        if s.get(pot, "held") < 0.5:
            raise DemonstrationFailed("dropped the pot")
        goal = np.array([*hand(s, robot)[:2], SAFE_Z])
        if at(s, robot, goal, 0.01):
            return None
        return move_action(s, robot, goal, -1.0)

    return phases + ([wait] if wait_hot else []) + [lift]


def place_phases(robot: Object, pot: Object, plate: Object) -> list[Phase]:
    """Carry the pot over the plate's centre, lower it until its feet touch, let go."""

    def goal_for(s: State, z: float) -> np.ndarray:
        offset = hand(s, robot)[:2] - pot_xy(s, pot)
        return np.array([*(s.data[plate][:2] + offset), z])

    def carry(s: State) -> np.ndarray | None:
        goal = goal_for(s, SAFE_Z)
        if at(s, robot, goal, 2 * POS_TOL):
            return None
        return move_action(s, robot, goal, -1.0)

    def lower(s: State) -> np.ndarray | None:
        if s.get(pot, "on_plate") > 0.5:
            return None
        goal = goal_for(s, PLATE_TOP + HANDLE_Z - 0.004)
        return slow_near(s, robot, goal, -1.0)

    return [carry, lower] + release_phases(robot, pot, "held", FREE_Z)


def press_phases(robot: Object, plate: Object) -> list[Phase]:
    """Close the fingers, go above the button, lower the fingertips onto it, push."""

    def button(s: State) -> np.ndarray:
        return np.array([s.get(plate, "button_x"), s.get(plate, "button_y")])

    def travel(s: State) -> np.ndarray | None:
        goal = np.array([*button(s), FREE_Z])
        if at(s, robot, goal, 2 * POS_TOL) and s.get(robot, "fingers") < 0.005:
            return None
        return move_action(s, robot, goal, -1.0, wrist=0.0)

    def approach(s: State) -> np.ndarray | None:
        z = s.get(plate, "button_z") + APPROACH_CLEARANCE + FINGERTIP_DROP
        goal = np.array([*button(s), z])
        if at(s, robot, goal):
            return None
        return slow_near(s, robot, goal, -1.0, wrist=0.0)

    def push(s: State) -> np.ndarray | None:
        if s.get(plate, "is_on") > 0.5:
            return None
        dxy = GAIN * (button(s) - hand(s, robot)[:2])
        return np.array([dxy[0], dxy[1], -PRESS_SPEED, 0.0, 0.0, -1.0])

    return [travel, approach, push, rise_phase(robot, FREE_Z, -1.0)]


def spout_clearance(tilt: float) -> float:
    """Height of the spout tip above a cup's rim that keeps the pot's body clear of the cup
    at pot tilt ``tilt``: upright the body hangs 9.4 cm below the tip, tilted past the
    pouring angle the tip is the pot's lowest point near the cup."""
    return float(np.clip(UPRIGHT_CLEARANCE - CLEARANCE_SLOPE * tilt, POUR_ABOVE_RIM, None))


def body_depth(tilt: float) -> float:
    """How far the pot's lowest point (the bottom's front edge) lies below the spout tip."""
    return 0.094 * np.cos(tilt) - 0.03 * np.sin(tilt)


def spout_height(s: State, pot: Object, cup: Object) -> float:
    """Spout tip height over ``cup`` that keeps the pot clear of it and of the cups nearby
    (the body hangs up to 9.4 cm below the tip, some 4-13 cm behind it)."""
    tilt = s.get(pot, "tilt")
    need = s.get(cup, "rim_z") + spout_clearance(tilt)
    for c in s.objects_of_type(CUP):
        near = np.hypot(s.get(c, "x") - s.get(cup, "x"), s.get(c, "y") - s.get(cup, "y"))
        if c != cup and near < NEIGHBOUR_RANGE:
            need = max(need, s.get(c, "rim_z") + body_depth(tilt) + NEIGHBOUR_CLEARANCE)
    return float(need)


def spout(s: State, pot: Object) -> np.ndarray:
    return np.array([s.get(pot, "spout_x"), s.get(pot, "spout_y"), s.get(pot, "spout_z")])


def pour_step(
    s: State,
    robot: Object,
    pot: Object,
    cup: Object,
    tilt: float,
    rate: float,
    descend: bool = True,
) -> np.ndarray:
    """Keep the spout tip over ``cup`` at a clear height while turning to pot tilt ``tilt``.

    ``descend=False`` never lowers the hand: tilting back raises the tip, and following it
    down swings the pot's back edge into a neighbouring cup."""
    tip_goal = np.array([s.get(cup, "x"), s.get(cup, "y"), spout_height(s, pot, cup)])
    goal = hand(s, robot) + tip_goal - spout(s, pot)
    if not descend:
        goal[2] = max(goal[2], hand(s, robot)[2])
    action = move_action(s, robot, goal, -1.0)
    action[3] = float(np.clip(TURN_GAIN * (tilt - s.get(robot, "tilt")), -rate, rate))
    return action


def pour_phases(robot: Object, pot: Object, cup: Object) -> list[Phase]:
    """Bring the spout tip over ``cup``, tilt, keep it there until the target, tilt back."""

    def goal_for(s: State, above: float) -> np.ndarray:
        tip_goal = np.array([s.get(cup, "x"), s.get(cup, "y"), s.get(cup, "rim_z") + above])
        return hand(s, robot) + tip_goal - spout(s, pot)

    def check(s: State) -> None:
        if s.get(pot, "held") < 0.5:
            raise DemonstrationFailed("dropped the pot")
        if s.get(pot, "spilled") > 0.5:
            raise DemonstrationFailed("spilled")

    def rise(s: State) -> np.ndarray | None:
        check(s)
        goal = np.array([*hand(s, robot)[:2], SAFE_Z])
        if at(s, robot, goal, 0.01) and turned(s, robot, None):
            return None
        return move_action(s, robot, goal, -1.0)

    def carry(s: State) -> np.ndarray | None:
        check(s)
        goal = goal_for(s, 0.0)
        goal[2] = SAFE_Z
        if at(s, robot, goal, 2 * POS_TOL):
            return None
        return move_action(s, robot, goal, -1.0)

    def lower(s: State) -> np.ndarray | None:
        check(s)
        goal = goal_for(s, spout_height(s, pot, cup) - s.get(cup, "rim_z"))
        if at(s, robot, goal, POS_TOL):
            return None
        return slow_near(s, robot, goal, -1.0)

    def pour(s: State) -> np.ndarray | None:
        check(s)
        if s.get(cup, "liquid") >= s.get(cup, "target"):
            return None
        return pour_step(s, robot, pot, cup, POUR_TILT_GOAL, POUR_TURN)

    def untilt(s: State) -> np.ndarray | None:
        check(s)
        if s.get(pot, "tilt") < POUR_TILT - 0.15 and turned(s, robot, None, 0.0):
            return None
        return pour_step(s, robot, pot, cup, 0.0, UNTILT_TURN, descend=False)

    return [rise, carry, lower, pour, untilt]
