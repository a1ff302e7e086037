"""Drawer: open a cabinet's drawer, put the cube in it, close the drawer.

Rules (as simulated):

* A cabinet (``mj_envs.parts.articulated.add_drawer``) stands on the table, its drawer on
  a damped slide joint that pulls out 19 cm towards the robot, its handle a bar across
  the front. A 4 cm cube (a free body, 0.1 kg) stands on the table beside it.
* Holding(c): both finger pads touch the cube. HoldingHandle(d): the fingers are closed
  to the bar's diameter with its axis between the pads (``env.caught``; the pads'
  contacts with the bar chatter). HandEmpty(r): neither. OnTable(c): the cube touches
  the table and is not held. InDrawer(c, d): the cube touches the drawer's floor and is
  not held (a binary predicate read from the feature ``in_<d>``). These five are
  contact-related (they mark skill boundaries).
* DrawerOpen(d): the slide joint is out at least 80 % of its travel. DrawerClosed(d): at
  most 5 %. Both read the joint, not a contact.
* Action (dx, dy, dz, grip) as in every Panda domain. Goal: InDrawer(cube, drawer) and
  DrawerClosed(drawer), from a closed drawer. Horizon 500 steps.
"""

from __future__ import annotations

from collections.abc import Sequence

from bpns.structs import Object, Predicate, State, Type
from mj_envs.parts.articulated import PART_GAP

CUBE_SIDE, CUBE_MASS = 0.04, 0.1
CABINET_SIZE = (0.24, 0.26, 0.07)  # low enough for the hand's box to pass over its top
WALL = 0.006
TRAVEL = 0.19
FLOOR_Z = 2 * WALL + PART_GAP  # the drawer floor's top face (Drawer.floor_z)
HANDLE_CLEARANCE = 0.06  # room for the open finger between the bar and the drawer front
CABINET_X, CABINET_Y = (0.70, 0.74), (-0.12, 0.12)
CUBE_X, CUBE_Y = (0.36, 0.56), (-0.32, 0.32)
CUBE_CLEARANCE = 0.2  # cube centre to cabinet centre, along y at least
OPEN_FRACTION, CLOSED_FRACTION = 0.8, 0.05
HORIZON = 500

ROBOT = Type("robot", ("x", "y", "z", "fingers"))
DRAWER = Type("drawer", ("x", "y", "z", "opening", "grasped"))  # x, y, z: the handle
CUBE = Type("cube", ("x", "y", "z", "grasped", "on_table", "in_drawer"))


def _holding(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "grasped") > 0.5


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    held = state.objects_of_type(CUBE) + state.objects_of_type(DRAWER)
    return not any(state.get(o, "grasped") > 0.5 for o in held)


def _on_table(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "on_table") > 0.5 and state.get(objs[0], "grasped") < 0.5


def _in_drawer(state: State, objs: Sequence[Object]) -> bool:
    c, d = objs
    return state.get(c, f"in_{d.name}") > 0.5 and state.get(c, "grasped") < 0.5


def _drawer_open(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "opening") >= OPEN_FRACTION


def _drawer_closed(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "opening") <= CLOSED_FRACTION


HOLDING = Predicate("Holding", (CUBE,), _holding)
HOLDING_HANDLE = Predicate("HoldingHandle", (DRAWER,), _holding)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
ON_TABLE = Predicate("OnTable", (CUBE,), _on_table)
IN_DRAWER = Predicate("InDrawer", (CUBE, DRAWER), _in_drawer)
DRAWER_OPEN = Predicate("DrawerOpen", (DRAWER,), _drawer_open)
DRAWER_CLOSED = Predicate("DrawerClosed", (DRAWER,), _drawer_closed)
CONTACT_PREDICATES = frozenset({HOLDING, HOLDING_HANDLE, HAND_EMPTY, ON_TABLE, IN_DRAWER})
PREDICATES = CONTACT_PREDICATES | {DRAWER_OPEN, DRAWER_CLOSED}
