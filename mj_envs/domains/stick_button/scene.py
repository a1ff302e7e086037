"""Stick Button's task scenes: buttons near and beyond the arm's reach, a stick in a holder."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import GroundAtom, Object
from mj_envs.base import TaskLayout
from mj_envs.domains.stick_button.rules import (
    BUTTON,
    BUTTON_SPACING,
    EVAL_BUTTONS,
    FAR_RADIUS,
    FAR_Y,
    HOLDER,
    HOLDER_FRICTION,
    HOLDER_GAP,
    HOLDER_HEIGHT,
    HOLDER_LENGTH,
    HOLDER_WALL,
    HOME_CLEARANCE,
    HOME_HAND_XY,
    HORIZON,
    LANE_HALF_WIDTH,
    NEAR_RADIUS,
    NEAR_X,
    NEAR_Y,
    PRESSED,
    ROBOT,
    STICK,
    STICK_BACK_X,
    STICK_HEIGHT,
    STICK_LENGTH,
    STICK_MASS,
    STICK_SIDE_Y,
    STICK_WIDTH,
    TABLE_CENTRE_X,
    TABLE_HALF,
    TRAIN_BUTTONS,
)
from mj_envs.parts.button import add_latching_button
from mj_envs.parts.objects import add_free_box
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE, make_arena, to_xml


def sample_layout(
    rng: np.random.Generator, train: bool, buttons: tuple[int, int] | None = None
) -> TaskLayout:
    """1-2 (train) or 3-4 (eval) buttons, near or far, and the stick in its holder.

    ``buttons``: (lo, hi) buttons instead, for eval tasks beyond the paper's; more than
    the paper's four are placed one at a time (:func:`_place_buttons`)."""
    n_lo, n_hi = TRAIN_BUTTONS if train else (buttons or EVAL_BUTTONS)
    n = int(rng.integers(n_lo, n_hi + 1))
    side = 1.0 if rng.random() < 0.5 else -1.0
    stick_y = side * rng.uniform(*STICK_SIDE_Y)
    back_x = rng.uniform(*STICK_BACK_X)
    points = _sample_buttons(rng, n) if n <= EVAL_BUTTONS[1] else _place_buttons(rng, n)

    arena = make_arena("stick_button")
    table = arena.worldbody.find("geom", "table")
    table.size = TABLE_HALF
    table.pos = (TABLE_CENTRE_X, 0.0, -TABLE_HALF[2])
    arena.worldbody.find("body", "workspace_focus").pos = (0.6, 0.0, 0.05)
    arena.worldbody.find("camera", "front").pos = (1.9, 0.0, 0.7)
    top = arena.worldbody.find("camera", "top")
    top.pos, top.fovy = (0.6, 0.0, 1.9), 50
    for i, (bx, by) in enumerate(points):
        add_latching_button(arena, f"button{i}", bx, by)
    _add_holder_and_stick(arena, back_x, stick_y)

    robot = Object("robot", ROBOT)
    button_objs = [Object(f"button{i}", BUTTON) for i in range(n)]
    stick = Object("stick", STICK)
    holder = Object("holder", HOLDER)
    goal = frozenset(GroundAtom(PRESSED, (b,)) for b in button_objs)
    return TaskLayout(
        xml=to_xml(arena),
        objects=(robot, *button_objs, stick, holder),
        goal=goal,
        horizon=HORIZON * max(n, EVAL_BUTTONS[1]) // EVAL_BUTTONS[1],
    )


def _sample_buttons(rng: np.random.Generator, n: int) -> list[tuple[float, float]]:
    """Button centres: each near or far with probability 1/2, spaced, lanes kept clear."""
    for _ in range(10_000):
        far = rng.random(n) < 0.5
        pts: list[tuple[float, float]] = []
        for is_far in far:
            if is_far:
                r = rng.uniform(*FAR_RADIUS)
                y = rng.uniform(-FAR_Y, FAR_Y)
                pts.append((float(np.sqrt(r * r - y * y)), float(y)))
            else:
                while True:
                    x, y = rng.uniform(*NEAR_X), rng.uniform(-NEAR_Y, NEAR_Y)
                    if np.hypot(x, y) <= NEAR_RADIUS:
                        break
                pts.append((float(x), float(y)))
        if _layout_ok(pts, far):
            return pts
    raise RuntimeError("could not place the buttons; widen the regions")


def _place_buttons(rng: np.random.Generator, n: int) -> list[tuple[float, float]]:
    """More buttons than the paper's four: one at a time, each far with probability 1/2,
    from fresh candidates until one keeps every rule of :func:`_layout_ok` with those
    placed; when neither band has room left (the far lanes fill the near band) the layout
    starts again. Joint rejection of eight buttons almost never succeeds."""
    for _ in range(1_000):
        pts: list[tuple[float, float]] = []
        far: list[bool] = []
        for _ in range(n):
            wants_far = bool(rng.random() < 0.5)
            for is_far in (wants_far, not wants_far):
                point = _fitting_point(rng, is_far, pts, far)
                if point is not None:
                    pts.append(point)
                    far.append(is_far)
                    break
            else:
                break
        if len(pts) == n:
            return pts
    raise RuntimeError(f"could not place {n} buttons; widen the regions")


def _fitting_point(
    rng: np.random.Generator, is_far: bool, pts: list[tuple[float, float]], far: list[bool]
) -> tuple[float, float] | None:
    for _ in range(200):
        point = _far_point(rng) if is_far else _near_point(rng)
        if _layout_ok([*pts, point], np.array([*far, is_far])):
            return point
    return None


def _far_point(rng: np.random.Generator) -> tuple[float, float]:
    r = rng.uniform(*FAR_RADIUS)
    y = rng.uniform(-FAR_Y, FAR_Y)
    return float(np.sqrt(r * r - y * y)), float(y)


def _near_point(rng: np.random.Generator) -> tuple[float, float]:
    while True:
        x, y = rng.uniform(*NEAR_X), rng.uniform(-NEAR_Y, NEAR_Y)
        if np.hypot(x, y) <= NEAR_RADIUS:
            return float(x), float(y)


def _layout_ok(pts: Sequence[tuple[float, float]], far: np.ndarray) -> bool:
    hx, hy = HOME_HAND_XY
    if any(np.hypot(x - hx, y - hy) < HOME_CLEARANCE for x, y in pts):
        return False
    for i in range(len(pts)):
        for j in range(i + 1, len(pts)):
            (xi, yi), (xj, yj) = pts[i], pts[j]
            if np.hypot(xi - xj, yi - yj) < BUTTON_SPACING:
                return False
            if (far[i] or far[j]) and abs(yi - yj) < LANE_HALF_WIDTH:
                return False
    return True


def _add_holder_and_stick(arena, back_x: float, stick_y: float) -> None:
    wb = arena.worldbody
    holder = wb.add("body", name="holder", pos=(back_x + HOLDER_LENGTH / 2, stick_y, 0.0))
    grey = (0.55, 0.56, 0.6, 1)
    offset = STICK_WIDTH / 2 + HOLDER_GAP + HOLDER_WALL / 2
    for k, sign in enumerate((-1.0, 1.0)):
        holder.add(
            "geom",
            name=f"holder_wall{k}",
            type="box",
            size=(HOLDER_LENGTH / 2, HOLDER_WALL / 2, HOLDER_HEIGHT / 2),
            pos=(0, sign * offset, HOLDER_HEIGHT / 2),
            rgba=grey,
            contype=OBJECT_CONTYPE,
            conaffinity=OBJECT_CONAFFINITY,
            friction=HOLDER_FRICTION,
        )
    holder.add(  # end stop behind the stick
        "geom",
        name="holder_back",
        type="box",
        size=(0.01, offset + HOLDER_WALL / 2, HOLDER_HEIGHT / 2),
        pos=(-HOLDER_LENGTH / 2 - 0.01 - HOLDER_GAP, 0, HOLDER_HEIGHT / 2),
        rgba=grey,
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
        friction=HOLDER_FRICTION,
    )
    add_free_box(
        wb,
        "stick",
        pos=(back_x + STICK_LENGTH / 2, stick_y, STICK_HEIGHT / 2),
        half_size=(STICK_LENGTH / 2, STICK_WIDTH / 2, STICK_HEIGHT / 2),
        mass=STICK_MASS,
        rgba=(0.62, 0.4, 0.2, 1),
    )
