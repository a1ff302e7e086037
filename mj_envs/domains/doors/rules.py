"""Doors' types, predicates, dimensions and the latch rule (see :mod:`mj_envs.domains.doors.env`).

Frames: the floor plan lies in the world xy plane; the arm's mounting plane (top of the
mobile base's pedestal) is z = 0 and the floor z = -0.75. A door's frame has its origin
at the doorway's centre on the wall's centre line, ``u`` = (cos theta, sin theta) along
the wall (pointing to the handle's jamb) and ``n`` = (-sin theta, cos theta) across it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bpns.structs import Object, Predicate, State, Type

# -- floor plan ----------------------------------------------------------------------------
ROOM_SIZE = 2.0  # metres, centre to centre
FLOOR_Z = -0.75
WALL_THICKNESS = 0.1
WALL_TOP = -0.10  # walls stay below the arm (the pedestal is the only part they stop)
DOORWAY_WIDTH = 0.9
# -- doors ---------------------------------------------------------------------------------
LEAF_THICKNESS = 0.05
LEAF_TRAVEL = 0.9  # the leaf slides this far along -u, into the wall (a pocket door)
OPEN_TRAVEL = 0.8  # DoorIsOpen: the leaf has slid at least this far
LEAF_MASS = (0.1, 1.0)  # kg, U(lo, hi): the "mass" of the paper's formula
LEAF_SPRING = 30.0  # N/m towards fully open; the latch (an equality) holds it shut
LEAF_DAMPING = 18.0
LEAF_ARMATURE = 2.0  # kg of reflected drive inertia: opening speed hardly depends on mass
HANDLE_FRICTION_SCALE = 0.1  # the handle hinge's frictionloss (N m) = scale * friction
HANDLE_DAMPING = 0.05
HANDLE_REST = -0.25  # rad: handles start here, below every opening angle
HANDLE_RANGE = (-0.5, 1.8)
HANDLE_TOLERANCE = 0.04  # rad: the latch releases within this of the door's angle
KNOB_ALONG = 0.52  # the handle sits on the wall top beside the doorway, along +u
KNOB_Z = 0.0  # height of the handle's wing (centre)
WING_HALF = (0.045, 0.011, 0.012)  # the wing the fingers close on (along its x)
# TouchingDoor needs the fingers (each finger's travel, m) open wider than this: a grip
# closes at about WING_HALF[1]; closed past half of it, the wing is not between them
TOUCH_MIN_OPENING = 0.006
# -- robot poses relative to a door ----------------------------------------------------------
APPROACH_ALONG = 0.15  # where the base stands to reach the handle (along u) ...
APPROACH_DEPTH = 0.55  # ... and how far from the wall's centre line (along +-n)
DOORWAY_DEPTH = 0.75  # InDoorway: |n-offset| <= this and |u-offset| <= DOORWAY_WIDTH / 2
HORIZON = 1500


def required_angle(mass: float, friction: float, target_rot: float) -> float:
    """The handle angle that releases a door's latch (paper, Doors)."""
    return math.tanh(target_rot) * (math.sin(mass) + math.cos(friction) * math.sqrt(mass))


# wrist: the hand's yaw in the world; twist: the arm's last joint (which turns the hand)
ROBOT = Type("robot", ("x", "y", "yaw", "hand_x", "hand_y", "hand_z", "wrist", "fingers", "twist"))
DOOR = Type(
    "door",
    (
        "x",
        "y",
        "theta",
        "mass",
        "friction",
        "rot",
        "target_rot",
        "open",
        "knob_x",
        "knob_y",
        "knob_z",
        "touched",
    ),
)
ROOM = Type("room", ("x", "y"))


def door_frame(state: State, door: Object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre, u, n) of a door from its features."""
    c = np.array([state.get(door, "x"), state.get(door, "y")])
    th = state.get(door, "theta")
    u = np.array([math.cos(th), math.sin(th)])
    return c, u, np.array([-u[1], u[0]])


def in_doorway_xy(state: State, door: Object, xy: np.ndarray) -> bool:
    c, u, n = door_frame(state, door)
    d = xy - c
    return abs(float(d @ u)) <= DOORWAY_WIDTH / 2 and abs(float(d @ n)) <= DOORWAY_DEPTH


def in_room_xy(state: State, room: Object, xy: np.ndarray) -> bool:
    """Half-open cell test, so a point is in exactly one room."""
    dx = xy[0] - state.get(room, "x")
    dy = xy[1] - state.get(room, "y")
    h = ROOM_SIZE / 2
    return -h <= dx < h and -h <= dy < h


def _base_xy(state: State, robot: Object) -> np.ndarray:
    return np.array([state.get(robot, "x"), state.get(robot, "y")])


def _in_room(state: State, objs: Sequence[Object]) -> bool:
    robot, room = objs
    return in_room_xy(state, room, _base_xy(state, robot))


def _in_doorway(state: State, objs: Sequence[Object]) -> bool:
    robot, door = objs
    return in_doorway_xy(state, door, _base_xy(state, robot))


def _in_main_room(state: State, objs: Sequence[Object]) -> bool:
    robot, room = objs
    xy = _base_xy(state, robot)
    if not in_room_xy(state, room, xy):
        return False
    return not any(in_doorway_xy(state, d, xy) for d in state.objects_of_type(DOOR))


def _touching_door(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[1], "touched") > 0.5


def _door_is_open(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "open") >= OPEN_TRAVEL


def door_in_room(state: State, door: Object, room: Object) -> bool:
    dx = state.get(door, "x") - state.get(room, "x")
    dy = state.get(door, "y") - state.get(room, "y")
    return abs(math.hypot(dx, dy) - ROOM_SIZE / 2) < 0.05


def _door_in_room(state: State, objs: Sequence[Object]) -> bool:
    return door_in_room(state, objs[0], objs[1])


def _doors_share_room(state: State, objs: Sequence[Object]) -> bool:
    d1, d2 = objs
    if d1 == d2:
        return False
    rooms = _rooms_of_doors(state)
    return not rooms[d1].isdisjoint(rooms[d2])


class _LastRooms:
    """The last state asked about and its doors' rooms (a cache, not a setting)."""

    state: State | None = None
    rooms: dict[Object, frozenset[Object]] = {}


def _rooms_of_doors(state: State) -> dict[Object, frozenset[Object]]:
    """Each door's rooms in ``state``, computed once per state: abstracting a state asks
    DoorsShareRoom of every pair of doors (3,600 on a 6x6 map), and scanning the rooms
    for each pair cost a third of the oracle's time there. States are immutable, so the
    same object has the same rooms."""
    if _LastRooms.state is not state:
        rooms = state.objects_of_type(ROOM)
        _LastRooms.rooms = {
            d: frozenset(r for r in rooms if door_in_room(state, d, r))
            for d in state.objects_of_type(DOOR)
        }
        _LastRooms.state = state
    return _LastRooms.rooms


IN_ROOM = Predicate("InRoom", (ROBOT, ROOM), _in_room)
IN_DOORWAY = Predicate("InDoorway", (ROBOT, DOOR), _in_doorway)
IN_MAIN_ROOM = Predicate("InMainRoom", (ROBOT, ROOM), _in_main_room)
TOUCHING_DOOR = Predicate("TouchingDoor", (ROBOT, DOOR), _touching_door)
DOOR_IS_OPEN = Predicate("DoorIsOpen", (DOOR,), _door_is_open)
DOOR_IN_ROOM = Predicate("DoorInRoom", (DOOR, ROOM), _door_in_room)
DOORS_SHARE_ROOM = Predicate("DoorsShareRoom", (DOOR, DOOR), _doors_share_room)
