"""The GNN Meta and GNN BC approaches' loops on ToyCover, with a scripted chooser/policy
standing in for the networks (the networks' own tests are in
test_learning_gnn_baselines.py)."""

from __future__ import annotations

import time

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.baselines.approaches import META_SAMPLES, GNNBehaviourCloning, GNNMeta
from bpns.env.abstraction import abstract
from bpns.execution.failures import FailureReason
from bpns.planning.config import PlanningConfig
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


class NothingChooser(GoalChooser):
    def choose(self, state, atoms, goal):
        return None


def _tasks(n: int, seed: int, num_blocks: int = 3):
    rng = np.random.default_rng(seed)
    return [toy_gnn.single_goal_task(rng, num_blocks) for _ in range(n)]


def _replays(env, task, actions) -> bool:
    state = task.init
    for a in actions:
        state = env.simulate(state, a)
    return task.goal_holds(abstract(state, toy.PREDICATES))


def _meta(skills, chooser=None) -> GNNMeta:
    env = toy_gnn.ToyCoverEnv()
    return GNNMeta(env, PlanningConfig(), skills, chooser or GoalChooser())


def test_metacontroller_solves_tasks_and_its_actions_replay() -> None:
    approach = _meta(toy_gnn.oracle_skills())
    for task in _tasks(5, seed=0):
        out = approach.solve(task, np.random.default_rng(0), 60.0)
        assert out.success and out.reason is None, out
        assert len(out.skeleton) == 2 and _replays(approach.env, task, out.actions)


def test_no_subgoal_skills_get_one_rollout_per_step() -> None:
    out = _meta(toy_gnn.oracle_skills(subgoals=False)).solve(
        _tasks(1, seed=1)[0], np.random.default_rng(0), 60.0
    )
    assert out.success and out.samples == 2


def test_a_failing_skill_uses_up_its_samples_then_the_attempt_fails() -> None:
    pick, place = toy_gnn.oracle_skills()
    # a pick sampler that grips 2 m beside the block: the grasp never happens
    bad = type(pick)(pick.operator, pick.policy, lambda s, o, r: s.vec(o) + [0, 0, 2.0, 0])
    out = _meta([bad, place]).solve(_tasks(1, seed=2)[0], np.random.default_rng(0), 60.0)
    assert not out.success and out.samples == META_SAMPLES and len(out.actions) == 0


def test_nothing_applicable_and_deadlines_end_the_attempt() -> None:
    task = _tasks(1, seed=3)[0]
    out = _meta(toy_gnn.oracle_skills(), NothingChooser()).solve(task, np.random.default_rng(0), 60)
    assert out.reason is FailureReason.NO_SKILL
    late = _meta(toy_gnn.oracle_skills()).solve(task, np.random.default_rng(0), 0.0)
    assert late.reason is FailureReason.TIMEOUT


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


def test_policy_acts_until_the_goal_or_the_horizon() -> None:
    env = toy_gnn.ToyCoverEnv()
    task = _tasks(1, seed=4)[0]
    rng = np.random.default_rng(0)
    out = GNNBehaviourCloning(env, _scripted_policy).solve(task, rng, 60.0)
    assert out.success and _replays(env, task, out.actions)
    idle = GNNBehaviourCloning(env, lambda s, a, g: np.zeros(2)).solve(task, rng, 60.0)
    assert idle.reason is FailureReason.TASK_HORIZON and idle.sim_steps == task.horizon
    nan = GNNBehaviourCloning(env, lambda s, a, g: np.full(2, np.nan)).solve(task, rng, 60.0)
    assert nan.reason is FailureReason.POLICY_NONFINITE and nan.sim_steps == 0


def test_running_out_of_task_steps_is_reported_as_the_task_horizon() -> None:
    task = _tasks(1, seed=5)[0]
    short = type(task)(task.init, task.goal, horizon=3)  # too few steps to reach anything
    out = _meta(toy_gnn.oracle_skills()).solve(short, np.random.default_rng(0), 60.0)
    assert out.reason is FailureReason.TASK_HORIZON and out.samples == META_SAMPLES


def _dawdling_policy(state, atoms, goal) -> np.ndarray:
    """Stands still, slowly: the task's horizon would take seconds to use up."""
    time.sleep(0.05)
    return np.zeros(2)


def test_a_policy_acting_every_step_stops_at_its_timeout_in_both_loops() -> None:
    env = toy_gnn.ToyCoverEnv()
    task = _tasks(1, seed=6)[0]
    assert task.horizon * 0.05 > 1.0  # the horizon alone would outlast the timeout
    approach = GNNBehaviourCloning(env, _dawdling_policy)
    model_only = approach.solve(task, np.random.default_rng(0), 0.2)
    closed = ExecutionConfig(closed_loop=True)
    in_world = approach.solve_in_world(task, env, env, np.random.default_rng(0), 0.2, closed)
    for out in (model_only, in_world):
        assert out.reason is FailureReason.TIMEOUT and 0 < out.sim_steps < task.horizon
