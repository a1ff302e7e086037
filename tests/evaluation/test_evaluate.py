"""The evaluation harness: per-task outcomes, validated plans, summaries, approach settings."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bpns.approaches import SkillSource, approach_names, get_approach
from bpns.approaches.bilevel import oracle_skills
from bpns.env.environment import Capabilities
from bpns.evaluation.evaluate import (
    EvalReport,
    TaskOutcome,
    markdown_table,
    plan_reaches_goal,
    solve_task,
)
from bpns.planning.config import PlanningConfig


def _outcome(index: int, solved: bool, seconds: float, nodes: int = 4) -> TaskOutcome:
    return TaskOutcome(
        index=index,
        solved=solved,
        seconds=seconds,
        reason=None if solved else "timeout",
        num_actions=10 if solved else 0,
        nodes_created=nodes,
        abstract_plans=1,
        samples=2,
        sim_steps=20,
        validated=True if solved else None,
    )


def _report(outcomes, label="BPNS") -> EvalReport:
    return EvalReport(
        env="toy",
        approach="bpns",
        label=label,
        planning=PlanningConfig(),
        outcomes=tuple(outcomes),
        task_seed=0,
        num_demos=100,
        learning_seconds=12.5,
    )


def test_agent_cpu_time_is_summarised_over_solved_tasks_that_recorded_it():
    timed = [
        dataclasses.replace(_outcome(i, True, 9.0), cpu_seconds=cpu, world_cpu_seconds=1.0)
        for i, cpu in enumerate((2.0, 4.0))
    ]
    untimed = _outcome(2, True, 9.0)  # e.g. an outcome made without a CPU clock
    failed = dataclasses.replace(_outcome(3, False, 60.0), cpu_seconds=50.0)
    report = _report([*timed, untimed, failed])
    assert math.isnan(untimed.agent_cpu_seconds)
    assert report.median_agent_cpu_seconds == 2.0  # median of 1.0 and 3.0
    assert report.to_json()["summary"]["median_agent_cpu_seconds"] == 2.0
    assert report.to_json()["tasks"][0]["cpu_seconds"] == 2.0
    assert math.isnan(_report([untimed]).median_agent_cpu_seconds)
    header, _, row = markdown_table([report]).strip().splitlines()
    cpu_column = header.split("|").index(" Median agent CPU (s) ")
    assert row.split("|")[cpu_column].strip() == "2.00"
    untimed_row = markdown_table([_report([untimed])]).strip().splitlines()[-1]
    assert untimed_row.split("|")[cpu_column].strip() == "–"


def test_times_are_summarised_over_solved_tasks_and_nodes_over_all():
    report = _report(
        [_outcome(0, True, 1.0, 2), _outcome(1, True, 3.0, 4), _outcome(2, False, 60.0, 9)]
    )
    assert report.num_solved == 2 and report.solved_percent == pytest.approx(200 / 3)
    assert report.median_seconds == 2.0 and report.mean_seconds == 2.0
    assert report.mean_nodes == 5.0
    assert report.failures == {"timeout": 1}
    summary = report.to_json()["summary"]
    assert summary["num_solved"] == 2 and summary["failures"] == {"timeout": 1}


def test_a_report_with_nothing_solved_has_no_times_but_still_renders():
    report = _report([_outcome(0, False, 5.0)])
    assert math.isnan(report.median_seconds)
    assert report.to_json()["summary"]["median_seconds"] is None
    row = markdown_table([report]).splitlines()[-1]
    assert row.startswith("| BPNS | 100 | 0/1 (0.0%) | – | – |")


def test_markdown_table_has_one_row_per_approach_with_the_issue_columns():
    table = markdown_table(
        [_report([_outcome(0, True, 0.5)]), _report([_outcome(0, True, 0.1)], "Oracle")]
    )
    lines = table.strip().splitlines()
    assert "Solved" in lines[0] and "Median time" in lines[0] and "Learning time" in lines[0]
    assert "Nodes created" in lines[0] and "Mean time" in lines[0]
    assert len(lines) == 4 and lines[3].startswith("| Oracle |")


def test_ablations_are_planner_settings_of_the_same_learned_skills():
    base = PlanningConfig(n_samples=10, n_abstract=8, timeout=5.0)
    assert get_approach("samples1").planning_config(base).n_samples == 1
    assert get_approach("abstract1").planning_config(base).n_abstract == 1
    assert get_approach("bpns").planning_config(base) == base
    assert get_approach("oracle").skills is SkillSource.ORACLE
    others = {get_approach(n).skills for n in approach_names() if n != "oracle"}
    assert others == {SkillSource.LEARNED}
    with pytest.raises(KeyError, match="unknown approach 'nope'"):
        get_approach("nope")


def test_solve_task_validates_the_plan_by_resimulating_it(cover_env):
    task = cover_env.task(0, 0, False)
    oracle = get_approach("oracle").make(cover_env, PlanningConfig(timeout=60.0))
    outcome = solve_task(oracle, task, 0, cover_env, 60.0, np.random.default_rng(0))
    assert outcome.solved and outcome.validated is True
    assert outcome.num_actions == len(outcome.actions) > 0
    assert outcome.nodes_created >= 1 and outcome.sim_steps >= outcome.num_actions
    # the actions alone (no planner state) solve the task; a truncated plan does not
    assert plan_reaches_goal(cover_env, task, outcome.actions)
    assert not plan_reaches_goal(cover_env, task, outcome.actions[:5])


def test_environments_declare_planning_defaults_that_cli_settings_override():
    from bpns.planning.config import planning_config_for

    class Env:
        capabilities = Capabilities(planning_defaults={"n_abstract": 1000})

    class Plain:
        capabilities = Capabilities()

    assert planning_config_for(Plain()) == PlanningConfig()
    assert planning_config_for(Env(), timeout=5.0).n_abstract == 1000
    config = planning_config_for(Env(), n_abstract=3, n_samples=None)
    assert config.n_abstract == 3 and config.n_samples == PlanningConfig().n_samples


def test_environments_declare_learning_defaults_that_cli_settings_override():
    from bpns.env.registry import make_environment as make_env
    from bpns.learning.config import LearningConfig, learning_config_for

    class Plain:
        contact_settle_steps = 1
        capabilities = Capabilities()

    class Declaring:
        contact_settle_steps = 3
        capabilities = Capabilities(learning_defaults={"near_goal_scale": 0.01})

    assert learning_config_for(Plain()) == LearningConfig()
    declaring = Declaring()
    assert learning_config_for(declaring).near_goal_scale == 0.01
    assert learning_config_for(declaring).settle_steps == 3
    assert learning_config_for(declaring, near_goal_scale=0.5, seed=None).near_goal_scale == 0.5
    sb = make_env("stick_button")
    assert learning_config_for(sb).settle_steps == sb.contact_settle_steps
    assert learning_config_for(make_env("coffee")).near_goal_scale is None


def test_failed_tasks_are_explained_step_by_step(cover_env):
    """A failed task's outcome says which abstract plans were tried and, per step, how many
    samples failed and why (results.json `explanation`; `bpns eval --explain` prints it)."""
    import dataclasses
    import json

    from bpns.approaches.bilevel import BilevelPlanning
    from bpns.evaluation.evaluate import EvalReport, solve_task
    from bpns.evaluation.reporting import explain_lines
    from bpns.planning.config import PlanningConfig

    pick, place = oracle_skills(cover_env)
    # a pick that aims 30 cm above the block: the grasp never happens
    far = dataclasses.replace(pick, sampler=lambda s, o, r: pick.sampler(s, o, r) + 0.3)
    config = PlanningConfig(n_abstract=2, n_samples=2, timeout=60.0, max_skill_horizon=40)
    approach = BilevelPlanning(cover_env, [far, place], config)
    task = cover_env.task(0, 7, False)
    outcome = solve_task(approach, task, 0, cover_env, 60.0, np.random.default_rng(0))
    assert not outcome.solved and outcome.reason == "refinement_failed"
    e = json.loads(json.dumps(outcome.to_json()))["explanation"]
    assert e["abstract_plans"] == len(e["skeletons"]) >= 1
    first = e["skeletons"][0]["steps"][0]
    assert first["successes"] == 0 and sum(first["failures"].values()) == 2
    report = EvalReport("cover", "bpns", "BPNS", config, (outcome,), 7)
    text = "\n".join(explain_lines(report))
    assert "BPNS, task 0: refinement_failed" in text and "plan 1 (exhausted)" in text
    assert "reasons:" in text


def test_summary_line_names_the_task_distribution_it_was_measured_on() -> None:
    from bpns.evaluation.reporting import solved_line

    outcome = TaskOutcome(0, True, 1.0, None, 3, 5, 1, 1, 100, True)
    eval_report = EvalReport("cover", "bpns", "BPNS", PlanningConfig(), (outcome,), 7)
    train_report = dataclasses.replace(eval_report, train_tasks=True)
    assert solved_line(eval_report) == "BPNS: solved 1/1 cover eval tasks"
    assert solved_line(train_report) == "BPNS: solved 1/1 cover train tasks"
    assert train_report.to_json()["train_tasks"] is True
