"""``bpns check-env --demo``: the demonstrator and the oracle skills on a few tasks, and
for each failure which phase failed and why."""

from __future__ import annotations

import dataclasses

import numpy as np

from bpns.cli import main
from bpns.workflow.demo_check import check_demonstrations
from mj_envs.domains.cover.env import CoverEnv
from mj_envs.oracles.phases import PhasedDemonstrator


class _StuckHover(PhasedDemonstrator):
    """Rises, then hovers for ever: its second phase never finishes."""

    max_phase_steps = 5

    def plan(self, state):
        def rise(s):
            return None  # done at once

        def hover_over_the_block(s):
            return np.zeros(4)

        return [rise, hover_over_the_block]

    def idle_action(self, state):
        return np.zeros(4)


class StuckDemonstrator(CoverEnv):
    def demonstrator(self, task, rng):
        return _StuckHover()


class ShortHorizon(CoverEnv):
    """Tasks whose horizon is too short for any demonstrator to reach the goal."""

    def sample_layout(self, rng, train):
        return dataclasses.replace(super().sample_layout(rng, train), horizon=5)


def test_a_demonstrator_stuck_in_a_phase_is_reported_with_that_phases_name():
    report = check_demonstrations(StuckDemonstrator(), n_tasks=1, timeout=5.0)
    train, evaluated, *oracle = report.rows
    for row in (train, evaluated):
        assert not row.solved
        assert "phase '_StuckHover.plan: hover_over_the_block' (2 of 2 in the plan)" in row.detail
        assert "did not finish within 5 actions" in row.detail
    assert [r.solved for r in oracle] == [True]  # the oracle skills are Cover's own
    assert report.failed == 2
    assert report.lines()[-1] == "1/3 demonstrations and oracle plans succeeded"
    assert report.lines()[0].startswith("FAILED demonstrator, train task 0: DemonstrationFailed")


def test_a_goal_the_demonstrator_cannot_reach_names_the_missing_atoms():
    report = check_demonstrations(ShortHorizon(), n_tasks=1, timeout=5.0)
    demo = report.rows[0]
    assert not demo.solved
    assert "goal not reached within the horizon (5); missing Covers(" in demo.detail


def test_an_oracle_plan_that_fails_says_why_and_what_the_planner_tried():
    report = check_demonstrations(CoverEnv(), n_tasks=1, timeout=1e-9)
    (oracle,) = [r for r in report.rows if r.who == "oracle"]
    assert not oracle.solved
    assert oracle.detail.startswith("no plan: timeout")


def test_check_env_demo_prints_a_line_per_task_and_exits_1_on_a_failure(capsys, monkeypatch):
    from bpns.cli import check_env as check_env_cli

    argv = ["check-env", "cover", "--tasks", "1", "--demos", "1", "--no-gym", "--demo"]
    assert main(argv) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "note: gym: skipped (disabled)" and "keeps the contract" in out[1]
    rows = out[2:-1]  # demonstrator on train task 0 and eval task 0, the oracle on eval 0
    assert [line.split(":")[0] for line in rows] == [
        "ok     demonstrator, train task 0",
        "ok     demonstrator, eval task 0",
        "ok     oracle, eval task 0",
    ]
    assert out[-1] == "3/3 demonstrations and oracle plans succeeded"
    monkeypatch.setattr(check_env_cli, "env_by_name", lambda name: StuckDemonstrator())
    assert main([*argv, "--timeout", "5"]) == 1
    out = capsys.readouterr().out
    assert "FAILED demonstrator, eval task 0: DemonstrationFailed: phase " in out
    assert "hover_over_the_block" in out
