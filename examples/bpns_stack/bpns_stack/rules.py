"""Stack: build a tower of two or three cubes on the table.

Rules (as simulated):

* Three 4.5 cm cubes (free bodies, 0.1 kg) stand on the table, pairwise at least 13 cm
  apart (the hand's collision box reaches 10 cm along the finger axis, world x).
* Holding(b): both finger pads touch b. HandEmpty(r): no cube is held.
  OnTable(b): b touches the table and is not held. On(a, b): a touches b from above and
  is not held (a BINARY predicate read from MuJoCo's contact list through the feature
  ``touching_<b>``). Clear(b): no cube is On b. All five are contact-related.
* Action (dx, dy, dz, grip) as in every Panda domain. Goals: a tower of two (one On
  atom) or three (two On atoms) in a random order. Horizon 400 steps.
"""

from __future__ import annotations

from collections.abc import Sequence

from bpns.structs import Object, Predicate, State, Type

N_BLOCKS = 3
SIDE, MASS = 0.045, 0.1
X_RANGE, Y_RANGE = (0.38, 0.58), (-0.22, 0.22)
MIN_DISTANCE = 0.13
HORIZON = 400
NAMES = tuple(f"block{i}" for i in range(N_BLOCKS))

ROBOT = Type("robot", ("x", "y", "z", "fingers"))
BLOCK = Type("block", ("x", "y", "z", "grasped", "on_table", *(f"touching_{n}" for n in NAMES)))


def _holding(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "grasped") > 0.5


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    return not any(state.get(b, "grasped") > 0.5 for b in state.objects_of_type(BLOCK))


def _on_table(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "on_table") > 0.5 and state.get(objs[0], "grasped") < 0.5


def _on(state: State, objs: Sequence[Object]) -> bool:
    a, b = objs
    return (
        state.get(a, f"touching_{b.name}") > 0.5
        and state.get(a, "grasped") < 0.5
        and state.get(a, "z") > state.get(b, "z") + SIDE / 2
    )


def _clear(state: State, objs: Sequence[Object]) -> bool:
    return not any(_on(state, (c, objs[0])) for c in state.objects_of_type(BLOCK) if c != objs[0])


HOLDING = Predicate("Holding", (BLOCK,), _holding)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
ON_TABLE = Predicate("OnTable", (BLOCK,), _on_table)
ON = Predicate("On", (BLOCK, BLOCK), _on)
CLEAR = Predicate("Clear", (BLOCK,), _clear)
PREDICATES = frozenset({HOLDING, HAND_EMPTY, ON_TABLE, ON, CLEAR})
