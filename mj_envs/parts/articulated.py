"""Articulated parts for task scenes: a cabinet with a sliding drawer, a cabinet with a
hinged door. Each moves on one damped joint with a range, and has a bar handle.

Units are metres and radians. Positions are in the world frame of an arena made by
:func:`mj_envs.scene.make_arena` (the Panda's base at the origin, +x forward, the table
top at z = 0). A cabinet stands with its bottom at ``surface_z`` (default: the table top)
and its open front facing the robot, at -x. The carcass (the cabinet's box walls) is one
body named ``name`` with no joint: part of the world, static, like a
:mod:`mj_envs.parts.containers` bin. The moving part is its child body on one joint:

* drawer: a slide joint along x, ``qpos`` = how far the drawer is pulled out towards the
  robot (m), range [0, ``travel``];
* hinged door: a hinge joint about the vertical through the door's hinge edge, ``qpos`` =
  how far the door is swung open towards the robot (rad), range [0, ``max_angle``].

Both joints are damped and have no spring: released, the part slows down and stays
where it is; its joint limits stop it at closed (0) and fully open. Contacts between the
carcass and its moving part are excluded (the joint and its limits keep them apart), so
nothing but the damping and the limits acts on the joint.

Collision groups follow :mod:`mj_envs.scene`: every geom here, the moving part and its
handle included, has ``contype`` :data:`~mj_envs.scene.OBJECT_CONTYPE` / ``conaffinity``
:data:`~mj_envs.scene.OBJECT_CONAFFINITY` (1 / 3): free objects rest in the drawer and
ride along with it, and the robot (2 / 1) collides with the carcass, the drawer, the door
and the handle, so it can hook, grasp, push and pull them. The handle bars have
:data:`~mj_envs.parts.objects.GRIPPABLE_FRICTION` and ``condim`` 4, like a free object.

The handle is a bar (a capsule) on two posts, ``handle_clearance`` (m) in front of the
moving part's front face: the free space a hand hooks into. The Panda's closed fingers
are 2 cm across; its hand's collision box is 5 cm across and 20 cm long along the finger
axis, its bottom 3.5 cm above the grip site, so a top-down hook behind a drawer's bar
needs the carcass top out of that box's way (a larger clearance, or a tilted hand).

Each builder returns a frozen description (:class:`Drawer`, :class:`HingedDoor`) with the
element names and the world-frame numbers at closed. A compiled scene's ids come from
:func:`drawer_ids` / :func:`hinged_door_ids`, and the readings from them are what a
predicate (DrawerOpen, DoorOpen, InDrawer) needs as features: :func:`opening` (the joint
reading, m or rad), :func:`open_fraction` (0 closed .. 1 fully open), :func:`is_open`
(the fraction past a threshold) and :func:`handle_xyz` (where the handle is now, the
target of a reach). Whether the hand holds the handle is a contact question:
:func:`mj_envs.contacts.geom_ids` for ``handle_geom``, or
:func:`mj_envs.contacts.body_geoms` for the moving body (handle and posts included).

Element names for a drawer called ``name``: carcass body ``name`` with geoms
``name_bottom``, ``name_top``, ``name_back``, ``name_side_yneg``, ``name_side_ypos``;
drawer body ``name_drawer`` on slide joint ``name_slide``, with geoms
``name_drawer_floor``, ``name_drawer_front``, ``name_drawer_back``, ``name_drawer_yneg``,
``name_drawer_ypos``, ``name_handle`` (the bar) and ``name_handle_post0``,
``name_handle_post1``. For a hinged door: the same carcass names, door body
``name_door`` on hinge joint ``name_hinge``, with geoms ``name_door_panel``,
``name_handle``, ``name_handle_post0``, ``name_handle_post1``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np
from dm_control import mjcf

from mj_envs.parts.containers import _check_name, _position, _rgba
from mj_envs.parts.objects import GRIPPABLE_FRICTION
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE

CABINET_RGBA = (0.55, 0.42, 0.3, 1.0)
DRAWER_RGBA = (0.7, 0.58, 0.42, 1.0)
DOOR_RGBA = (0.7, 0.58, 0.42, 1.0)
HANDLE_RGBA = (0.75, 0.75, 0.78, 1.0)
# Gap between a moving part and the carcass around it (m): it never touches the carcass.
PART_GAP = 0.002
DRAWER_MASS = 0.5  # kg, the drawer with its handle
DRAWER_DAMPING = 10.0  # N s/m on the slide joint: pulled with 10 N it moves at 1 m/s
DOOR_MASS = 0.5  # kg, the door panel with its handle
DOOR_DAMPING = 0.5  # N m s/rad on the hinge: 1 N m turns the door at 2 rad/s
HANDLE_RADIUS = 0.008
HANDLE_CLEARANCE = 0.035  # free space between the bar and the front face (m)
HANDLE_LENGTH = 0.1  # the bar's full length, end caps included (m), if the part is wide enough
DOOR_HANDLE_INSET = 0.04  # from the door's free edge to the bar's axis (m)
# Joint limits a little stiffer than MuJoCo's default (0.02, 1): a part pulled hard against
# its stop goes past it by millimetres, not centimetres.
LIMIT_SOLREF = (0.01, 1.0)


@dataclass(frozen=True)
class Drawer:
    """A cabinet with a sliding drawer in the world frame (metres), built by :func:`add_drawer`.

    ``joint`` is the slide joint (``qpos`` = opening, 0 closed .. ``travel`` fully out,
    towards -x); ``carcass_body`` the static cabinet, ``drawer_body`` the moving drawer;
    ``handle_geom`` the handle bar and ``handle_post_geoms`` its posts;
    ``carcass_geoms`` and ``drawer_geoms`` (floor, front, back, yneg, ypos) the box geoms.
    All positions are at closed: ``handle_closed`` the bar's centre; ``front_x`` the x of
    the carcass's front face (the drawer's front is flush with it); ``floor_centre`` the
    centre of the drawer floor's top face, where an object set down in the middle of the
    drawer rests; ``inner_half`` the half extents along x and y of the free space inside
    the drawer's walls; ``floor_z`` and ``rim_z`` the heights of its floor's top face and
    of its walls' top.
    """

    name: str
    joint: str
    carcass_body: str
    drawer_body: str
    handle_geom: str
    handle_post_geoms: tuple[str, str]
    carcass_geoms: tuple[str, ...]
    drawer_geoms: tuple[str, str, str, str, str]
    travel: float
    handle_closed: tuple[float, float, float]
    front_x: float
    floor_centre: tuple[float, float, float]
    inner_half: tuple[float, float]
    floor_z: float
    rim_z: float

    def contains(self, xyz: Sequence[float], opening: float = 0.0, margin: float = 0.0) -> bool:
        """Whether the point ``xyz`` (world frame, m) is inside the drawer when it is pulled
        out by ``opening`` (m, the :func:`opening` reading; default 0, closed): strictly
        inside its walls along x and y, above its floor's top face and below its rim.

        ``margin`` (m, default 0) shrinks the region on x and y, e.g. to an object's
        horizontal half extent. A point with a NaN coordinate is not contained.
        """
        x, y, z = (float(v) for v in xyz)
        cx = self.floor_centre[0] - float(opening)
        hx, hy = self.inner_half[0] - margin, self.inner_half[1] - margin
        return bool(
            abs(x - cx) < hx
            and abs(y - self.floor_centre[1]) < hy
            and self.floor_z < z < self.rim_z
        )


@dataclass(frozen=True)
class HingedDoor:
    """A cabinet with a hinged door in the world frame (metres, radians), built by
    :func:`add_hinged_door`.

    ``joint`` is the hinge (``qpos`` = opening angle, 0 closed .. ``max_angle`` fully open,
    the free edge swinging towards -x); ``hinge_side`` which edge it is on, as seen by the
    robot looking along +x (``"left"``: the +y edge, ``"right"``: the -y edge);
    ``hinge_xyz`` the point of the hinge axis at the door's mid-height and ``hinge_axis``
    its direction (opening is a positive rotation about it). ``carcass_body`` is the
    static cabinet, ``door_body`` the moving door; ``panel_geom`` the door panel,
    ``handle_geom`` the handle bar (vertical, near the free edge) and
    ``handle_post_geoms`` its posts; ``carcass_geoms`` the cabinet's box geoms.
    ``handle_closed`` is the bar's centre at closed and ``front_x`` the x of the carcass's
    front face (the closed door stands just in front of it).
    """

    name: str
    joint: str
    carcass_body: str
    door_body: str
    panel_geom: str
    handle_geom: str
    handle_post_geoms: tuple[str, str]
    carcass_geoms: tuple[str, ...]
    hinge_side: str
    max_angle: float
    hinge_xyz: tuple[float, float, float]
    hinge_axis: tuple[float, float, float]
    handle_closed: tuple[float, float, float]
    front_x: float


def add_drawer(
    arena: mjcf.RootElement,
    name: str,
    x: float,
    y: float,
    size: Sequence[float],
    travel: float,
    *,
    wall_thickness: float = 0.01,
    damping: float = DRAWER_DAMPING,
    mass: float = DRAWER_MASS,
    handle_length: float | None = None,
    handle_clearance: float = HANDLE_CLEARANCE,
    handle_radius: float = HANDLE_RADIUS,
    surface_z: float = 0.0,
    rgba: Sequence[float] = CABINET_RGBA,
    drawer_rgba: Sequence[float] = DRAWER_RGBA,
    handle_rgba: Sequence[float] = HANDLE_RGBA,
) -> Drawer:
    """Add a cabinet called ``name`` with one drawer: the carcass centred at (``x``, ``y``)
    on ``surface_z``, open at its -x face (towards the robot), the drawer inside it on a
    slide joint that pulls it out towards -x by up to ``travel``.

    Arguments (metres, world frame): ``size`` = (sx, sy, sz), the carcass's outer extents
    (depth along x, width along y, height); ``travel``, how far the drawer comes out at
    most (the slide joint's upper limit), at most the drawer's depth ``sx -
    wall_thickness - PART_GAP`` (at that travel its back reaches the carcass front);
    ``wall_thickness``, of every carcass and drawer wall and floor (default 0.01);
    ``damping``, of the slide joint (N s/m, default :data:`DRAWER_DAMPING`); ``mass``, of
    the drawer with its handle (kg, default :data:`DRAWER_MASS`); ``handle_length``, the
    bar's full length along y (default :data:`HANDLE_LENGTH`, or the drawer's width if
    that is less); ``handle_clearance``, the free space between the bar and the drawer's
    front face (default :data:`HANDLE_CLEARANCE`); ``handle_radius``, the bar's (default
    :data:`HANDLE_RADIUS`); ``surface_z``, what the cabinet stands on (default 0.0, the
    table top); ``rgba``, ``drawer_rgba``, ``handle_rgba``, colours (looks only).

    The drawer is an open box (a floor and four walls, the front wall its front panel,
    flush with the carcass front when closed) that fills the carcass's inside less
    :data:`PART_GAP` on every side, with walls as high as that inside; the handle bar runs
    along y at the middle of the front panel's height. A free object set inside (on
    ``Drawer.floor_centre``) rides out with the drawer on friction and its walls.

    Returns a :class:`Drawer` describing it. Raises ``ValueError`` naming the argument if a
    size, ``travel``, ``mass`` or a handle dimension is not a positive finite number,
    ``damping`` is negative, ``travel`` exceeds the drawer's depth, the walls leave no
    inside or the handle does not fit on the front panel, a position is NaN or infinite,
    or ``name`` or a colour is malformed.
    """
    spec = _drawer_spec(
        name,
        (x, y, surface_z),
        size,
        travel,
        wall_thickness,
        damping,
        mass,
        (handle_length, handle_clearance, handle_radius),
        (rgba, drawer_rgba, handle_rgba),
    )
    carcass = arena.worldbody.add("body", name=name, pos=(spec.x, spec.y, spec.surface_z))
    carcass_geoms = _add_carcass(carcass, name, spec.sx, spec.sy, spec.sz, spec.t, spec.rgba)
    drawer_geoms = _add_drawer_part(carcass, spec)
    arena.contact.add("exclude", body1=name, body2=f"{name}_drawer")
    return _describe_drawer(spec, carcass_geoms, drawer_geoms)


def add_hinged_door(
    arena: mjcf.RootElement,
    name: str,
    x: float,
    y: float,
    width: float,
    height: float,
    hinge_side: Literal["left", "right"],
    *,
    depth: float = 0.2,
    max_angle: float = math.pi / 2,
    wall_thickness: float = 0.01,
    damping: float = DOOR_DAMPING,
    mass: float = DOOR_MASS,
    handle_length: float | None = None,
    handle_clearance: float = HANDLE_CLEARANCE,
    handle_radius: float = HANDLE_RADIUS,
    handle_inset: float = DOOR_HANDLE_INSET,
    surface_z: float = 0.0,
    rgba: Sequence[float] = CABINET_RGBA,
    door_rgba: Sequence[float] = DOOR_RGBA,
    handle_rgba: Sequence[float] = HANDLE_RGBA,
) -> HingedDoor:
    """Add a cabinet called ``name`` with a hinged door: the carcass centred at (``x``,
    ``y``) on ``surface_z``, open at its -x face (towards the robot), the door in front of
    that face on a vertical hinge at its ``hinge_side`` edge, swinging open towards -x.

    Arguments (metres, radians, world frame): ``width`` and ``height``, the carcass's (and
    so the front's) extent along y and z; ``hinge_side``, ``"left"`` (the +y edge, on the
    robot's left as it looks along +x) or ``"right"`` (the -y edge); ``depth``, the
    carcass's extent along x (default 0.2); ``max_angle``, the hinge's upper limit, in (0,
    pi] (default pi/2: the door stops square to the front); ``wall_thickness``, of the
    carcass walls and the door panel (default 0.01); ``damping``, of the hinge (N m s/rad,
    default :data:`DOOR_DAMPING`); ``mass``, of the door with its handle (kg, default
    :data:`DOOR_MASS`); ``handle_length``, the vertical bar's full length (default
    :data:`HANDLE_LENGTH`, or the door's height if that is less); ``handle_clearance``,
    the free space between the bar and the door's front face (default
    :data:`HANDLE_CLEARANCE`); ``handle_radius`` (default :data:`HANDLE_RADIUS`);
    ``handle_inset``, from the door's free edge to the bar's axis (default
    :data:`DOOR_HANDLE_INSET`); ``surface_z``, what the cabinet stands on (default 0.0,
    the table top); ``rgba``, ``door_rgba``, ``handle_rgba``, colours (looks only).

    The door panel covers the front less :data:`PART_GAP` at each edge; its back face is
    :data:`PART_GAP` in front of the carcass, where the hinge axis runs, so the door swings
    clear of the carcass. The handle bar is vertical, centred on the door's height.

    The hinge's range is written in the arena's angle unit: an arena whose compiler unit is
    unset (``make_arena(..., robot=None)``) is set to radians, as attaching the Panda
    does (its MJCF declares radians), so the scene compiles the same with or without it.

    Returns a :class:`HingedDoor` describing it. Raises ``ValueError`` naming the argument
    if a size, ``mass`` or a handle dimension is not a positive finite number,
    ``max_angle`` is not in (0, pi], ``damping`` is negative, ``hinge_side`` is unknown,
    the walls leave no inside or the handle does not fit on the door, a position is NaN or
    infinite, or ``name`` or a colour is malformed.
    """
    spec = _door_spec(
        name,
        (x, y, surface_z),
        (width, height, depth, wall_thickness),
        hinge_side,
        max_angle,
        damping,
        mass,
        (handle_length, handle_clearance, handle_radius, handle_inset),
        (rgba, door_rgba, handle_rgba),
    )
    carcass = arena.worldbody.add("body", name=name, pos=(spec.x, spec.y, spec.surface_z))
    carcass_geoms = _add_carcass(carcass, name, spec.d, spec.w, spec.h, spec.t, spec.rgba)
    _add_door_part(arena, carcass, spec)
    arena.contact.add("exclude", body1=name, body2=f"{name}_door")
    return _describe_door(spec, carcass_geoms)


# -- ids and readings ---------------------------------------------------------------------


@dataclass(frozen=True)
class DrawerIds:
    """One drawer's ids in a compiled scene (:func:`drawer_ids`): its slide joint's
    ``qpos`` and ``dof`` addresses, the drawer's ``body`` id, the handle bar's
    ``handle_geom`` id and ``limit``, the joint's upper limit (the travel, m)."""

    qpos: int
    dof: int
    body: int
    handle_geom: int
    limit: float


@dataclass(frozen=True)
class HingedDoorIds:
    """One hinged door's ids in a compiled scene (:func:`hinged_door_ids`): its hinge's
    ``qpos`` and ``dof`` addresses, the door's ``body`` id, the handle bar's
    ``handle_geom`` id and ``limit``, the hinge's upper limit (``max_angle``, rad)."""

    qpos: int
    dof: int
    body: int
    handle_geom: int
    limit: float


def drawer_ids(model: mujoco.MjModel, name: str) -> DrawerIds:
    """The ids of the drawer called ``name`` (built by :func:`add_drawer`) in ``model``;
    look them up once per compiled scene. Raises ``KeyError`` for an unknown name."""
    joint = model.joint(f"{name}_slide")
    return DrawerIds(
        qpos=int(joint.qposadr[0]),
        dof=int(joint.dofadr[0]),
        body=model.body(f"{name}_drawer").id,
        handle_geom=model.geom(f"{name}_handle").id,
        limit=float(model.jnt_range[joint.id][1]),
    )


def hinged_door_ids(model: mujoco.MjModel, name: str) -> HingedDoorIds:
    """The ids of the hinged door called ``name`` (built by :func:`add_hinged_door`) in
    ``model``; look them up once per compiled scene. Raises ``KeyError`` for an unknown
    name."""
    joint = model.joint(f"{name}_hinge")
    return HingedDoorIds(
        qpos=int(joint.qposadr[0]),
        dof=int(joint.dofadr[0]),
        body=model.body(f"{name}_door").id,
        handle_geom=model.geom(f"{name}_handle").id,
        limit=float(model.jnt_range[joint.id][1]),
    )


def opening(data: mujoco.MjData, ids: DrawerIds | HingedDoorIds) -> float:
    """How far the part is open, read from its joint: a drawer's pull-out (m), a door's
    angle (rad); 0 closed, ``ids.limit`` fully open (a joint pressed hard against a limit
    can read a little past it: MuJoCo's limits are soft). The joint reading a predicate
    (DrawerOpen, DoorOpen) thresholds, or a feature for a learned one."""
    return float(data.qpos[ids.qpos])


def open_fraction(data: mujoco.MjData, ids: DrawerIds | HingedDoorIds) -> float:
    """:func:`opening` over the joint's upper limit, clipped to [0, 1]: 0 closed, 1 fully
    open, whichever the part. A scale-free feature for predicates such as DrawerOpen."""
    return min(1.0, max(0.0, opening(data, ids) / ids.limit))


def is_open(data: mujoco.MjData, ids: DrawerIds | HingedDoorIds, fraction: float = 0.8) -> bool:
    """Whether :func:`open_fraction` is at least ``fraction`` (default 0.8): a DrawerOpen /
    DoorOpen predicate's test, true from the first state whose joint reading reaches
    ``fraction`` of the range. Raises ``ValueError`` if ``fraction`` is not in (0, 1]."""
    if not 0.0 < fraction <= 1.0:  # also rejects NaN
        raise ValueError(f"is_open: fraction must be in (0, 1], got {fraction!r}")
    return open_fraction(data, ids) >= fraction


def handle_xyz(data: mujoco.MjData, ids: DrawerIds | HingedDoorIds) -> np.ndarray:
    """The handle bar's centre in the world frame now (m), a copy of ``data.geom_xpos``:
    the feature a reach to the handle aims at. Like every position in ``data`` it is as of
    the last ``mujoco.mj_forward`` (``mj_step`` computes it before integrating)."""
    return data.geom_xpos[ids.handle_geom].copy()


# -- building the parts -------------------------------------------------------------------


@dataclass(frozen=True)
class _DrawerSpec:
    """:func:`add_drawer`'s arguments once checked (m, kg, N s/m), with the drawer's
    outer extents derived from them: ``dx`` deep, ``2 * hyd`` wide, ``hd`` high."""

    name: str
    x: float
    y: float
    surface_z: float
    sx: float
    sy: float
    sz: float
    travel: float
    t: float
    damping: float
    mass: float
    clearance: float
    radius: float
    length: float
    rgba: tuple[float, ...]
    drawer_rgba: tuple[float, ...]
    handle_rgba: tuple[float, ...]
    dx: float
    hyd: float
    hd: float

    @property
    def wall_hz(self) -> float:
        """Half height of the drawer's walls: they stand on its floor, up to its top."""
        return (self.hd - self.t) / 2

    @property
    def bar(self) -> tuple[float, float]:
        """(x, z) of the handle bar's axis in the drawer's frame (its front face at -dx/2)."""
        return -self.dx / 2 - self.clearance - self.radius, self.t + self.wall_hz


@dataclass(frozen=True)
class _DoorSpec:
    """:func:`add_hinged_door`'s arguments once checked (m, rad, kg, N m s/rad), with the
    panel's extents ``panel_w`` x ``panel_h`` derived from them."""

    name: str
    x: float
    y: float
    surface_z: float
    w: float
    h: float
    d: float
    t: float
    hinge_side: str
    angle: float
    damping: float
    mass: float
    clearance: float
    radius: float
    inset: float
    length: float
    rgba: tuple[float, ...]
    door_rgba: tuple[float, ...]
    handle_rgba: tuple[float, ...]
    panel_w: float
    panel_h: float

    @property
    def side(self) -> float:
        """+1 or -1: the door extends from its hinge along ``side * y``."""
        return 1.0 if self.hinge_side == "right" else -1.0

    @property
    def axis(self) -> tuple[float, float, float]:
        """The hinge axis: a positive turn swings the free edge towards -x."""
        return (0.0, 0.0, self.side)

    @property
    def hinge_rel(self) -> tuple[float, float, float]:
        """The hinge axis at mid-height in the carcass's frame: a gap in front of its face."""
        return (-self.d / 2 - PART_GAP, -self.side * self.w / 2, self.h / 2)

    @property
    def bar(self) -> tuple[float, float, float]:
        """The handle bar's centre in the door's frame (the panel's front face at -t)."""
        s, g = self.side, PART_GAP
        return (-self.t - self.clearance - self.radius, s * (self.w - g - self.inset), 0.0)


def _add_drawer_part(carcass: mjcf.Element, spec: _DrawerSpec) -> tuple[str, ...]:
    """The drawer body on its slide joint, its floor and walls and its handle, in the
    carcass; returns the names of the drawer's box geoms."""
    name, t, dx = spec.name, spec.t, spec.dx
    drawer = carcass.add(
        "body", name=f"{name}_drawer", pos=(-spec.sx / 2 + dx / 2, 0, t + PART_GAP)
    )
    drawer.add(
        "joint",
        name=f"{name}_slide",
        type="slide",
        axis=(-1, 0, 0),  # qpos = opening, positive towards the robot
        range=(0.0, spec.travel),
        limited=True,
        damping=spec.damping,
        solreflimit=LIMIT_SOLREF,
    )
    boxes = _drawer_boxes(spec)
    bar_x, bar_z = spec.bar
    handle = _handle_shapes(name, (bar_x, 0.0, bar_z), -dx / 2, spec.length, spec.radius, "y")
    _add_moving_geoms(drawer, boxes, handle, spec.mass, spec.drawer_rgba, spec.handle_rgba)
    return tuple(boxes)


def _drawer_boxes(spec: _DrawerSpec) -> dict[str, tuple[tuple, tuple]]:
    """The drawer's floor and four walls as {geom name: (half extents, pos)}."""
    name, t, dx, hyd, wall_hz = spec.name, spec.t, spec.dx, spec.hyd, spec.wall_hz
    return {
        f"{name}_drawer_floor": ((dx / 2, hyd, t / 2), (0, 0, t / 2)),
        f"{name}_drawer_front": ((t / 2, hyd, wall_hz), (-dx / 2 + t / 2, 0, t + wall_hz)),
        f"{name}_drawer_back": ((t / 2, hyd, wall_hz), (dx / 2 - t / 2, 0, t + wall_hz)),
        f"{name}_drawer_yneg": ((dx / 2 - t, t / 2, wall_hz), (0, -(hyd - t / 2), t + wall_hz)),
        f"{name}_drawer_ypos": ((dx / 2 - t, t / 2, wall_hz), (0, hyd - t / 2, t + wall_hz)),
    }


def _describe_drawer(
    spec: _DrawerSpec, carcass_geoms: tuple[str, ...], drawer_geoms: tuple[str, ...]
) -> Drawer:
    """The built drawer's names and its world-frame numbers at closed."""
    name, x, y, t, g = spec.name, spec.x, spec.y, spec.t, PART_GAP
    floor_z = spec.surface_z + 2 * t + g
    cx = x - spec.sx / 2 + spec.dx / 2
    bar_x, bar_z = spec.bar
    return Drawer(
        name=name,
        joint=f"{name}_slide",
        carcass_body=name,
        drawer_body=f"{name}_drawer",
        handle_geom=f"{name}_handle",
        handle_post_geoms=(f"{name}_handle_post0", f"{name}_handle_post1"),
        carcass_geoms=carcass_geoms,
        drawer_geoms=drawer_geoms,  # type: ignore[arg-type]
        travel=spec.travel,
        handle_closed=(cx + bar_x, y, spec.surface_z + t + g + bar_z),
        front_x=x - spec.sx / 2,
        floor_centre=(cx, y, floor_z),
        inner_half=(spec.dx / 2 - t, spec.hyd - t),
        floor_z=floor_z,
        rim_z=spec.surface_z + t + g + spec.hd,
    )


def _add_door_part(arena: mjcf.RootElement, carcass: mjcf.Element, spec: _DoorSpec) -> None:
    """The door body on its hinge, its panel and its handle, in the carcass."""
    name, t, s = spec.name, spec.t, spec.side
    door = carcass.add("body", name=f"{name}_door", pos=spec.hinge_rel)
    door.add(
        "joint",
        name=f"{name}_hinge",
        type="hinge",
        axis=spec.axis,
        range=(0.0, spec.angle * _angle_unit(arena)),
        limited=True,
        damping=spec.damping,
        solreflimit=LIMIT_SOLREF,
    )
    panel_half = (t / 2, spec.panel_w / 2, spec.panel_h / 2)
    panel = {f"{name}_door_panel": (panel_half, (-t / 2, s * spec.w / 2, 0.0))}
    handle = _handle_shapes(name, spec.bar, -t, spec.length, spec.radius, "z")
    _add_moving_geoms(door, panel, handle, spec.mass, spec.door_rgba, spec.handle_rgba)


def _angle_unit(arena: mjcf.RootElement) -> float:
    """The arena's angle unit per radian, set to radians where unset: MJCF's default unit
    is degrees, the Panda's radians, and a scene must compile alike with or without it."""
    if arena.compiler.angle is None:
        arena.compiler.angle = "radian"
    return 1.0 if arena.compiler.angle == "radian" else 180.0 / math.pi


def _describe_door(spec: _DoorSpec, carcass_geoms: tuple[str, ...]) -> HingedDoor:
    """The built door's names and its world-frame numbers at closed."""
    name, rel, bar = spec.name, spec.hinge_rel, spec.bar
    hx, hy, hz = spec.x + rel[0], spec.y + rel[1], spec.surface_z + rel[2]
    return HingedDoor(
        name=name,
        joint=f"{name}_hinge",
        carcass_body=name,
        door_body=f"{name}_door",
        panel_geom=f"{name}_door_panel",
        handle_geom=f"{name}_handle",
        handle_post_geoms=(f"{name}_handle_post0", f"{name}_handle_post1"),
        carcass_geoms=carcass_geoms,
        hinge_side=spec.hinge_side,
        max_angle=spec.angle,
        hinge_xyz=(hx, hy, hz),
        hinge_axis=spec.axis,
        handle_closed=(hx + bar[0], hy + bar[1], hz),
        front_x=spec.x - spec.d / 2,
    )


def _add_moving_geoms(
    body: mjcf.Element,
    boxes: dict[str, tuple[tuple, tuple]],
    handle: list[tuple],
    mass: float,
    rgba: tuple[float, ...],
    handle_rgba: tuple[float, ...],
) -> None:
    """A moving part's boxes ({name: (half extents, pos)}) and its handle, sharing ``mass``."""
    masses = _split_mass(mass, [half for half, _ in boxes.values()], handle)
    for (geom, (half, pos)), m in zip(boxes.items(), masses[: len(boxes)], strict=True):
        body.add("geom", name=geom, size=half, pos=pos, mass=m, **_geom_kw(rgba))
    _add_handle(body, handle, masses[len(boxes) :], handle_rgba)


# -- geometry -----------------------------------------------------------------------------


def _geom_kw(rgba: tuple[float, ...]) -> dict:
    return {
        "type": "box",
        "rgba": rgba,
        "contype": OBJECT_CONTYPE,
        "conaffinity": OBJECT_CONAFFINITY,
    }


def _add_carcass(body, name: str, sx: float, sy: float, sz: float, t: float, rgba) -> tuple:
    """A box open at -x in ``body``'s frame (footprint centred, bottom at z = 0)."""
    inner_hz = (sz - 2 * t) / 2
    boxes = {
        f"{name}_bottom": ((sx / 2, sy / 2, t / 2), (0, 0, t / 2)),
        f"{name}_top": ((sx / 2, sy / 2, t / 2), (0, 0, sz - t / 2)),
        f"{name}_back": ((t / 2, sy / 2, inner_hz), (sx / 2 - t / 2, 0, sz / 2)),
        f"{name}_side_yneg": (((sx - t) / 2, t / 2, inner_hz), (-t / 2, -(sy - t) / 2, sz / 2)),
        f"{name}_side_ypos": (((sx - t) / 2, t / 2, inner_hz), (-t / 2, (sy - t) / 2, sz / 2)),
    }
    for geom, (half, pos) in boxes.items():
        body.add("geom", name=geom, size=half, pos=pos, **_geom_kw(rgba))
    return tuple(boxes)


def _handle_shapes(name, bar_centre, face_x, length, r, along) -> list[tuple]:
    """The bar (a capsule along ``along``) and its two posts (boxes back to the face at
    ``face_x``), as (geom name, type, size, pos or fromto)."""
    bx, by, bz = bar_centre
    k = 1 if along == "y" else 2
    half = length / 2 - r  # the capsule's cylinder half length; the caps add r each end
    ends = [list(bar_centre), list(bar_centre)]
    ends[0][k] -= half
    ends[1][k] += half
    shapes = [(f"{name}_handle", "capsule", (r,), (*ends[0], *ends[1]))]
    post_half = ((face_x - bx) / 2, 0.75 * r, 0.75 * r)
    for i, sign in enumerate((-1, 1)):
        pos = [(face_x + bx) / 2, by, bz]
        pos[k] += sign * half
        shapes.append((f"{name}_handle_post{i}", "box", post_half, tuple(pos)))
    return shapes


def _volume(kind: str, size: Sequence[float], where: Sequence[float] = ()) -> float:
    if kind == "box":
        return 8 * size[0] * size[1] * size[2]
    r = size[0]
    cylinder = float(np.linalg.norm(np.subtract(where[3:], where[:3])))
    return math.pi * r * r * cylinder + 4 / 3 * math.pi * r**3


def _split_mass(mass: float, boxes: list, handle: list[tuple]) -> list[float]:
    """``mass`` shared over the boxes then the handle's geoms in proportion to volume."""
    volumes = [_volume("box", s) for s in boxes]
    volumes += [_volume(kind, size, where) for _, kind, size, where in handle]
    total = sum(volumes)
    return [mass * v / total for v in volumes]


def _add_handle(body, shapes: list[tuple], masses: list[float], rgba) -> None:
    for (geom, kind, size, where), m in zip(shapes, masses, strict=True):
        placement = {"fromto": where} if kind == "capsule" else {"pos": where}
        body.add(
            "geom",
            name=geom,
            type=kind,
            size=size,
            mass=m,
            rgba=rgba,
            contype=OBJECT_CONTYPE,
            conaffinity=OBJECT_CONAFFINITY,
            friction=GRIPPABLE_FRICTION,
            condim=4,
            **placement,
        )


# -- argument checks: a ValueError that names the argument and the value --------------------


def _drawer_spec(
    name: str,
    position: tuple[float, float, float],
    size: Sequence[float],
    travel: float,
    wall_thickness: float,
    damping: float,
    mass: float,
    handle: tuple[float | None, float, float],
    colours: tuple[Sequence[float], Sequence[float], Sequence[float]],
) -> _DrawerSpec:
    """:func:`add_drawer`'s arguments, checked one by one (the first bad one is named)
    before anything is added to the arena. ``handle`` is (length, clearance, radius),
    ``colours`` (carcass, drawer, handle)."""
    fn = "add_drawer"
    _check_name(fn, name)
    x, y, surface_z = _position(fn, *position)
    sx, sy, sz = _triple(fn, "size", size)
    travel = _positive(fn, "travel", travel)
    t = _positive(fn, "wall_thickness", wall_thickness)
    damping = _non_negative(fn, "damping", damping, "N s/m")
    mass = _positive(fn, "mass", mass, "kg")
    handle_length, handle_clearance, handle_radius = handle
    c = _positive(fn, "handle_clearance", handle_clearance)
    r = _positive(fn, "handle_radius", handle_radius)
    rgba, drawer_rgba, handle_rgba = (_rgba(fn, v) for v in colours)
    g = PART_GAP
    dx, hyd, hd = sx - t - g, sy / 2 - t - g, sz - 2 * t - 2 * g  # drawer's outer extents
    if dx <= 2 * t or hyd <= t or hd <= t:
        raise ValueError(
            f"{fn}: size {tuple(size)!r} leaves no inside for a drawer with walls "
            f"{wall_thickness!r} thick (a {PART_GAP} m gap around it)"
        )
    if travel > dx:
        raise ValueError(
            f"{fn}: travel ({travel!r}) exceeds the drawer's depth ({dx!r} m = size[0] - "
            "wall_thickness - PART_GAP): the drawer would leave the carcass"
        )
    if 2 * r > hd - t or 4 * r > 2 * hyd:
        raise ValueError(
            f"{fn}: handle_radius ({handle_radius!r}) is too large for a front panel "
            f"{hd - t!r} m high and {2 * hyd!r} m wide"
        )
    length = _bar_length(fn, handle_length, 2 * hyd, r, "the drawer's width")
    return _DrawerSpec(
        name, x, y, surface_z, sx, sy, sz, travel, t, damping, mass, c, r, length,
        rgba, drawer_rgba, handle_rgba, dx, hyd, hd,
    )  # fmt: skip


def _door_spec(
    name: str,
    position: tuple[float, float, float],
    shape: tuple[float, float, float, float],
    hinge_side: str,
    max_angle: float,
    damping: float,
    mass: float,
    handle: tuple[float | None, float, float, float],
    colours: tuple[Sequence[float], Sequence[float], Sequence[float]],
) -> _DoorSpec:
    """:func:`add_hinged_door`'s arguments, checked one by one (the first bad one is
    named) before anything is added to the arena. ``shape`` is (width, height, depth,
    wall_thickness), ``handle`` (length, clearance, radius, inset), ``colours`` (carcass,
    door, handle)."""
    fn = "add_hinged_door"
    _check_name(fn, name)
    x, y, surface_z = _position(fn, *position)
    width, height, depth, wall_thickness = shape
    w = _positive(fn, "width", width)
    h = _positive(fn, "height", height)
    if hinge_side not in ("left", "right"):
        raise ValueError(f"{fn}: hinge_side must be 'left' or 'right', got {hinge_side!r}")
    d = _positive(fn, "depth", depth)
    angle = _positive(fn, "max_angle", max_angle, "rad")
    if angle > math.pi:
        raise ValueError(f"{fn}: max_angle must be at most pi (rad), got {max_angle!r}")
    t = _positive(fn, "wall_thickness", wall_thickness)
    damping = _non_negative(fn, "damping", damping, "N m s/rad")
    mass = _positive(fn, "mass", mass, "kg")
    handle_length, handle_clearance, handle_radius, handle_inset = handle
    c = _positive(fn, "handle_clearance", handle_clearance)
    r = _positive(fn, "handle_radius", handle_radius)
    inset = _positive(fn, "handle_inset", handle_inset)
    rgba, door_rgba, handle_rgba = (_rgba(fn, v) for v in colours)
    if d <= t or w <= 2 * t or h <= 2 * t:
        raise ValueError(
            f"{fn}: depth {depth!r}, width {width!r} and height {height!r} leave no inside "
            f"for a cabinet with walls {wall_thickness!r} thick"
        )
    g = PART_GAP
    panel_w, panel_h = w - 2 * g, h - 2 * g
    if inset < r or inset > panel_w / 2:
        raise ValueError(
            f"{fn}: handle_inset ({handle_inset!r}) must be between handle_radius ({r!r}) "
            f"and half the door's width ({panel_w / 2!r})"
        )
    length = _bar_length(fn, handle_length, panel_h, r, "the door's height")
    return _DoorSpec(
        name, x, y, surface_z, w, h, d, t, hinge_side, angle, damping, mass, c, r, inset,
        length, rgba, door_rgba, handle_rgba, panel_w, panel_h,
    )  # fmt: skip


def _bar_length(
    fn: str, handle_length: float | None, room: float, r: float, room_name: str
) -> float:
    """The handle bar's length: ``handle_length``, or :data:`HANDLE_LENGTH` cut to the
    ``room`` the part has for it; at least 4 radii (the caps and the posts need them)."""
    length = min(HANDLE_LENGTH, room) if handle_length is None else handle_length
    length = _positive(fn, "handle_length", length)
    if length > room or length < 4 * r:
        raise ValueError(
            f"{fn}: handle_length ({length!r}) must be between 4 handle radii "
            f"({4 * r!r}) and {room_name} ({room!r})"
        )
    return length


def _finite(fn: str, label: str, value: object, unit: str = "m") -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{fn}: {label} must be a number ({unit}), got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{fn}: {label} must be finite ({unit}), got {value!r}")
    return v


def _positive(fn: str, label: str, value: object, unit: str = "m") -> float:
    v = _finite(fn, label, value, unit)
    if v <= 0.0:
        raise ValueError(f"{fn}: {label} must be positive ({unit}), got {value!r}")
    return v


def _non_negative(fn: str, label: str, value: object, unit: str) -> float:
    v = _finite(fn, label, value, unit)
    if v < 0.0:
        raise ValueError(f"{fn}: {label} must not be negative ({unit}), got {value!r}")
    return v


def _triple(fn: str, label: str, value: object) -> tuple[float, float, float]:
    try:
        items = () if isinstance(value, str | bytes) else tuple(value)  # type: ignore[arg-type]
    except TypeError:
        items = ()
    if len(items) != 3:
        raise ValueError(
            f"{fn}: {label} must be three lengths (sx, sy, sz) in metres, got {value!r}"
        )
    return tuple(_positive(fn, f"{label}[{i}]", v) for i, v in enumerate(items))  # type: ignore[return-value]
