"""Tiny pure-numpy domains and demonstrators for the learning tests.

ToyCover (1D): a robot on a line picks blocks and places them on targets. Action
(dx, grip): the robot moves by dx (clipped to +-SPEED), then grip > 0.5 grasps a block
within GRASP_TOL of the hand (the block keeps its offset to the hand while held) and
grip < -0.5 releases. Covers(block, target) holds for a released block within COVER_TOL
of the target. The demonstrator grasps at a random offset, so place subgoals depend on
the grasp (the sampler has something to learn), and releases on its target.
Contact predicates: HandEmpty, Holding, Covers (every predicate here).

Point2D: a point robot driven by a linear controller towards random subgoals, used to
check that subgoal-conditioned behaviour cloning recovers a controller.
"""

from __future__ import annotations

import functools

import numpy as np
import torch

from bpns.env.abstraction import abstract
from bpns.learning.config import LearningConfig, MLPConfig
from bpns.learning.operators import SkillDataset
from bpns.learning.pipeline import LearnedSkills, learn_skills
from bpns.structs import (
    Demonstration,
    GroundAtom,
    Object,
    Predicate,
    Segment,
    State,
    STRIPSOperator,
    Task,
    Type,
    Variable,
)

SPEED = 0.5
GRASP_TOL = 0.3
COVER_TOL = 0.3
GRASP_OFFSET = 0.15  # demonstrator's grasp offsets are uniform in +-this
PLACE_NOISE = 0.05
WORLD = 10.0

ROBOT = Type("robot", ("x", "holding"))
BLOCK = Type("block", ("x", "held"))
TARGET = Type("target", ("x",))
TYPES = frozenset({ROBOT, BLOCK, TARGET})


def _hand_empty(s: State, o) -> bool:
    return s.get(o[0], "holding") < 0.5


def _holding(s: State, o) -> bool:
    return s.get(o[0], "holding") > 0.5 and s.get(o[1], "held") > 0.5


def _covers(s: State, o) -> bool:
    return s.get(o[0], "held") < 0.5 and abs(s.get(o[0], "x") - s.get(o[1], "x")) < COVER_TOL


HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), _hand_empty)
HOLDING = Predicate("Holding", (ROBOT, BLOCK), _holding)
COVERS = Predicate("Covers", (BLOCK, TARGET), _covers)
PREDICATES = frozenset({HAND_EMPTY, HOLDING, COVERS})
CONTACT_PREDICATES = PREDICATES

ROBOT_OBJ = Object("robot", ROBOT)


def blocks(n: int) -> list[Object]:
    return [Object(f"block{i}", BLOCK) for i in range(n)]


def targets(n: int) -> list[Object]:
    return [Object(f"target{i}", TARGET) for i in range(n)]


def make_state(robot_x: float, block_xs, target_xs, held: int | None = None) -> State:
    data = {ROBOT_OBJ: np.array([robot_x, 0.0 if held is None else 1.0])}
    for i, (b, x) in enumerate(zip(blocks(len(block_xs)), block_xs, strict=True)):
        data[b] = np.array([x, 1.0 if held == i else 0.0])
    for t, x in zip(targets(len(target_xs)), target_xs, strict=True):
        data[t] = np.array([x])
    return State(data)


def simulate(state: State, action: np.ndarray) -> State:
    """Deterministic toy transition."""
    data = {o: v.copy() for o, v in state.data.items()}
    robot = data[ROBOT_OBJ]
    dx = float(np.clip(action[0], -SPEED, SPEED)) if np.isfinite(action[0]) else 0.0
    robot[0] += dx
    for o, v in data.items():
        if o.type == BLOCK and v[1] > 0.5:
            v[0] += dx
    grip = float(action[1])
    if grip > 0.5 and robot[1] < 0.5:
        near = [o for o, v in data.items() if o.type == BLOCK and abs(v[0] - robot[0]) < GRASP_TOL]
        if near:
            block = min(near, key=lambda o: abs(data[o][0] - robot[0]))
            data[block][1] = 1.0
            robot[1] = 1.0
    elif grip < -0.5 and robot[1] > 0.5:
        robot[1] = 0.0
        for o, v in data.items():
            if o.type == BLOCK:
                v[1] = 0.0
    return State(data)


def _move_to(states: list[State], actions: list[np.ndarray], goal_x: float, grip: float) -> None:
    """Drive the robot to ``goal_x``; the last step also sends ``grip``."""
    while True:
        state = states[-1]
        delta = goal_x - state.get(ROBOT_OBJ, "x")
        last = abs(delta) <= SPEED
        action = np.array([np.clip(delta, -SPEED, SPEED), grip if last else 0.0])
        actions.append(action)
        states.append(simulate(state, action))
        if last:
            return


def sample_task(rng: np.random.Generator, num_blocks: int = 2) -> Task:
    """Blocks and targets at well-separated random places; goal: block i covers target i."""
    while True:
        xs = rng.uniform(0.0, WORLD, size=2 * num_blocks + 1)
        if np.min(np.diff(np.sort(xs))) > 1.0:
            break
    init = make_state(xs[0], xs[1 : 1 + num_blocks], xs[1 + num_blocks :])
    goal = frozenset(
        GroundAtom(COVERS, (b, t))
        for b, t in zip(blocks(num_blocks), targets(num_blocks), strict=True)
    )
    return Task(init, goal, horizon=10 * num_blocks)


def demonstrate(task: Task, rng: np.random.Generator) -> Demonstration:
    states, actions = [task.init], []
    n = len(task.init.objects_of_type(BLOCK))
    for b, t in zip(blocks(n), targets(n), strict=True):
        offset = rng.uniform(-GRASP_OFFSET, GRASP_OFFSET)
        _move_to(states, actions, states[-1].get(b, "x") + offset, grip=1.0)
        hand_to_block = states[-1].get(b, "x") - states[-1].get(ROBOT_OBJ, "x")
        place_x = states[-1].get(t, "x") - hand_to_block + rng.uniform(-PLACE_NOISE, PLACE_NOISE)
        _move_to(states, actions, place_x, grip=-1.0)
    demo = Demonstration(task, tuple(states), np.array(actions))
    assert task.goal_holds(abstract(states[-1], PREDICATES)), "demonstrator failed"
    return demo


def demos(n: int, seed: int, num_blocks: int = 2) -> list[Demonstration]:
    rng = np.random.default_rng(seed)
    return [demonstrate(sample_task(rng, num_blocks), rng) for _ in range(n)]


def fast_config(seed: int = 0, steps: int = 1500, **kwargs) -> LearningConfig:
    """Few gradient steps: enough for the toy, quick enough for unit tests."""
    net = MLPConfig(num_steps=steps, batch_size=128)
    return LearningConfig(seed=seed, policy=net, generator=net, classifier=net, **kwargs)


@functools.cache
def learned_toy_skills(seed: int = 0) -> LearnedSkills:
    """Skills learned once per test session from 30 ToyCover demos (on one torch thread,
    the fastest for these tiny nets; the caller's setting is restored)."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _learn_toy(seed)
    finally:
        torch.set_num_threads(before)


def _learn_toy(seed: int) -> LearnedSkills:
    return learn_skills(
        demos(30, seed=seed), PREDICATES, CONTACT_PREDICATES, fast_config(seed, 2500)
    )


def run_skill(
    skill, state: State, objects, subgoal: np.ndarray, max_steps: int = 60
) -> State | None:
    """Run a ground skill's policy until its operator's expected abstract state holds
    (returns that state) or ``max_steps`` pass (returns None)."""
    ground = skill.operator.ground(objects)
    atoms = abstract(state, PREDICATES)
    if not ground.applicable(atoms):
        raise ValueError(f"{ground} is not applicable")
    expected = ground.apply(atoms)
    for _ in range(max_steps):
        state = simulate(state, skill.policy(state, objects, subgoal))
        atoms = abstract(state, PREDICATES)
        if atoms == expected:
            return state
    return None


# ----------------------------------------------------------------------------- Point2D

POINT = Type("point", ("x", "y"))
POINT_OBJ = Object("p", POINT)
GAIN = 0.5


def point_state(xy) -> State:
    return State({POINT_OBJ: np.asarray(xy, dtype=np.float64)})


def point_step(state: State, action: np.ndarray) -> State:
    return point_state(state.data[POINT_OBJ] + action)


def point_dataset(n: int, seed: int) -> SkillDataset:
    """Segments of a linear controller a = GAIN * (goal - x) driving to random goals."""
    rng = np.random.default_rng(seed)
    segs = []
    for _ in range(n):
        x, goal = rng.uniform(-1, 1, size=2), rng.uniform(-1, 1, size=2)
        states, actions = [point_state(x)], []
        for _ in range(8):
            a = GAIN * (goal - states[-1].data[POINT_OBJ])
            actions.append(a)
            states.append(point_step(states[-1], a))
        segs.append(Segment(tuple(states), np.array(actions), frozenset(), frozenset()))
    var = Variable("?point0", POINT)
    op = STRIPSOperator("Move", (var,), frozenset(), frozenset(), frozenset())
    return SkillDataset(op, tuple(segs), tuple((POINT_OBJ,) for _ in segs))
