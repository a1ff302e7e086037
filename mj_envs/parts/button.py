"""A latching push button: a housing, a spring-loaded cap on a slide joint, and a latch.

Stick Button's buttons and Coffee's plate switch are this part. The cap is a real body on
a vertical slide joint with a preloaded spring (stiffness 25 N/m, 0.15 N at rest, 0.35 N
at the latch depth) and 12 mm of travel. Pushed down past :data:`LATCH_DEPTH` (8 mm) it
*latches*: after that physics step an equality constraint (saved with the simulator state
in ``eq_active``) holds it at 9.5 mm, so it stays down when released. Whether a button is
pressed is the slide joint's reading, never a flag.

Element names for a button called ``name``: body ``name``, geoms ``name_housing`` and
``name_cap_geom``, cap body ``name_cap``, joint ``name_cap_joint``, equality
``name_cap_latch``.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
from dm_control import mjcf

from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE

HOUSING_RADIUS, HOUSING_HEIGHT = 0.035, 0.03
CAP_RADIUS, CAP_HALF_HEIGHT = 0.022, 0.0125
CAP_REST_TOP = 0.045  # cap top above the surface the button stands on, when up
CAP_MASS = 0.02
STIFFNESS, PRELOAD = 25.0, 0.006  # N/m; spring reference 6 mm above rest
DAMPING = 0.5
TRAVEL = 0.012
LATCH_DEPTH = 0.008  # travel at which the cap latches (pressed)
LATCH_HOLD = 0.0095  # travel the latch holds the cap at
CAP_RGBA = (0.85, 0.18, 0.15, 1.0)
PRESSED_RGBA = (0.2, 0.8, 0.3, 1.0)
HOUSING_RGBA = (0.22, 0.22, 0.25, 1)


def add_latching_button(arena: mjcf.RootElement, name: str, x: float, y: float) -> None:
    """Add a button called ``name`` standing on the table at (x, y)."""
    base = arena.worldbody.add("body", name=name, pos=(x, y, 0.0))
    base.add(
        "geom",
        name=f"{name}_housing",
        type="cylinder",
        size=(HOUSING_RADIUS, HOUSING_HEIGHT / 2),
        pos=(0, 0, HOUSING_HEIGHT / 2),
        rgba=HOUSING_RGBA,
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
    )
    cap = base.add(
        "body", name=f"{name}_cap", pos=(0, 0, CAP_REST_TOP - CAP_HALF_HEIGHT), gravcomp=1
    )
    cap.add(
        "joint",
        name=f"{name}_cap_joint",
        type="slide",
        axis=(0, 0, -1),  # qpos = travel, positive downwards
        range=(0.0, TRAVEL),
        limited=True,
        stiffness=STIFFNESS,
        springref=-PRELOAD,
        damping=DAMPING,
        armature=0.001,
    )
    cap.add(
        "geom",
        name=f"{name}_cap_geom",
        type="cylinder",
        size=(CAP_RADIUS, CAP_HALF_HEIGHT),
        mass=CAP_MASS,
        rgba=CAP_RGBA,
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
    )
    # the cap slides inside the housing: never collide the two
    arena.contact.add("exclude", body1=name, body2=f"{name}_cap")
    arena.equality.add(
        "joint",
        name=f"{name}_cap_latch",
        joint1=f"{name}_cap_joint",
        polycoef=(LATCH_HOLD, 0, 0, 0, 0),
        active=False,
        solref=(0.004, 1),
    )


@dataclass(frozen=True)
class ButtonIds:
    """One button's ids in a compiled scene."""

    cap_qpos: int
    cap_geom: int
    latch_eq: int


def button_ids(model: mujoco.MjModel, name: str) -> ButtonIds:
    return ButtonIds(
        cap_qpos=int(model.joint(f"{name}_cap_joint").qposadr[0]),
        cap_geom=model.geom(f"{name}_cap_geom").id,
        latch_eq=model.equality(f"{name}_cap_latch").id,
    )


def travel(data: mujoco.MjData, ids: ButtonIds) -> float:
    """How far the cap is pushed down (m), read from its slide joint."""
    return float(data.qpos[ids.cap_qpos])


def is_pressed(data: mujoco.MjData, ids: ButtonIds) -> bool:
    return bool(data.qpos[ids.cap_qpos] >= LATCH_DEPTH)


def engage_latch(data: mujoco.MjData, ids: ButtonIds) -> None:
    """Latch the cap once it travelled past the latch depth (call after each step)."""
    if data.eq_active[ids.latch_eq] == 0 and data.qpos[ids.cap_qpos] >= LATCH_DEPTH:
        data.eq_active[ids.latch_eq] = 1


def is_latched(data: mujoco.MjData, ids: ButtonIds) -> bool:
    return bool(data.eq_active[ids.latch_eq])


def draw_cap(model: mujoco.MjModel, data: mujoco.MjData, ids: ButtonIds) -> None:
    """Latched caps are drawn green (geom colours are looks, not simulator state)."""
    model.geom_rgba[ids.cap_geom] = PRESSED_RGBA if data.eq_active[ids.latch_eq] else CAP_RGBA
