"""Stick Button in 3D: press every button, the far ones with a stick (paper App. A.3).

Rules (final, as simulated):

* Buttons are real push buttons: a static housing (7 cm wide) with a red cap (4.4 cm
  wide, top 4.5 cm above the table) on a vertical slide joint with a preloaded spring
  (stiffness 25 N/m, 0.15 N at rest, 0.35 N at the latch depth) and 12 mm of travel.
  A cap pushed down past ``LATCH_DEPTH`` (8 mm) *latches*: after that physics step an
  equality constraint (saved with the simulator state, ``eq_active``) holds it at 9.5 mm,
  so it stays down when released, and it is drawn green.
* Near buttons lie within 0.68 m of the Panda's base and are pressed with the closed
  fingertips. Far buttons lie 0.92-1.02 m from the base, beyond the fingertips' physical
  reach (about 0.84 m at button height; the workspace box is wider, so this is the arm's
  own limit, not a software clip). Train tasks have 1-2 buttons, eval tasks 3-4; each is
  far with probability 1/2. Goal: Pressed for every button.
* The stick (a 50 x 3 x 3 cm, 60 g box) lies on the table pointing forward (+x); its back
  12 cm rest in a slotted holder whose walls are taller than the stick and leave 6 mm
  either side (less than a finger's thickness), so fingers can only close around the
  stick's free part: over the holder they land on the walls' tops. The fingers close
  along y (the hand is turned 90 deg from Cover's), so a grasped stick stays horizontal
  along +x and its tip (a point 1.5 cm behind the front end, on the bottom face) presses
  a button when lowered onto the cap. The grasp point along the free part decides how far
  the tip reaches (paper KD1). No button lies in a far button's stick lane (|dy| < 8 cm),
  so the lowered stick never rests on another button. No button lies within 6 cm (xy) of
  the gripper's home position, so every task starts with AboveNoButton.
* Pressed(button): the cap's slide joint reads a travel >= LATCH_DEPTH (joint reading).
  Grasped(robot, stick): both finger pads touch the stick (MuJoCo contact list).
  HandEmpty(robot): no stick is grasped. RobotAboveButton(robot, button): the gripper
  centre is within 3 cm of the button's axis in xy. StickAboveButton(stick, button): the
  stick tip is within 3 cm of it in xy. AboveNoButton(): neither the gripper nor the tip
  is above any button (zero-arity, as in the paper). Contact-related: Grasped, Pressed.
* Action (dx, dy, dz, grip): end-effector translation in metres per 0.05 s step
  (|d| <= 2 cm) and a finger command in [-1, 1] (+1 opens, -1 closes at 0.1 m/s), as in
  Cover. The robot starts at its home pose; the stick (and holder) start on the left or
  right, 38-45 cm from the centre line. Horizon 1000 steps.
* Eval tasks with more buttons (``bpns eval --eval-set large``: 5-8; ``--objects
  button=N``, N in 1..8) use the same regions and rules, the buttons placed one at a
  time; the horizon grows to 250 steps per button.
"""

from __future__ import annotations

from collections.abc import Sequence

from bpns.structs import Object, Predicate, State, Type
from ik import ControllerConfig
from mj_envs.parts.button import CAP_HALF_HEIGHT, CAP_REST_TOP, LATCH_DEPTH  # noqa: F401
from mj_envs.robots.panda import HOME_QPOS_TURNED

ABOVE_RADIUS = 0.03
# -- stick and holder ------------------------------------------------------------------
STICK_LENGTH, STICK_WIDTH, STICK_HEIGHT, STICK_MASS = 0.5, 0.03, 0.03, 0.06
TIP_INSET = 0.015  # the tip point lies this far behind the front end
HOLDER_LENGTH, HOLDER_WALL, HOLDER_HEIGHT, HOLDER_GAP = 0.12, 0.05, 0.04, 0.006
HOLDER_FRICTION = (0.3, 0.005, 0.0001)  # smooth plastic: the stick slides out freely
STICK_BACK_X = (0.12, 0.20)
STICK_SIDE_Y = (0.38, 0.45)
# -- layout ----------------------------------------------------------------------------
NEAR_X, NEAR_Y, NEAR_RADIUS = (0.35, 0.62), 0.25, 0.68
FAR_RADIUS, FAR_Y = (0.92, 1.02), 0.30
BUTTON_SPACING = 0.09  # centre distance, housings 2 cm apart
LANE_HALF_WIDTH = 0.08  # |dy| that keeps a button out of a far button's stick lane
# The gripper's xy at the home pose: no button starts under the hand, so every task
# starts in AboveNoButton (as in the paper, whose skills all start from there or from
# a button just pressed).
HOME_HAND_XY, HOME_CLEARANCE = (0.463, 0.0), 0.06
TRAIN_BUTTONS, EVAL_BUTTONS = (1, 2), (3, 4)
# ``--objects button=N``: up to eight fit the regions with their spacing and lanes (more
# than four are placed one at a time); the ``large`` set has 5-8.
BUTTON_LIMITS = (1, 8)
HORIZON = 1000
TABLE_HALF = (0.62, 0.65, 0.025)
TABLE_CENTRE_X = 0.55

ROBOT = Type("robot", ("x", "y", "z", "fingers"))
BUTTON = Type("button", ("x", "y", "z", "pressed"))
STICK = Type("stick", ("x", "y", "z", "tip_x", "tip_y", "tip_z", "grasped"))
HOLDER = Type("holder", ("x", "y"))


def _robot_above(state: State, objs: Sequence[Object]) -> bool:
    robot, button = objs
    return _near_xy(state, robot, "x", "y", button)


def _stick_above(state: State, objs: Sequence[Object]) -> bool:
    stick, button = objs
    return _near_xy(state, stick, "tip_x", "tip_y", button)


def _near_xy(state: State, obj: Object, fx: str, fy: str, button: Object) -> bool:
    dx = state.get(obj, fx) - state.get(button, "x")
    dy = state.get(obj, fy) - state.get(button, "y")
    return dx * dx + dy * dy <= ABOVE_RADIUS * ABOVE_RADIUS


def _above_no_button(state: State, objs: Sequence[Object]) -> bool:
    buttons = state.objects_of_type(BUTTON)
    for robot in state.objects_of_type(ROBOT):
        if any(_robot_above(state, (robot, b)) for b in buttons):
            return False
    for stick in state.objects_of_type(STICK):
        if any(_stick_above(state, (stick, b)) for b in buttons):
            return False
    return True


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    return not any(state.get(s, "grasped") > 0.5 for s in state.objects_of_type(STICK))


def _pressed(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "pressed") > 0.5


def _grasped(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[1], "grasped") > 0.5


# Classifiers are module-level functions (not lambdas) so tasks pickle to worker processes.
PRESSED = Predicate("Pressed", (BUTTON,), _pressed)
GRASPED = Predicate("Grasped", (ROBOT, STICK), _grasped)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
ROBOT_ABOVE_BUTTON = Predicate("RobotAboveButton", (ROBOT, BUTTON), _robot_above)
STICK_ABOVE_BUTTON = Predicate("StickAboveButton", (STICK, BUTTON), _stick_above)
ABOVE_NO_BUTTON = Predicate("AboveNoButton", (), _above_no_button)

# The hand is turned a quarter turn about the vertical (joint 7) so the fingers close
# along y and hold the stick along +x; the workspace box reaches past the arm's own
# limit so that reach is decided by kinematics, not by clipping.
CONTROLLER = ControllerConfig(
    home_qpos=HOME_QPOS_TURNED,
    workspace_low=(0.15, -0.6, 0.005),
    workspace_high=(1.0, 0.6, 0.45),
)
