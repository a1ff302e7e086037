"""Coffee in 3D: twist the pot, carry it to the hot plate, switch it on, pour (paper App. A.4).

Rules (final, as simulated):

* The pot (100 g, free body) is a cylinder (radius 5 cm, 10 cm tall) standing on four
  small feet, with a spout at its front (+x of the pot), a lid with a square knob
  (2.6 x 2.6 x 3 cm) on top and a straight handle bar sticking out 9.4 cm at the back
  (4 cm wide, 2.5 cm tall, 8 cm above the pot's base; a 2.9 cm finger slot between
  3 mm ridges, centred 8.5 cm from the pot's axis, keeps the pads from sliding along
  the bar). It is moved only by the fingers' contacts. Its ``rotation`` is its yaw: 0
  when the handle faces the robot (points to -x); tasks start with a rotation drawn
  uniformly in [-120, 120] deg.
* The hand points down; the fingers close across the handle bar when the wrist is turned
  by the pot's rotation. Handle rule (explicit, checked from geometry every step): while
  the hand is within 6 cm (xy) of the handle's centre and holds nothing, the finger
  command is obeyed only if the handle faces the robot within +-60 deg (|rotation| <=
  60 deg); beyond that the fingers do not move, so the handle cannot be grasped.
* Twisting: the knob is grasped from above (fingers across two of its faces) and the
  wrist is turned about the vertical; the pot turns with the knob (contact forces).
* The hot plate (radius 9 cm, top 2 cm above the table) has an on-button 14 cm in front
  of it (+x), a latching push button as in Stick Button (cap 4.4 cm wide, top 4.5 cm
  above the table, latches at 8 mm of travel through an equality constraint saved in
  ``eq_active``). The pot heats while it stands on the plate (PotOnPlate) and the button
  is latched: heat += 0.05 per 0.05 s step, capped at 1; PotHot when heat >= 1. The heat
  never drops.
* Liquid (scalar flow model): while the pot is hot and tilted more than 0.5 rad (its
  axis from the vertical, spout down), 0.006 l flows per step from the spout tip. If the
  tip is over a cup's opening (xy within its inner radius) the cup receives it, else it
  lands on the table. Pouring onto the table or filling a cup past its capacity sets the
  ``spilled`` flag for good: the task has failed (no CupFilled holds any more). A cold pot
  pours nothing (the coffee is brewed by the heat).
* Cups are fixed to the table (they do not tip): radius 3-4.2 cm, rim 5-8 cm high; capacity
  pi r^2 h (litres), target 0.5-0.7 of the capacity. Train tasks have 1-2 cups, eval 2-3.
  Goal: CupFilled for every cup (target <= liquid <= capacity, nothing spilled). Cups
  stand 5 cm apart and at least 2.5 cm beyond the reach of the pot's handle.
* Scalar state (heat, spilled, liquid per cup) lives in ``data.userdata`` after the
  controller's 7 slots and is updated in ``after_step``, so it is saved with MuJoCo's
  integration state and replay is exact.
* Predicates: Holding(robot, pot) = both finger pads touch the handle (bar or its finger-slot
  ridges; contact list);
  Twisting(robot, pot) = both pads touch the knob; HandEmpty(robot) = neither;
  OnTable(pot) = the pot stands upright on the table (its base less than 5 mm above the
  table top, tilted less than 0.3 rad: the closing fingers may lift it a millimetre or
  two without it counting as picked up); PotOnPlate(pot, plate) = likewise on the plate
  (base within 5 mm of its top, feet over it); ButtonPressed(plate) = the button's slide
  joint reads >= 8 mm; PotHot(pot);
  PressingButton(robot, plate) = the closed fingertips are on the cap (hand within 2.5 cm
  of its axis in xy and fingertips < 1 cm above its top); PotAboveCup(pot, cup) = the spout
  tip is over the cup's opening and above its rim; RobotAboveCup(robot, cup) = the robot
  holds a pot that is above the cup (the pouring pose); NotAboveCup(robot, pot) = the pot is
  above no cup; CupFilled(cup). Contact-related: Holding, HandEmpty, CupFilled,
  ButtonPressed.
* Action (dx, dy, dz, dtilt, dwrist, dfingers): hand translation in metres per 0.05 s step
  (|d| <= 2 cm), tilt and wrist deltas in radians (|d| <= 0.1) and a finger command in
  [-1, 1] (+1 opens). Wrist = yaw of the hand about the vertical from its home pose
  (fingers closing along y), tilt = rotation about the fingers' closing axis (positive
  dips the hand's +x side, which pours a pot held by the handle). The commanded angles
  are clipped to wrist in [-1.9, 1.9] and tilt in [-0.3, 1.2] rad (ik.orientation). The
  robot's features x, y, z, tilt, wrist are *measured* (grip site); deltas apply to the
  *commanded* pose. Horizon 1000 steps.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import mujoco
import numpy as np

from bpns.structs import Object, Predicate, State, Type
from ik import ControllerConfig
from ik.orientation import yaw_tilt_from_matrix
from mj_envs.parts.button import CAP_HALF_HEIGHT, LATCH_DEPTH  # noqa: F401  (re-exported)
from mj_envs.robots.panda import FINGERTIP_DROP, HOME_QPOS_TURNED, ik_model
from mj_envs.world import DOMAIN_USERDATA_START

# -- pot -------------------------------------------------------------------------------
POT_RADIUS, POT_HEIGHT = 0.05, 0.10
FOOT_RADIUS, FOOT_OFFSET = 0.005, 0.035
HANDLE_INNER, HANDLE_LENGTH = 0.046, 0.094  # from the pot's axis, along its -x
HANDLE_HALF_WIDTH, HANDLE_HALF_HEIGHT, HANDLE_Z = 0.02, 0.0125, 0.08
KNOB_HALF, KNOB_HALF_HEIGHT = 0.013, 0.015
KNOB_Z = POT_HEIGHT + KNOB_HALF_HEIGHT
SPOUT_TIP = np.array([POT_RADIUS + 0.03, 0.0, 0.094])  # pot frame
POT_MASSES = {"body": 0.075, "handle": 0.015, "knob": 0.008, "foot": 0.002}
GRIP_FROM_AXIS = 0.085  # the handle's finger slot, from the pot's axis
RIDGE_OFFSET, RIDGE_HALF = 0.0175, 0.003  # ridges either side of the slot (along the bar)
RIDGE_PROTRUSION = 0.003
HANDLE_RULE = np.deg2rad(60.0)
STANDING_HEIGHT, STANDING_TILT = 0.005, 0.3  # OnTable
HANDLE_NEAR = 0.06
# -- plate and its switch (a latching push button: mj_envs.parts.button) -----------------
PLATE_RADIUS, PLATE_TOP = 0.09, 0.02
BUTTON_OFFSET = np.array([0.14, 0.0])
PRESSING_RADIUS, PRESSING_HEIGHT = 0.025, 0.01
# -- heat and liquid -----------------------------------------------------------------------
HEAT_RATE = 0.05
POUR_TILT = 0.5
FLOW = 0.006  # litres per step
CUP_WALL = 0.004
CUP_RADIUS, CUP_HEIGHT = (0.03, 0.042), (0.05, 0.08)
TARGET_FRACTION = (0.5, 0.7)
HEAT_IDX = DOMAIN_USERDATA_START
SPILL_IDX = DOMAIN_USERDATA_START + 1
CUP_IDX = DOMAIN_USERDATA_START + 2
# -- layout ------------------------------------------------------------------------------
POT_X, POT_Y = (0.38, 0.50), (-0.05, 0.06)
PLATE_X, PLATE_Y = (0.40, 0.50), (0.23, 0.31)
CUP_X, CUP_Y = (0.42, 0.64), (-0.40, -0.17)
CUP_GAP = 0.05
POT_REACH = HANDLE_INNER + HANDLE_LENGTH + 0.005  # the handle's end, from the pot's axis
ROTATION_RANGE = np.deg2rad(120.0)
TRAIN_CUPS, EVAL_CUPS = (1, 2), (2, 3)
# More cups than the paper's three (``--objects cup=N``; the ``large`` set: 4-6) stand in
# a larger region on the same side, placed one at a time, each centre within the reach
# the pour needs (the hand holds the pot's handle behind the cup).
WIDE_CUP_X, WIDE_CUP_Y, CUP_REACH = (0.32, 0.68), (-0.52, -0.15), 0.78
CUP_LIMITS = (1, 6)
HORIZON = 1000
# -- action ------------------------------------------------------------------------------
MAX_TURN = 0.1  # rad per step, tilt and wrist
WRIST_LIMITS = (-1.9, 1.9)
TILT_LIMITS = (-0.3, 1.2)
TILT_AXIS = np.array([0.0, 1.0, 0.0])  # the fingers' closing axis at wrist 0
CONTROLLER = ControllerConfig(
    home_qpos=HOME_QPOS_TURNED,
    workspace_low=(0.15, -0.6, 0.005),
    workspace_high=(0.85, 0.6, 0.45),
)

ROBOT = Type("robot", ("x", "y", "z", "tilt", "wrist", "fingers"))
POT = Type(
    "pot",
    (
        "x",
        "y",
        "z",
        "rotation",
        "tilt",
        "spout_x",
        "spout_y",
        "spout_z",
        "held",
        "twisted",
        "on_table",
        "on_plate",
        "heat",
        "spilled",
    ),
)
PLATE = Type("plate", ("x", "y", "button_x", "button_y", "button_z", "is_on"))
CUP = Type("cup", ("x", "y", "radius", "rim_z", "capacity", "target", "liquid"))


# -- classifiers (module level so that tasks pickle) --------------------------------------
def _holding(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[1], "held") > 0.5


def _twisting(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[1], "twisted") > 0.5


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    return not any(
        state.get(p, "held") > 0.5 or state.get(p, "twisted") > 0.5
        for p in state.objects_of_type(POT)
    )


def _on_table(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "on_table") > 0.5


def _pot_on_plate(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "on_plate") > 0.5


def _button_pressed(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "is_on") > 0.5


def _pot_hot(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "heat") >= 1.0


def _pressing_button(state: State, objs: Sequence[Object]) -> bool:
    robot, plate = objs
    dx = state.get(robot, "x") - state.get(plate, "button_x")
    dy = state.get(robot, "y") - state.get(plate, "button_y")
    tips = state.get(robot, "z") - FINGERTIP_DROP
    return (
        dx * dx + dy * dy <= PRESSING_RADIUS**2
        and tips - state.get(plate, "button_z") < PRESSING_HEIGHT
    )


def pot_above_cup(state: State, pot: Object, cup: Object) -> bool:
    dx = state.get(pot, "spout_x") - state.get(cup, "x")
    dy = state.get(pot, "spout_y") - state.get(cup, "y")
    r = state.get(cup, "radius") - CUP_WALL
    return dx * dx + dy * dy <= r * r and state.get(pot, "spout_z") > state.get(cup, "rim_z")


def _pot_above_cup(state: State, objs: Sequence[Object]) -> bool:
    return pot_above_cup(state, objs[0], objs[1])


def _robot_above_cup(state: State, objs: Sequence[Object]) -> bool:
    cup = objs[1]
    return any(
        state.get(p, "held") > 0.5 and pot_above_cup(state, p, cup)
        for p in state.objects_of_type(POT)
    )


def _not_above_cup(state: State, objs: Sequence[Object]) -> bool:
    pot = objs[1]
    return not any(pot_above_cup(state, pot, c) for c in state.objects_of_type(CUP))


def spilled(state: State) -> bool:
    """Has coffee been spilled? Then no CupFilled holds again, and every task's goal
    fills a cup: the environment's dead end (``Capabilities.dead_end``)."""
    return any(state.get(p, "spilled") > 0.5 for p in state.objects_of_type(POT))


def _cup_filled(state: State, objs: Sequence[Object]) -> bool:
    cup = objs[0]
    liquid = state.get(cup, "liquid")
    # the cheap test first: segmentation evaluates this on every demonstrated state
    return state.get(cup, "target") <= liquid <= state.get(cup, "capacity") and not spilled(state)


HOLDING = Predicate("Holding", (ROBOT, POT), _holding)
TWISTING = Predicate("Twisting", (ROBOT, POT), _twisting)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
ON_TABLE = Predicate("OnTable", (POT,), _on_table)
POT_ON_PLATE = Predicate("PotOnPlate", (POT, PLATE), _pot_on_plate)
BUTTON_PRESSED = Predicate("ButtonPressed", (PLATE,), _button_pressed)
POT_HOT = Predicate("PotHot", (POT,), _pot_hot)
PRESSING_BUTTON = Predicate("PressingButton", (ROBOT, PLATE), _pressing_button)
POT_ABOVE_CUP = Predicate("PotAboveCup", (POT, CUP), _pot_above_cup)
ROBOT_ABOVE_CUP = Predicate("RobotAboveCup", (ROBOT, CUP), _robot_above_cup)
NOT_ABOVE_CUP = Predicate("NotAboveCup", (ROBOT, POT), _not_above_cup)
CUP_FILLED = Predicate("CupFilled", (CUP,), _cup_filled)


@functools.lru_cache(maxsize=1)
def home_rotation() -> np.ndarray:
    """The grip site's rotation matrix at the home posture (the wrist/tilt reference)."""
    cfg = CONTROLLER
    m = ik_model()
    d = mujoco.MjData(m)
    for name, q in zip(cfg.arm_joints, cfg.home_qpos, strict=True):
        d.qpos[m.joint(name).qposadr[0]] = q
    mujoco.mj_kinematics(m, d)
    return d.site_xmat[m.site(cfg.site).id].reshape(3, 3).copy()


@functools.lru_cache(maxsize=1)
def home_quat() -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, home_rotation().reshape(-1))
    return q


def hand_angles(rot: np.ndarray) -> tuple[float, float]:
    """(wrist, tilt) of a grip-site rotation matrix relative to the home pose."""
    return yaw_tilt_from_matrix(rot, home_rotation(), TILT_AXIS)


def handle_centre(state: State, pot: Object) -> np.ndarray:
    """World xy of the handle bar's centre, from the pot's features."""
    rot = state.get(pot, "rotation")
    r = HANDLE_INNER + HANDLE_LENGTH / 2
    return np.array([state.get(pot, "x"), state.get(pot, "y")]) - r * np.array(
        [np.cos(rot), np.sin(rot)]
    )
