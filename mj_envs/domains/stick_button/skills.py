"""Hand-written ("oracle") Stick Button skills: operators, subgoal samplers and policies.

The six operators of the paper (App. B): press a button with the hand, pick up the stick,
press a button with the stick's tip, each "from nothing" (AboveNoButton) or "from another
button" (the hand or tip is still above the button pressed last). No predicate says
whether a button is within the hand's reach, so the shortest abstract plans press every
button by hand and fail on far buttons (paper KD2); where the stick is gripped decides
which buttons its tip can reach (KD1).

Subgoals are absolute scope vectors; policies read the hand's target xy from the robot
part (``subgoal[0:2]``): the press point for a hand press, the hand position that puts
the tip on the button for a stick press, the grasp point for a pick. Policies are
stateless functions of (state, subgoal). Samplers know the arm's reach (they are the
oracle): a sampler raises :class:`bpns.structs.NoSubgoal` for a subgoal no motion can
achieve, which the planner counts as a failed sample without simulating anything.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import NoSubgoal, Object, Skill, State, Variable
from mj_envs.domains.stick_button.behaviours import (
    FINGER_REACH,
    GRASP_MAX,
    GRASP_MIN,
    HAND_REACH,
    POS_TOL,
    SAFE_Z,
    SLOW_STEP,
    grasp_limit_for,
    grasp_point,
    move_action,
    pusher,
    slow_near,
    stick_axis,
)
from mj_envs.domains.stick_button.rules import (
    ABOVE_NO_BUTTON,
    BUTTON,
    GRASPED,
    HAND_EMPTY,
    PRESSED,
    ROBOT,
    ROBOT_ABOVE_BUTTON,
    STICK,
    STICK_ABOVE_BUTTON,
    STICK_HEIGHT,
)
from mj_envs.oracles.motions import GAIN
from mj_envs.oracles.operators import atom, make_operator

APPROACH_CLEARANCE = 0.008  # pusher height above the cap before the slow push
PRESS_SPEED = 0.003  # metres per step while pushing

XY_NOISE = 0.004  # subgoal jitter of press points (the cap is 4.4 cm wide)
ALIGNED_HIGH, ALIGNED_LOW = 0.006, 0.012  # xy error to start / keep descending
STICK_BACK_MIN_X = 0.12  # the held stick's back end must stay clear of the robot's base
FINGERS_CLOSED, FINGERS_OPEN = 0.004, 0.035


_R, _S = Variable("?robot", ROBOT), Variable("?stick", STICK)
_B, _F = Variable("?button", BUTTON), Variable("?from", BUTTON)


_NOTHING = atom(ABOVE_NO_BUTTON)
ROBOT_PRESS_FROM_NOTHING = make_operator(
    "RobotPressButtonFromNothing",
    (_R, _B),
    {_NOTHING, atom(HAND_EMPTY, _R)},
    {atom(PRESSED, _B), atom(ROBOT_ABOVE_BUTTON, _R, _B)},
    {_NOTHING},
)
ROBOT_PRESS_FROM_BUTTON = make_operator(
    "RobotPressButtonFromButton",
    (_R, _B, _F),
    {atom(ROBOT_ABOVE_BUTTON, _R, _F), atom(HAND_EMPTY, _R)},
    {atom(PRESSED, _B), atom(ROBOT_ABOVE_BUTTON, _R, _B)},
    {atom(ROBOT_ABOVE_BUTTON, _R, _F)},
)
PICK_FROM_NOTHING = make_operator(
    "PickStickFromNothing",
    (_R, _S),
    {_NOTHING, atom(HAND_EMPTY, _R)},
    {atom(GRASPED, _R, _S)},
    {atom(HAND_EMPTY, _R)},
)
PICK_FROM_BUTTON = make_operator(
    "PickStickFromButton",
    (_R, _S, _F),
    {atom(ROBOT_ABOVE_BUTTON, _R, _F), atom(HAND_EMPTY, _R)},
    {atom(GRASPED, _R, _S), _NOTHING},
    {atom(HAND_EMPTY, _R), atom(ROBOT_ABOVE_BUTTON, _R, _F)},
)
STICK_PRESS_FROM_NOTHING = make_operator(
    "StickPressButtonFromNothing",
    (_R, _S, _B),
    {_NOTHING, atom(GRASPED, _R, _S)},
    {atom(PRESSED, _B), atom(STICK_ABOVE_BUTTON, _S, _B)},
    {_NOTHING},
)
STICK_PRESS_FROM_BUTTON = make_operator(
    "StickPressButtonFromButton",
    (_R, _S, _B, _F),
    {atom(STICK_ABOVE_BUTTON, _S, _F), atom(GRASPED, _R, _S)},
    {atom(PRESSED, _B), atom(STICK_ABOVE_BUTTON, _S, _B)},
    {atom(STICK_ABOVE_BUTTON, _S, _F)},
)


# -- policies ------------------------------------------------------------------------------
def _rise(state: State, robot: Object, grip: float, stick: Object | None) -> np.ndarray:
    """Straight up to the travel height; a held stick is eased off the table first."""
    goal = np.array([state.get(robot, "x"), state.get(robot, "y"), SAFE_Z])
    action = move_action(state, robot, goal, grip)
    if stick is not None and state.get(robot, "z") < SAFE_Z / 2:
        resting = state.get(stick, "z") - STICK_HEIGHT / 2 < 0.004
        action[2] = min(action[2], 0.001 if resting else SLOW_STEP)
    return action


def _press(
    state: State, robot: Object, button: Object, stick: Object | None, hand_xy: np.ndarray
) -> np.ndarray:
    """Put the pusher (fingertips or stick tip) over the button and push down slowly.

    ``hand_xy`` is the subgoal's hand position (the sampler put the pusher over the cap
    from there); the pusher's height above the cap is re-measured every step.
    """
    grip = -1.0
    hand = state.data[robot][:3]
    p = pusher(state, robot, stick)
    err = float(np.max(np.abs(hand[:2] - hand_xy)))
    low = hand[2] < SAFE_Z - 0.01
    if low and err > ALIGNED_LOW:
        return _rise(state, robot, grip, stick)
    if not low and err > ALIGNED_HIGH:
        return move_action(state, robot, np.array([*hand_xy, SAFE_Z]), grip)
    if stick is None and state.get(robot, "fingers") > FINGERS_CLOSED:
        return np.array([*(hand_xy - hand[:2]), 0.0, grip])  # close before touching down
    approach_z = state.get(button, "z") + APPROACH_CLEARANCE
    if p[2] > approach_z + POS_TOL:
        goal = np.array([*hand_xy, hand[2] + approach_z - p[2]])
        return slow_near(state, robot, goal, grip)
    dxy = GAIN * (hand_xy - hand[:2])
    return np.array([dxy[0], dxy[1], -PRESS_SPEED, grip])


class RobotPressPolicy:
    """Close the fingers, go above the press point, lower the fingertips onto the cap."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, button = objects[0], objects[1]
        return _press(state, robot, button, None, subgoal[0:2])


class StickPressPolicy:
    """Carry the stick so the tip is over the button, lower it onto the cap, push."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, stick, button = objects[0], objects[1], objects[2]
        return _press(state, robot, button, stick, subgoal[0:2])


class PickPolicy:
    """Open, go above the grasp point, descend beside the stick, close."""

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, stick = objects[0], objects[1]
        grasp = np.array([subgoal[0], subgoal[1], grasp_point(state, stick, GRASP_MIN)[2]])
        hand = state.data[robot][:3]
        err = float(np.max(np.abs(hand[:2] - grasp[:2])))
        low = hand[2] < SAFE_Z - 0.01
        if low and err > ALIGNED_LOW:
            return _rise(state, robot, 1.0, None)
        if not low and err > ALIGNED_HIGH:
            return move_action(state, robot, np.array([*grasp[:2], SAFE_Z]), 1.0)
        if hand[2] > grasp[2] + 0.004:
            if state.get(robot, "fingers") < FINGERS_OPEN:
                return np.array([*(grasp[:2] - hand[:2]), 0.0, 1.0])  # open before descending
            return slow_near(state, robot, grasp, 1.0)
        return move_action(state, robot, grasp, -1.0)


# -- samplers ------------------------------------------------------------------------------
class RobotPressSampler:
    """Press near the cap's centre; buttons beyond the fingertips' reach are declined."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        button = objects[1]
        if np.hypot(state.get(button, "x"), state.get(button, "y")) > FINGER_REACH:
            raise NoSubgoal(f"{button.name} is beyond the fingertips' reach")
        sub = state.vec(objects).copy()
        sub[0:2] = state.data[button][:2] + rng.uniform(-XY_NOISE, XY_NOISE, 2)
        return sub


class StickPressSampler:
    """Hand position that puts the measured tip over the cap, if the arm can hold it there."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        robot, stick, button = objects[0], objects[1], objects[2]
        tip = np.array([state.get(stick, "tip_x"), state.get(stick, "tip_y")])
        hand = state.data[robot][:2] + state.data[button][:2] - tip
        hand = hand + rng.uniform(-XY_NOISE, XY_NOISE, 2)
        back, _ = stick_axis(state, stick)
        back = back + hand - state.data[robot][:2]
        if np.hypot(*hand) > HAND_REACH or back[0] < STICK_BACK_MIN_X:
            raise NoSubgoal(f"the stick's tip cannot be held over {button.name}")
        sub = state.vec(objects).copy()
        sub[0:2] = hand
        return sub


class PickSampler:
    """A grasp point on the stick's free part; usually one whose tip reaches every
    unpressed button beyond the fingertips' reach (the further, the nearer the holder)."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        stick = objects[1]
        far = [
            b
            for b in state.objects_of_type(BUTTON)
            if state.get(b, "pressed") < 0.5
            and np.hypot(state.get(b, "x"), state.get(b, "y")) > FINGER_REACH
        ]
        hi = grasp_limit_for(state, far) if far else GRASP_MAX
        if hi < GRASP_MIN or rng.random() < 0.2:
            hi = GRASP_MAX
        sub = state.vec(objects).copy()
        sub[0:2] = grasp_point(state, stick, float(rng.uniform(GRASP_MIN, hi)))[:2]
        return sub


def oracle_skills() -> list[Skill]:
    robot_press = (RobotPressPolicy(), RobotPressSampler())
    stick_press = (StickPressPolicy(), StickPressSampler())
    pick = (PickPolicy(), PickSampler())
    return [
        Skill(ROBOT_PRESS_FROM_NOTHING, *robot_press),
        Skill(ROBOT_PRESS_FROM_BUTTON, *robot_press),
        Skill(PICK_FROM_NOTHING, *pick),
        Skill(PICK_FROM_BUTTON, *pick),
        Skill(STICK_PRESS_FROM_NOTHING, *stick_press),
        Skill(STICK_PRESS_FROM_BUTTON, *stick_press),
    ]
