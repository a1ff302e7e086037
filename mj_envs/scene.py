"""Compose task scenes from entities with dm_control's ``mjcf``: arena, table, Panda, objects.

Conventions (DESIGN §5): the Panda's base at the origin, the table top at z = 0, +x
forward. Collision bitmasks: robot contype=2/conaffinity=1 (never self-collides), world
and objects contype=1/conaffinity=3, decorations (targets, regions) contype=0.
"""

from __future__ import annotations

import numpy as np
from dm_control import mjcf

from mj_envs import gl as _gl  # noqa: F401
from mj_envs.robots.panda import PANDA, Robot, robot_mjcf_text
from mj_envs.world import DOMAIN_USERDATA_START

TABLE_SIZE = (0.5, 0.65, 0.025)  # half extents
TABLE_CENTER_X = 0.45
OBJECT_CONTYPE, OBJECT_CONAFFINITY = 1, 3
# the overview camera frames the whole arm (home posture reaches ~0.9 m) and the table top
OVERVIEW_POS, OVERVIEW_TARGET = (1.4, -1.0, 0.95), (0.35, 0.0, 0.3)


def make_arena(
    model_name: str,
    domain_userdata: int = 0,
    timestep: float = 0.002,
    robot: Robot | None = PANDA,
) -> mjcf.RootElement:
    """An arena with physics settings that hold grasps, a table, lights, cameras and the
    robot attached under its prefix.

    ``domain_userdata`` slots follow the controller's in ``data.userdata`` (from
    ``DOMAIN_USERDATA_START``): domain state that must be saved with the simulator state.
    ``robot=None`` leaves the robot out, for scenes that mount it elsewhere (on a mobile
    base: :mod:`mj_envs.robots.mobile_panda`).
    """
    arena = mjcf.RootElement(model=model_name)
    _set_physics(arena, timestep, domain_userdata)
    _set_visual(arena)
    _add_materials(arena)
    _add_room(arena.worldbody)
    _add_cameras(arena.worldbody)
    if robot is not None:
        arena.attach(mjcf.from_xml_string(robot_mjcf_text(robot), model_dir=str(robot.mjcf.parent)))
    return arena


def _set_physics(arena: mjcf.RootElement, timestep: float, domain_userdata: int) -> None:
    """Solver settings under which the fingers hold a grasp, and the userdata slots."""
    opt = arena.option
    opt.timestep = timestep
    opt.integrator = "implicitfast"
    opt.cone = "elliptic"
    opt.impratio = 10
    arena.size.nuserdata = DOMAIN_USERDATA_START + domain_userdata


def _set_visual(arena: mjcf.RootElement) -> None:
    """A soft headlight and an offscreen buffer large enough for the video resolutions."""
    arena.visual.headlight.ambient = (0.35, 0.35, 0.35)
    arena.visual.headlight.diffuse = (0.5, 0.5, 0.5)
    getattr(arena.visual, "global").offwidth = 1280
    getattr(arena.visual, "global").offheight = 960


def _add_materials(arena: mjcf.RootElement) -> None:
    """The sky, the checkered floor and the wooden table top (looks only)."""
    arena.asset.add(
        "texture",
        name="sky",
        type="skybox",
        builtin="gradient",
        rgb1=(0.55, 0.68, 0.82),
        rgb2=(0.1, 0.12, 0.16),
        width=256,
        height=256,
    )
    arena.asset.add(
        "texture",
        name="floor_tex",
        type="2d",
        builtin="checker",
        rgb1=(0.28, 0.3, 0.33),
        rgb2=(0.22, 0.24, 0.27),
        width=256,
        height=256,
    )
    arena.asset.add("material", name="floor_mat", texture="floor_tex", texrepeat=(6, 6))
    arena.asset.add(
        "texture",
        name="wood",
        type="2d",
        builtin="flat",
        rgb1=(0.62, 0.5, 0.38),
        width=64,
        height=64,
    )
    arena.asset.add("material", name="table_mat", texture="wood", specular=0.1)


def _add_room(wb: mjcf.Element) -> None:
    """The key light, a floor that collides with nothing and the table, world geometry."""
    wb.add("light", name="key", pos=(0.6, -0.8, 1.8), dir=(-0.2, 0.5, -1), diffuse=(0.6, 0.6, 0.6))
    wb.add(
        "geom",
        name="floor",
        type="plane",
        size=(3, 3, 0.1),
        pos=(0, 0, -0.75),
        material="floor_mat",
        contype=0,
        conaffinity=0,
    )
    wb.add(
        "geom",
        name="table",
        type="box",
        size=TABLE_SIZE,
        pos=(TABLE_CENTER_X, 0, -TABLE_SIZE[2]),
        material="table_mat",
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
        friction=(0.6, 0.02, 0.001),
    )


def _add_cameras(wb: mjcf.Element) -> None:
    """The overview, front and top cameras; the front one follows ``workspace_focus``,
    a body domains move to where their task happens."""
    focus = wb.add("body", name="workspace_focus", pos=(0.45, 0.0, 0.12))
    wb.add(
        "camera",
        name="overview",
        pos=OVERVIEW_POS,
        xyaxes=look_at(OVERVIEW_POS, OVERVIEW_TARGET),
        fovy=45,
    )
    wb.add("camera", name="front", pos=(1.6, 0.0, 0.55), mode="targetbody", target=focus, fovy=40)
    wb.add("camera", name="top", pos=(0.5, 0.0, 1.6), quat=(0.7071068, 0, 0, 0.7071068), fovy=45)


def look_at(pos: tuple[float, ...], target: tuple[float, ...]) -> tuple[float, ...]:
    """A fixed camera's ``xyaxes`` looking from ``pos`` at ``target`` with +z up in the image."""
    forward = np.subtract(target, pos) / np.linalg.norm(np.subtract(target, pos))
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return tuple(round(float(v), 6) for v in (*right, *up))


def to_xml(arena: mjcf.RootElement) -> str:
    return arena.to_xml_string()
