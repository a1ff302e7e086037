"""Motion primitives the scripted demonstrators and oracle skills are built from.

Every primitive maps the current state (and a goal) to the next end-effector delta; none
keeps state, so a demonstrator stays a closed-loop policy that a small network can
imitate. The arm lags its command, so the gains are below 1 and descents slow down near
their goal.

Conventions shared by every function here:

* Positions are world-frame metres (the Panda's base at the origin, +x forward, the table
  top at z = 0). The hand is the grip site, midway between the finger pads, read from
  the robot's features: its first three are the grip site's (x, y, z) (:func:`hand`), the
  fourth is one finger's opening in metres (:func:`fingers`), as
  :func:`mj_envs.robots.panda.hand_xyz_fingers` writes them.
* An action is ``(dx, dy, dz, grip)``: the hand's translation for one control step
  (0.05 s) in metres, and a finger command in [-1, 1] (+1 opens, -1 closes, each finger
  at |grip| x 0.1 m/s; 0 keeps the fingers' target). The primitives do not clip the
  translation: the controller clips each axis to its ``max_translation``, 0.02 m per step
  by default (:class:`ik.controller.ControllerConfig`), and the environment's action
  bounds are the same.
* No primitive fails or reports completion: each returns an action for any state. Whether
  a motion is done is the caller's test (:func:`at`, or the skill's atoms flipping), and
  :class:`mj_envs.oracles.phases.PhasedDemonstrator` bounds how long a phase may take.
"""

from __future__ import annotations

from collections.abc import Callable
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
    """The grip site's (x, y, z) in metres, world frame: the first three robot features by
    convention.

    Returns a view into ``state``'s feature vector, not a copy: copy it before editing.
    """
    return state.data[robot][:3]


def move_action(state: State, robot: Object, goal_xyz: np.ndarray, grip: float = 0.0) -> np.ndarray:
    """Proportional step toward ``goal_xyz`` with a finger command: (dx, dy, dz, grip).

    ``goal_xyz`` is the grip site's goal (m, world frame); the translation is
    :data:`GAIN` (0.4) times the remaining error on each axis, so each step commands 40 %
    of the remaining way and the hand slows down as it arrives (the controller clips each axis
    to 0.02 m per step, so a far goal is approached at that speed). ``grip`` in [-1, 1] is
    passed through unchanged (default 0: keep the fingers' target). Returns a new array of
    4 floats; never fails. A straight line: nothing keeps the hand above obstacles, see
    :func:`funnel_action` for that.
    """
    return np.array([*(GAIN * (goal_xyz - hand(state, robot))), grip])


def at(state: State, robot: Object, goal_xyz: np.ndarray, tol: float = POS_TOL) -> bool:
    """Whether the grip site is within ``tol`` of ``goal_xyz`` on every axis.

    ``goal_xyz`` in metres (world frame); ``tol`` in metres, default :data:`POS_TOL`
    (0.003). The test is per axis (a cube of half side ``tol``, bounds included), not a
    sphere. False if any coordinate is NaN.
    """
    return bool(np.all(np.abs(hand(state, robot) - goal_xyz) <= tol))


def limit_descent(
    action: np.ndarray, height_above_goal: float, slow_zone: float, slow_step: float
) -> np.ndarray:
    """Within ``slow_zone`` above the goal, descend at most ``slow_step`` per step.

    A full-speed descent overshoots by several millimetres (the arm lags its command):
    enough to put the fingertips on the table. Edits ``action`` in place and returns it.

    ``height_above_goal`` is the hand's height above its goal (m; negative below it),
    ``slow_zone`` the height (m) under which the limit applies (strictly below: at exactly
    ``slow_zone`` the action is untouched), ``slow_step`` the largest descent (m per
    control step, a positive number) allowed there. Only a downward ``action[2]`` is
    limited: rising, sideways motion and the finger command are left as they are. No
    defaults: choose them per task (Stick Button: the last 6 cm at <= 6 mm per step).
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

    The hand is held to the funnel's height ``goal_z + min(max(safe_z - goal_z, 0), slope *
    d)``, where d is the horizontal distance to the goal (less ``deadzone``, inside which the
    funnel is flat), and it moves sideways only as far as that height is reached (fading in
    over ``band``). No phase switches: a continuous function of the state, easy to imitate.

    Arguments: ``goal_xyz``, the grip site's goal (m, world frame); ``grip``, the finger
    command in [-1, 1], passed through; ``safe_z``, the travel height (m, world z, not
    relative to the goal; the funnel is flat at the goal's height where ``safe_z`` is
    below it); ``slope``, the funnel's rise per horizontal distance (m/m, dimensionless);
    ``band`` (m, must be > 0), how far below the funnel the sideways motion fades to zero;
    ``deadzone`` (m, default 0), the horizontal radius around the goal where the funnel is
    flat at the goal's height, so that noise in the horizontal position does not become
    noise in height.

    Precisely, with z_req the funnel's height at the hand: dz = GAIN (z_req - z), so the
    hand is pulled *to* the funnel's surface, up when below it and down when above it;
    dx, dy = GAIN (goal - hand) times s, where s = clip(1 - (z_req - z) / band, 0, 1) is 1
    at or above the funnel and 0 when ``band`` or more below it. Over the goal (d = 0)
    z_req is the goal's height, so the law converges to ``goal_xyz``. It does not slow the
    last centimetres of a descent: combine it with :func:`limit_descent` where that
    matters. Returns a new array (dx, dy, dz, grip); never fails.
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
    """A funnel's shape (see :func:`funnel_action`): travel height, slope and fade band.

    ``safe_z`` (m, world z; default 0.12, 12 cm above the table top) is the travel height,
    ``slope`` (m of height per m of horizontal distance; default 4) how steeply the funnel
    rises away from the goal, ``band`` (m; default 0.02) how far below the funnel the
    sideways motion fades out, ``deadzone`` (m; default 0.005) the radius around the goal
    where the funnel is flat. :func:`grasp_action` uses all four; :func:`release_action`
    does not use ``deadzone``.
    """

    safe_z: float = 0.12
    slope: float = 4.0
    band: float = 0.02
    deadzone: float = 0.005


def fingers(state: State, robot: Object) -> float:
    """The finger opening: the fourth robot feature by convention.

    One finger's joint position in metres: 0 closed, 0.04 fully open (so the gap between
    the pads is twice this). Returns a float.
    """
    return float(state.data[robot][3])


def open_first(state: State, robot: Object, action: np.ndarray) -> np.ndarray:
    """Hold the hand still and open while the fingers are narrower than OPEN_FINGERS.

    Used at the start of any skill that may begin with an object between the fingers.
    Edits ``action`` in place and returns it.

    While :func:`fingers` is below :data:`OPEN_FINGERS` (0.035 m per finger, strictly
    below), the translation is set to 0 and the finger command to +1 (open); at or above
    it the action is returned unchanged.
    """
    if fingers(state, robot) < OPEN_FINGERS:
        action[:3] = 0.0
        action[3] = 1.0
    return action


@dataclass(frozen=True)
class BackOffToStart:
    """A back-off (``Capabilities.back_off``): open the fingers, take the hand straight up
    to ``height``, then back to where it was when the task began; None once there.

    The recovery a closed loop runs when no plan starts from where a failed skill left
    the robot: a hand on the table beside the stick it dropped (still half closed on it),
    or hovering where no demonstration went. Letting go first leaves a dropped object
    where it lies, to be grasped again by a plan; rising to the travel ``height`` (m,
    world z) before moving sideways sweeps nothing aside; the task's start pose with open
    fingers is where every demonstration began, so the skills a plan starts with know it.

    ``wait_open``: hold the hand still until the fingers are :data:`OPEN_FINGERS` open,
    and count the back-off done only then; False where the fingers may not open
    everywhere (Cover's allowed regions): they are told to open all the way and open
    where they may. "There" is every axis of the hand within ``tol`` (m; default 2 cm,
    four times the `hard` worlds' observation noise) of its start.

    ``keep_held``: a type name (e.g. ``"stick"``) whose objects carry a ``grasped``
    feature. While one reads held (> 0.5), the back-off keeps the fingers closed and only
    takes the hand straight up to ``height``, done there: a tool still in hand after a
    stalled skill is worth more than the start pose (Stick Button's press with the stick
    that stopped at its horizon: at the travel height, holding the stick, is where a
    demonstrated second press starts). None: always let go.

    ``holds``: a test of the observed state, ``holds(seen) -> bool``, that the hand still
    carries something though the ``grasped`` reading dropped (a pad slipped off a stick
    that is still between the fingers, rising with the hand). While it says so the
    back-off closes the fingers again and rises, as for ``keep_held``: letting go there
    drops what a re-closed grip would have kept. None: only ``keep_held`` decides.

    For a Panda whose robot object (type ``robot``) has the hand's (x, y, z, fingers)
    first and whose action is ``(dx, dy, dz, grip)`` (+1 opens).
    """

    height: float
    wait_open: bool = True
    tol: float = 0.02
    keep_held: str | None = None
    holds: Callable[[State], bool] | None = None

    def __call__(self, env: object, seen: State, start: State) -> np.ndarray | None:
        robot = next(o for o in seen.data if o.type.name == "robot")
        if self._keeps(seen):
            now = hand(seen, robot)
            up = np.array([now[0], now[1], self.height])
            return None if at(seen, robot, up, self.tol) else move_action(seen, robot, up, -1.0)
        if self.wait_open and fingers(seen, robot) < OPEN_FINGERS:
            return open_first(seen, robot, np.zeros(4))  # let go where it is
        goal = hand(start, robot)
        if at(seen, robot, goal, self.tol):
            return None
        now = hand(seen, robot)
        if now[2] < self.height - self.tol and np.max(np.abs(goal[:2] - now[:2])) > self.tol:
            goal = np.array([now[0], now[1], self.height])  # straight up first
        return move_action(seen, robot, goal, 1.0)

    def _keeps(self, seen: State) -> bool:
        """Does the hand carry something to keep (``keep_held`` or ``holds``)?"""
        if self.keep_held is not None and any(
            o.type.name == self.keep_held and seen.get(o, "grasped") > 0.5 for o in seen.data
        ):
            return True
        return self.holds is not None and bool(self.holds(seen))


def grasp_action(
    state: State, robot: Object, grasp_xyz: np.ndarray, funnel: Funnel, close_tol: float = 0.006
) -> np.ndarray:
    """Go above, descend (funnel) with the fingers open and close once within
    ``close_tol`` of ``grasp_xyz``. The pick is over when both pads touch.

    ``grasp_xyz`` is where the grip site should be when the fingers close (m, world
    frame; e.g. the object's centre, plus a few millimetres to keep the fingertips off its
    support); ``funnel`` the path's shape (all four fields are used); ``close_tol`` (m,
    default 0.006) the largest 3-D (Euclidean) distance from ``grasp_xyz`` at which the
    fingers close.

    Farther than ``close_tol``: the :func:`funnel_action` toward ``grasp_xyz`` with +1
    (open), and :func:`open_first` on top of it, so a hand whose fingers are narrower than
    :data:`OPEN_FINGERS` first opens where it stands. Within ``close_tol``: the same funnel
    step with -1 (close) and no :func:`open_first`, so the hand keeps centring while it
    closes. Returns a new array (dx, dy, dz, grip). It never says the pick is done or
    failed: the caller watches the pads (both touching: Holding) and bounds the steps.
    """
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
    hold still and open (pushing on would slide the object up the pads).

    ``release_xyz`` is the grip site's position (m, world frame) when the object rests
    where it should, not the object's position; ``landed`` is the caller's judgement that
    the object touches its support (e.g. a contact feature); ``funnel`` the path's shape
    (``safe_z``, ``slope`` and ``band``; its ``deadzone`` is not used, the funnel here is
    flat only exactly above ``release_xyz``); ``release_tol`` (m, default 0.006) the
    largest horizontal (x, y) distance from ``release_xyz`` at which the fingers open.

    Until then: the :func:`funnel_action` toward ``release_xyz`` with -1 (closed). Then:
    :func:`move_action` toward (release x, release y, the hand's current z) with +1
    (open), which holds the height and keeps centring. So an object that lands above
    ``release_xyz`` (a higher support) is let go where it landed, and one that never lands
    is held closed at ``release_xyz``. Returns a new array (dx, dy, dz, grip); it never
    says the place is done: the caller watches the pads let go.
    """
    pos = hand(state, robot)
    if landed and np.hypot(*(release_xyz[:2] - pos[:2])) <= release_tol:
        return move_action(state, robot, np.array([release_xyz[0], release_xyz[1], pos[2]]), 1.0)
    return funnel_action(state, robot, release_xyz, -1.0, funnel.safe_z, funnel.slope, funnel.band)
