"""Doors' floor plans: sampling (rooms, doors, obstacles) and their MJCF.

Cell (i, j) of a plan is the room centred at (ROOM_SIZE * (i + 0.5), ROOM_SIZE * (j + 0.5)).
Two kinds of plan:

* :func:`sample_plan`: a full grid of ``rows x cols`` rooms; every wall between two
  adjacent rooms has one doorway at its centre (today's default maps).
* :func:`sample_room_map`: the paper's (App. A: "4-25 rooms with random connectivity"):
  a random connected set of cells of a ``size x size`` map, its shared walls joined by a
  random spanning tree of doorways plus each other shared wall with probability
  ``door_fraction``; every other wall is solid. :class:`RoomMap` holds the parameters.

A doorway has a sliding leaf and a handle on the wall top beside it. Each room has 0-3
rotated box obstacles in its corner zones, which keeps the cross-shaped band through the
room's centre (where the robot starts and every approach lane runs) free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mj_envs.domains.doors.rules import (
    DOORWAY_WIDTH,
    FLOOR_Z,
    HANDLE_DAMPING,
    HANDLE_FRICTION_SCALE,
    HANDLE_RANGE,
    KNOB_ALONG,
    KNOB_Z,
    LEAF_ARMATURE,
    LEAF_DAMPING,
    LEAF_MASS,
    LEAF_SPRING,
    LEAF_THICKNESS,
    LEAF_TRAVEL,
    ROOM_SIZE,
    WALL_THICKNESS,
    WALL_TOP,
    WING_HALF,
)
from mj_envs.robots.mobile_panda import BaseConfig, add_mobile_panda
from mj_envs.scene import make_arena

WORLD_CONTYPE, WORLD_CONAFFINITY = 1, 3
# Leaves slide into the walls: they collide with the robot only (robot contype 2).
LEAF_CONTYPE, LEAF_CONAFFINITY = 4, 2
OBSTACLE_HALF = (0.06, 0.13)  # half extents U(lo, hi)
OBSTACLE_ZONE = (0.64, 0.78)  # |offset| from the room centre on both axes
START_JITTER = 0.15
WALL_RGBA = (0.78, 0.76, 0.72, 1.0)
LEAF_RGBA = (0.55, 0.35, 0.2, 1.0)
HANDLE_RGBA = (0.85, 0.7, 0.15, 1.0)


@dataclass(frozen=True)
class DoorSpec:
    """A doorway between rooms ``a`` and ``b`` (grid cells), centre and wall direction."""

    a: tuple[int, int]
    b: tuple[int, int]
    x: float
    y: float
    theta: float  # direction u of the wall (towards the handle's jamb)
    mass: float
    friction: float
    target_rot: float


@dataclass(frozen=True)
class FloorPlan:
    rows: int  # cells along x (of the bounding grid)
    cols: int  # cells along y
    doors: tuple[DoorSpec, ...]
    obstacles: tuple[tuple[float, float, float, float, float], ...]  # x, y, yaw, hx, hy
    start: tuple[float, float, float]  # base x, y, yaw
    start_room: tuple[int, int]
    goal_room: tuple[int, int]
    # the rooms that exist, sorted; None: every cell of the rows x cols grid
    cells: tuple[tuple[int, int], ...] | None = None

    def rooms(self) -> list[tuple[int, int]]:
        if self.cells is not None:
            return list(self.cells)
        return [(i, j) for i in range(self.rows) for j in range(self.cols)]

    def doors_between(self, a: tuple[int, int], b: tuple[int, int]) -> int:
        """The fewest doors crossed from room ``a`` to room ``b`` (BFS over doorways)."""
        links: dict[tuple[int, int], list[tuple[int, int]]] = {r: [] for r in self.rooms()}
        for d in self.doors:
            links[d.a].append(d.b)
            links[d.b].append(d.a)
        depth, frontier = {a: 0}, [a]
        while frontier:
            nxt = []
            for r in frontier:
                for r2 in links[r]:
                    if r2 not in depth:
                        depth[r2] = depth[r] + 1
                        nxt.append(r2)
            frontier = nxt
        if b not in depth:
            raise ValueError(f"room {b} is not reachable from {a}")
        return depth[b]


@dataclass(frozen=True)
class RoomMap:
    """The paper's floor plans: ``rooms`` (inclusive range) connected cells of a
    ``size x size`` map, joined by a spanning tree of doorways plus each other shared wall
    with probability ``door_fraction`` (1: every shared wall has a door)."""

    size: int = 5
    rooms: tuple[int, int] = (4, 25)
    door_fraction: float = 0.5

    def __post_init__(self) -> None:
        lo, hi = self.rooms
        if not 2 <= self.size <= 8:
            raise ValueError(f"room map size must lie in 2..8, got {self.size}")
        if not 2 <= lo <= hi <= self.size**2:
            raise ValueError(
                f"room counts must satisfy 2 <= low <= high <= {self.size**2}, got {self.rooms}"
            )
        if not 0.0 <= self.door_fraction <= 1.0:  # (NaN fails too)
            raise ValueError(f"door_fraction must lie in [0, 1], got {self.door_fraction}")

    @property
    def max_doors(self) -> int:
        return 2 * self.size * (self.size - 1)


def room_centre(cell: tuple[int, int]) -> tuple[float, float]:
    return ROOM_SIZE * (cell[0] + 0.5), ROOM_SIZE * (cell[1] + 0.5)


def sample_plan(rng: np.random.Generator, sizes: tuple[int, ...]) -> FloorPlan:
    rows, cols = int(rng.choice(sizes)), int(rng.choice(sizes))
    doors = []
    for i in range(rows):
        for j in range(cols):
            cx, cy = room_centre((i, j))
            h = ROOM_SIZE / 2
            for (di, dj), (x, y), theta in (
                ((1, 0), (cx + h, cy), math.pi / 2),  # wall along y
                ((0, 1), (cx, cy + h), 0.0),  # wall along x
            ):
                if i + di < rows and j + dj < cols:
                    # The leaf slides along -u into the wall line, 0.35 m past the room's
                    # corner: towards the side where the wall line goes on inside the map
                    # (hidden in the next wall), either way if both do.
                    flip = rng.random() < 0.5
                    k, n = (j, cols) if di else (i, rows)
                    if k == 0:
                        flip = True
                    elif k == n - 1:
                        flip = False
                    theta = theta + (math.pi if flip else 0.0)
                    doors.append(
                        DoorSpec(
                            (i, j),
                            (i + di, j + dj),
                            x,
                            y,
                            theta,
                            float(rng.uniform(*LEAF_MASS)),
                            float(rng.uniform(0, 1)),
                            float(rng.uniform(0, 1)),
                        )
                    )
    obstacles = _sample_obstacles(rng, [(i, j) for i in range(rows) for j in range(cols)])
    cells = [(i, j) for i in range(rows) for j in range(cols)]
    a, b = rng.choice(len(cells), size=2, replace=False)
    start_room, goal_room = cells[int(a)], cells[int(b)]
    sx, sy = room_centre(start_room)
    start = (
        sx + rng.uniform(-START_JITTER, START_JITTER),
        sy + rng.uniform(-START_JITTER, START_JITTER),
        float(rng.uniform(-math.pi, math.pi)),
    )
    return FloorPlan(rows, cols, tuple(doors), tuple(obstacles), start, start_room, goal_room)


NEIGHBOURS = ((1, 0), (-1, 0), (0, 1), (0, -1))


def sample_room_map(rng: np.random.Generator, spec: RoomMap) -> FloorPlan:
    """A floor plan of the paper's distribution (see :class:`RoomMap`): grow a connected
    set of cells from a random one, a random frontier cell at a time; doorways on a random
    spanning tree of their shared walls (so every room is reachable) plus each other
    shared wall with probability ``spec.door_fraction``."""
    n = spec.size
    k = int(rng.integers(spec.rooms[0], spec.rooms[1] + 1))
    cells = {(int(rng.integers(n)), int(rng.integers(n)))}
    while len(cells) < k:
        frontier = sorted(
            {
                (i + di, j + dj)
                for i, j in cells
                for di, dj in NEIGHBOURS
                if 0 <= i + di < n and 0 <= j + dj < n and (i + di, j + dj) not in cells
            }
        )
        cells.add(frontier[int(rng.integers(len(frontier)))])
    i0, j0 = min(i for i, _ in cells), min(j for _, j in cells)
    cells = {(i - i0, j - j0) for i, j in cells}  # the map starts at the origin
    shared = sorted((a, (a[0] + di, a[1] + dj)) for a in cells for di, dj in ((1, 0), (0, 1)))
    shared = [(a, b) for a, b in shared if b in cells]
    parent = {c: c for c in cells}

    def root(c: tuple[int, int]) -> tuple[int, int]:
        while parent[c] != c:
            c = parent[c]
        return c

    kept = set()
    for idx in rng.permutation(len(shared)):  # Kruskal on random weights
        a, b = shared[int(idx)]
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[ra] = rb
            kept.add((a, b))
        elif rng.random() < spec.door_fraction:
            kept.add((a, b))
    doors = [_door_spec(rng, a, b, cells) for a, b in shared if (a, b) in kept]
    rooms = sorted(cells)
    obstacles = _sample_obstacles(rng, rooms)
    a, b = rng.choice(len(rooms), size=2, replace=False)
    start_room, goal_room = rooms[int(a)], rooms[int(b)]
    sx, sy = room_centre(start_room)
    start = (
        sx + rng.uniform(-START_JITTER, START_JITTER),
        sy + rng.uniform(-START_JITTER, START_JITTER),
        float(rng.uniform(-math.pi, math.pi)),
    )
    rows, cols = max(i for i, _ in rooms) + 1, max(j for _, j in rooms) + 1
    return FloorPlan(
        rows, cols, tuple(doors), tuple(obstacles), start, start_room, goal_room, tuple(rooms)
    )


def _door_spec(
    rng: np.random.Generator,
    a: tuple[int, int],
    b: tuple[int, int],
    cells: set[tuple[int, int]],
) -> DoorSpec:
    """The doorway between adjacent rooms ``a`` and ``b`` (b is a's +x or +y neighbour).

    The leaf slides along -u into the wall line, 0.35 m past the room's corner: towards a
    side where that wall line goes on (a wall of either cell beyond the corner hides it),
    either way if both do."""
    cx, cy = room_centre(a)
    h = ROOM_SIZE / 2
    along_y = b[0] == a[0] + 1  # the shared wall runs along y
    if along_y:
        (x, y), theta = (cx + h, cy), math.pi / 2
        beyond = {s: ((a[0], a[1] + s), (b[0], b[1] + s)) for s in (1, -1)}
    else:
        (x, y), theta = (cx, cy + h), 0.0
        beyond = {s: ((a[0] + s, a[1]), (b[0] + s, b[1])) for s in (1, -1)}
    goes_on = {s: any(c in cells for c in beyond[s]) for s in (1, -1)}
    flip = rng.random() < 0.5  # flip: u = -axis, the leaf slides towards +axis
    if goes_on[1] != goes_on[-1]:
        flip = goes_on[1]
    return DoorSpec(
        a,
        b,
        x,
        y,
        theta + (math.pi if flip else 0.0),
        float(rng.uniform(*LEAF_MASS)),
        float(rng.uniform(0, 1)),
        float(rng.uniform(0, 1)),
    )


def _sample_obstacles(
    rng: np.random.Generator, rooms: list[tuple[int, int]]
) -> list[tuple[float, float, float, float, float]]:
    obstacles = []
    for cell in rooms:
        cx, cy = room_centre(cell)
        corners = rng.permutation(4)[: int(rng.integers(0, 4))]
        for k in corners:
            sx, sy = (1 if k & 1 else -1), (1 if k & 2 else -1)
            obstacles.append(
                (
                    cx + sx * rng.uniform(*OBSTACLE_ZONE),
                    cy + sy * rng.uniform(*OBSTACLE_ZONE),
                    float(rng.uniform(-math.pi, math.pi)),
                    float(rng.uniform(*OBSTACLE_HALF)),
                    float(rng.uniform(*OBSTACLE_HALF)),
                )
            )
    return obstacles


def door_name(k: int) -> str:
    return f"door{k}"


def room_name(cell: tuple[int, int]) -> str:
    return f"room{cell[0]}_{cell[1]}"


def build_xml(plan: FloorPlan, base: BaseConfig, domain_userdata: int) -> str:
    arena = make_arena("doors", domain_userdata=domain_userdata, robot=None)
    wb = arena.worldbody
    wb.find("geom", "table").remove()
    width, depth = plan.rows * ROOM_SIZE, plan.cols * ROOM_SIZE
    floor = wb.find("geom", "floor")
    floor.pos = (width / 2, depth / 2, FLOOR_Z)
    floor.size = (width / 2 + 0.5, depth / 2 + 0.5, 0.1)
    for name in ("overview", "front", "top"):
        wb.find("camera", name).remove()
    wb.find("body", "workspace_focus").remove()
    wb.find("light", "key").pos = (width / 2, depth / 2 - 1.0, 4.0)
    wb.find("light", "key").dir = (0, 0.3, -1)
    span = max(width, depth)
    wb.add("camera", name="top", pos=(width / 2, depth / 2, 1.2 * span + 1.0), fovy=55)
    wb.add(
        "camera",
        name="overview",
        pos=(width / 2, -0.6 * depth - 0.5, 1.0 * span + 0.8),
        xyaxes=(1, 0, 0, 0, 0.8, 0.6),
        fovy=55,
    )
    _add_walls(wb, plan)
    for k, door in enumerate(plan.doors):
        _add_door(arena, k, door)
    for k, (x, y, yaw, hx, hy) in enumerate(plan.obstacles):
        wb.add(
            "geom",
            name=f"obstacle{k}",
            type="box",
            size=(hx, hy, (WALL_TOP - FLOOR_Z) / 2),
            pos=(x, y, (WALL_TOP + FLOOR_Z) / 2),
            quat=(math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)),
            rgba=(0.35, 0.45, 0.6, 1),
            contype=WORLD_CONTYPE,
            conaffinity=WORLD_CONAFFINITY,
        )
    add_mobile_panda(arena, plan.start, base)
    # the base follows the robot in a tracking camera (videos)
    base_body = arena.find("body", "mobile_base")
    base_body.add(
        "camera",
        name="follow",
        pos=(-1.6, -1.6, 1.6),
        mode="trackcom",
        xyaxes=(0.7071, -0.7071, 0, 0.45, 0.45, 0.77),
        fovy=50,
    )
    # a close view of the hand's work in front of the base (turning a handle)
    focus = base_body.add("body", name="closeup_focus", pos=(0.55, 0.0, 0.0))
    base_body.add(
        "camera", name="closeup", pos=(-0.3, -0.9, 0.75), mode="targetbody", target=focus, fovy=60
    )
    return arena.to_xml_string()


def _wall(wb, name: str, centre: tuple[float, float], length: float, along_x: bool) -> None:
    half_h = (WALL_TOP - FLOOR_Z) / 2
    size = (
        (length / 2, WALL_THICKNESS / 2, half_h)
        if along_x
        else (WALL_THICKNESS / 2, length / 2, half_h)
    )
    wb.add(
        "geom",
        name=name,
        type="box",
        size=size,
        pos=(*centre, FLOOR_Z + half_h),
        rgba=WALL_RGBA,
        contype=WORLD_CONTYPE,
        conaffinity=WORLD_CONAFFINITY,
    )


def _add_walls(wb, plan: FloorPlan) -> None:
    width, depth = plan.rows * ROOM_SIZE, plan.cols * ROOM_SIZE
    t = WALL_THICKNESS
    if plan.cells is None:
        _wall(wb, "wall_south", (width / 2, 0.0), width + t, True)
        _wall(wb, "wall_north", (width / 2, depth), width + t, True)
        _wall(wb, "wall_west", (0.0, depth / 2), depth + t, False)
        _wall(wb, "wall_east", (width, depth / 2), depth + t, False)
    else:
        _add_solid_walls(wb, plan)
    seg = (ROOM_SIZE - DOORWAY_WIDTH) / 2
    for k, door in enumerate(plan.doors):
        along_x = abs(math.sin(door.theta)) < 0.5
        for s, sign in enumerate((-1.0, 1.0)):
            off = sign * (DOORWAY_WIDTH / 2 + seg / 2)
            c = (door.x + off, door.y) if along_x else (door.x, door.y + off)
            _wall(wb, f"wall_door{k}_{s}", c, seg, along_x)


def _add_solid_walls(wb, plan: FloorPlan) -> None:
    """A room map's walls without a doorway: every side of a room with no room beyond
    it, and every shared wall the plan has no door in (named ``wall_...``: the base's
    motion planner avoids every geom so named)."""
    cells = set(plan.rooms())
    with_door = {frozenset((d.a, d.b)) for d in plan.doors}
    h, length = ROOM_SIZE / 2, ROOM_SIZE + WALL_THICKNESS
    for i, j in plan.rooms():
        cx, cy = room_centre((i, j))
        for di, dj in NEIGHBOURS:
            other = (i + di, j + dj)
            if other in cells and (other < (i, j) or frozenset(((i, j), other)) in with_door):
                continue  # drawn from the other side, or a doorway's wall
            centre = (cx + di * h, cy + dj * h)
            _wall(wb, f"wall_{i}_{j}_{di}_{dj}", centre, length, along_x=dj != 0)


def _add_door(arena, k: int, door: DoorSpec) -> None:
    """Doorway ``k``: its sliding leaf, latched shut, and the turning handle beside it on
    the wall top (both in the door frame, whose x axis is the wall's direction u)."""
    quat = (math.cos(door.theta / 2), 0, 0, math.sin(door.theta / 2))  # door frame: x = u
    _add_leaf(arena, k, door, quat)
    _add_door_handle(arena.worldbody, k, door, quat)


def _add_leaf(arena, k: int, door: DoorSpec, quat: tuple[float, ...]) -> None:
    """The leaf on a slide joint whose spring pulls it open along -u (into the wall), and
    the joint equality that holds it shut until the environment releases it (the handle
    turned to the door's angle)."""
    half_h = (WALL_TOP - 0.01 - FLOOR_Z) / 2
    leaf = arena.worldbody.add(
        "body", name=f"door{k}_leaf", pos=(door.x, door.y, FLOOR_Z + half_h + 0.005), quat=quat
    )
    leaf.add(
        "joint",
        name=f"door{k}_slide",
        type="slide",
        axis=(-1, 0, 0),
        range=(0.0, LEAF_TRAVEL),
        stiffness=LEAF_SPRING,
        springref=LEAF_TRAVEL * 1.2,
        damping=LEAF_DAMPING,
        armature=LEAF_ARMATURE,
    )
    leaf.add(
        "geom",
        name=f"door{k}_leaf_geom",
        type="box",
        size=(DOORWAY_WIDTH / 2 - 0.005, LEAF_THICKNESS / 2, half_h),
        mass=door.mass,
        rgba=LEAF_RGBA,
        contype=LEAF_CONTYPE,
        conaffinity=LEAF_CONAFFINITY,
    )
    arena.equality.add(
        "joint",
        name=f"door{k}_latch",
        joint1=f"door{k}_slide",
        polycoef=(0, 0, 0, 0, 0),
        active=True,
        solref=(0.01, 1),
    )


def _add_door_handle(wb, k: int, door: DoorSpec, quat: tuple[float, ...]) -> None:
    """A post on the wall top ``KNOB_ALONG`` along u from the doorway's centre, and on it
    the handle: a wing on a hinge whose friction is the door's."""
    u = (math.cos(door.theta), math.sin(door.theta))
    kx, ky = door.x + KNOB_ALONG * u[0], door.y + KNOB_ALONG * u[1]
    post = wb.add("body", name=f"door{k}_post", pos=(kx, ky, WALL_TOP), quat=quat)
    stem_top = KNOB_Z - WING_HALF[2] - WALL_TOP
    post.add(
        "geom",
        name=f"door{k}_stem",
        type="cylinder",
        size=(0.012, stem_top / 2),
        pos=(0, 0, stem_top / 2),
        rgba=(0.3, 0.3, 0.3, 1),
        contype=0,
        conaffinity=0,
    )
    handle = post.add("body", name=f"door{k}_handle", pos=(0, 0, KNOB_Z - WALL_TOP))
    handle.add(
        "joint",
        name=f"door{k}_handle_joint",
        type="hinge",
        axis=(0, 0, 1),
        range=HANDLE_RANGE,
        frictionloss=HANDLE_FRICTION_SCALE * door.friction,
        damping=HANDLE_DAMPING,
        armature=0.002,
    )
    _add_wing(handle, k)


def _add_wing(handle, k: int) -> None:
    """The wing the robot turns, and a red pointer on it that shows its angle."""
    handle.add(
        "geom",
        name=f"door{k}_wing",
        type="box",
        size=WING_HALF,
        mass=0.05,
        rgba=HANDLE_RGBA,
        contype=WORLD_CONTYPE,
        conaffinity=WORLD_CONAFFINITY,
        friction=(1.0, 0.02, 0.001),
        condim=4,
    )
    handle.add(
        "geom",
        name=f"door{k}_pointer",
        type="box",
        size=(0.004, 0.004, 0.002),
        pos=(WING_HALF[0] - 0.006, 0, WING_HALF[2] + 0.002),
        rgba=(0.8, 0.1, 0.1, 1),
        contype=0,
        conaffinity=0,
        mass=0.0,
    )
