"""Cover as an environment: features read from MuJoCo, the allowed-regions grip rule, and
the domain's demonstrator and oracle skills (rules in :mod:`.rules`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.env.environment import Capabilities
from bpns.env.object_counts import ObjectCounts
from bpns.structs import Object, Predicate, State, Task, Type
from mj_envs.base import MujocoEnv, TaskLayout, observe, perturbed, with_objects
from mj_envs.domains.cover import scene
from mj_envs.domains.cover.behaviours import SAFE_Z
from mj_envs.domains.cover.demonstrator import CoverDemonstrator
from mj_envs.domains.cover.rules import (
    BLOCK,
    BLOCK_LIMITS,
    COVERS,
    HAND_EMPTY,
    HOLDING,
    IS_BLOCK,
    IS_TARGET,
    LINE_X,
    N_BLOCKS,
    REGION,
    REGION_X_HALF,
    ROBOT,
    TARGET,
)
from mj_envs.domains.cover.skills import oracle_skills
from mj_envs.oracles.motions import BackOffToStart
from mj_envs.robots.panda import hand_xyz_fingers, pads_touching, panda_ids
from mj_envs.world import World


class CoverEnv(MujocoEnv):
    """Pick blocks and place them so that they cover target pads."""

    name = "cover"
    # The place policy hovered two centimetres above the table where its commands (a
    # descent proportional to the remaining height) faded in a network trained on 100
    # demos; an affine base under it keeps them (docs/METHOD.md). Subgoals are drawn with
    # correlated noise: a place whose block and hand subgoals disagree (independent draws)
    # passed in the nominal model and stalled in a noisy world (docs/WORLDS.md).
    capabilities = Capabilities(
        oracle_skills=oracle_skills,
        learning_defaults={"linear_policy_base": True, "correlated_subgoal_noise": True},
        demo_noise=0.05,
        perturbed=perturbed,
        observe=observe,
        eval_sets={"large": ObjectCounts.of({"block": (3, 4)})},
        object_limits={"block": BLOCK_LIMITS},
        with_objects=with_objects,
        motion_dims=(0, 1, 2),  # hand translation; not the fingers
        back_off=BackOffToStart(SAFE_Z, wait_open=False),  # they open only over regions
    )

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
        n = self.most_objects("block", N_BLOCKS)
        return {"robot": 1, "block": n, "target": n, "region": 2 * n}

    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        return scene.sample_layout(rng, train, self.eval_counts("block", train))

    # -- features -------------------------------------------------------------------
    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        m, d = world.model, world.data
        robot_ids = panda_ids(m, world.cache)
        geom_ids: dict[str, int] = world.cache.setdefault("cover_geoms", {})

        def geom(name: str) -> int:
            g = geom_ids.get(name)
            if g is None:
                g = geom_ids[name] = m.geom(name).id
            return g

        contacts = self.contact_pairs(world)
        table = geom("table")
        out: dict[Object, np.ndarray] = {}
        for obj in objects:
            if obj.type == ROBOT:
                out[obj] = hand_xyz_fingers(d, robot_ids)
            elif obj.type == BLOCK:
                g = geom(f"{obj.name}_geom")
                x, y, z = d.geom_xpos[g]
                grasped = pads_touching(d, robot_ids, {g}) == 2
                out[obj] = np.array(
                    [
                        x,
                        y,
                        z,
                        2 * m.geom_size[g][1],
                        2 * m.geom_size[g][2],
                        float(grasped),
                        float((min(g, table), max(g, table)) in contacts),
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

    def grip_enabled(self, state: State) -> bool:
        """The fingers obey only inside an allowed region (the paper's KD1)."""
        robot = next(o for o in state.objects if o.type == ROBOT)
        x, y = state.get(robot, "x"), state.get(robot, "y")
        if abs(x - LINE_X) > REGION_X_HALF:
            return False
        return any(
            state.get(r, "y_lo") <= y <= state.get(r, "y_hi") for r in state.objects_of_type(REGION)
        )

    # -- the domain's oracles -----------------------------------------------------------
    def demonstrator(self, task: Task, rng: np.random.Generator) -> CoverDemonstrator:
        return CoverDemonstrator(task, rng)
