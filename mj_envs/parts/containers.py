"""Static containers for task scenes: an open bin and a shelf, built from box geoms.

Units are metres. Positions are in the world frame of an arena made by
:func:`mj_envs.scene.make_arena` (the Panda's base at the origin, +x forward, the table
top at z = 0), and a container stands with its bottom at ``surface_z`` (default: the
table top). A container is one body named ``name`` with no joint, so MuJoCo treats it as
part of the world: it never moves, its mass plays no role, and it never collides with the
table or other static geoms (MuJoCo skips contacts between two bodies fixed to the world).

Collision groups follow :mod:`mj_envs.scene`: every geom here is world geometry,
``contype`` :data:`~mj_envs.scene.OBJECT_CONTYPE` / ``conaffinity``
:data:`~mj_envs.scene.OBJECT_CONAFFINITY` (1 / 3). So free objects (1 / 3) rest on and
bump into it, and so does the robot (2 / 1): the arm cannot reach through a wall, which a
demonstrator must plan around. Contact friction is the larger of the two geoms' (MuJoCo's
default mixing), so an object built with :data:`~mj_envs.parts.objects.GRIPPABLE_FRICTION`
keeps its own friction on a container.

Each builder returns a small frozen description (:class:`Bin`, :class:`Shelf`) with the
world-frame numbers and a point test (:meth:`Bin.contains`, :meth:`Shelf.on_top`) a
predicate can call on an object's position feature. The point tests are pure geometry;
whether an object touches the container is a contact question: ask
:func:`mj_envs.contacts.body_geoms` for the body ``name`` (all of its geoms) or
:func:`mj_envs.contacts.geom_ids` for one geom (``Bin.floor_geom``, ``Shelf.board_geom``).

Element names for a bin called ``name``: body ``name``, geoms ``name_floor``,
``name_wall_xneg``, ``name_wall_xpos``, ``name_wall_yneg``, ``name_wall_ypos``. For a
shelf: body ``name``, geoms ``name_board`` and ``name_leg0`` .. ``name_leg3`` (legs) or
``name_back`` (back panel).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from dm_control import mjcf

from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE

BIN_RGBA = (0.45, 0.5, 0.55, 1.0)
SHELF_RGBA = (0.55, 0.42, 0.3, 1.0)
# How far above a shelf's board a point may be and still count as on top of it (m): an
# object's centre, for objects up to 10 cm tall (the tabletop objects here are 4.5 cm).
ON_TOP_MAX_HEIGHT = 0.05


@dataclass(frozen=True)
class Bin:
    """An open box-shaped bin in the world frame (metres), as built by :func:`add_bin`.

    ``centre`` is the centre of the floor plate's top face, where an object set down in
    the middle of the bin rests; ``inner_half`` the half extents of the free space inside
    the walls along x and y; ``floor_z`` and ``rim_z`` the heights of the floor's top face
    and of the walls' top. ``floor_geom`` and ``wall_geoms`` are the geom names.
    """

    name: str
    centre: tuple[float, float, float]
    inner_half: tuple[float, float]
    floor_z: float
    rim_z: float
    floor_geom: str
    wall_geoms: tuple[str, str, str, str]

    def contains(self, xyz: Sequence[float], margin: float = 0.0) -> bool:
        """Whether the point ``xyz`` (world frame, m) is inside the bin: strictly inside the
        walls along x and y, above the floor's top face and below the rim.

        ``margin`` (m, default 0) shrinks the region on x and y: pass an object's
        horizontal half extent to ask whether its whole footprint is inside (with the
        object's centre as ``xyz``). A point with a NaN coordinate is not contained.
        """
        x, y, z = (float(v) for v in xyz)
        hx, hy = self.inner_half[0] - margin, self.inner_half[1] - margin
        return bool(
            abs(x - self.centre[0]) < hx
            and abs(y - self.centre[1]) < hy
            and self.floor_z < z < self.rim_z
        )


@dataclass(frozen=True)
class Shelf:
    """A horizontal board at a height in the world frame (metres), built by :func:`add_shelf`.

    ``centre`` is the centre of the board's top face, ``half_size`` the board's half
    extents along x and y, ``top_z`` the height of its top face. ``board_geom`` and
    ``support_geoms`` (legs or back panel) are the geom names.
    """

    name: str
    centre: tuple[float, float, float]
    half_size: tuple[float, float]
    top_z: float
    board_geom: str
    support_geoms: tuple[str, ...]

    def on_top(
        self, xyz: Sequence[float], max_height: float = ON_TOP_MAX_HEIGHT, margin: float = 0.0
    ) -> bool:
        """Whether the point ``xyz`` (world frame, m) is over the board and at most
        ``max_height`` (m, default :data:`ON_TOP_MAX_HEIGHT` = 0.05) above its top face.

        Meant for an object's centre: one resting on the board has its centre half its
        height above ``top_z``. ``margin`` (m, default 0) shrinks the board on x and y, e.g.
        to an object's horizontal half extent so that its whole footprint is over the
        board. A point with a NaN coordinate is not on top.
        """
        x, y, z = (float(v) for v in xyz)
        hx, hy = self.half_size[0] - margin, self.half_size[1] - margin
        return bool(
            abs(x - self.centre[0]) < hx
            and abs(y - self.centre[1]) < hy
            and self.top_z < z <= self.top_z + max_height
        )


def add_bin(
    arena: mjcf.RootElement,
    name: str,
    x: float,
    y: float,
    inner_size: Sequence[float],
    wall_height: float = 0.05,
    wall_thickness: float = 0.01,
    *,
    surface_z: float = 0.0,
    rgba: Sequence[float] = BIN_RGBA,
) -> Bin:
    """Add an open bin called ``name`` centred at (``x``, ``y``), standing at ``surface_z``.

    Arguments (metres, world frame): ``inner_size`` = (sx, sy), the full width of the free
    space inside the walls along x and y; ``wall_height``, from ``surface_z`` to the rim
    (default 0.05); ``wall_thickness``, of the four walls and the floor plate (default
    0.01); ``surface_z``, the height the bin stands on (default 0.0, the table top: the
    table spans x in [-0.05, 0.95], y in [-0.65, 0.65]; the floor plane below it does not
    collide with anything); ``rgba``, the colour of every geom (looks only).

    The floor plate fills the inside (its top face at ``surface_z + wall_thickness``), so a
    contact with ``name_floor`` means "resting in the bin" whatever the bin stands on. The
    walls stand on ``surface_z`` around it; the x walls span the corners. Every geom is
    static world geometry with contype 1 / conaffinity 3 (see the module docstring): the
    robot's hand collides with the walls too, so keep the rim below the hand's collision
    box when it lowers an object inside (the box's bottom is 3.5 cm above the grip site)
    and the inside wider than the open fingers (8 cm along x at the home posture) if the
    fingers must reach in.

    Returns a :class:`Bin` describing it. Raises ``ValueError`` naming the argument if a
    size is not a positive finite number, ``wall_height`` is not above the floor plate, a
    position is NaN or infinite, or ``name`` or ``rgba`` is malformed.
    """
    fn = "add_bin"
    _check_name(fn, name)
    x, y, surface_z = _position(fn, x, y, surface_z)
    sx, sy = _pair(fn, "inner_size", inner_size)
    h = _positive(fn, "wall_height", wall_height)
    t = _positive(fn, "wall_thickness", wall_thickness)
    if h <= t:
        raise ValueError(
            f"{fn}: wall_height ({wall_height!r}) must exceed wall_thickness "
            f"({wall_thickness!r}), the floor plate's thickness, or the bin has no inside"
        )
    rgba = _rgba(fn, rgba)
    hx, hy = sx / 2, sy / 2
    body = arena.worldbody.add("body", name=name, pos=(x, y, surface_z))
    geom = _static_box(rgba)
    body.add("geom", name=f"{name}_floor", size=(hx, hy, t / 2), pos=(0, 0, t / 2), **geom)
    walls = (f"{name}_wall_xneg", f"{name}_wall_xpos", f"{name}_wall_yneg", f"{name}_wall_ypos")
    for wall, sign in zip(walls[:2], (-1, 1), strict=True):  # span the corners
        body.add(
            "geom",
            name=wall,
            size=(t / 2, hy + t, h / 2),
            pos=(sign * (hx + t / 2), 0, h / 2),
            **geom,
        )
    for wall, sign in zip(walls[2:], (-1, 1), strict=True):
        body.add(
            "geom", name=wall, size=(hx, t / 2, h / 2), pos=(0, sign * (hy + t / 2), h / 2), **geom
        )
    return Bin(
        name=name,
        centre=(x, y, surface_z + t),
        inner_half=(hx, hy),
        floor_z=surface_z + t,
        rim_z=surface_z + h,
        floor_geom=f"{name}_floor",
        wall_geoms=walls,
    )


def add_shelf(
    arena: mjcf.RootElement,
    name: str,
    x: float,
    y: float,
    size: Sequence[float],
    height: float,
    board_thickness: float = 0.02,
    support: Literal["legs", "back"] = "legs",
    support_thickness: float = 0.02,
    *,
    surface_z: float = 0.0,
    rgba: Sequence[float] = SHELF_RGBA,
) -> Shelf:
    """Add a shelf called ``name``: a board centred at (``x``, ``y``) whose top face is
    ``height`` above ``surface_z``.

    Arguments (metres, world frame): ``size`` = (sx, sy), the board's full extent along x
    and y; ``height``, of the board's top face above ``surface_z``; ``board_thickness``
    (default 0.02); ``support``, what holds the board up: ``"legs"`` (default), four square
    legs of side ``support_thickness`` (default 0.02) under its corners, or ``"back"``, one
    panel ``support_thickness`` thick under the board's +x edge (the edge away from the
    robot, which stands at the origin facing +x), so the space under the board is open
    from the robot's side; ``surface_z``, what the shelf stands on (default 0.0, the table
    top); ``rgba``, the colour of every geom (looks only).

    The supports reach from ``surface_z`` to the board's underside, so nothing of the
    shelf sticks up above the board. Every geom is static world geometry with contype 1 /
    conaffinity 3 (see the module docstring): objects rest on the board, and the robot
    collides with the board and the supports, also when reaching under the board.

    Returns a :class:`Shelf` describing it. Raises ``ValueError`` naming the argument if a
    size is not a positive finite number, ``height`` is not above ``board_thickness``,
    legs do not fit under the board, ``support`` is unknown, a position is NaN or
    infinite, or ``name`` or ``rgba`` is malformed.
    """
    fn = "add_shelf"
    _check_name(fn, name)
    x, y, surface_z = _position(fn, x, y, surface_z)
    sx, sy, h, bt, st = _shelf_sizes(fn, size, height, board_thickness, support, support_thickness)
    rgba = _rgba(fn, rgba)
    hx, hy = sx / 2, sy / 2
    body = arena.worldbody.add("body", name=name, pos=(x, y, surface_z))
    geom = _static_box(rgba)
    body.add("geom", name=f"{name}_board", size=(hx, hy, bt / 2), pos=(0, 0, h - bt / 2), **geom)
    under = h - bt  # from the surface to the board's underside
    if support == "legs":
        supports = _add_legs(body, name, hx, hy, st, under, geom)
    else:
        supports = _add_back(body, name, hx, hy, st, under, geom)
    return Shelf(
        name=name,
        centre=(x, y, surface_z + h),
        half_size=(hx, hy),
        top_z=surface_z + h,
        board_geom=f"{name}_board",
        support_geoms=supports,
    )


def _shelf_sizes(
    fn: str,
    size: Sequence[float],
    height: float,
    board_thickness: float,
    support: str,
    support_thickness: float,
) -> tuple[float, float, float, float, float]:
    """A shelf's (sx, sy, height, board thickness, support thickness), checked, so that a
    bad argument fails before anything is added to the arena."""
    sx, sy = _pair(fn, "size", size)
    h = _positive(fn, "height", height)
    bt = _positive(fn, "board_thickness", board_thickness)
    st = _positive(fn, "support_thickness", support_thickness)
    if h <= bt:
        raise ValueError(
            f"{fn}: height ({height!r}) must exceed board_thickness ({board_thickness!r}): "
            "the board would sink below the surface it stands on"
        )
    if support not in ("legs", "back"):
        raise ValueError(f"{fn}: support must be 'legs' or 'back', got {support!r}")
    limit = min(sx, sy) / 2 if support == "legs" else sx
    if st > limit:
        raise ValueError(
            f"{fn}: support_thickness ({support_thickness!r}) does not fit under a board of "
            f"size {tuple(size)!r}"
        )
    return sx, sy, h, bt, st


def _add_legs(
    body: mjcf.Element, name: str, hx: float, hy: float, st: float, under: float, geom: dict
) -> tuple[str, ...]:
    """Four square legs under the board's corners, from the surface to its underside."""
    supports = tuple(f"{name}_leg{i}" for i in range(4))
    corners = [(cx, cy) for cx in (-1, 1) for cy in (-1, 1)]
    for leg, (cx, cy) in zip(supports, corners, strict=True):
        body.add(
            "geom",
            name=leg,
            size=(st / 2, st / 2, under / 2),
            pos=(cx * (hx - st / 2), cy * (hy - st / 2), under / 2),
            **geom,
        )
    return supports


def _add_back(
    body: mjcf.Element, name: str, hx: float, hy: float, st: float, under: float, geom: dict
) -> tuple[str, ...]:
    """One panel under the board's +x edge, so the space under it is open from the robot."""
    supports = (f"{name}_back",)
    body.add(
        "geom",
        name=supports[0],
        size=(st / 2, hy, under / 2),
        pos=(hx - st / 2, 0, under / 2),
        **geom,
    )
    return supports


def _static_box(rgba: tuple[float, ...]) -> dict:
    """A box geom's attributes as world geometry (see the module docstring)."""
    return {
        "type": "box",
        "rgba": rgba,
        "contype": OBJECT_CONTYPE,
        "conaffinity": OBJECT_CONAFFINITY,
    }


# -- argument checks: a ValueError that names the argument and the value --------------------


def _check_name(fn: str, name: object) -> None:
    if not isinstance(name, str) or not name:
        raise ValueError(f"{fn}: name must be a non-empty string, got {name!r}")


def _position(fn: str, x: object, y: object, surface_z: object) -> tuple[float, float, float]:
    """``x``, ``y`` and ``surface_z`` as finite floats (m), checked in that order."""
    return _finite(fn, "x", x), _finite(fn, "y", y), _finite(fn, "surface_z", surface_z)


def _finite(fn: str, label: str, value: object) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{fn}: {label} must be a number (m), got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{fn}: {label} must be finite (m), got {value!r}")
    return v


def _positive(fn: str, label: str, value: object) -> float:
    v = _finite(fn, label, value)
    if v <= 0.0:
        raise ValueError(f"{fn}: {label} must be positive (m), got {value!r}")
    return v


def _pair(fn: str, label: str, value: object) -> tuple[float, float]:
    try:
        items = () if isinstance(value, str | bytes) else tuple(value)  # type: ignore[arg-type]
    except TypeError:
        items = ()
    if len(items) != 2:
        raise ValueError(f"{fn}: {label} must be two lengths (sx, sy) in metres, got {value!r}")
    return _positive(fn, f"{label}[0]", items[0]), _positive(fn, f"{label}[1]", items[1])


def _rgba(fn: str, value: object) -> tuple[float, float, float, float]:
    try:
        rgba = tuple(float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"{fn}: rgba must be four numbers in [0, 1], got {value!r}") from None
    if len(rgba) != 4 or not all(0.0 <= c <= 1.0 for c in rgba):
        raise ValueError(f"{fn}: rgba must be four numbers in [0, 1], got {value!r}")
    return rgba  # type: ignore[return-value]
