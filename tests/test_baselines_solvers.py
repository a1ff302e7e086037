"""The GNN Meta and GNN BC solving loops on ToyCover, with a scripted chooser/policy
standing in for the networks (the networks' own tests are in
test_learning_gnn_baselines.py)."""

from __future__ import annotations

import time

import numpy as np

from bpns.abstraction import abstract
from bpns.baselines import MetaSolveConfig, solve_with_metacontroller, solve_with_policy
from bpns.baselines import result as R
from tests import toy_gnn
from tests import toy_learning as toy


class GoalChooser:
    """Duck-typed metacontroller: pick the goal block, then place it on its target."""

    def __init__(self) -> None:
        self.operators = toy_gnn.operators()

    def choose(self, state, atoms, goal):
        pick, place = self.operators
        (atom,) = goal
        block, target = atom.objects
        if pick.ground((block, toy.ROBOT_OBJ)).applicable(atoms):
            return pick.ground((block, toy.ROBOT_OBJ))
        if place.ground((block, toy.ROBOT_OBJ, target)).applicable(atoms):
            return place.ground((block, toy.ROBOT_OBJ, target))
        return None


def _tasks(n: int, seed: int, num_blocks: int = 3):
    rng = np.random.default_rng(seed)
    return [toy_gnn.single_goal_task(rng, num_blocks) for _ in range(n)]


def _replays(env, task, actions) -> bool:
    state = task.init
    for a in actions:
        state = env.simulate(state, a)
    return task.goal_holds(abstract(state, toy.PREDICATES))


def test_metacontroller_loop_solves_tasks_and_its_actions_replay() -> None:
    env = toy_gnn.ToyCoverEnv()
    for task in _tasks(5, seed=0):
        out = solve_with_metacontroller(
            env,
            task,
            np.random.default_rng(0),
            None,
            GoalChooser(),
            toy_gnn.oracle_skills(),
            toy.PREDICATES,
        )
        assert out.success and out.reason is None, out
        assert out.stats["skills"] == 2 and _replays(env, task, out.actions)


def test_no_subgoal_skills_get_one_rollout_per_step() -> None:
    env = toy_gnn.ToyCoverEnv()
    task = _tasks(1, seed=1)[0]
    out = solve_with_metacontroller(
        env,
        task,
        np.random.default_rng(0),
        None,
        GoalChooser(),
        toy_gnn.oracle_skills(subgoals=False),
        toy.PREDICATES,
    )
    assert out.success and out.stats["samples"] == 2


def test_failing_skills_use_up_their_samples_then_the_loop_fails() -> None:
    env = toy_gnn.ToyCoverEnv()
    pick, place = toy_gnn.oracle_skills()
    # a pick sampler that grips 2 m beside the block: the grasp never happens
    bad = type(pick)(pick.operator, pick.policy, lambda s, o, r: s.vec(o) + [0, 0, 2.0, 0])
    out = solve_with_metacontroller(
        env,
        _tasks(1, seed=2)[0],
        np.random.default_rng(0),
        None,
        GoalChooser(),
        [bad, place],
        toy.PREDICATES,
        MetaSolveConfig(max_samples=7),
    )
    assert not out.success and out.reason == R.SUBGOALS_EXHAUSTED
    assert out.stats["samples"] == 7 and len(out.actions) == 0


def test_nothing_applicable_and_deadlines_end_the_loop() -> None:
    env = toy_gnn.ToyCoverEnv()
    task = _tasks(1, seed=3)[0]
    chooser = GoalChooser()
    chooser.choose = lambda state, atoms, goal: None
    out = solve_with_metacontroller(
        env, task, np.random.default_rng(0), None, chooser, toy_gnn.oracle_skills(), toy.PREDICATES
    )
    assert out.reason == R.NO_APPLICABLE_SKILL
    late = solve_with_metacontroller(
        env,
        task,
        np.random.default_rng(0),
        time.monotonic() - 1,
        GoalChooser(),
        toy_gnn.oracle_skills(),
        toy.PREDICATES,
    )
    assert late.reason == R.TIMEOUT


def _scripted_policy(state, atoms, goal) -> np.ndarray:
    """Move to the goal block and grip, then carry it onto its target and release."""
    (atom,) = goal
    block, target = atom.objects
    robot_x = state.get(toy.ROBOT_OBJ, "x")
    if state.get(block, "held") < 0.5:
        dx = state.get(block, "x") - robot_x
        return np.array([dx, 1.0 if abs(dx) <= toy.SPEED else 0.0])
    dx = state.get(target, "x") - state.get(block, "x")
    return np.array([dx, -1.0 if abs(dx) <= toy.SPEED else 0.0])


def test_policy_loop_runs_until_the_goal_or_the_horizon() -> None:
    env = toy_gnn.ToyCoverEnv()
    task = _tasks(1, seed=4)[0]
    out = solve_with_policy(
        env, task, np.random.default_rng(0), None, _scripted_policy, toy.PREDICATES
    )
    assert out.success and _replays(env, task, out.actions)
    idle = solve_with_policy(
        env, task, np.random.default_rng(0), None, lambda s, a, g: np.zeros(2), toy.PREDICATES
    )
    assert idle.reason == R.TASK_HORIZON and len(idle.actions) == task.horizon
    nan = solve_with_policy(
        env,
        task,
        np.random.default_rng(0),
        None,
        lambda s, a, g: np.full(2, np.nan),
        toy.PREDICATES,
    )
    assert nan.reason == R.POLICY_NONFINITE and len(nan.actions) == 0


def test_running_out_of_task_steps_is_reported_as_the_task_horizon() -> None:
    env = toy_gnn.ToyCoverEnv()
    task = _tasks(1, seed=5)[0]
    short = type(task)(task.init, task.goal, horizon=3)  # too few steps to reach anything
    out = solve_with_metacontroller(
        env,
        short,
        np.random.default_rng(0),
        None,
        GoalChooser(),
        toy_gnn.oracle_skills(),
        toy.PREDICATES,
        MetaSolveConfig(max_samples=4),
    )
    assert out.reason == R.TASK_HORIZON and out.stats["samples"] == 4
