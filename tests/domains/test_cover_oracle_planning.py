"""Hand-written Cover skills solve tasks through the same bilevel planner in physics."""

from __future__ import annotations

import time

import numpy as np

from bpns.approaches.bilevel import oracle_skills
from bpns.env.abstraction import abstract
from bpns.planning.bilevel import plan
from bpns.planning.config import PlanningConfig


def test_oracle_skills_solve_seeded_eval_tasks_and_the_plan_replays(cover_env):
    skills = oracle_skills(cover_env)
    config = PlanningConfig(timeout=30.0, max_skill_horizon=150)
    for i in range(2):
        task = cover_env.task(i, 0, False)
        result = plan(task, skills, cover_env, config, np.random.default_rng(i))
        assert result.success, result.reason
        state = task.init
        for action in result.actions:  # f is exact: the returned actions solve the task
            state = cover_env.simulate(state, action)
        assert task.goal <= abstract(state, cover_env.goal_predicates)


def test_planner_obeys_its_timeout_in_physics(cover_env):
    skills = oracle_skills(cover_env)
    task = cover_env.task(5, 0, False)  # needs many samples: refinement outlasts 1 s
    config = PlanningConfig(timeout=1.0, max_skill_horizon=150)
    t0 = time.monotonic()
    result = plan(task, skills, cover_env, config, np.random.default_rng(0))
    elapsed = time.monotonic() - t0
    assert elapsed < 1.0 + 1.0  # the contract: the timeout is obeyed within 1 s
    if not result.success:
        assert str(result.reason) == "timeout"
