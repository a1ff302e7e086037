"""Cover in 3D: put blocks over target pads on a line across the table (paper App. A.1).

Rules (final, as simulated):

* Two blocks (free bodies, 4.5 cm deep along x, 4 cm tall, 6-10 cm wide along y, 0.1 kg)
  and two flat target pads (3-5 cm wide, decoration only) lie on the line x = 0.5 m,
  y in [-0.3, 0.3]. The Panda's fingers close along x, so a block can be gripped anywhere
  along its width: the grasp offset is a continuous choice.
* Allowed regions (yellow strips) are the blocks' initial spans and +-1 cm around each
  target's centre. The finger command is *ignored* unless the gripper centre is inside a
  region (within 5 cm of the line in x). So a block can only be released over a target
  with the hand within 1 cm of the target's centre, and the grasp offset chosen at pick
  time decides whether the released block can cover the target (the paper's KD1).
* Covers(block, target): the block rests on the table (contact with the table), is not
  held, is within 1.5 cm of the line and its y-extent contains the target's.
  Holding(block): both finger pads touch the block (MuJoCo contact list).
  HandEmpty(robot): no block is held. IsBlock, IsTarget: type tests.
  Contact-related: Covers, HandEmpty, Holding.
* Action (dx, dy, dz, grip): end-effector translation in metres per 0.05 s step
  (|d| <= 2 cm) and a finger command in [-1, 1] (+1 opens, -1 closes at 0.1 m/s).
* Train and eval tasks come from the same distribution (different seeds); goals hold one
  or two Covers atoms. Horizon 500 steps.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.structs import GroundAtom, Object, Predicate, State, Type
from mj_envs.base import MujocoEnv, TaskLayout
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE, make_arena, to_xml
from mj_envs.world import ROBOT_PREFIX, World

LINE_X = 0.5
Y_RANGE = (-0.30, 0.30)
BLOCK_DEPTH, BLOCK_HEIGHT, BLOCK_MASS = 0.045, 0.04, 0.1
BLOCK_WIDTH_RANGE = (0.06, 0.10)
TARGET_WIDTH_RANGE = (0.03, 0.05)
TARGET_REGION_HALF = 0.01
REGION_X_HALF = 0.05
COVER_X_TOL = 0.015
HORIZON = 500
N_BLOCKS = N_TARGETS = 2

ROBOT = Type("robot", ("x", "y", "z", "fingers"))
BLOCK = Type("block", ("x", "y", "z", "width", "height", "grasped", "on_table"))
TARGET = Type("target", ("x", "y", "width"))
REGION = Type("region", ("y_lo", "y_hi"))


def _holding(state: State, objs: Sequence[Object]) -> bool:
    return state.get(objs[0], "grasped") > 0.5


def _hand_empty(state: State, objs: Sequence[Object]) -> bool:
    return not any(state.get(b, "grasped") > 0.5 for b in state.objects_of_type(BLOCK))


def _covers(state: State, objs: Sequence[Object]) -> bool:
    block, target = objs
    b, t = state.data[block], state.data[target]
    bx, by, _, bw, _, grasped, on_table = b
    tx, ty, tw = t
    return (
        grasped < 0.5
        and on_table > 0.5
        and abs(bx - tx) <= COVER_X_TOL
        and by - bw / 2 <= ty - tw / 2
        and ty + tw / 2 <= by + bw / 2
    )


HOLDING = Predicate("Holding", (BLOCK,), _holding)
HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
COVERS = Predicate("Covers", (BLOCK, TARGET), _covers)


def _always(state: State, objs: Sequence[Object]) -> bool:
    """Type predicates hold for every object of their type."""
    return True


IS_BLOCK = Predicate("IsBlock", (BLOCK,), _always)
IS_TARGET = Predicate("IsTarget", (TARGET,), _always)


class CoverEnv(MujocoEnv):
    """Pick blocks and place them so that they cover target pads."""

    name = "cover"

    @property
    def types(self) -> frozenset[Type]:
        return frozenset({ROBOT, BLOCK, TARGET, REGION})

    @property
    def predicates(self) -> frozenset[Predicate]:
        return frozenset({HOLDING, HAND_EMPTY, COVERS, IS_BLOCK, IS_TARGET})

    @property
    def contact_predicates(self) -> frozenset[Predicate]:
        return frozenset({COVERS, HAND_EMPTY, HOLDING})

    @property
    def goal_predicates(self) -> frozenset[Predicate]:
        return frozenset({COVERS})

    @property
    def max_objects(self) -> dict[str, int]:
        return {"robot": 1, "block": N_BLOCKS, "target": N_TARGETS, "region": N_BLOCKS + N_TARGETS}

    # -- tasks ----------------------------------------------------------------------
    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        widths = rng.uniform(*BLOCK_WIDTH_RANGE, size=N_BLOCKS)
        twidths = rng.uniform(*TARGET_WIDTH_RANGE, size=N_TARGETS)
        # Spans that must not overlap: each block, and each target's landing zone.
        landing = BLOCK_WIDTH_RANGE[1] / 2 + 0.01
        halves = [w / 2 for w in widths] + [landing] * N_TARGETS
        centres = _sample_disjoint(rng, halves, Y_RANGE, gap=0.015)
        bys, tys = centres[:N_BLOCKS], centres[N_BLOCKS:]

        arena = make_arena("cover", nuserdata=7)
        wb = arena.worldbody
        region_spans = [(by - w / 2, by + w / 2) for by, w in zip(bys, widths, strict=True)]
        region_spans += [(ty - TARGET_REGION_HALF, ty + TARGET_REGION_HALF) for ty in tys]
        for i, (lo, hi) in enumerate(region_spans):
            wb.add(
                "geom",
                name=f"region{i}",
                type="box",
                contype=0,
                conaffinity=0,
                size=(REGION_X_HALF, (hi - lo) / 2, 0.0004),
                pos=(LINE_X, (lo + hi) / 2, 0.0004),
                rgba=(0.95, 0.85, 0.2, 0.45),
            )
        for i, (ty, tw) in enumerate(zip(tys, twidths, strict=True)):
            wb.add(
                "geom",
                name=f"target{i}",
                type="box",
                contype=0,
                conaffinity=0,
                size=(0.03, tw / 2, 0.0008),
                pos=(LINE_X, ty, 0.0008),
                rgba=(0.2, 0.75, 0.3, 1),
            )
        colours = [(0.85, 0.25, 0.2, 1), (0.2, 0.4, 0.85, 1)]
        for i, (by, w) in enumerate(zip(bys, widths, strict=True)):
            body = wb.add("body", name=f"block{i}", pos=(LINE_X, by, BLOCK_HEIGHT / 2))
            body.add("freejoint", name=f"block{i}_joint")
            body.add(
                "geom",
                name=f"block{i}_geom",
                type="box",
                size=(BLOCK_DEPTH / 2, w / 2, BLOCK_HEIGHT / 2),
                mass=BLOCK_MASS,
                rgba=colours[i % 2],
                contype=OBJECT_CONTYPE,
                conaffinity=OBJECT_CONAFFINITY,
                friction=(1.0, 0.02, 0.001),
                condim=4,
            )

        robot = Object("robot", ROBOT)
        blocks = [Object(f"block{i}", BLOCK) for i in range(N_BLOCKS)]
        targets = [Object(f"target{i}", TARGET) for i in range(N_TARGETS)]
        regions = [Object(f"region{i}", REGION) for i in range(len(region_spans))]
        n_goal = int(rng.integers(1, N_BLOCKS + 1))
        perm = rng.permutation(N_TARGETS)
        chosen = rng.choice(N_BLOCKS, size=n_goal, replace=False)
        goal = frozenset(GroundAtom(COVERS, (blocks[b], targets[perm[b]])) for b in chosen)
        return TaskLayout(
            xml=to_xml(arena),
            objects=(robot, *blocks, *targets, *regions),
            goal=goal,
            horizon=HORIZON,
        )

    # -- features -------------------------------------------------------------------
    def _ids(self, world: World) -> dict:
        ids = world.cache.get("cover")
        if ids is None:
            m = world.model
            ids = {
                "site": m.site(ROBOT_PREFIX + "grip_site").id,
                "finger": m.joint(ROBOT_PREFIX + "finger_joint1").qposadr[0],
                "left_pad": m.geom(ROBOT_PREFIX + "left_pad").id,
                "right_pad": m.geom(ROBOT_PREFIX + "right_pad").id,
                "table": m.geom("table").id,
            }
            world.cache["cover"] = ids
        return ids

    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        m, d = world.model, world.data
        ids = self._ids(world)
        contacts = self.contact_pairs(world)

        def touching(g1: int, g2: int) -> bool:
            return (min(g1, g2), max(g1, g2)) in contacts

        geom_ids: dict[str, int] = ids.setdefault("geoms", {})

        def geom(name: str) -> int:
            g = geom_ids.get(name)
            if g is None:
                g = geom_ids[name] = m.geom(name).id
            return g

        out: dict[Object, np.ndarray] = {}
        for obj in objects:
            if obj.type == ROBOT:
                x, y, z = d.site_xpos[ids["site"]]
                out[obj] = np.array([x, y, z, d.qpos[ids["finger"]]])
            elif obj.type == BLOCK:
                g = geom(f"{obj.name}_geom")
                x, y, z = d.geom_xpos[g]
                grasped = touching(g, ids["left_pad"]) and touching(g, ids["right_pad"])
                out[obj] = np.array(
                    [
                        x,
                        y,
                        z,
                        2 * m.geom_size[g][1],
                        2 * m.geom_size[g][2],
                        float(grasped),
                        float(touching(g, ids["table"])),
                    ]
                )
            elif obj.type == TARGET:
                g = geom(obj.name)
                out[obj] = np.array([d.geom_xpos[g][0], d.geom_xpos[g][1], 2 * m.geom_size[g][1]])
            elif obj.type == REGION:
                g = geom(obj.name)
                y, half = d.geom_xpos[g][1], m.geom_size[g][1]
                out[obj] = np.array([y - half, y + half])
            else:
                raise KeyError(f"cover has no object type {obj.type.name!r}")
        return out

    def demonstrator(self, task, rng):
        from mj_envs.cover_oracle import CoverDemonstrator

        return CoverDemonstrator(task, rng)

    def oracle_skills(self):
        from mj_envs.cover_skills import oracle_skills

        return oracle_skills()

    def grip_enabled(self, state: State) -> bool:
        robot = next(o for o in state.objects if o.type == ROBOT)
        x, y = state.get(robot, "x"), state.get(robot, "y")
        if abs(x - LINE_X) > REGION_X_HALF:
            return False
        return any(
            state.get(r, "y_lo") <= y <= state.get(r, "y_hi") for r in state.objects_of_type(REGION)
        )


def _sample_disjoint(
    rng: np.random.Generator, halves: Sequence[float], span: tuple[float, float], gap: float
) -> list[float]:
    """Centres for intervals of the given half-widths, pairwise disjoint with ``gap``."""
    for _ in range(10_000):
        centres = [rng.uniform(span[0] + h, span[1] - h) for h in halves]
        if all(
            abs(centres[i] - centres[j]) >= halves[i] + halves[j] + gap
            for i in range(len(halves))
            for j in range(i + 1, len(halves))
        ):
            return centres
    raise RuntimeError("could not place the objects without overlap; widen the span")
