"""The solved-task video is rendered in a fresh worker process, not in the caller: writing
an mp4 forks ffmpeg, and forking a caller that holds a thousand loaded demonstrations
failed with ENOMEM (`bpns run` at 1000 demos)."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.approaches.bilevel import BilevelPlanning, oracle_skills
from bpns.evaluation import reporting
from bpns.evaluation.evaluate import EvalReport, solve_task
from bpns.evaluation.reporting import render_longest_solved
from bpns.planning.config import PlanningConfig


def test_solved_task_video_is_rendered_outside_the_calling_process(
    cover_env, tmp_path, monkeypatch
):
    config = PlanningConfig(timeout=60.0)
    approach = BilevelPlanning(cover_env, oracle_skills(cover_env), config)
    outcome = solve_task(
        approach, cover_env.task(0, 7, False), 0, cover_env, 60.0, np.random.default_rng(0)
    )
    assert outcome.solved
    report = EvalReport("cover", "oracle", "Oracle", config, (outcome,), 7)

    def fail_here(*args, **kwargs):
        raise AssertionError("rendered in the calling process")

    monkeypatch.setattr(reporting, "render_rollout", fail_here)  # the worker imports its own
    made = render_longest_solved(cover_env, report, tmp_path / "solved.mp4", 7, False)
    if made is None:
        pytest.fail("nothing rendered")
    assert made.frames > 0 and (tmp_path / "solved.mp4").stat().st_size > 0
    assert (tmp_path / "solved.png").exists()
