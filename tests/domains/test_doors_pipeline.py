"""Doors end to end on 2x2 maps: a few demos -> four operators, the moving ones bound to
the given motion-planning skills, OpenDoor learned -> a held-out task solved."""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from bpns.data.demos import run_demonstrator
from bpns.learning.artifacts.skills_dir import load_skills, save_skills
from bpns.learning.config import MLPConfig, learning_config_for
from bpns.learning.given import BoundPolicy, given_skills_of
from bpns.learning.pipeline import learn_skills
from bpns.learning.policies import LearnedPolicy
from bpns.planning.bilevel import plan
from bpns.planning.config import PlanningConfig
from mj_envs.domains.doors.env import DoorsEnv


def test_few_demos_learn_four_operators_using_the_given_skills_and_solve_a_task(tmp_path):
    env = DoorsEnv(grid_sizes=(2,))
    demos = [run_demonstrator(env, t, [0, i]) for i, t in enumerate(env.train_tasks(6, seed=4))]
    assert all(d is not None for d in demos)
    # 400 steps left OpenDoor's policy from six demos on the edge: in a fresh install of
    # 2026-12-07 (mujoco 3.17.0, numpy 2.4.6; 3b01046 failed there too) refinement failed
    # from half the planner seeds; 1500 solve the task from each of seeds 0-3 within 5
    # samples
    fast = MLPConfig(num_steps=1500)
    config = dataclasses.replace(
        learning_config_for(env), policy=fast, generator=fast, classifier=fast
    )
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        learned = learn_skills(
            demos, env.predicates, env.contact_predicates, config, given=given_skills_of(env)
        )
    finally:
        torch.set_num_threads(before)
    given = [s for s in learned.skills if isinstance(s.policy, BoundPolicy)]
    trained = [s for s in learned.skills if isinstance(s.policy, LearnedPolicy)]
    # short 2x2 routes may never show MoveToDoor from a doorway: 3 or 4 operators
    assert len(learned.skills) in (3, 4) and len(trained) == 1
    assert len(given) == len(learned.skills) - 1
    assert {a.predicate.name for a in trained[0].operator.add_effects} == {"DoorIsOpen"}
    # saved and loaded back (given skills by name and binding): the same plan solves
    save_skills(learned, tmp_path / "skills", env_name=env.name)
    loaded = load_skills(tmp_path / "skills", env.predicates, env.types, given_skills_of(env))
    assert [s.name for s in loaded.skills] == [s.name for s in learned.skills]
    task = env.eval_tasks(1, seed=9)[0]
    result = plan(task, loaded.skills, env, PlanningConfig(timeout=60.0), np.random.default_rng(0))
    assert result.success
