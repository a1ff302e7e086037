"""Stick Button as an environment: features read from MuJoCo (button travel, stick tip,
pad contacts), the buttons' latches, and the domain's demonstrator and oracle skills
(rules in :mod:`.rules`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.env.environment import Capabilities
from bpns.env.object_counts import ObjectCounts
from bpns.structs import Object, Predicate, Task, Type
from mj_envs.base import MujocoEnv, TaskLayout, observe, perturbed, with_objects
from mj_envs.domains.stick_button import scene
from mj_envs.domains.stick_button.behaviours import SAFE_Z, stick_in_hand
from mj_envs.domains.stick_button.demonstrator import StickButtonDemonstrator
from mj_envs.domains.stick_button.rules import (
    ABOVE_NO_BUTTON,
    BUTTON,
    BUTTON_LIMITS,
    CONTROLLER,
    EVAL_BUTTONS,
    GRASPED,
    HAND_EMPTY,
    HOLDER,
    PRESSED,
    ROBOT,
    ROBOT_ABOVE_BUTTON,
    STICK,
    STICK_ABOVE_BUTTON,
    STICK_HEIGHT,
    STICK_LENGTH,
    TIP_INSET,
)
from mj_envs.domains.stick_button.skills import oracle_skills
from mj_envs.oracles.motions import BackOffToStart
from mj_envs.parts import button as push_button
from mj_envs.robots.panda import hand_xyz_fingers, pads_touching, panda_ids
from mj_envs.world import World


class StickButtonEnv(MujocoEnv):
    """Press all buttons; those beyond the arm's reach with the tip of a held stick."""

    name = "stick_button"
    # Paper appendix B: many abstract plans are not refinable here (whether a button is
    # within reach is not in the predicates), so the planner may try up to 1000.
    # Demonstrations with signal-dependent DART noise (docs/METHOD.md, "Learning from few
    # demonstrations"): without it the cloned stick press kept rising wherever it had
    # overshot the demonstrations' travel height. No near-goal policy features any more:
    # with DART they no longer help nominally, and their 1 cm tanh is a steep gain near
    # every subgoal that two steps of latency turn into oscillation (docs/WORLDS.md).
    capabilities = Capabilities(
        planning_defaults={"n_abstract": 1000},
        oracle_skills=oracle_skills,
        demo_noise=0.05,
        perturbed=perturbed,
        observe=observe,
        eval_sets={"large": ObjectCounts.of({"button": (5, 8)})},
        object_limits={"button": BUTTON_LIMITS},
        with_objects=with_objects,
        motion_dims=(0, 1, 2),  # hand translation; not the fingers
        # up, keeping the stick if it is still held; else open, up, back to the start pose
        back_off=BackOffToStart(SAFE_Z, keep_held="stick", holds=stick_in_hand),
    )
    controller_config = CONTROLLER

    @property
    def types(self) -> frozenset[Type]:
        return frozenset({ROBOT, BUTTON, STICK, HOLDER})

    @property
    def predicates(self) -> frozenset[Predicate]:
        return frozenset(
            {
                PRESSED,
                ROBOT_ABOVE_BUTTON,
                STICK_ABOVE_BUTTON,
                ABOVE_NO_BUTTON,
                GRASPED,
                HAND_EMPTY,
            }
        )

    @property
    def contact_predicates(self) -> frozenset[Predicate]:
        return frozenset({GRASPED, PRESSED})

    @property
    def goal_predicates(self) -> frozenset[Predicate]:
        return frozenset({PRESSED})

    @property
    def max_objects(self) -> dict[str, int]:
        n = self.most_objects("button", EVAL_BUTTONS[1])
        return {"robot": 1, "button": n, "stick": 1, "holder": 1}

    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        return scene.sample_layout(rng, train, self.eval_counts("button", train))

    # -- physics beyond MuJoCo's: the latch --------------------------------------------
    def after_step(self, world: World) -> None:
        """Engage a button's latch (its equality constraint) once it travelled far enough."""
        for ids in self._ids(world)["buttons"].values():
            push_button.engage_latch(world.data, ids)

    def decorate(self, world: World) -> None:
        for ids in self._ids(world)["buttons"].values():
            push_button.draw_cap(world.model, world.data, ids)

    # -- features -------------------------------------------------------------------
    def _ids(self, world: World) -> dict:
        ids = world.cache.get("stick_button")
        if ids is None:
            m = world.model
            caps = sorted(m.body(i).name for i in range(m.nbody) if m.body(i).name.endswith("_cap"))
            names = [c[: -len("_cap")] for c in caps]
            ids = {
                "stick": m.geom("stick_geom").id,
                "holder": m.body("holder").id,
                "buttons": {name: push_button.button_ids(m, name) for name in names},
            }
            world.cache["stick_button"] = ids
        return ids

    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        d = world.data
        ids = self._ids(world)
        robot_ids = panda_ids(world.model, world.cache)
        out: dict[Object, np.ndarray] = {}
        for obj in objects:
            if obj.type == ROBOT:
                out[obj] = hand_xyz_fingers(d, robot_ids)
            elif obj.type == BUTTON:
                b = ids["buttons"][obj.name]
                x, y, z = d.geom_xpos[b.cap_geom]
                pressed = float(push_button.is_pressed(d, b))
                out[obj] = np.array([x, y, z + push_button.CAP_HALF_HEIGHT, pressed])
            elif obj.type == STICK:
                g = ids["stick"]
                centre = d.geom_xpos[g]
                rot = d.geom_xmat[g].reshape(3, 3)
                tip = centre + rot @ np.array(
                    [STICK_LENGTH / 2 - TIP_INSET, 0.0, -STICK_HEIGHT / 2]
                )
                grasped = pads_touching(d, robot_ids, {g}) == 2
                out[obj] = np.array([*centre, *tip, float(grasped)])
            elif obj.type == HOLDER:
                x, y, _ = d.xpos[ids["holder"]]
                out[obj] = np.array([x, y])
            else:
                raise KeyError(f"stick_button has no object type {obj.type.name!r}")
        return out

    # -- the domain's oracles -----------------------------------------------------------
    def demonstrator(self, task: Task, rng: np.random.Generator) -> StickButtonDemonstrator:
        return StickButtonDemonstrator(task, rng)
