"""``--eval-set`` and ``--objects`` (issue 38): bad choices are one ``bpns: error:`` line
before any work; an evaluation on the large set records it in results.json and its
rollouts file, whose tasks rebuild and replay exactly."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from bpns.env.environment import eval_environment
from bpns.env.object_counts import PAPER_SET, EvalSet
from bpns.evaluation.evaluate import EvalSpec, evaluate, markdown_table
from bpns.evaluation.reporting import write_results
from bpns.evaluation.rollout_files import RolloutsFile, replay_rollouts, rollouts_name
from bpns.planning.config import planning_config_for
from tests.cli_probe import error_line

EVAL = ["eval", "--env", "cover", "--approach", "oracle", "-n", "1", "--workers", "1"]
RUN = ["run", "--env", "cover", "--demos", "1", "--tasks", "1", "--workers", "1"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--objects", "block=99"], "--objects: block=99: cover scenes hold 1..4 block objects"),
        (["--objects", "button=6"], "no object kind 'button'; kinds: block"),
        (["--objects", "block"], "expected KIND=N or KIND=LO:HI"),
        (["--objects", "block=4:3"], "low 4 exceeds high 3"),
        (["--eval-set", "huge"], "no eval set 'huge'; known: paper, large"),
        (["--eval-set", "large", "--train"], "choose eval tasks: drop them or --train"),
    ],
)
def test_bad_eval_sets_are_one_error_line_before_any_work(argv, message, capsys, tmp_path):
    for base in (EVAL, [*RUN, "--out", str(tmp_path / "r")]):
        if "--train" in argv and base is not EVAL:
            continue  # bpns run has no --train
        line = error_line([*base, *argv], capsys)
        assert message in line
    assert not (tmp_path / "r").exists()


def test_stick_button_refuses_more_buttons_than_its_scenes_hold(capsys):
    argv = ["eval", "--env", "stick_button", "--approach", "oracle", "--objects", "button=99"]
    assert "button=99: stick_button scenes hold 1..8 button objects" in error_line(argv, capsys)


@pytest.fixture(scope="module")
def large_eval(cover_env, tmp_path_factory):
    spec = EvalSpec(
        "cover",
        "oracle",
        planning_config_for(cover_env, timeout=60.0),
        task_seed=3,
        eval_set=EvalSet("large"),
    )
    report = evaluate(spec, 1)
    out = tmp_path_factory.mktemp("large")
    write_results(out, [report], markdown_table([report]), cover_env)
    return report, out


def test_results_and_rollouts_record_the_eval_set(large_eval):
    report, out = large_eval
    (saved,) = json.loads((out / "results.json").read_text())
    assert (saved["eval_set"], saved["objects"]) == ("large", "")
    assert RolloutsFile.read(out / rollouts_name("oracle")).eval_set == EvalSet("large")


def test_a_task_rebuilt_from_the_rollouts_file_is_the_evaluated_one(cover_env, large_eval):
    report, out = large_eval
    path = out / rollouts_name("oracle")
    f = RolloutsFile.read(path)
    (row,) = f.rows
    demo = f.demonstration(cover_env, row)
    rebuilt = eval_environment(cover_env, f.eval_set).task(row.task, report.task_seed, False)
    assert sum(o.type.name == "block" for o in rebuilt.init.objects) >= 3
    assert demo.task.init.sim.world.xml == rebuilt.init.sim.world.xml
    assert np.array_equal(demo.states[0].sim.flat, rebuilt.init.sim.flat)
    assert report.outcomes[0].solved
    assert replay_rollouts(cover_env, path).ok


def test_a_rollouts_file_without_an_eval_set_means_paper(large_eval, tmp_path):
    _, out = large_eval
    old = tmp_path / "old.h5"
    old.write_bytes((out / rollouts_name("oracle")).read_bytes())
    with h5py.File(old, "a") as h5:
        del h5.attrs["eval_set"]
    assert RolloutsFile.read(old).eval_set == PAPER_SET
