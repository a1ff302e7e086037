"""Drawer as a bpns environment: the scene and the features read from MuJoCo.

The cabinet is ``mj_envs.parts.articulated``'s drawer: its joint gives the drawer's
opening, its handle bar's position the target of a reach, and MuJoCo's contacts say what
the pads hold and where the cube rests. The demonstrator (``demonstrator.py``) and the
oracle skills (``skills.py``) act on these features only.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.env.environment import Capabilities
from bpns.structs import GroundAtom, Object, Task
from bpns_drawer.demonstrator import DrawerDemonstrator
from bpns_drawer.rules import (
    CABINET_SIZE,
    CABINET_X,
    CABINET_Y,
    CONTACT_PREDICATES,
    CUBE,
    CUBE_CLEARANCE,
    CUBE_MASS,
    CUBE_SIDE,
    CUBE_X,
    CUBE_Y,
    DRAWER,
    DRAWER_CLOSED,
    HANDLE_CLEARANCE,
    HORIZON,
    IN_DRAWER,
    PREDICATES,
    ROBOT,
    TRAVEL,
    WALL,
)
from bpns_drawer.skills import oracle_skills
from mj_envs.base import MujocoEnv, TaskLayout, observe, perturbed
from mj_envs.contacts import Contacts, geom_ids
from mj_envs.parts.articulated import (
    HANDLE_LENGTH,
    HANDLE_RADIUS,
    add_drawer,
    drawer_ids,
    handle_xyz,
    open_fraction,
)
from mj_envs.parts.objects import add_free_box
from mj_envs.robots.panda import FINGERTIP_DROP, hand_xyz_fingers, pads_touching, panda_ids
from mj_envs.scene import make_arena, to_xml
from mj_envs.world import World

CABINET = "cabinet"  # the MJCF name: geoms cabinet_handle, cabinet_drawer_floor, ...


def caught(hand: np.ndarray, bar: np.ndarray) -> bool:
    """Whether the handle bar is held: the fingers closed to its diameter with its axis
    between the pads. (Not the pads' contacts: squeezed with ~1.6 N per pad, the bar
    rattles between them and a snapshot of the contact list misses one pad or both.)"""
    x, y, z, fingers = hand
    return bool(
        fingers <= HANDLE_RADIUS + 0.002
        and abs(x - bar[0]) < fingers
        and abs(z - bar[2]) < FINGERTIP_DROP  # the pads reach 1.2 cm above and below
        and abs(y - bar[1]) < HANDLE_LENGTH / 2
    )


class DrawerEnv(MujocoEnv):
    """Open the drawer, put the cube in, close the drawer."""

    name = "drawer"  # must equal the entry-point name
    types = frozenset({ROBOT, DRAWER, CUBE})
    predicates = PREDICATES
    contact_predicates = CONTACT_PREDICATES
    goal_predicates = frozenset({IN_DRAWER, DRAWER_CLOSED})
    capabilities = Capabilities(oracle_skills=oracle_skills, perturbed=perturbed, observe=observe)

    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        arena = make_arena("drawer")
        cx, cy = rng.uniform(*CABINET_X), rng.uniform(*CABINET_Y)
        add_drawer(arena, CABINET, cx, cy, CABINET_SIZE, TRAVEL, wall_thickness=WALL,
                   handle_clearance=HANDLE_CLEARANCE)  # fmt: skip
        while True:  # the cube beside the cabinet, out of the drawer's way
            x, y = rng.uniform(*CUBE_X), rng.uniform(*CUBE_Y)
            if abs(y - cy) >= CUBE_CLEARANCE:
                break
        add_free_box(arena.worldbody, "cube", (x, y, CUBE_SIDE / 2), (CUBE_SIDE / 2,) * 3,
                     CUBE_MASS, (0.85, 0.25, 0.2, 1))  # fmt: skip
        robot, drawer, cube = Object("robot", ROBOT), Object("drawer", DRAWER), Object("cube", CUBE)
        goal = {GroundAtom(IN_DRAWER, (cube, drawer)), GroundAtom(DRAWER_CLOSED, (drawer,))}
        return TaskLayout(to_xml(arena), (robot, drawer, cube), frozenset(goal), HORIZON)

    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        m, d, cache = world.model, world.data, world.cache
        ids = panda_ids(m, cache)
        if "cabinet" not in cache:  # ids once per compiled scene
            cache["cabinet"] = drawer_ids(m, CABINET)
        cabinet = cache["cabinet"]
        contacts = Contacts.read(d)
        hand, bar = hand_xyz_fingers(d, ids), handle_xyz(d, cabinet)
        cube = set(geom_ids(m, cache, "cube_geom"))
        table, floor = geom_ids(m, cache, "table", f"{CABINET}_drawer_floor")
        out = {}
        for obj in objects:
            if obj.type == ROBOT:
                out[obj] = hand
            elif obj.type == DRAWER:
                out[obj] = np.array([*bar, open_fraction(d, cabinet), caught(hand, bar)])
            else:
                (g,) = cube
                flags = [pads_touching(d, ids, cube) == 2, contacts.touching(cube, table),
                         contacts.touching(cube, floor)]  # fmt: skip
                out[obj] = np.array([*d.geom_xpos[g], *flags], dtype=float)
        return out

    def demonstrator(self, task: Task, rng: np.random.Generator) -> DrawerDemonstrator:
        return DrawerDemonstrator(task, rng)
