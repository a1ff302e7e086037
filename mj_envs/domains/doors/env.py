"""Doors in 3D: a Panda on a mobile base crosses a floor plan of rooms through latched doors.

Rules (final, as simulated):

* **Floor plan.** A full grid of rooms 2 m across (``rows x cols``, each drawn from
  ``grid_sizes``, default {2, 3}: 4-9 rooms; the generator takes sizes up to 5), or, as
  ``doors_paper`` (:class:`DoorsPaperEnv`), the paper's plans: 4-25 connected rooms of a
  5x5 map joined by a random spanning tree of doorways plus each other shared wall with
  probability 0.5, solid walls elsewhere (:class:`~mj_envs.domains.doors.scene.RoomMap`). Walls
  are 10 cm thick box geoms reaching from the floor (z = -0.75) to z = -0.10, below the
  arm's mounting plane (z = 0): only the base's pedestal (radius 22 cm) can hit them. Every
  wall between adjacent rooms has a 0.9 m doorway at its centre. Each room has 0-3 rotated
  box obstacles in its corner zones (their centres 0.64-0.78 m from the room's centre on
  both axes), so the cross-shaped band through the room's centre, where the robot starts
  and every approach lane runs, stays free. Train and eval tasks come from the same
  distribution (as in the paper): start near the centre of a random room (random yaw),
  goal ``InRoom(robot, another random room)``. Horizon 1500 steps, or 350 per door on
  the longest room path of larger grids (on a room map: on the task's shortest room
  path, plus one).
* **Larger plans.** Eval tasks may come from larger plans (``bpns eval --eval-set large``:
  sides 5-6; ``--objects grid=N``, N in 2..6): full grids of those sides, or on a room map
  one of that side holding up to all its cells. Train tasks are unchanged.
* **Doors.** A leaf (a 5 cm board filling the doorway up to the wall top) on a slide joint
  along the wall: a *pocket door* that slides into the wall (the leaf collides with the
  robot but not with the walls; it slides towards the side where the wall line goes on
  inside the map, so the part past the room's corner hides in the next wall). Sliding is
  what a mobile arm can really do from the doorway without a swing arc sweeping the
  base's approach lane. A spring pulls the leaf
  open; a *latch* (a joint equality, ``eq_active``) holds it shut. The latch releases for
  good after a control step that ends with the door's handle within 0.04 rad of the
  door's own angle ``tanh(target_rot) * (sin(mass) + cos(friction) * sqrt(mass))``, where
  ``mass`` is the leaf's mass in kg (U(0.1, 1)), ``friction`` the handle hinge's
  frictionloss / 0.1 N m (U(0, 1)) - both as the scene declares them: a perturbed
  world's ``mass_scale`` makes the leaf heavier to slide, not the angle another - and
  ``target_rot`` ~ U(0, 1) lives in ``userdata`` (saved state). Handles are a wing on a
  vertical hinge on the wall top 0.52 m beside the doorway's centre, starting at -0.25 rad
  (below every opening angle); the fingers grip the wing and the wrist turns it. The spring
  opens a released leaf within about a second.
* **Robot.** The Panda on a holonomic base (:mod:`mj_envs.mobile_panda`). Action
  (8): the base's target offset from its measured pose, (dx, dy) in the world frame
  (<= 8 cm: the servo then moves it <= ~4 cm per 0.05 s step) and dyaw (<= 0.25 rad),
  hand (dx, dy, dz) in the *base* frame (<= 2 cm), a wrist turn about the vertical
  (<= 0.15 rad) and the finger command in [-1, 1]. Robot features: the base's measured
  pose (x, y, yaw), the grip site (world), the hand's yaw (wrist), the finger opening and
  the arm's last joint (twist: the turn the wrist has left before its limit).
* **Predicates.** InRoom(robot, room): the base's centre is in the room's cell.
  InDoorway(robot, door): the base's centre within 0.45 m along and 0.75 m across the
  doorway. InMainRoom(robot, room): in the room and in no doorway. TouchingDoor(robot,
  door): a finger geom touches the door's handle (MuJoCo contact list), the fingers open
  wider than half the wing's width (closed past it they hold nothing). DoorIsOpen(door):
  the leaf slid >= 0.8 m (joint reading). DoorInRoom(door, room) and
  DoorsShareRoom(door, door): static. Contact-related: TouchingDoor, InRoom (paper).
* **Skills.** MoveToDoor (drive to the door's approach pose on a planned path, then put
  the fingers on its handle: TouchingDoor is where the demonstrations' segments end) and
  MoveThroughDoor (straight through the open doorway until InRoom of the far room) are
  *given* (``capabilities.given_skills``, :mod:`bpns.learning.given`), policies on the base motion
  planner (:mod:`mj_envs.domains.doors.motion`, a seeded RRT-Connect among walls, obstacles and
  closed leaves). OpenDoor (grip, turn to the angle, wait, let go) is learned. Operators
  are learned for all four (:mod:`mj_envs.domains.doors.skills` has the oracle's).
* **Not modelled.** The arm is never checked against walls (they stay below it); the
  planner's disc is the pedestal plus 4 cm; the leaf's part past the room's corner is
  hidden in the walls, except on an outer wall of a map one room wide.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bpns.env.environment import Capabilities
from bpns.env.object_counts import ObjectCounts
from bpns.structs import GroundAtom, Object, Predicate, Task, Type
from ik import ControllerConfig
from mj_envs.base import MujocoEnv, TaskLayout, observe, perturbed, with_objects
from mj_envs.domains.doors.demonstrator import DoorsDemonstrator
from mj_envs.domains.doors.rules import (
    DOOR,
    DOOR_IN_ROOM,
    DOOR_IS_OPEN,
    DOORS_SHARE_ROOM,
    HANDLE_FRICTION_SCALE,
    HANDLE_REST,
    HANDLE_TOLERANCE,
    HORIZON,
    IN_DOORWAY,
    IN_MAIN_ROOM,
    IN_ROOM,
    ROBOT,
    ROOM,
    TOUCH_MIN_OPENING,
    TOUCHING_DOOR,
    required_angle,
)
from mj_envs.domains.doors.scene import (
    FloorPlan,
    RoomMap,
    build_xml,
    door_name,
    room_centre,
    room_name,
    sample_plan,
    sample_room_map,
)
from mj_envs.domains.doors.skills import given_skills, oracle_skills
from mj_envs.robots.mobile_panda import BaseConfig, BaseIds, base_pose, command_base
from mj_envs.robots.panda import PANDA
from mj_envs.world import DOMAIN_USERDATA_START, World

MAX_GRID = 5
STEPS_PER_DOOR = 350
# ``--objects grid=N``: eval floor plans N rooms on a side (full grids, or room maps of
# that size); the ``large`` set has 5x5 and 6x6 plans.
GRID_LIMITS = (2, 6)


class DoorsEnv(MujocoEnv):
    """Reach a target room through latched sliding doors (paper App. A, Doors)."""

    name = "doors"
    # MoveToDoor and MoveThroughDoor are given: motion-planned skills learning keeps.
    # Videos follow the base: it travels rooms away, and the overview shows it tiny.
    capabilities = Capabilities(
        oracle_skills=oracle_skills,
        given_skills=given_skills,
        default_camera="follow",
        demo_noise=0.05,
        perturbed=perturbed,
        observe=observe,
        eval_sets={"large": ObjectCounts.of({"grid": (5, 6)})},
        object_limits={"grid": GRID_LIMITS},
        with_objects=with_objects,
        motion_dims=(0, 1, 2, 3, 4, 5, 6),  # base, hand, wrist turn; not the fingers
    )
    base_config = BaseConfig()
    controller_config = ControllerConfig(
        workspace_low=(0.2, -0.5, -0.06),
        workspace_high=(0.8, 0.5, 0.45),
    )

    def __init__(
        self, grid_sizes: tuple[int, ...] = (2, 3), room_map: RoomMap | None = None
    ) -> None:
        """Full ``rows x cols`` grids with sizes from ``grid_sizes``, or, given a
        ``room_map``, the paper's floor plans (:class:`~mj_envs.domains.doors.scene.RoomMap`;
        ``grid_sizes`` is then unused)."""
        if not grid_sizes or min(grid_sizes) < 1 or max(grid_sizes) > MAX_GRID:
            raise ValueError(f"grid sizes must lie in 1..{MAX_GRID}, got {grid_sizes}")
        if max(grid_sizes) < 2 and len(grid_sizes) == 1:
            raise ValueError("a 1x1 floor plan has no door")
        self.grid_sizes = tuple(int(s) for s in grid_sizes)
        self.room_map = room_map

    # -- declarations ------------------------------------------------------------------
    @property
    def types(self) -> frozenset[Type]:
        return frozenset({ROBOT, DOOR, ROOM})

    @property
    def predicates(self) -> frozenset[Predicate]:
        return frozenset(
            {
                IN_ROOM,
                IN_DOORWAY,
                IN_MAIN_ROOM,
                TOUCHING_DOOR,
                DOOR_IS_OPEN,
                DOOR_IN_ROOM,
                DOORS_SHARE_ROOM,
            }
        )

    @property
    def contact_predicates(self) -> frozenset[Predicate]:
        return frozenset({TOUCHING_DOOR, IN_ROOM})

    @property
    def goal_predicates(self) -> frozenset[Predicate]:
        return frozenset({IN_ROOM})

    @property
    def action_low(self) -> np.ndarray:
        b, c = self.base_config, self.controller_config
        m = c.max_translation
        return np.array(
            [-b.max_offset, -b.max_offset, -b.max_yaw_offset, -m, -m, -m, -c.max_rotation, -1.0]
        )

    @property
    def action_high(self) -> np.ndarray:
        return -self.action_low

    @property
    def max_objects(self) -> dict[str, int]:
        if self.room_map is not None:
            spec = self.room_map
            side = self.most_objects("grid", spec.size)
            rooms = spec.rooms[1] if side == spec.size else side * side
            return {"robot": 1, "door": max(spec.max_doors, 2 * side * (side - 1)), "room": rooms}
        n = self.most_objects("grid", max(self.grid_sizes))
        return {"robot": 1, "door": 2 * n * (n - 1), "room": n * n}

    # -- tasks ------------------------------------------------------------------------
    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        if self.room_map is None:
            plan = self._grid_plan(rng, self.eval_counts("grid", train))
            # the longest room path crosses rows + cols - 2 doors
            doors_on_path = plan.rows + plan.cols - 2
        else:
            plan = sample_room_map(rng, self._room_map(rng, self.eval_counts("grid", train)))
            doors_on_path = plan.doors_between(plan.start_room, plan.goal_room) + 1
        n = len(plan.doors)
        xml = build_xml(plan, self.base_config, n)
        robot = Object("robot", ROBOT)
        rooms = [Object(room_name(c), ROOM) for c in plan.rooms()]
        doors = [Object(door_name(k), DOOR) for k in range(n)]
        goal = frozenset({GroundAtom(IN_ROOM, (robot, Object(room_name(plan.goal_room), ROOM)))})
        return TaskLayout(
            xml=xml,
            objects=(robot, *doors, *rooms),
            goal=goal,
            horizon=max(HORIZON, STEPS_PER_DOOR * doors_on_path),
            init_qpos={f"door{k}_handle_joint": np.array([HANDLE_REST]) for k in range(n)},
            init_userdata={
                DOMAIN_USERDATA_START + k: d.target_rot for k, d in enumerate(plan.doors)
            },
        )

    def _grid_plan(self, rng: np.random.Generator, grid: tuple[int, int] | None) -> FloorPlan:
        """A full grid; sides from ``grid`` (eval counts), else from ``grid_sizes``."""
        sizes = self.grid_sizes if grid is None else tuple(range(grid[0], grid[1] + 1))
        return sample_plan(rng, sizes)

    def _room_map(self, rng: np.random.Generator, grid: tuple[int, int] | None) -> RoomMap:
        """The room map tasks are drawn on: this environment's own, or (eval counts) one
        ``grid`` cells on a side holding up to all of them; a single side draws nothing,
        so that the own side draws the own tasks."""
        spec = self.room_map
        assert spec is not None
        if grid is None:
            return spec
        side = grid[0] if grid[0] == grid[1] else int(rng.integers(grid[0], grid[1] + 1))
        if side == spec.size:
            return spec
        rooms = (min(spec.rooms[0], side * side), side * side)
        return RoomMap(size=side, rooms=rooms, door_fraction=spec.door_fraction)

    # -- the action: the base is commanded before the arm ----------------------------
    def before_control(self, action: np.ndarray, world: World) -> None:
        command_base(self._ids(world)["base"], world.data, action[0:3], self.base_config)

    def command(self, action: np.ndarray, world: World):
        """Hand translation (base frame) and a wrist turn about the vertical, fingers."""
        return action[3:6], np.array([0.0, 0.0, float(action[6])]), float(action[7])

    def after_step(self, world: World) -> None:
        """Release a latch whose handle ends the step within tolerance of its angle."""
        ids = self._ids(world)
        d = world.data
        for k, eq in enumerate(ids["latch"]):
            if (
                d.eq_active[eq]
                and abs(d.qpos[ids["handle_q"][k]] - self._required(world, k)) <= HANDLE_TOLERANCE
            ):
                d.eq_active[eq] = 0

    def _required(self, world: World, k: int) -> float:
        ids = self._ids(world)
        return required_angle(
            ids["mass"][k],
            ids["friction"][k],
            float(world.data.userdata[DOMAIN_USERDATA_START + k]),
        )

    # -- features ----------------------------------------------------------------------
    def _ids(self, world: World) -> dict:
        ids = world.cache.get("doors")
        if ids is None:
            m = world.model
            n = sum(1 for i in range(m.neq) if m.equality(i).name.endswith("_latch"))
            leaf_bodies = [m.body(f"door{k}_leaf").id for k in range(n)]
            fingers = {m.body(PANDA.scene_name(b)).id for b in ("left_finger", "right_finger")}
            ids = {
                "base": BaseIds.of(m),
                "site": m.site(PANDA.scene_name(PANDA.grip_site)).id,
                "finger_q": m.joint(PANDA.scene_name(PANDA.finger_joint)).qposadr[0],
                "twist_q": m.joint(PANDA.scene_name("joint7")).qposadr[0],
                "finger_geoms": frozenset(g for g in range(m.ngeom) if m.geom_bodyid[g] in fingers),
                "latch": [m.equality(f"door{k}_latch").id for k in range(n)],
                "handle_q": [m.joint(f"door{k}_handle_joint").qposadr[0] for k in range(n)],
                "leaf_q": [m.joint(f"door{k}_slide").qposadr[0] for k in range(n)],
                "wing": [m.geom(f"door{k}_wing").id for k in range(n)],
                # the leaf's mass as the task declares it: a heavier world makes the
                # leaf slower to slide, not the latch's angle another one
                "mass": [float(world.declared_body_mass[b]) for b in leaf_bodies],
                "friction": [
                    float(m.dof_frictionloss[m.joint(f"door{k}_handle_joint").dofadr[0]])
                    / HANDLE_FRICTION_SCALE
                    for k in range(n)
                ],
                "door_pose": [
                    (
                        float(m.body_pos[b][0]),
                        float(m.body_pos[b][1]),
                        2.0 * math.atan2(m.body_quat[b][3], m.body_quat[b][0]),
                    )
                    for b in leaf_bodies
                ],
            }
            world.cache["doors"] = ids
        return ids

    def touched_doors(self, world: World) -> set[int]:
        """Doors whose handle wing is in contact with a finger geom while the fingers are
        open wider than :data:`TOUCH_MIN_OPENING`: fingers closed past the wing's
        half-width hold nothing between them, and their touch from the side or from
        below (a grip the wing slipped out of) is no TouchingDoor a turn could start
        from."""
        ids = self._ids(world)
        d = world.data
        if d.qpos[ids["finger_q"]] <= TOUCH_MIN_OPENING:
            return set()
        wings = {g: k for k, g in enumerate(ids["wing"])}
        fingers = ids["finger_geoms"]
        out: set[int] = set()
        for c in range(d.ncon):
            if d.contact.dist[c] > 0.0:
                continue
            a, b = int(d.contact.geom[c][0]), int(d.contact.geom[c][1])
            if a in wings and b in fingers:
                out.add(wings[a])
            elif b in wings and a in fingers:
                out.add(wings[b])
        return out

    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        d = world.data
        ids = self._ids(world)
        touched = self.touched_doors(world)
        out: dict[Object, np.ndarray] = {}
        for obj in objects:
            if obj.type == ROBOT:
                x, y, yaw = base_pose(ids["base"], d)
                hand = d.site_xpos[ids["site"]]
                xmat = d.site_xmat[ids["site"]]
                wrist = math.atan2(xmat[3], xmat[0])  # world yaw of the hand's x axis
                out[obj] = np.array(
                    [x, y, yaw, *hand, wrist, d.qpos[ids["finger_q"]], d.qpos[ids["twist_q"]]]
                )
            elif obj.type == DOOR:
                k = int(obj.name[len("door") :])
                dx, dy, theta = ids["door_pose"][k]
                knob = d.geom_xpos[ids["wing"][k]]
                out[obj] = np.array(
                    [
                        dx,
                        dy,
                        theta,
                        ids["mass"][k],
                        ids["friction"][k],
                        d.qpos[ids["handle_q"][k]],
                        d.userdata[DOMAIN_USERDATA_START + k],
                        d.qpos[ids["leaf_q"][k]],
                        *knob,
                        float(k in touched),
                    ]
                )
            elif obj.type == ROOM:
                i, j = (int(v) for v in obj.name[len("room") :].split("_"))
                out[obj] = np.array(room_centre((i, j)))
            else:
                raise KeyError(f"doors has no object type {obj.type.name!r}")
        return out

    def decorate(self, world: World) -> None:
        """Handles turn green once their latch released (looks only)."""
        ids = self._ids(world)
        m, d = world.model, world.data
        for g, eq in zip(ids["wing"], ids["latch"], strict=True):
            m.geom_rgba[g] = (0.85, 0.7, 0.15, 1) if d.eq_active[eq] else (0.2, 0.8, 0.3, 1)

    # -- the domain's oracles ----------------------------------------------------------
    def demonstrator(self, task: Task, rng: np.random.Generator) -> DoorsDemonstrator:
        return DoorsDemonstrator(task)


class DoorsPaperEnv(DoorsEnv):
    """Doors on the paper's floor plans (App. A: "4-25 rooms with random connectivity"):
    4-25 connected rooms of a 5x5 map, a spanning tree of doorways plus each other shared
    wall with probability 0.5. Train and eval tasks come from this one distribution, as
    in the paper."""

    name = "doors_paper"

    def __init__(self, room_map: RoomMap | None = None) -> None:
        super().__init__(room_map=RoomMap() if room_map is None else room_map)
