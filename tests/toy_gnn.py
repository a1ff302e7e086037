"""ToyCover tasks for the GNN baselines: the goal names one block (chosen at random) and
its target, so the next ground operator depends on the goal, not on object names.

The demonstrator picks the goal block (random grasp offset) and places it on its target:
two segments, Pick(robot, block) then Place(robot, block, target).
"""

from __future__ import annotations

import functools

import numpy as np

from bpns.env.abstraction import abstract
from bpns.env.environment import Capabilities
from bpns.learning.operators import learn_operators
from bpns.learning.partition import partition_segments
from bpns.learning.samplers import CurrentStateSampler
from bpns.learning.segmentation import segment_demonstration, segment_demonstrations
from bpns.structs import (
    Demonstration,
    GroundAtom,
    Segment,
    Skill,
    State,
    STRIPSOperator,
    Task,
)
from tests import toy_learning as toy


def single_goal_task(rng: np.random.Generator, num_blocks: int = 2) -> Task:
    """Robot, blocks and targets on a jittered grid (at least 1 apart, in [0, 10] for
    two blocks, wider for more), shuffled."""
    n = 2 * num_blocks + 1
    xs = rng.permutation(np.arange(n) * 2.0 + rng.uniform(0.0, 1.0, size=n))
    init = toy.make_state(xs[0], xs[1 : 1 + num_blocks], xs[1 + num_blocks :])
    k = int(rng.integers(num_blocks))
    block, target = toy.blocks(num_blocks)[k], toy.targets(num_blocks)[k]
    return Task(init, frozenset({GroundAtom(toy.COVERS, (block, target))}), horizon=40)


def demonstrate(task: Task, rng: np.random.Generator) -> Demonstration:
    (atom,) = task.goal
    block, target = atom.objects
    states, actions = [task.init], []
    offset = rng.uniform(-toy.GRASP_OFFSET, toy.GRASP_OFFSET)
    toy._move_to(states, actions, states[-1].get(block, "x") + offset, grip=1.0)
    hand_to_block = states[-1].get(block, "x") - states[-1].get(toy.ROBOT_OBJ, "x")
    place_x = states[-1].get(target, "x") - hand_to_block
    toy._move_to(states, actions, place_x, grip=-1.0)
    assert task.goal_holds(abstract(states[-1], toy.PREDICATES)), "demonstrator failed"
    return Demonstration(task, tuple(states), np.array(actions))


def demos(n: int, seed: int, num_blocks: int = 2) -> list[Demonstration]:
    rng = np.random.default_rng(seed)
    return [demonstrate(single_goal_task(rng, num_blocks), rng) for _ in range(n)]


def segments_of(demos: list[Demonstration]) -> tuple[tuple[Segment, ...], ...]:
    """Each demo's segments, as ``learn_skills`` records them in ``LearnedSkills.segments``."""
    return tuple(
        tuple(segment_demonstration(d, toy.PREDICATES, toy.CONTACT_PREDICATES)) for d in demos
    )


@functools.cache
def operators(seed: int = 0) -> tuple[STRIPSOperator, ...]:
    """Pick and Place, learned by BPNS's own stages from 30 demos."""
    segments = segment_demonstrations(demos(30, seed), toy.PREDICATES, toy.CONTACT_PREDICATES)
    return tuple(d.operator for d in learn_operators(partition_segments(segments)))


def toward_goal_block(state: State, goal) -> np.ndarray:
    """A toy goal-conditioned policy: half the way from the robot to the goal's block,
    gripper proportional to the block's distance to its target."""
    (atom,) = goal
    block, target = atom.objects
    dx = state.get(block, "x") - state.get(toy.ROBOT_OBJ, "x")
    dt = state.get(target, "x") - state.get(block, "x")
    return np.array([0.5 * dx, 0.25 * dt])


class ToyCoverEnv:
    """What the baselines' approaches use of an environment, for ToyCover."""

    name = "toy_cover"
    contact_settle_steps = 1
    capabilities = Capabilities()
    predicates = toy.PREDICATES
    goal_predicates = toy.PREDICATES
    contact_predicates = toy.CONTACT_PREDICATES
    types = toy.TYPES
    action_low = np.array([-1.0, -1.0])
    action_high = np.array([1.0, 1.0])

    def __init__(self) -> None:
        self.sim_steps = 0

    def simulate(self, state: State, action: np.ndarray) -> State:
        self.sim_steps += 1
        return toy.simulate(state, action)


def _move_policy(grip: float):
    def policy(state: State, objects, subgoal: np.ndarray) -> np.ndarray:
        robot = objects[1]
        delta = subgoal[2] - state.get(robot, "x")  # scope: block (x, held), robot (x, ...)
        last = abs(delta) <= toy.SPEED
        return np.array([np.clip(delta, -toy.SPEED, toy.SPEED), grip if last else 0.0])

    return policy


def _pick_sampler(state: State, objects, rng: np.random.Generator) -> np.ndarray:
    g = state.vec(objects).copy()
    g[2] = state.get(objects[0], "x") + rng.uniform(-toy.GRASP_OFFSET, toy.GRASP_OFFSET)
    return g


def _place_sampler(state: State, objects, rng: np.random.Generator) -> np.ndarray:
    block, robot, target = objects
    g = state.vec(objects).copy()
    g[2] = state.get(target, "x") - (state.get(block, "x") - state.get(robot, "x"))
    return g


def oracle_skills(seed: int = 0, subgoals: bool = True):
    """Hand-written skills for the learned Pick (Op0) and Place (Op1) operators; without
    subgoals the sampler is BPNS's CurrentStateSampler (and the policies, which read
    the subgoal, are given one that already sits at the goal)."""
    pick, place = operators(seed)
    if subgoals:
        return [
            Skill(pick, _move_policy(1.0), _pick_sampler),
            Skill(place, _move_policy(-1.0), _place_sampler),
        ]

    def nosub(policy, sampler):
        rng = np.random.default_rng(0)
        return lambda state, objects, _: policy(state, objects, sampler(state, objects, rng))

    return [
        Skill(pick, nosub(_move_policy(1.0), _pick_sampler), CurrentStateSampler()),
        Skill(place, nosub(_move_policy(-1.0), _place_sampler), CurrentStateSampler()),
    ]
