"""Rollouts as data: every evaluated task, solved or failed, is kept in a rollouts file
(the demonstration format plus the plan), replays exactly under the physics it ran under,
and renders offline with captions from any camera."""

from __future__ import annotations

import dataclasses
import shutil

import h5py
import imageio.v2 as imageio
import numpy as np
import pytest

from bpns.acting.world import BACK_OFF
from bpns.cli import main
from bpns.env.perturbations import Perturbation
from bpns.evaluation import reporting
from bpns.evaluation.evaluate import EvalSpec, evaluate
from bpns.evaluation.rollout_files import RolloutsFile, replay_rollouts, save_rollouts
from bpns.execution import video
from bpns.execution.rollouts import REACHED, PlanStep, outcome_caption, step_captions
from bpns.execution.video import VideoError, draw_caption, render_rollout
from bpns.planning.config import planning_config_for
from bpns.workflow.report import report_evaluation
from tests.evaluation.test_dead_workers import kill_a_worker_once_started

SLIPPERY = Perturbation(friction_scale=0.0)


@pytest.fixture(scope="module")
def failed_report(cover_env):
    """The oracle on one Cover task with frictionless pads: the pick succeeds (the pads
    touch), the place cannot (the block stays on the table); the closed loop finds no
    plan from there, backs off and finds none again."""
    config = dataclasses.replace(
        planning_config_for(cover_env, timeout=60.0), n_abstract=1, n_samples=1
    )
    return evaluate(EvalSpec("cover", "oracle", config, task_seed=7, perturbation=SLIPPERY), 1)


@pytest.fixture(scope="module")
def perturbed_report(cover_env):
    physics = Perturbation(
        mass_scale=1.5,
        friction_scale=0.8,
        gain_scale=0.9,
        action_noise=0.02,
        obs_noise=0.001,
        latency=1,
        seed=3,
    )
    config = planning_config_for(cover_env, timeout=60.0)
    return evaluate(EvalSpec("cover", "oracle", config, task_seed=7, perturbation=physics), 2)


def test_a_failed_bilevel_task_keeps_its_furthest_attempt(failed_report):
    (o,) = failed_report.outcomes
    assert not o.solved and o.reason == "refinement_failed"
    steps = o.rollout.steps
    assert [s.operator for s in steps] == ["Pick", "Place", BACK_OFF]
    assert steps[0].outcome == REACHED and steps[1].outcome != REACHED
    assert steps[0].start == 0 and steps[1].start > 0  # the place starts after the pick
    assert len(o.rollout.actions) > steps[1].start  # the failed place's own actions too
    assert steps[1].subgoal is not None


def test_rollouts_of_failed_and_perturbed_tasks_replay_exactly(
    cover_env, failed_report, perturbed_report, tmp_path
):
    for report in (failed_report, perturbed_report):
        path = tmp_path / f"{report.perturbation.label()}.h5"
        assert save_rollouts(path, cover_env, report) == report.num_tasks
        checked = replay_rollouts(cover_env, path)
        assert checked.ok, checked.lines()
        assert [i.solved for i, _ in checked.rows] == [o.solved for o in report.outcomes]
        f = RolloutsFile.read(path)
        assert f.perturbation == report.perturbation and f.approach == "oracle"
        for row, o in zip(f.rows, report.outcomes, strict=True):
            assert row.task == o.index and row.steps == o.rollout.steps
            demo = f.demonstration(cover_env, row)
            np.testing.assert_array_equal(demo.actions, o.rollout.actions)
    assert perturbed_report.num_solved >= 1  # solved rows are checked to reach the goal


def test_a_task_where_nothing_was_executed_is_a_one_state_row(cover_env, tmp_path):
    from bpns.evaluation.evaluate import EvalReport, TaskOutcome

    config = planning_config_for(cover_env, timeout=1.0)
    nothing = TaskOutcome(
        0, False, 0.1, "no_abstract_plan", 0, 3, 0, 0, 0, None, actions=np.zeros((0, 4))
    )
    report = EvalReport("cover", "bpns", "BPNS", config, (nothing,), task_seed=7)
    path = tmp_path / "empty.h5"
    save_rollouts(path, cover_env, report)
    f = RolloutsFile.read(path)
    demo = f.demonstration(cover_env, f.row(0))
    assert demo.actions.shape == (0, 4) and len(demo.states) == 1
    assert f.row(0).reason == "no_abstract_plan" and f.row(0).steps == ()
    assert replay_rollouts(cover_env, path).ok


def test_a_solved_rollout_is_the_validated_plan(perturbed_report):
    o = next(o for o in perturbed_report.outcomes if o.solved)
    np.testing.assert_array_equal(o.rollout.actions, o.actions)
    assert tuple(s.label for s in o.rollout.steps) == o.skeleton
    assert all(s.outcome == REACHED for s in o.rollout.steps)


def test_a_failed_rollout_renders_from_every_camera_tiled_with_its_failure(
    cover_env, failed_report, tmp_path
):
    path = tmp_path / "r.h5"
    save_rollouts(path, cover_env, failed_report)
    f = RolloutsFile.read(path)
    row = f.row(0)
    demo = f.demonstration(cover_env, row)
    mp4, png = tmp_path / "r.mp4", tmp_path / "r.png"
    n = render_rollout(
        f.environment(cover_env),
        demo.states[:12],
        row.steps,
        row.solved,
        row.reason,
        mp4,
        "all",
        320,
        240,
        png,
    )
    assert n > 0 and mp4.stat().st_size > 0
    last = imageio.imread(png)
    assert last.shape == (240, 320, 3)
    assert last[-5:].mean() < last[100:140].mean()  # the dark caption band at the bottom


def test_captions_name_the_current_skill_and_end_with_the_outcome():
    steps = (
        PlanStep("Pick", ("robot", "block0"), (0.1,), 0, REACHED),
        PlanStep("Place", ("robot", "block0", "target0"), (0.2,), 3, "skill_horizon"),
    )
    caps = step_captions(steps, 6)  # states 0..5 after actions 0..4
    assert caps[:4] == ["1/2 Pick(robot, block0)"] * 4
    assert caps[4:] == ["2/2 Place(robot, block0, target0)"] * 2
    text = outcome_caption(False, "refinement_failed", steps, 5, "friction_scale=0")
    assert "FAILED: refinement_failed [friction_scale=0]" in text
    assert "Place(robot, block0, target0) -> skill_horizon" in text
    assert outcome_caption(True, "", steps[:1], 3).startswith("SOLVED in 3 steps")


def test_a_caption_darkens_and_writes_only_its_band():
    frame = np.full((120, 160, 3), 200, dtype=np.uint8)
    out = draw_caption(frame, "Pick(robot, block0)")
    assert np.array_equal(out[:60], frame[:60])
    band = out[-20:]
    assert band.min() < 100 and band.max() > 240  # dark band, white text


def test_a_caption_too_long_for_the_frame_covers_at_most_half_of_it_and_ends_in_dots():
    frame = np.full((240, 320, 3), 200, dtype=np.uint8)
    plan = " ".join(f"Pick(robot, block{i})" for i in range(5000))  # a huge plan name
    out = draw_caption(frame, plan)
    assert out.shape == frame.shape
    assert np.array_equal(out[: 240 // 2 - 10], frame[: 240 // 2 - 10])  # top half kept
    lines = video._wrapped(plan, 10, 320 - 20, (240 // 2) // 13)
    assert len(lines) == (240 // 2) // 13 and lines[-1].endswith(" ...")
    word = video._wrapped("x" * 500, 10, 100, 50)  # a word wider than a line is cut
    assert len(word) > 1 and all(len(line) < 500 for line in word)


def test_eval_writes_rollouts_that_replay_and_render_by_task(tmp_path, capsys):
    out = tmp_path / "ev"
    args = ["eval", "--env", "cover", "--approach", "oracle", "-n", "1", "--seed", "7"]
    args += ["--timeout", "60", "--workers", "1", "--out", str(out)]
    args += ["--perturb", "latency=1", "mass_scale=1.2"]
    assert main(args) == 0
    rollouts = out / "rollouts_oracle.h5"
    assert main(["replay", str(rollouts)]) == 0
    assert "1/1 exact with the recorded outcome" in capsys.readouterr().out
    mp4 = tmp_path / "t.mp4"
    render = ["render", str(rollouts), "--task", "0", "--camera", "top", "--out", str(mp4)]
    assert main([*render, "--width", "160", "--height", "120"]) == 0
    assert mp4.stat().st_size > 0


def test_render_and_eval_refuse_a_task_they_cannot_show(tmp_path, capsys, cover_demo_file):
    assert main(["render", str(cover_demo_file), "--task", "0"]) == 2
    assert "--task needs a rollouts file" in capsys.readouterr().err
    assert main(["eval", "--env", "cover", "--approach", "oracle", "--task", "0"]) == 2
    assert "pass --video too" in capsys.readouterr().err
    assert main(["eval", "--env", "cover", "--approach", "oracle", "--perturb", "mass=2"]) == 2
    assert "unknown perturbation 'mass'" in capsys.readouterr().err


def test_doors_videos_default_to_a_camera_its_scene_has():
    from bpns.env.registry import make_environment
    from bpns.execution.video import default_camera
    from mj_envs.render import camera_names

    doors = make_environment("doors")
    assert default_camera(doors) == "follow"
    assert "follow" in camera_names(doors.task(0, 0, False).init.sim.world)
    assert default_camera(make_environment("cover")) == "overview"


def test_a_metacontroller_keeps_the_skills_it_executed_and_the_one_that_failed():
    from tests import toy_gnn
    from tests.baselines.test_baseline_approaches import _meta, _tasks

    task = _tasks(1, seed=2)[0]
    solved = _meta(toy_gnn.oracle_skills()).solve(task, np.random.default_rng(0), 60.0)
    assert solved.success
    assert tuple(s.label for s in solved.rollout.steps) == solved.skeleton
    np.testing.assert_array_equal(solved.rollout.actions, solved.actions)
    pick, place = toy_gnn.oracle_skills()
    # a pick sampler that grips 2 m beside the block: the grasp never happens
    bad = type(pick)(pick.operator, pick.policy, lambda s, o, r: s.vec(o) + [0, 0, 2.0, 0])
    failed = _meta([bad, place]).solve(task, np.random.default_rng(0), 60.0)
    assert not failed.success
    (step,) = failed.rollout.steps
    assert step.operator == pick.operator.name and step.outcome != REACHED
    assert len(failed.rollout.actions) > 0  # the last failed sample's own actions


@pytest.fixture(scope="module")
def tiny_rollouts(tmp_path_factory):
    """One oracle Cover rollout written by `bpns eval --out` (copy it before mutating)."""
    out = tmp_path_factory.mktemp("tiny_eval")
    args = ["eval", "--env", "cover", "--approach", "oracle", "-n", "1", "--timeout", "10"]
    assert main([*args, "--workers", "1", "--report-videos", "none", "--out", str(out)]) == 0
    return out / "rollouts_oracle.h5"


@pytest.mark.parametrize(
    ("group", "attribute", "where"),
    [
        ("/", "approach", "the file"),
        ("data/demo_0", "plan", "row demo_0"),
        # the world the row ran in: without it, it would replay in the nominal physics
        ("data/demo_0", "physics", "row demo_0"),
    ],
)
def test_replay_and_render_name_the_row_and_attribute_a_rollouts_file_lacks(
    tiny_rollouts, tmp_path, capsys, group, attribute, where
):
    path = tmp_path / "rollouts_oracle.h5"
    shutil.copy(tiny_rollouts, path)
    with h5py.File(path, "a") as f:
        del f[group].attrs[attribute]
    for args in (["replay", str(path)], ["render", str(path), "--task", "0"]):
        assert main(args) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert line.startswith("bpns: error: ")
        assert f"{where} lacks the attribute '{attribute}'" in line
        assert "bpns eval --out" in line


def test_a_row_of_a_file_older_than_per_task_worlds_replays_in_the_file_s_physics(
    tiny_rollouts, tmp_path
):
    path = tmp_path / "rollouts_oracle.h5"
    shutil.copy(tiny_rollouts, path)
    with h5py.File(path, "a") as f:  # as written before rows recorded their worlds
        del f.attrs["worlds"]
        del f["data/demo_0"].attrs["physics"]
        f.attrs["perturbation"] = Perturbation(mass_scale=1.5).to_json()
    (row,) = RolloutsFile.read(path).rows
    assert row.physics == Perturbation(mass_scale=1.5)


def test_a_video_past_its_rendering_deadline_stops_and_writes_nothing(
    cover_env, failed_report, tmp_path
):
    from bpns.evaluation.reporting import render_longest_solved
    from bpns.execution.video import OutOfTimeError

    mp4 = tmp_path / "late.mp4"
    with pytest.raises(OutOfTimeError):  # raised in the rendering worker, seen here
        render_longest_solved(cover_env, failed_report, mp4, 7, False, task=0, deadline=0.0)
    assert list(tmp_path.iterdir()) == []


def test_the_report_s_video_budget_bounds_a_video_under_way(
    cover_env, failed_report, tmp_path, monkeypatch
):
    from bpns.evaluation.evaluate import markdown_table
    from bpns.workflow import report_page

    deadlines = []

    def render(*args):  # a long rollout whose rendering reaches the deadline it was given
        deadlines.append(args[-1])
        raise video.OutOfTimeError("the rendering time budget ran out")

    monkeypatch.setattr(report_page, "render_longest_solved", render)
    request = report_page.PageRequest(videos="all", budget=60.0)
    page = report_page.write_eval_page(
        cover_env, [failed_report], tmp_path, markdown_table([failed_report]), 7, False, request
    )
    assert (page.videos, page.left_out) == (0, 1)
    assert len(deadlines) == 1 and deadlines[0] is not None
    assert "1 videos left out after 60 s" in (tmp_path / "report.html").read_text()
    assert not (tmp_path / "videos").exists()


def _rendering_workers_killed(monkeypatch) -> None:
    """Every rendering worker is SIGKILLed as soon as it exists (the OOM killer)."""
    real = reporting.make_pool

    def make_pool(workers, *args, **kwargs):
        pool = real(workers, *args, **kwargs)
        kill_a_worker_once_started(pool)
        return pool

    monkeypatch.setattr(reporting, "make_pool", make_pool)


def test_a_rendering_worker_killed_loses_no_results_and_leaves_no_temporaries(
    cover_env, failed_report, tmp_path, monkeypatch
):
    _rendering_workers_killed(monkeypatch)
    out = tmp_path / "eval"
    reported = report_evaluation(cover_env, [failed_report], out, seed=7)
    assert reported.page is not None and reported.page.videos == 0
    page = (out / "report.html").read_text()
    assert "videos not rendered" in page and "while the video of task 0 was unfinished" in page
    assert (out / "results.json").is_file() and (out / "rollouts_oracle.h5").is_file()
    assert not [p for p in out.rglob("*") if p.name.startswith(".")]  # no temporaries
    # a video asked for by name fails the command, after the results are in place
    again = tmp_path / "again"
    with pytest.raises(VideoError, match=f"the results were written to {again}"):
        report_evaluation(cover_env, [failed_report], again, tmp_path / "v.mp4", seed=7, task=0)
    assert (again / "results.json").is_file() and not (tmp_path / "v.mp4").exists()
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]
