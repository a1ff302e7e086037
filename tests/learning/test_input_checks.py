"""Learning refuses non-finite demonstrations and configs; results stay strict JSON."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from bpns.evaluation.evaluate import EvalReport, TaskOutcome
from bpns.learning.artifacts.skills_dir import save_skills
from bpns.learning.config import LearningConfig, MLPConfig
from bpns.learning.demo_checks import DemonstrationError
from bpns.learning.pipeline import LearnedSkills, learn_skills
from bpns.planning.config import PlanningConfig
from bpns.structs import Demonstration, State
from tests import toy_learning as toy


def _with_nan_action(demo: Demonstration, step: int, value: float) -> Demonstration:
    actions = demo.actions.copy()
    actions[step, 0] = value
    return Demonstration(task=demo.task, states=demo.states, actions=actions)


def _with_nan_feature(demo: Demonstration, step: int) -> Demonstration:
    states = list(demo.states)
    s = states[step]
    data = {o: v.copy() for o, v in s.data.items()}
    data[toy.ROBOT_OBJ][0] = np.nan
    states[step] = State(data, s.sim)
    return Demonstration(task=demo.task, states=tuple(states), actions=demo.actions)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_learning_refuses_non_finite_actions_naming_demo_and_step(value):
    demos = toy.demos(3, seed=0)
    demos[1] = _with_nan_action(demos[1], 4, value)
    with pytest.raises(DemonstrationError, match="demonstration 1: action at step 4 holds NaN"):
        learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, toy.fast_config(steps=1))


@pytest.mark.parametrize("value", [1e300, -1e12])
def test_learning_refuses_finite_but_absurd_actions_before_training(value):
    demos = toy.demos(3, seed=0)
    demos[0] = _with_nan_action(demos[0], 2, value)
    with pytest.raises(DemonstrationError, match="demonstration 0: action at step 2 holds .*e"):
        learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, toy.fast_config(steps=1))


def test_learning_refuses_non_finite_features_naming_demo_and_step():
    demos = toy.demos(3, seed=0)
    demos[2] = _with_nan_feature(demos[2], 3)
    with pytest.raises(DemonstrationError, match="demonstration 2: features of robot at step 3"):
        learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, toy.fast_config(steps=1))


@pytest.mark.parametrize("margin", [math.inf, math.nan, -0.1])
def test_input_margin_must_be_finite(margin):
    with pytest.raises(ValueError, match="input_margin"):
        MLPConfig(input_margin=margin)


@pytest.mark.parametrize(
    "field, value",
    [
        ("skill_horizon_factor", math.inf),
        ("near_goal_scale", math.inf),
        ("change_tolerance", math.nan),
        ("min_segment_fraction", math.nan),
    ],
)
def test_learning_config_rejects_non_finite_numbers(field, value):
    with pytest.raises(ValueError, match=field):
        LearningConfig(**{field: value})


@pytest.mark.parametrize(
    "field, value",
    [
        ("timeout", math.inf),
        ("timeout", math.nan),
        ("stuck_atol", math.nan),
        ("nogood_atol", math.inf),
    ],
)
def test_planning_config_rejects_non_finite_numbers(field, value):
    with pytest.raises(ValueError, match=field):
        PlanningConfig(**{field: value})


def test_eval_report_is_strict_json_even_when_nothing_was_solved():
    outcome = TaskOutcome(0, False, 1.5, "timeout", 0, 3, 1, 2, 10, None)
    report = EvalReport("cover", "bpns", "BPNS", PlanningConfig(), (outcome,), task_seed=0)
    json.dumps(report.to_json(), allow_nan=False)  # raises on NaN / Infinity


def test_saving_refuses_non_finite_weights(tmp_path):
    skills = toy.learned_toy_skills()
    skill = skills.skills[0]
    params = skill.policy.params
    bad_w0 = params.weights[0].copy()
    bad_w0[0, 0] = np.nan
    bad_params = dataclasses.replace(params, weights=(bad_w0, *params.weights[1:]))
    policy = type(skill.policy)(skill.policy.dims, bad_params, skill.policy.use_subgoals)
    damaged = LearnedSkills(
        (dataclasses.replace(skill, policy=policy), *skills.skills[1:]),
        skills.predicates,
        skills.config,
        skills.stats,
    )
    with pytest.raises(ValueError, match="holds NaN or inf"):
        save_skills(damaged, tmp_path / "skills")
    assert not (tmp_path / "skills").exists()
