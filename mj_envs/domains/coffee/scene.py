"""Coffee's task scenes: the pot (handle, knob, spout), the hot plate and its switch, cups."""

from __future__ import annotations

import numpy as np

from bpns.structs import GroundAtom, Object
from mj_envs.base import TaskLayout
from mj_envs.domains.coffee.rules import (
    BUTTON_OFFSET,
    CUP,
    CUP_FILLED,
    CUP_GAP,
    CUP_HEIGHT,
    CUP_IDX,
    CUP_RADIUS,
    CUP_REACH,
    CUP_WALL,
    CUP_X,
    CUP_Y,
    EVAL_CUPS,
    FOOT_OFFSET,
    FOOT_RADIUS,
    GRIP_FROM_AXIS,
    HANDLE_HALF_HEIGHT,
    HANDLE_HALF_WIDTH,
    HANDLE_INNER,
    HANDLE_LENGTH,
    HANDLE_Z,
    HORIZON,
    KNOB_HALF,
    KNOB_HALF_HEIGHT,
    KNOB_Z,
    PLATE,
    PLATE_RADIUS,
    PLATE_TOP,
    PLATE_X,
    PLATE_Y,
    POT,
    POT_HEIGHT,
    POT_MASSES,
    POT_RADIUS,
    POT_REACH,
    POT_X,
    POT_Y,
    RIDGE_HALF,
    RIDGE_OFFSET,
    RIDGE_PROTRUSION,
    ROBOT,
    ROTATION_RANGE,
    SPOUT_TIP,
    TARGET_FRACTION,
    TRAIN_CUPS,
    WIDE_CUP_X,
    WIDE_CUP_Y,
)
from mj_envs.parts.button import add_latching_button
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE, make_arena, to_xml
from mj_envs.world import DOMAIN_USERDATA_START

STEEL_RGBA = (0.75, 0.76, 0.8, 1)
GRIP_RGBA = (0.15, 0.12, 0.1, 1)  # the handle, its ridges and the knob


def sample_layout(
    rng: np.random.Generator, train: bool, cups_range: tuple[int, int] | None = None
) -> TaskLayout:
    """The pot turned up to +-120 deg, the plate with its switch, 1-2 (train) or 2-3 (eval) cups.

    ``cups_range``: (lo, hi) cups instead, for eval tasks beyond the paper's; more than
    three stand in a larger region (:func:`_place_cups`)."""
    n_lo, n_hi = TRAIN_CUPS if train else (cups_range or EVAL_CUPS)
    n = int(rng.integers(n_lo, n_hi + 1))
    pot_xy = np.array([rng.uniform(*POT_X), rng.uniform(*POT_Y)])
    rotation = float(rng.uniform(-ROTATION_RANGE, ROTATION_RANGE))
    plate_xy = np.array([rng.uniform(*PLATE_X), rng.uniform(*PLATE_Y)])
    cups = _sample_cups(rng, n, pot_xy) if n <= EVAL_CUPS[1] else _place_cups(rng, n, pot_xy)

    arena = make_arena("coffee", domain_userdata=CUP_IDX - DOMAIN_USERDATA_START + n)
    arena.worldbody.find("body", "workspace_focus").pos = (0.5, 0.0, 0.05)
    _add_plate(arena, plate_xy)
    for k, (x, y, r, h, frac) in enumerate(cups):
        _add_cup(arena, k, x, y, r, h, frac)
    _add_pot(arena, pot_xy, rotation)

    robot = Object("robot", ROBOT)
    pot = Object("pot", POT)
    plate = Object("plate", PLATE)
    cup_objs = [Object(f"cup{k}", CUP) for k in range(n)]
    goal = frozenset(GroundAtom(CUP_FILLED, (c,)) for c in cup_objs)
    return TaskLayout(
        xml=to_xml(arena),
        objects=(robot, pot, plate, *cup_objs),
        goal=goal,
        horizon=HORIZON * max(n, EVAL_CUPS[1]) // EVAL_CUPS[1],
    )


def _sample_cups(rng: np.random.Generator, n: int, pot_xy: np.ndarray) -> list[tuple[float, ...]]:
    """(x, y, radius, height, target fraction) per cup, spaced CUP_GAP apart and clear of
    the pot's handle whichever way it is turned."""
    for _ in range(10_000):
        cups = [
            (
                float(rng.uniform(*CUP_X)),
                float(rng.uniform(*CUP_Y)),
                float(rng.uniform(*CUP_RADIUS)),
                float(rng.uniform(*CUP_HEIGHT)),
                float(rng.uniform(*TARGET_FRACTION)),
            )
            for _ in range(n)
        ]
        clear = all(
            np.hypot(c[0] - pot_xy[0], c[1] - pot_xy[1]) >= POT_REACH + c[2] + CUP_GAP / 2
            for c in cups
        )
        if clear and all(
            np.hypot(a[0] - b[0], a[1] - b[1]) >= a[2] + b[2] + CUP_GAP
            for i, a in enumerate(cups)
            for b in cups[i + 1 :]
        ):
            return cups
    raise RuntimeError("could not place the cups; widen the region")


def _place_cups(rng: np.random.Generator, n: int, pot_xy: np.ndarray) -> list[tuple[float, ...]]:
    """More cups than the paper's three, in the wider region: one at a time from fresh
    candidates kept clear of the pot's handle and the cups placed (the rules of
    :func:`_sample_cups`) and within ``CUP_REACH``; the layout starts again when a cup
    finds no room. Joint rejection of six cups almost never succeeds."""
    for _ in range(1_000):
        cups: list[tuple[float, ...]] = []
        for _ in range(n):
            cup = _fitting_cup(rng, cups, pot_xy)
            if cup is None:
                break
            cups.append(cup)
        if len(cups) == n:
            return cups
    raise RuntimeError(f"could not place {n} cups; widen the region")


def _fitting_cup(
    rng: np.random.Generator, cups: list[tuple[float, ...]], pot_xy: np.ndarray
) -> tuple[float, ...] | None:
    for _ in range(200):
        c = (
            float(rng.uniform(*WIDE_CUP_X)),
            float(rng.uniform(*WIDE_CUP_Y)),
            float(rng.uniform(*CUP_RADIUS)),
            float(rng.uniform(*CUP_HEIGHT)),
            float(rng.uniform(*TARGET_FRACTION)),
        )
        if (
            np.hypot(c[0], c[1]) <= CUP_REACH
            and np.hypot(c[0] - pot_xy[0], c[1] - pot_xy[1]) >= POT_REACH + c[2] + CUP_GAP / 2
            and all(np.hypot(c[0] - b[0], c[1] - b[1]) >= c[2] + b[2] + CUP_GAP for b in cups)
        ):
            return c
    return None


def _add_pot(arena, xy: np.ndarray, rotation: float) -> None:
    """The pot, a free body turned by ``rotation`` about z: its shell on four feet, the
    handle the robot grasps, the knob it twists and the spout it pours from."""
    half = rotation / 2
    pot = arena.worldbody.add(
        "body", name="pot", pos=(xy[0], xy[1], 0.0005), quat=(np.cos(half), 0, 0, np.sin(half))
    )
    pot.add("freejoint", name="pot_joint")
    _add_pot_shell(pot)
    _add_pot_handle(pot)
    _add_pot_knob(pot)
    _add_pot_spout(pot)


def _solid() -> dict[str, int]:
    """Collision attributes of a geom objects and the robot collide with."""
    return {"contype": OBJECT_CONTYPE, "conaffinity": OBJECT_CONAFFINITY}


def _add_pot_shell(pot) -> None:
    """The pot's body, standing on four spherical feet, and its lid (looks only)."""
    body_bottom = 2 * FOOT_RADIUS + 0.001
    pot.add(
        "geom",
        name="pot_body",
        type="cylinder",
        size=(POT_RADIUS, (POT_HEIGHT - body_bottom) / 2),
        pos=(0, 0, (POT_HEIGHT + body_bottom) / 2),
        mass=POT_MASSES["body"],
        rgba=STEEL_RGBA,
        **_solid(),
    )
    pot.add(
        "geom",
        name="pot_lid",
        type="cylinder",
        size=(POT_RADIUS - 0.004, 0.002),
        pos=(0, 0, POT_HEIGHT + 0.001),
        mass=0.0,
        rgba=(0.35, 0.35, 0.35, 1),
        contype=0,
        conaffinity=0,
    )
    for i in range(4):
        a = np.pi / 4 + i * np.pi / 2
        pot.add(
            "geom",
            name=f"pot_foot{i}",
            type="sphere",
            size=(FOOT_RADIUS,),
            pos=(FOOT_OFFSET * np.cos(a), FOOT_OFFSET * np.sin(a), FOOT_RADIUS),
            mass=POT_MASSES["foot"],
            rgba=(0.2, 0.2, 0.2, 1),
            friction=(0.5, 0.005, 0.0001),
            **_solid(),
        )


def _add_pot_handle(pot) -> None:
    """The handle bar along -x, with ridges either side of the grip that keep the finger
    pads from sliding along the bar."""
    pot.add(
        "geom",
        name="pot_handle",
        type="box",
        size=(HANDLE_LENGTH / 2, HANDLE_HALF_WIDTH, HANDLE_HALF_HEIGHT),
        pos=(-(HANDLE_INNER + HANDLE_LENGTH / 2), 0, HANDLE_Z),
        mass=POT_MASSES["handle"],
        rgba=GRIP_RGBA,
        friction=(1.0, 0.02, 0.001),
        condim=4,
        **_solid(),
    )
    for i, (dx, side) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        pot.add(
            "geom",
            name=f"pot_ridge{i}",
            type="box",
            size=(RIDGE_HALF, RIDGE_PROTRUSION / 2, HANDLE_HALF_HEIGHT),
            pos=(
                -GRIP_FROM_AXIS + dx * RIDGE_OFFSET,
                side * (HANDLE_HALF_WIDTH + RIDGE_PROTRUSION / 2),
                HANDLE_Z,
            ),
            mass=0.0005,
            rgba=GRIP_RGBA,
            **_solid(),
        )


def _add_pot_knob(pot) -> None:
    """The knob on the lid, a box the robot grasps to twist the pot."""
    pot.add(
        "geom",
        name="pot_knob",
        type="box",
        size=(KNOB_HALF, KNOB_HALF, KNOB_HALF_HEIGHT),
        pos=(0, 0, KNOB_Z),
        mass=POT_MASSES["knob"],
        rgba=GRIP_RGBA,
        friction=(1.0, 0.02, 0.001),
        condim=4,
        **_solid(),
    )


def _add_pot_spout(pot) -> None:
    """The spout at +x (looks only: pouring is computed from ``SPOUT_TIP``)."""
    pot.add(
        "geom",
        name="pot_spout",
        type="box",
        size=(0.02, 0.009, 0.007),
        pos=(POT_RADIUS + 0.01, 0, SPOUT_TIP[2] - 0.004),
        euler=(0, -0.5, 0),
        mass=0.0,
        rgba=STEEL_RGBA,
        contype=0,
        conaffinity=0,
    )


def _add_plate(arena, xy: np.ndarray) -> None:
    plate = arena.worldbody.add("body", name="plate", pos=(xy[0], xy[1], 0.0))
    plate.add(
        "geom",
        name="plate_geom",
        type="cylinder",
        size=(PLATE_RADIUS, PLATE_TOP / 2),
        pos=(0, 0, PLATE_TOP / 2),
        rgba=(0.12, 0.12, 0.14, 1),
        friction=(0.8, 0.005, 0.0001),
        **_solid(),
    )
    plate.add(
        "geom",
        name="plate_top",
        type="cylinder",
        size=(PLATE_RADIUS - 0.015, 0.0005),
        pos=(0, 0, PLATE_TOP + 0.0003),
        rgba=(0.3, 0.3, 0.33, 1),
        contype=0,
        conaffinity=0,
    )
    bx, by = xy + BUTTON_OFFSET
    add_latching_button(arena, "button", bx, by)


def _add_cup(arena, k: int, x: float, y: float, r: float, h: float, frac: float) -> None:
    capacity = float(np.pi * r * r * h * 1000.0)  # litres
    cup = arena.worldbody.add("body", name=f"cup{k}", pos=(x, y, 0.0))
    cup.add(
        "geom",
        name=f"cup{k}_geom",
        type="cylinder",
        size=(r, h / 2),
        pos=(0, 0, h / 2),
        rgba=(0.95, 0.95, 0.97, 1),
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
    )
    cup.add(
        "geom",
        name=f"cup{k}_liquid",
        type="cylinder",
        size=(r - CUP_WALL, 0.001),
        pos=(0, 0, h + 0.0005),
        rgba=(0.92, 0.92, 0.9, 1),
        contype=0,
        conaffinity=0,
    )
    arena.custom.add("numeric", name=f"cup{k}_capacity", data=[capacity])
    arena.custom.add("numeric", name=f"cup{k}_target", data=[capacity * frac])
