"""Stack as a bpns environment: scene, features from contacts, demonstrator, oracle skills.

Everything generic comes from mj_envs: the arena and free boxes (``parts``), the robot's
features and grasp test (``robots``), contact relations (``contacts``) and the pick and
place motion laws (``oracles.motions``). What is left is this task's own choices.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.env.environment import Capabilities
from bpns.structs import (
    GroundAtom,
    LiftedAtom,
    Object,
    Skill,
    State,
    STRIPSOperator,
    Task,
    Variable,
)
from bpns_stack.rules import (
    BLOCK,
    CLEAR,
    HAND_EMPTY,
    HOLDING,
    HORIZON,
    MASS,
    MIN_DISTANCE,
    N_BLOCKS,
    NAMES,
    ON,
    ON_TABLE,
    PREDICATES,
    ROBOT,
    SIDE,
    X_RANGE,
    Y_RANGE,
)
from mj_envs.base import MujocoEnv, TaskLayout, observe, perturbed
from mj_envs.contacts import Contacts, body_geoms, geom_ids, relation_features
from mj_envs.oracles.motions import Funnel, grasp_action, open_first, release_action
from mj_envs.oracles.phases import DemonstrationFailed
from mj_envs.parts.objects import add_free_box, sample_separated_points
from mj_envs.robots.panda import hand_xyz_fingers, pads_touching, panda_ids
from mj_envs.scene import make_arena, to_xml
from mj_envs.world import World

COLOURS = [(0.85, 0.25, 0.2, 1), (0.2, 0.45, 0.85, 1), (0.95, 0.75, 0.15, 1)]
FUNNEL = Funnel(safe_z=0.16)  # travel above a two-cube tower (9 cm) with a cube in hand
GRASP_ABOVE_CENTRE = 0.006  # keeps the fingertips off whatever the cube stands on
MAX_ATOM_STEPS = 300


def oracle_skills() -> list[Skill]:
    """Hand-written Pick and Stack: what ``--approach oracle`` plans with."""
    return [
        Skill(PICK, PickPolicy(), PickSampler()),
        Skill(STACK, StackPolicy(), StackSampler()),
    ]


class StackEnv(MujocoEnv):
    """Stack cubes into the goal tower."""

    name = "stack"  # must equal the entry-point name
    types = frozenset({ROBOT, BLOCK})
    predicates = PREDICATES
    contact_predicates = PREDICATES
    goal_predicates = frozenset({ON})
    # what it offers beyond the required members: its hand-written skills (oracle_skills
    # above, a module-level function; their operators and policies below) and MuJoCo's
    # perturbed physics (`bpns eval --perturb`)
    capabilities = Capabilities(oracle_skills=oracle_skills, perturbed=perturbed, observe=observe)

    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        arena = make_arena("stack")
        points = sample_separated_points(rng, N_BLOCKS, X_RANGE, Y_RANGE, MIN_DISTANCE)
        for name, (x, y), rgba in zip(NAMES, points, COLOURS, strict=True):
            add_free_box(arena.worldbody, name, (x, y, SIDE / 2), (SIDE / 2,) * 3, MASS, rgba)
        blocks = [Object(n, BLOCK) for n in NAMES]
        order = rng.permutation(N_BLOCKS)  # tower top first
        height = int(rng.integers(2, N_BLOCKS + 1))
        goal = frozenset(
            GroundAtom(ON, (blocks[order[k]], blocks[order[k + 1]])) for k in range(height - 1)
        )
        objects = (Object("robot", ROBOT), *blocks)
        return TaskLayout(xml=to_xml(arena), objects=objects, goal=goal, horizon=HORIZON)

    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        m, d = world.model, world.data
        ids = panda_ids(m, world.cache)
        contacts = Contacts.read(d)  # once per state
        (table,) = geom_ids(m, world.cache, "table")
        geoms = [body_geoms(m, world.cache, n) for n in NAMES]
        out = {}
        for obj in objects:
            if obj.type == ROBOT:
                out[obj] = hand_xyz_fingers(d, ids)
                continue
            own = geoms[NAMES.index(obj.name)]
            (g,) = own
            held = pads_touching(d, ids, own) == 2
            flags = [float(held), float(contacts.touching(own, table))]
            touching = relation_features(contacts, own, geoms)
            out[obj] = np.concatenate([d.geom_xpos[g], flags, touching])
        return out

    def demonstrator(self, task: Task, rng: np.random.Generator) -> StackDemonstrator:
        return StackDemonstrator(task)


# -- behaviours shared by the demonstrator and the oracle skills ---------------------------
def grasp_point(state: State, block: Object) -> np.ndarray:
    return state.data[block][:3] + np.array([0.0, 0.0, GRASP_ABOVE_CENTRE])


def stack_action(state: State, robot: Object, a: Object, b: Object) -> np.ndarray:
    """Carry ``a`` over ``b``, lower it until it touches ``b``, open."""
    # the hand height that puts a's bottom 1 mm into b's top
    drop = (state.get(a, "z") - SIDE / 2) - (state.get(b, "z") + SIDE / 2) + 0.001
    goal = np.array([state.get(b, "x"), state.get(b, "y"), state.get(robot, "z") - drop])
    landed = state.get(a, f"touching_{b.name}") > 0.5
    return release_action(state, robot, goal, landed, FUNNEL)


class StackDemonstrator:
    """Builds the tower bottom-up, closed loop on features, acting only through actions."""

    def __init__(self, task: Task) -> None:
        below = {a.objects[0]: a.objects[1] for a in task.goal}
        # bottom-up: an atom On(a, b) comes after the atom that puts b on its support
        self.atoms = sorted(task.goal, key=lambda a: _depth(a.objects[1], below))
        self.robot = next(o for o in task.objects if o.type == ROBOT)
        self.steps = 0

    def __call__(self, state: State) -> np.ndarray:
        atom = next((a for a in self.atoms if not a.holds(state)), None)
        if atom is None:
            return open_first(state, self.robot, np.zeros(4))
        self.steps += 1
        if self.steps > MAX_ATOM_STEPS * len(self.atoms):
            raise DemonstrationFailed(f"could not achieve {atom}")
        a, b = atom.objects
        if state.get(a, "grasped") > 0.5:
            return stack_action(state, self.robot, a, b)
        return grasp_action(state, self.robot, grasp_point(state, a), FUNNEL)


def _depth(block: Object, below: dict[Object, Object]) -> int:
    return 0 if block not in below else 1 + _depth(below[block], below)


# -- oracle skills ---------------------------------------------------------------------------
_R, _A, _B = Variable("?robot", ROBOT), Variable("?block", BLOCK), Variable("?base", BLOCK)
PICK = STRIPSOperator(
    "Pick",
    (_R, _A),
    frozenset({LiftedAtom(p, (v,)) for p, v in ((HAND_EMPTY, _R), (ON_TABLE, _A), (CLEAR, _A))}),
    frozenset({LiftedAtom(HOLDING, (_A,))}),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,)), LiftedAtom(ON_TABLE, (_A,))}),
)
STACK = STRIPSOperator(
    "Stack",
    (_R, _A, _B),
    frozenset({LiftedAtom(HOLDING, (_A,)), LiftedAtom(CLEAR, (_B,))}),
    frozenset({LiftedAtom(ON, (_A, _B)), LiftedAtom(HAND_EMPTY, (_R,))}),
    frozenset({LiftedAtom(HOLDING, (_A,)), LiftedAtom(CLEAR, (_B,))}),
)


class PickPolicy:
    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        return grasp_action(state, objects[0], subgoal[:3], FUNNEL)  # the subgoal's hand xyz


class PickSampler:
    def __call__(self, state: State, objects: Sequence[Object], rng: np.random.Generator):
        sub = state.vec(objects).copy()
        sub[:3] = grasp_point(state, objects[1]) + rng.uniform(-0.002, 0.002, size=3)
        return sub


class StackPolicy:
    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        return stack_action(state, *objects)


class StackSampler:
    def __call__(self, state: State, objects: Sequence[Object], rng: np.random.Generator):
        return state.vec(objects).copy()
