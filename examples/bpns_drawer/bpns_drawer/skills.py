"""Drawer's oracle skills: five operators, each with a policy built from the motion
primitives of ``mj_envs.oracles.motions`` and a sampler of its subgoal.

A subgoal is a vector over the operator's objects' features (``state.vec(objects)``); the
policies here read its first three entries, where the hand should end. The scripted
demonstrator runs these same policies (``demonstrator.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import LiftedAtom, Object, Skill, State, STRIPSOperator, Variable
from bpns_drawer.rules import (
    CUBE,
    CUBE_SIDE,
    DRAWER,
    DRAWER_CLOSED,
    DRAWER_OPEN,
    FLOOR_Z,
    HAND_EMPTY,
    HOLDING,
    HOLDING_HANDLE,
    IN_DRAWER,
    ON_TABLE,
    ROBOT,
    TRAVEL,
)
from mj_envs.oracles.motions import (
    Funnel,
    funnel_action,
    grasp_action,
    limit_descent,
    move_action,
)

# travel above the cabinet (7 cm) with a cube in hand; over the goal, a flat 1 cm wide
# bottom: a cloned policy a few millimetres off its goal still descends instead of
# hovering where the funnel's slope would send it up again
FUNNEL = Funnel(safe_z=0.13, deadzone=0.01)
# a place aims 1 cm below where the cube lands, descends the last 6 cm at a steady 3 mm a
# step anywhere within 2 cm of its goal, and opens without stopping: its command never
# fades near the goal (a cloned policy would stall 2 mm above the floor, between
# "descend" and "stop")
PLACE_FUNNEL = Funnel(safe_z=0.13, deadzone=0.02)
PLACE_BELOW, PLACE_STEP = 0.01, 0.003
HANDLE_CLOSE_TOL = 0.012  # a handle grasp closes this near its grasp point (the bar is
# caught anywhere between the open fingers; a wide tolerance keeps the close decision
# away from where the hand comes to rest)
GRASP_DZ = 0.005  # the grip site this far above a cube's centre or the handle's axis
SLIDE_STEP = 0.005  # m a step: the drawer's damping then resists with 1 N, well under
# the ~3 N with which the closed fingers squeeze the bar
RELEASE_FRACTION = 0.95  # a pull lets go of the handle once the drawer is this far out
INSIDE_X = (0.155, 0.175)  # where the cube goes in the open drawer: x beyond the handle,
INSIDE_Y = 0.01  # and at most this far from it along y (the open fingers stay clear)


def handle_policy(state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    """Grasp the handle with the hand at ``subgoal[:3]``."""
    return grasp(state, objects[0], subgoal[:3], HANDLE_CLOSE_TOL)


def pick_policy(state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    """Grasp the cube with the hand at ``subgoal[:3]``."""
    return grasp(state, objects[0], subgoal[:3], 0.006)


def grasp(state: State, robot: Object, goal: np.ndarray, close_tol: float) -> np.ndarray:
    """``grasp_action`` with the last 5 cm of its descent at most 4 mm a step (a faster
    one overshoots the grasp point by a centimetre: the arm lags its command)."""
    action = grasp_action(state, robot, goal, FUNNEL, close_tol)
    return limit_descent(action, state.get(robot, "z") - goal[2], 0.05, 0.004)


def handle_sampler(state: State, objects: Sequence[Object], rng: np.random.Generator):
    robot, drawer = objects
    sub = state.vec(objects).copy()
    sub[:3] = state.data[drawer][:3] + [0.0, rng.uniform(-0.02, 0.02), GRASP_DZ]
    return sub


def cube_sampler(state: State, objects: Sequence[Object], rng: np.random.Generator):
    sub = state.vec(objects).copy()
    sub[:3] = state.data[objects[1]][:3] + [0.0, 0.0, GRASP_DZ] + rng.uniform(-0.002, 0.002, 3)
    return sub


def open_policy(state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    """Pull the held handle towards ``subgoal[:3]``; let go once the drawer is out."""
    robot, drawer = objects
    if state.get(drawer, "opening") >= RELEASE_FRACTION:
        return move_action(state, robot, state.data[robot][:3], grip=1.0)  # hold still, open
    return slide_action(state, robot, subgoal[:3])


def close_policy(state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    """Push the held handle towards ``subgoal[:3]``."""
    return slide_action(state, objects[0], subgoal[:3])


def slide_action(state: State, robot: Object, goal: np.ndarray) -> np.ndarray:
    """Move the closed hand towards ``goal`` at most ``SLIDE_STEP`` a step per axis."""
    action = move_action(state, robot, goal, grip=-1.0)
    action[:3] = np.clip(action[:3], -SLIDE_STEP, SLIDE_STEP)
    return action


def open_sampler(state: State, objects: Sequence[Object], rng: np.random.Generator):
    sub = state.vec(objects).copy()
    sub[0] -= (1.0 - state.get(objects[1], "opening")) * TRAVEL
    return sub


def close_sampler(state: State, objects: Sequence[Object], rng: np.random.Generator):
    sub = state.vec(objects).copy()
    sub[0] += state.get(objects[1], "opening") * TRAVEL
    return sub


def place_policy(state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    """Carry the cube to ``subgoal[:3]`` over the open drawer and lower it in; once it
    touches the drawer's floor, let go while still sinking 1 mm a step."""
    robot, cube, drawer = objects
    goal = subgoal[:3] - [0.0, 0.0, PLACE_BELOW]
    f = PLACE_FUNNEL
    action = funnel_action(state, robot, goal, -1.0, f.safe_z, f.slope, f.band, f.deadzone)
    action = limit_descent(action, state.get(robot, "z") - goal[2], 0.06, PLACE_STEP)
    if state.get(cube, f"in_{drawer.name}") > 0.5:
        action[2:] = max(action[2], -0.001), 1.0
    return action


def place_sampler(state: State, objects: Sequence[Object], rng: np.random.Generator):
    robot, cube, drawer = objects
    sub = state.vec(objects).copy()
    held_above = state.get(robot, "z") - state.get(cube, "z")  # the grasp's height offset
    handle = state.data[drawer][:3]
    sub[0] = handle[0] + rng.uniform(*INSIDE_X)
    sub[1] = handle[1] + rng.uniform(-INSIDE_Y, INSIDE_Y)
    sub[2] = FLOOR_Z + CUBE_SIDE / 2 + held_above  # where the cube lands
    return sub


_R, _D, _C = Variable("?robot", ROBOT), Variable("?drawer", DRAWER), Variable("?cube", CUBE)


def _op(name, params, pre, add, delete) -> STRIPSOperator:
    def atoms(spec):
        return frozenset(LiftedAtom(p, tuple(args)) for p, *args in spec)

    return STRIPSOperator(name, params, atoms(pre), atoms(add), atoms(delete))


GRASP_HANDLE = _op(
    "GraspHandle", (_R, _D), [(HAND_EMPTY, _R)], [(HOLDING_HANDLE, _D)], [(HAND_EMPTY, _R)]
)
OPEN = _op(
    "OpenDrawer", (_R, _D),
    [(HOLDING_HANDLE, _D), (DRAWER_CLOSED, _D)],
    [(DRAWER_OPEN, _D), (HAND_EMPTY, _R)],
    [(HOLDING_HANDLE, _D), (DRAWER_CLOSED, _D)],
)  # fmt: skip
PICK = _op(
    "Pick", (_R, _C),
    [(HAND_EMPTY, _R), (ON_TABLE, _C)],
    [(HOLDING, _C)],
    [(HAND_EMPTY, _R), (ON_TABLE, _C)],
)  # fmt: skip
PLACE = _op(
    "PlaceInDrawer", (_R, _C, _D),
    [(HOLDING, _C), (DRAWER_OPEN, _D)],
    [(IN_DRAWER, _C, _D), (HAND_EMPTY, _R)],
    [(HOLDING, _C)],
)  # fmt: skip
CLOSE = _op(
    "CloseDrawer", (_R, _D),
    [(HOLDING_HANDLE, _D), (DRAWER_OPEN, _D)],
    [(DRAWER_CLOSED, _D)],
    [(DRAWER_OPEN, _D)],
)  # fmt: skip
SKILLS = {
    GRASP_HANDLE: (handle_policy, handle_sampler),
    OPEN: (open_policy, open_sampler),
    PICK: (pick_policy, cube_sampler),
    PLACE: (place_policy, place_sampler),
    CLOSE: (close_policy, close_sampler),
}


def oracle_skills() -> list[Skill]:
    """The five hand-written skills: what ``--approach oracle`` plans with."""
    return [Skill(op, policy, sampler) for op, (policy, sampler) in SKILLS.items()]
