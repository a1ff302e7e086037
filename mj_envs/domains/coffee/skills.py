"""Hand-written ("oracle") Coffee skills: the paper's seven operators, samplers, policies.

Operators (App. B): PickPot, PlacePotOnPlate, TurnOnPlate, PourFromNothing,
PourFromOtherCup, Twist, PickPotAfterTwist. As simulated:

* Twist grasps the knob (Twisting) with the wrist across two knob faces drawn by the
  sampler; PickPotAfterTwist turns the pot by the knob to a sampled rotation, lets go and
  picks the pot by the handle (Holding). No predicate says whether the handle faces the
  robot, so the shortest abstract plans pick the pot directly and fail when it is turned
  beyond 60 deg (paper: "the first abstract plan does not rotate the pot").
* PickPot ends when both pads hold the handle, with the pot still resting on the table or
  the plate; PlacePotOnPlate ends when the pot stands on the plate and the fingers let go;
  TurnOnPlate presses the button and waits, hand raised, until the pot is hot.
* The pours end when the cup holds its target: the pot is still tilted then, and the next
  pour (from the other cup) first tilts it back over the cup it is above.

Subgoals are absolute scope vectors; policies read their parameters from them (the knob
wrist, the turned rotation, the pot's place on the plate, the press point, the pouring
tilt). Policies are stateless functions of (state, subgoal). Samplers know the rules
(they are the oracle): they raise :class:`bpns.structs.NoSubgoal` for a subgoal no
motion achieves (e.g. a handle turned beyond 60 deg), which the planner counts as a
failed sample without simulating anything.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import NoSubgoal, Object, Skill, State, Variable
from mj_envs.domains.coffee.behaviours import (
    APPROACH_CLEARANCE,
    FREE_Z,
    POS_TOL,
    POUR_TILT_GOAL,
    POUR_TURN,
    PRESS_SPEED,
    SAFE_Z,
    SLOW_STEP,
    TURN_GAIN,
    TWIST_TARGET,
    TWIST_TOL,
    TWIST_TURN,
    UNTILT_TURN,
    hand,
    handle_grasp,
    knob_grasp,
    knob_wrist,
    move_action,
    pour_step,
    slow_near,
    spout,
    spout_height,
    wrap,
)
from mj_envs.domains.coffee.rules import (
    BUTTON_PRESSED,
    CUP,
    CUP_FILLED,
    FINGERTIP_DROP,
    HAND_EMPTY,
    HANDLE_RULE,
    HANDLE_Z,
    HOLDING,
    KNOB_Z,
    NOT_ABOVE_CUP,
    ON_TABLE,
    PLATE,
    PLATE_TOP,
    POT,
    POT_ABOVE_CUP,
    POT_HOT,
    POT_ON_PLATE,
    POUR_TILT,
    ROBOT,
    ROBOT_ABOVE_CUP,
    TWISTING,
    WRIST_LIMITS,
    pot_above_cup,
)
from mj_envs.oracles.operators import atom, make_operator

# Scope vector layout: the robot's features come first in every operator, the pot next.
R_WRIST, R_TILT = 4, 3
P_OFF = 6  # the pot's features start here
P_X, P_Y, P_ROTATION = P_OFF + 0, P_OFF + 1, P_OFF + 3
PICK_RULE = HANDLE_RULE - np.deg2rad(5.0)  # samplers keep a margin to the 60 deg rule
WRIST_MARGIN = 0.1
ALIGNED_HIGH, ALIGNED_LOW = 0.006, 0.012  # xy error to start / keep descending
WRIST_ALIGNED = 0.05
NEAR_GRASP = 0.06
OPEN = 0.038  # fingers this open (per finger) count as open
GRASP_NOISE, PLACE_NOISE, PRESS_NOISE = 0.002, 0.015, 0.004
UPRIGHT = 0.15  # hand tilt below which the pot counts as upright
SPOUT_ALIGNED, SPOUT_OFF = 0.006, 0.02
# Hysteresis bands: a stateless policy on a noisy, delayed observation must not flip
# between two motions at one threshold (close/reopen, lower/untilt), or it chatters there
# until its horizon (the oracle under action noise and latency, docs/WORLDS.md).
GRIP_BAND = 0.012  # closing fingers keep closing while the hand is this close above
CLOSED_EMPTY = 0.006  # fingers closed this far hold nothing: open and try again
POURING = 0.05  # a hand tilted this far has begun pouring: keep pouring


_R, _P = Variable("?robot", ROBOT), Variable("?pot", POT)
_L, _C, _O = Variable("?plate", PLATE), Variable("?cup", CUP), Variable("?other", CUP)


TWIST = make_operator(
    "Twist",
    (_R, _P),
    {atom(HAND_EMPTY, _R), atom(ON_TABLE, _P)},
    {atom(TWISTING, _R, _P)},
    {atom(HAND_EMPTY, _R)},
)
PICK_POT_AFTER_TWIST = make_operator(
    "PickPotAfterTwist",
    (_R, _P),
    {atom(TWISTING, _R, _P), atom(ON_TABLE, _P)},
    {atom(HOLDING, _R, _P)},
    {atom(TWISTING, _R, _P)},
)
PICK_POT = make_operator(
    "PickPot",
    (_R, _P),
    {atom(HAND_EMPTY, _R)},
    {atom(HOLDING, _R, _P)},
    {atom(HAND_EMPTY, _R)},
)
PLACE_POT_ON_PLATE = make_operator(
    "PlacePotOnPlate",
    (_R, _P, _L),
    {atom(HOLDING, _R, _P)},
    {atom(POT_ON_PLATE, _P, _L), atom(HAND_EMPTY, _R)},
    {atom(HOLDING, _R, _P), atom(ON_TABLE, _P)},
)
TURN_ON_PLATE = make_operator(
    "TurnOnPlate",
    (_R, _P, _L),
    {atom(HAND_EMPTY, _R), atom(POT_ON_PLATE, _P, _L)},
    {atom(BUTTON_PRESSED, _L), atom(POT_HOT, _P)},
    set(),
)
POUR_FROM_NOTHING = make_operator(
    "PourFromNothing",
    (_R, _P, _L, _C),
    {atom(HOLDING, _R, _P), atom(POT_HOT, _P), atom(NOT_ABOVE_CUP, _R, _P)},
    {atom(CUP_FILLED, _C), atom(POT_ABOVE_CUP, _P, _C), atom(ROBOT_ABOVE_CUP, _R, _C)},
    {atom(NOT_ABOVE_CUP, _R, _P), atom(POT_ON_PLATE, _P, _L), atom(ON_TABLE, _P)},
)
POUR_FROM_OTHER_CUP = make_operator(
    "PourFromOtherCup",
    (_R, _P, _C, _O),
    {
        atom(HOLDING, _R, _P),
        atom(POT_HOT, _P),
        atom(POT_ABOVE_CUP, _P, _O),
        atom(ROBOT_ABOVE_CUP, _R, _O),
    },
    {atom(CUP_FILLED, _C), atom(POT_ABOVE_CUP, _P, _C), atom(ROBOT_ABOVE_CUP, _R, _C)},
    {atom(POT_ABOVE_CUP, _P, _O), atom(ROBOT_ABOVE_CUP, _R, _O)},
)


# -- policy building blocks ------------------------------------------------------------------
def _open_in_place() -> np.ndarray:
    return np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])


def _near_pot(s: State, robot: Object, pot: Object) -> bool:
    """The hand is low at the pot's handle or knob (where fingers that are not fully open
    could snag it when moving off)."""
    h = hand(s, robot)
    if h[2] > s.get(pot, "z") + KNOB_Z + 0.05:
        return False
    knob = np.array([s.get(pot, "x"), s.get(pot, "y")])
    handle = handle_grasp(s, pot)[:2]
    return bool(min(np.linalg.norm(h[:2] - knob), np.linalg.norm(h[:2] - handle)) < NEAR_GRASP)


def _clear_of_pot(s: State, robot: Object, pot: Object) -> np.ndarray | None:
    """An empty hand low beside the pot opens fully, then backs straight up slowly."""
    if not _near_pot(s, robot, pot):
        return None
    if s.get(robot, "fingers") < OPEN:
        return _open_in_place()
    goal = np.array([*hand(s, robot)[:2], FREE_Z])
    action = move_action(s, robot, goal, 1.0)
    action[2] = min(action[2], SLOW_STEP)
    return action


def _grasp(
    s: State, robot: Object, target: np.ndarray, wrist: float, near: Object | None
) -> np.ndarray:
    """Open, go above ``target`` with the wrist at ``wrist``, descend, close (stateless)."""
    h = hand(s, robot)
    err = float(np.max(np.abs(h[:2] - target[:2])))
    werr = abs(s.get(robot, "wrist") - wrist)
    low = h[2] < FREE_Z - 0.01
    if low and (err > ALIGNED_LOW or werr > 2 * WRIST_ALIGNED):
        if near is not None:
            clear = _clear_of_pot(s, robot, near)
            if clear is not None:
                return clear
        return move_action(s, robot, np.array([*h[:2], FREE_Z]), 1.0)
    if not low and (err > ALIGNED_HIGH or werr > WRIST_ALIGNED):
        return move_action(s, robot, np.array([*target[:2], FREE_Z]), 1.0, wrist=wrist)
    fingers = s.get(robot, "fingers")
    closing = CLOSED_EMPTY < fingers < 0.035 and h[2] <= target[2] + GRIP_BAND
    if h[2] > target[2] + 0.004 and not closing:
        if fingers < 0.035:
            return np.array([*(target[:2] - h[:2]), 0.0, 0.0, 0.0, 1.0])  # open first
        return slow_near(s, robot, target, 1.0, wrist=wrist)
    return move_action(s, robot, target, -1.0, wrist=wrist)


def _pick_handle(s: State, robot: Object, pot: Object, offset: np.ndarray) -> np.ndarray:
    target = handle_grasp(s, pot) + np.array([*offset, 0.0])
    return _grasp(s, robot, target, s.get(pot, "rotation"), pot)


def _cup_below(s: State, pot: Object) -> Object | None:
    return next((c for c in s.objects_of_type(CUP) if pot_above_cup(s, pot, c)), None)


def _pour(s: State, robot: Object, pot: Object, cup: Object, tilt: float) -> np.ndarray:
    """Tilt a pot still pouring elsewhere back, carry it over ``cup``, lower, tilt, pour.

    Tilted means the *hand* is: a heavy pot in a slippery grasp sags forward in the
    fingers, and untilting a hand that is level does not right it."""
    tilted = s.get(robot, "tilt") > UPRIGHT
    if tilted:
        below = _cup_below(s, pot)
        if below is None:
            return move_action(s, robot, hand(s, robot), -1.0, tilt=0.0)
        if below != cup:
            return pour_step(s, robot, pot, below, 0.0, UNTILT_TURN)
        return pour_step(s, robot, pot, cup, tilt, POUR_TURN)
    tip = spout(s, pot)
    goal_tip = np.array([s.get(cup, "x"), s.get(cup, "y"), spout_height(s, pot, cup)])
    err = float(np.max(np.abs(tip[:2] - goal_tip[:2])))
    h = hand(s, robot)
    low = h[2] < SAFE_Z - 0.01
    if low and err > SPOUT_OFF:
        return move_action(s, robot, np.array([*h[:2], SAFE_Z]), -1.0)
    if not low and err > SPOUT_ALIGNED:
        goal = h + goal_tip - tip
        goal[2] = SAFE_Z
        return move_action(s, robot, goal, -1.0)
    pouring = s.get(robot, "tilt") > POURING
    if abs(tip[2] - goal_tip[2]) > POS_TOL and not pouring:
        return slow_near(s, robot, h + goal_tip - tip, -1.0, tilt=s.get(robot, "tilt"))
    return pour_step(s, robot, pot, cup, tilt, POUR_TURN)


# -- policies ----------------------------------------------------------------------------------
class TwistPolicy:
    """Grasp the knob from above with the wrist at the subgoal's wrist angle."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, pot = objects[0], objects[1]
        return _grasp(state, robot, knob_grasp(state, pot), float(subgoal[R_WRIST]), pot)


class PickPotAfterTwistPolicy:
    """Turn the held knob until the pot's rotation is the subgoal's, let go, pick it."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, pot = objects[0], objects[1]
        if state.get(pot, "twisted") > 0.5:
            err = wrap(float(subgoal[P_ROTATION]) - state.get(pot, "rotation"))
            if abs(err) <= TWIST_TOL:
                return _open_in_place()
            action = move_action(state, robot, knob_grasp(state, pot), -1.0)
            action[4] = float(np.clip(TURN_GAIN * err, -TWIST_TURN, TWIST_TURN))
            return action
        return _pick_handle(state, robot, pot, np.zeros(2))


class PickPotPolicy:
    """Turn the wrist by the pot's rotation, go above the handle's slot, descend, close."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, pot = objects[0], objects[1]
        offset = subgoal[0:2] - handle_grasp(state, pot)[:2]
        return _pick_handle(state, robot, pot, np.clip(offset, -0.004, 0.004))


class PlacePotOnPlatePolicy:
    """Carry the pot over the subgoal's place on the plate, lower it, let go."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, pot = objects[0], objects[1]
        if state.get(pot, "on_plate") > 0.5:
            return _open_in_place()
        h = hand(state, robot)
        pot_xy = np.array([state.get(pot, "x"), state.get(pot, "y")])
        target = np.array([subgoal[P_X], subgoal[P_Y]])
        err = float(np.max(np.abs(pot_xy - target)))
        low = h[2] < SAFE_Z - 0.01
        goal_xy = h[:2] + target - pot_xy
        if low and err > 0.02:
            return move_action(state, robot, np.array([*h[:2], SAFE_Z]), -1.0)
        if not low and err > ALIGNED_HIGH:
            return move_action(state, robot, np.array([*goal_xy, SAFE_Z]), -1.0)
        z = PLATE_TOP + HANDLE_Z - 0.004
        return slow_near(state, robot, np.array([*goal_xy, z]), -1.0)


class TurnOnPlatePolicy:
    """Back away from the pot, press the button with the closed fingertips, then wait
    with the hand raised until the pot is hot."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, pot, plate = objects[0], objects[1], objects[2]
        clear = _clear_of_pot(state, robot, pot)
        if clear is not None:
            return clear
        h = hand(state, robot)
        if state.get(plate, "is_on") > 0.5:
            goal = np.array([*h[:2], FREE_Z])
            if h[2] < FREE_Z - 0.01:
                return move_action(state, robot, goal, -1.0)
            return np.array([0.0, 0.0, 0.0, 0.0, 0.0, -1.0])
        k = P_OFF + POT.dim
        press_xy = subgoal[k + 2 : k + 4]
        err = float(np.max(np.abs(h[:2] - press_xy)))
        low = h[2] < FREE_Z - 0.01
        if low and err > ALIGNED_LOW:
            return move_action(state, robot, np.array([*h[:2], FREE_Z]), -1.0)
        if not low and err > ALIGNED_HIGH:
            return move_action(state, robot, np.array([*press_xy, FREE_Z]), -1.0, wrist=0.0)
        if state.get(robot, "fingers") > 0.004:
            return np.array([*(press_xy - h[:2]), 0.0, 0.0, 0.0, -1.0])
        approach = state.get(plate, "button_z") + APPROACH_CLEARANCE + FINGERTIP_DROP
        if h[2] > approach + POS_TOL:
            return slow_near(state, robot, np.array([*press_xy, approach]), -1.0)
        dxy = 0.7 * (press_xy - h[:2])
        return np.array([dxy[0], dxy[1], -PRESS_SPEED, 0.0, 0.0, -1.0])


class PourPolicy:
    """Pour into the operator's ``?cup`` (its last parameter but one for PourFromOtherCup)
    at the subgoal's tilt."""

    def __init__(self, cup_index: int) -> None:
        self.cup_index = cup_index

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, pot = objects[0], objects[1]
        return _pour(state, robot, pot, objects[self.cup_index], float(subgoal[R_TILT]))


# -- samplers ----------------------------------------------------------------------------------
class TwistSampler:
    """A knob grasp wrist from which the pot can be turned to face the robot."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        pot = objects[1]
        rotation = state.get(pot, "rotation")
        side = 1.0 if rotation >= 0 else -1.0
        sub = state.vec(objects).copy()
        try:
            sub[R_WRIST] = knob_wrist(rotation, side * float(rng.uniform(*TWIST_TARGET)))
        except RuntimeError as err:
            raise NoSubgoal(str(err)) from None
        return sub


class PickPotAfterTwistSampler:
    """A rotation within the handle rule that the wrist can turn the pot to from here."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        robot, pot = objects[0], objects[1]
        rotation, wrist = state.get(pot, "rotation"), state.get(robot, "wrist")
        # the wrist turns by (target - rotation): keep it inside its range
        lo = max(-PICK_RULE + 0.1, rotation - wrist + WRIST_LIMITS[0] + WRIST_MARGIN)
        hi = min(PICK_RULE - 0.1, rotation - wrist + WRIST_LIMITS[1] - WRIST_MARGIN)
        if lo > hi:
            raise NoSubgoal("the wrist cannot turn the pot to face the robot from this grasp")
        sub = state.vec(objects).copy()
        sub[P_ROTATION] = float(rng.uniform(lo, hi))
        return sub


class PickPotSampler:
    """The handle's finger slot (the handle rule: only within +-60 deg)."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        pot = objects[1]
        if abs(state.get(pot, "rotation")) > PICK_RULE:
            raise NoSubgoal("the handle faces away from the robot")
        sub = state.vec(objects).copy()
        sub[0:2] = handle_grasp(state, pot)[:2] + rng.uniform(-GRASP_NOISE, GRASP_NOISE, 2)
        return sub


class PlacePotOnPlateSampler:
    """A place for the pot's centre near the plate's centre."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        plate = objects[2]
        sub = state.vec(objects).copy()
        centre = np.array([state.get(plate, "x"), state.get(plate, "y")])
        sub[P_X : P_Y + 1] = centre + rng.uniform(-PLACE_NOISE, PLACE_NOISE, 2)
        return sub


class TurnOnPlateSampler:
    """A press point near the button's axis."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        plate = objects[2]
        sub = state.vec(objects).copy()
        k = P_OFF + POT.dim
        button = np.array([state.get(plate, "button_x"), state.get(plate, "button_y")])
        sub[k + 2 : k + 4] = button + rng.uniform(-PRESS_NOISE, PRESS_NOISE, 2)
        return sub


class PourSampler:
    """A pouring tilt a little past the flow threshold."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        sub = state.vec(objects).copy()
        sub[R_TILT] = float(rng.uniform(POUR_TILT + 0.1, POUR_TILT_GOAL + 0.03))
        return sub


def oracle_skills() -> list[Skill]:
    return [
        Skill(PICK_POT, PickPotPolicy(), PickPotSampler()),
        Skill(PLACE_POT_ON_PLATE, PlacePotOnPlatePolicy(), PlacePotOnPlateSampler()),
        Skill(TURN_ON_PLATE, TurnOnPlatePolicy(), TurnOnPlateSampler()),
        Skill(POUR_FROM_NOTHING, PourPolicy(3), PourSampler()),
        Skill(POUR_FROM_OTHER_CUP, PourPolicy(2), PourSampler()),
        Skill(TWIST, TwistPolicy(), TwistSampler()),
        Skill(PICK_POT_AFTER_TWIST, PickPotAfterTwistPolicy(), PickPotAfterTwistSampler()),
    ]
