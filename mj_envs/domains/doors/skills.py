"""Doors' skills: the paper's four operators, the given motion-planning policies
(MoveToDoor, MoveThroughDoor) and the oracle OpenDoor policy and samplers.

Policies are stateless functions of (state, objects, subgoal), so the scripted
demonstrator runs the very same code the planner does. The given ones are deterministic
given their inputs: the base planner's random numbers are seeded from the query.

* MoveToDoor: retract the arm to its carry pose and drive (RRT path inside the map, among
  walls, obstacles and closed leaves) to the door's approach pose on the robot's side,
  facing the wall; then put the open fingers around the handle's wing and close them
  until they touch it (TouchingDoor: the segment boundary the demonstrations show).
* OpenDoor (learned in BPNS; oracle here): grip the wing, turn the wrist until the handle
  reads the subgoal's angle, hold until the leaf has slid open, let go and lift.
* MoveThroughDoor: arm in carry pose, straight through the doorway towards the far side's
  approach pose until the base is in the far room.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from bpns.structs import GivenSkill, Object, Skill, State, Variable
from mj_envs.domains.doors.motion import BasePlanner, NoPathFound, path_seed, scene_boxes
from mj_envs.domains.doors.rules import (
    APPROACH_ALONG,
    APPROACH_DEPTH,
    DOOR,
    DOOR_IN_ROOM,
    DOOR_IS_OPEN,
    DOORS_SHARE_ROOM,
    HANDLE_TOLERANCE,
    IN_DOORWAY,
    IN_MAIN_ROOM,
    IN_ROOM,
    KNOB_Z,
    OPEN_TRAVEL,
    ROBOT,
    ROOM,
    ROOM_SIZE,
    TOUCHING_DOOR,
    WING_HALF,
    door_frame,
    required_angle,
)
from mj_envs.oracles.motions import GAIN
from mj_envs.oracles.operators import atom, make_operator
from mj_envs.robots.mobile_panda import to_base_frame

CARRY = np.array([0.45, 0.0, 0.35])  # hand in the base frame while driving
CARRY_WRIST = math.pi / 2  # hand x axis relative to the base's heading at home
ABOVE = 0.07  # hand height above the wing before descending
DESCENDING = 0.02  # a hand this far below ABOVE has begun its descent onto the wing
POS_TOL, YAW_TOL = 0.015, 0.03
FINGERS_OPEN, FINGERS_GRIP = 0.035, 0.016
TURN_GAIN = 0.3
TURN_MAX = 0.06
ROT_NOISE = HANDLE_TOLERANCE / 3
J7_GRASP = 0.85  # joint 7 at the grasp: the opening turn (<= 1.75 rad) then stays in range


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _robot(state: State, robot: Object):
    v = state.data[robot]
    return v[0:2], float(v[2]), v[3:6], float(v[6]), float(v[7])


def _action(base=(0.0, 0.0, 0.0), hand=(0.0, 0.0, 0.0), wrist=0.0, grip=0.0) -> np.ndarray:
    return np.array([*base, *hand, wrist, grip], dtype=np.float64)


def _hand_to(
    state: State,
    robot: Object,
    target_world: np.ndarray,
    wrist_target: float,
    grip: float,
    speed: float = 0.02,
) -> tuple[np.ndarray, bool]:
    """Hand (and wrist) towards a world target; returns (hand delta in base frame, wrist
    delta) packed into an action and whether it is there."""
    xy, yaw, hand, wrist, _ = _robot(state, robot)
    err = target_world - hand
    d = GAIN * to_base_frame(yaw, err)
    n = float(np.max(np.abs(d)))
    if n > speed:
        d = d * (speed / n)
    dw = float(np.clip(GAIN * _wrap(wrist_target - wrist), -0.15, 0.15))
    done = float(np.max(np.abs(err))) < POS_TOL * 0.5 and abs(_wrap(wrist_target - wrist)) < 0.05
    return _action(hand=d, wrist=dw, grip=grip), done


def _carry(state: State, robot: Object, grip: float = 1.0) -> np.ndarray:
    """Hand back to the carry pose (base frame) and the wrist to its home angle."""
    xy, yaw, hand, wrist, _ = _robot(state, robot)
    c, s = math.cos(yaw), math.sin(yaw)
    target = np.array(
        [xy[0] + c * CARRY[0] - s * CARRY[1], xy[1] + s * CARRY[0] + c * CARRY[1], CARRY[2]]
    )
    a, _ = _hand_to(state, robot, target, yaw + CARRY_WRIST, grip)
    return a


def _side(state: State, door: Object, point: np.ndarray) -> float:
    c, _, n = door_frame(state, door)
    return 1.0 if float((point - c) @ n) >= 0 else -1.0


def approach_pose(state: State, door: Object, side: float) -> tuple[np.ndarray, float]:
    """Base pose from which the handle is reached, on ``side`` (+-1 along n) of the door."""
    c, u, n = door_frame(state, door)
    xy = c + APPROACH_ALONG * u + side * APPROACH_DEPTH * n
    forward = -side * n
    return xy, math.atan2(forward[1], forward[0])


def _closed_doors(state: State) -> frozenset[int]:
    return frozenset(
        int(d.name[len("door") :])
        for d in state.objects_of_type(DOOR)
        if state.get(d, "open") < OPEN_TRAVEL
    )


@functools.lru_cache(maxsize=256)
def _planner(world, closed: frozenset[int], rooms: tuple[float, float, float, float]):
    return BasePlanner(scene_boxes(world.model, closed), np.array(rooms[:2]), np.array(rooms[2:]))


def plan_base_path(state: State, goal: np.ndarray) -> list[np.ndarray]:
    """A collision-free base path from the measured base position to ``goal`` (seeded from
    the query: the same state gives the same path)."""
    robot = state.objects_of_type(ROBOT)[0]
    xy = _robot(state, robot)[0]
    rooms = state.objects_of_type(ROOM)
    h = ROOM_SIZE / 2
    xs = [state.get(r, "x") for r in rooms]
    ys = [state.get(r, "y") for r in rooms]
    bounds = (min(xs) - h, min(ys) - h, max(xs) + h, max(ys) + h)
    world = state.sim.world if state.sim is not None else None
    planner = _planner(world, _closed_doors(state), bounds)
    rng = np.random.default_rng(path_seed(xy[0], xy[1], goal[0], goal[1]))
    return planner.plan(xy, goal, rng)


def _drive(
    state: State, robot: Object, goal_xy: np.ndarray, goal_yaw: float, path: list[np.ndarray] | None
) -> tuple[np.ndarray, bool]:
    xy, yaw, *_ = _robot(state, robot)
    waypoint = goal_xy if path is None or len(path) < 2 else path[1]
    d = waypoint - xy
    dyaw = _wrap(goal_yaw - yaw)
    done = float(np.linalg.norm(goal_xy - xy)) < POS_TOL and abs(dyaw) < YAW_TOL
    a = _carry(state, robot)
    a[0:2] = GAIN * d
    a[2] = GAIN * dyaw
    return a, done


class MoveToDoorPolicy:
    """Given skill: plan and drive to the door's approach pose, then touch its handle."""

    def __init__(self, door_index: int) -> None:
        self.door_index = door_index  # which operator parameter is the target door

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, door = objects[0], objects[self.door_index]
        xy, yaw, hand, wrist, fingers = _robot(state, robot)
        side = _side(state, door, xy)
        goal_xy, goal_yaw = approach_pose(state, door, side)
        at_base = (
            float(np.linalg.norm(goal_xy - xy)) < 3 * POS_TOL
            and abs(_wrap(goal_yaw - yaw)) < 3 * YAW_TOL
        )
        if not at_base:
            try:
                path = plan_base_path(state, goal_xy)
            except NoPathFound:
                path = None
            return _drive(state, robot, goal_xy, goal_yaw, path)[0]
        return reach_handle(state, robot, door)


def reach_handle(state: State, robot: Object, door: Object) -> np.ndarray:
    """Open fingers above the wing, aligned with it; descend; close until touching.

    The descent starts once the hand is within ``POS_TOL`` of the wing and the fingers
    within 0.05 rad of it, and goes on while they stay within looser bounds (1.5x,
    0.15 rad; the open fingers clear the wing by 24 mm): without that hysteresis a
    hand that rings about its target (two steps of command latency) meets the strict
    bounds only for a step at a time and hovers above the wing until its horizon.

    A hand low beside the wing with its fingers closed, outside those bounds (or one
    under the wing), that does not touch it first rises straight up, its fingers and
    wrist as they are (turning or opening them there catches the wing: a touch that is
    no grasp), then comes down again as above. Without that a hand whose grip the wing
    had slipped out of stayed closed on nothing, and a replan from there never refined.
    A low hand with open fingers aligns as it descends, as before."""
    xy, yaw, hand, wrist, fingers = _robot(state, robot)
    knob = np.array([state.get(door, "knob_x"), state.get(door, "knob_y"), KNOB_Z])
    dw = grasp_wrist_delta(state, robot, door)
    err_xy = float(np.max(np.abs(knob[:2] - hand[:2])))
    descending = hand[2] < knob[2] + ABOVE - DESCENDING
    aligned = abs(dw) < (0.15 if descending else 0.05)
    off = err_xy > (1.5 * POS_TOL if descending else POS_TOL) or not aligned
    low = hand[2] <= knob[2] + 0.02
    bottom = hand[2] <= knob[2] + 0.004
    under = hand[2] < knob[2] - 1.25 * WING_HALF[2]
    closed = fingers < FINGERS_GRIP  # too closed to pass the wing: nothing between them
    missed = low and state.get(door, "touched") < 0.5 and ((off and closed) or under)
    if missed:  # straight up, fingers and wrist as they are, clear of the wing
        a, _ = _hand_to(state, robot, hand + np.array([0, 0, ABOVE]), wrist, 0.0)
        return a
    if not low and (off or fingers < FINGERS_OPEN):
        a, _ = _hand_to(state, robot, knob + np.array([0, 0, ABOVE]), wrist, 1.0)
    elif not bottom:
        a, _ = _hand_to(state, robot, knob, wrist, 1.0, speed=0.01)
    else:
        a, _ = _hand_to(state, robot, knob, wrist, -1.0, speed=0.005)
    a[6] = float(np.clip(GAIN * dw, -0.15, 0.15))
    return a


def grasp_wrist_delta(state: State, robot: Object, door: Object) -> float:
    """Wrist turn that aligns the fingers with the wing: of the wing's alignments (mod pi)
    the one that leaves joint 7 ("twist") room to turn the handle up to its largest
    opening angle (turning the hand by +a moves joint 7 by about -a)."""
    wrist = state.get(robot, "wrist")
    d = _wrap(state.get(door, "theta") + state.get(door, "rot") - wrist)
    twist = state.get(robot, "twist")
    return min(
        (d + k * math.pi for k in (-2, -1, 0, 1, 2)), key=lambda c: abs(twist - c - J7_GRASP)
    )


class OpenDoorPolicy:
    """Oracle: grip the wing, turn the handle to the subgoal's angle, wait for the leaf,
    let go and lift. ``subgoal`` is the scope vector (robot, door); its door ``rot`` is the
    angle to turn to."""

    ROT = ROBOT.dim + DOOR.feature_names.index("rot")

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, door = objects[0], objects[1]
        xy, yaw, hand, wrist, fingers = _robot(state, robot)
        knob = np.array([state.get(door, "knob_x"), state.get(door, "knob_y"), KNOB_Z])
        opening = state.get(door, "open")
        if opening >= OPEN_TRAVEL:  # let go and lift
            a, _ = _hand_to(state, robot, knob + np.array([0, 0, ABOVE]), wrist, 1.0, speed=0.01)
            if fingers < FINGERS_OPEN * 0.8:
                a[3:6] = 0.0
            return a
        if opening > 0.02:  # released: hold still while the leaf slides
            return _action(grip=-1.0)
        if fingers > FINGERS_GRIP:  # close on the wing first
            a, _ = _hand_to(state, robot, knob, wrist, -1.0, speed=0.005)
            return a
        err = float(subgoal[self.ROT]) - state.get(door, "rot")
        a, _ = _hand_to(state, robot, knob, wrist, -1.0, speed=0.005)
        a[6] = float(np.clip(TURN_GAIN * err, -TURN_MAX, TURN_MAX))
        return a


class MoveThroughDoorPolicy:
    """Given skill: arm in carry pose, straight through the doorway into room ``to``
    (the operator parameter at ``to_index``)."""

    def __init__(self, to_index: int = 3) -> None:
        self.to_index = to_index

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        robot, door, to_room = objects[0], objects[1], objects[self.to_index]
        room_xy = np.array([state.get(to_room, "x"), state.get(to_room, "y")])
        goal_xy, goal_yaw = approach_pose(state, door, _side(state, door, room_xy))
        xy, yaw, *_ = _robot(state, robot)
        fwd_yaw = goal_yaw + math.pi  # keep facing the way we go
        a, _ = _drive(
            state, robot, goal_xy, yaw if abs(_wrap(fwd_yaw - yaw)) < 0.3 else fwd_yaw, None
        )
        if float(np.max(np.abs(a[3:6]))) > 0.01 and state.get(robot, "hand_z") < 0.1:
            a[0:3] = 0.0  # lift the hand clear before driving
        return a


# -- samplers ------------------------------------------------------------------------------
class CurrentSubgoal:
    """Given skills need no subgoal: the scope vector as it is."""

    def __call__(self, state: State, objects: Sequence[Object], rng: np.random.Generator):
        return state.vec(objects).copy()


class OpenDoorSampler:
    """Oracle: the door's own angle (the paper's formula), jittered within the tolerance."""

    def __call__(self, state: State, objects: Sequence[Object], rng: np.random.Generator):
        door = objects[1]
        sub = state.vec(objects).copy()
        target = required_angle(
            state.get(door, "mass"), state.get(door, "friction"), state.get(door, "target_rot")
        )
        sub[OpenDoorPolicy.ROT] = target + rng.uniform(-ROT_NOISE, ROT_NOISE)
        return sub


# -- operators -----------------------------------------------------------------------------
_R = Variable("?robot", ROBOT)
_D, _F = Variable("?door", DOOR), Variable("?from_door", DOOR)
_RM, _TO = Variable("?room", ROOM), Variable("?to_room", ROOM)


MOVE_TO_DOOR_FROM_MAIN_ROOM = make_operator(
    "MoveToDoorFromMainRoom",
    (_R, _D, _RM),
    {atom(IN_MAIN_ROOM, _R, _RM), atom(DOOR_IN_ROOM, _D, _RM)},
    {atom(IN_DOORWAY, _R, _D), atom(TOUCHING_DOOR, _R, _D)},
    {atom(IN_MAIN_ROOM, _R, _RM)},
)
MOVE_TO_DOOR_FROM_DOORWAY = make_operator(
    "MoveToDoorFromDoorway",
    (_R, _D, _F, _RM),
    {
        atom(IN_DOORWAY, _R, _F),
        atom(IN_ROOM, _R, _RM),
        atom(DOOR_IN_ROOM, _D, _RM),
        atom(DOORS_SHARE_ROOM, _F, _D),
    },
    {atom(IN_DOORWAY, _R, _D), atom(TOUCHING_DOOR, _R, _D)},
    {atom(IN_DOORWAY, _R, _F)},
)
OPEN_DOOR = make_operator(
    "OpenDoor",
    (_R, _D),
    {atom(IN_DOORWAY, _R, _D), atom(TOUCHING_DOOR, _R, _D)},
    {atom(DOOR_IS_OPEN, _D)},
    {atom(TOUCHING_DOOR, _R, _D)},
)
MOVE_THROUGH_DOOR = make_operator(
    "MoveThroughDoor",
    (_R, _D, _RM, _TO),
    {
        atom(IN_DOORWAY, _R, _D),
        atom(DOOR_IS_OPEN, _D),
        atom(IN_ROOM, _R, _RM),
        atom(DOOR_IN_ROOM, _D, _RM),
        atom(DOOR_IN_ROOM, _D, _TO),
    },
    {atom(IN_ROOM, _R, _TO)},
    {atom(IN_ROOM, _R, _RM)},
)


def oracle_skills() -> list[Skill]:
    given = CurrentSubgoal()
    return [
        Skill(MOVE_TO_DOOR_FROM_MAIN_ROOM, MoveToDoorPolicy(1), given),
        Skill(MOVE_TO_DOOR_FROM_DOORWAY, MoveToDoorPolicy(1), given),
        Skill(OPEN_DOOR, OpenDoorPolicy(), OpenDoorSampler()),
        Skill(MOVE_THROUGH_DOOR, MoveThroughDoorPolicy(), given),
    ]


# -- given skills (bpns.learning.given): what the motion planner provides -----------------------
MOVE_TO_DOOR_SIGNATURE = make_operator(
    "MoveToDoor", (_R, _D), set(), {atom(IN_DOORWAY, _R, _D), atom(TOUCHING_DOOR, _R, _D)}, set()
)
MOVE_THROUGH_DOOR_SIGNATURE = make_operator(
    "MoveThroughDoor",
    (_R, _D, _TO),
    {atom(IN_DOORWAY, _R, _D), atom(DOOR_IS_OPEN, _D), atom(DOOR_IN_ROOM, _D, _TO)},
    {atom(IN_ROOM, _R, _TO)},
    set(),
)


def given_skills() -> list[GivenSkill]:
    """MoveToDoor and MoveThroughDoor: any learned operator they produce uses them."""
    return [
        GivenSkill("MoveToDoor", MOVE_TO_DOOR_SIGNATURE, MoveToDoorPolicy(1), CurrentSubgoal()),
        GivenSkill(
            "MoveThroughDoor",
            MOVE_THROUGH_DOOR_SIGNATURE,
            MoveThroughDoorPolicy(2),
            CurrentSubgoal(),
        ),
    ]
