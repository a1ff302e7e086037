"""`bpns run` learns the baselines its approaches plan with (issue 24), and refuses an
impossible combination before any work."""

from __future__ import annotations

import json

import pytest

from bpns.approaches import get_approach
from bpns.cli import main
from bpns.env.environment import Capabilities
from bpns.workflow import baselines_needed

ALL = ("bpns", "nosubgoal", "gnn-meta", "gnn-meta-nosubgoal", "gnn-bc")


@pytest.mark.parametrize(
    "approaches, stages",
    [
        (("bpns", "oracle"), ()),
        (("gnn-bc",), ("gnn_bc",)),
        (("nosubgoal",), ("nosubgoal",)),
        (("gnn-meta",), ("gnn_meta",)),
        (("gnn-meta-nosubgoal",), ("gnn_meta", "nosubgoal")),
        (ALL, ("gnn_meta", "gnn_bc", "nosubgoal")),
    ],
)
def test_run_learns_exactly_the_baselines_its_approaches_use(approaches, stages):
    assert baselines_needed(get_approach(a) for a in approaches) == stages


def test_a_plugin_needing_baselines_it_does_not_name_gets_them_all():
    import dataclasses

    plugin = dataclasses.replace(get_approach("gnn-bc"), name="mine", learned_stages=None)
    assert baselines_needed([plugin]) == ("gnn_meta", "gnn_bc", "nosubgoal")


def test_run_with_every_baseline_works_end_to_end(tmp_path, capsys):
    out = tmp_path / "r"
    argv = ["run", "--env", "cover", "--approach", *ALL, "--demos", "3", "--tasks", "1"]
    argv += ["--timeout", "5", "--workers", "1", "--baseline-steps", "20", "--out", str(out)]
    code = main(argv)
    captured = capsys.readouterr()
    assert code in (0, 1), captured.err  # 1: some approach solved nothing (3 demos)
    assert "error" not in captured.err
    skills = out / "skills"
    for name in ("skills.json", "gnn_meta.npz", "gnn_bc.npz", "nosubgoal/skills.json"):
        assert (skills / name).is_file(), name
    results = json.loads((out / "eval" / "results.json").read_text())
    assert [r["label"] for r in results] == [get_approach(a).label for a in ALL]
    assert all(r["summary"]["num_tasks"] == 1 for r in results)


def test_run_learns_no_baseline_an_approach_does_not_use(tmp_path, capsys):
    out = tmp_path / "r"
    argv = ["run", "--env", "cover", "--approach", "gnn-bc", "--demos", "2", "--tasks", "1"]
    argv += ["--timeout", "5", "--workers", "1", "--baseline-steps", "10", "--out", str(out)]
    assert main(argv) in (0, 1), capsys.readouterr().err
    assert (out / "skills" / "gnn_bc.npz").is_file()
    assert not (out / "skills" / "gnn_meta.npz").exists()
    assert not (out / "skills" / "nosubgoal").exists()


class _NoOracleSkills:
    name = "plain"
    capabilities = Capabilities()  # no oracle_skills


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["--approach", "bpns", "--baseline-steps", "5"],
            "--baseline-steps applies to the baselines, and none of bpns uses one",
        ),
        (
            ["--correction-rounds", "2"],
            "--correction-rounds applies to corrections: add --corrections",
        ),
        (["--perturb", "moderat"], None),
        (["--corrections", "latency=-1"], None),
    ],
)
def test_run_refuses_flags_that_do_nothing_before_any_work(tmp_path, capsys, argv, message):
    out = tmp_path / "r"
    code = main(["run", "--env", "cover", "--out", str(out), *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert err.startswith(f"bpns: error: {message or argv[0] + ':'}")
    assert not out.exists()


def test_run_refuses_hand_written_skills_an_environment_lacks(capsys):
    from bpns.cli.common import UserError
    from bpns.cli.run import approaches_to_run

    assert [e.name for e in approaches_to_run(_NoOracleSkills(), None)] == ["bpns"]
    with pytest.raises(UserError, match="environment 'plain' declares none"):
        approaches_to_run(_NoOracleSkills(), ["bpns", "oracle"])


def test_run_collects_then_prints_the_demos_and_the_replay_check_in_that_order(tmp_path, capsys):
    from bpns.cli import build_parser
    from bpns.cli.run import collect, parse_run

    args = build_parser().parse_args(
        ["run", "--env", "cover", "--demos", "2", "--workers", "1", "--out", str(tmp_path / "r")]
    )
    assert collect(parse_run(args))
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(" ", 2)[:2] for line in lines] == [
        ["==", "demos:"],
        ["wrote", "2"],
        ["==", "replay:"],
        ["replayed", "2"],
    ]
    assert lines[-1].endswith("2/2 exact and reaching their goal")


def test_run_that_cannot_learn_from_its_demos_says_why_in_one_line(tmp_path, capsys, monkeypatch):
    import bpns.cli.run as run_command
    from bpns.workflow import CannotLearnError

    def cannot(env, demos_path, *args, **kwargs):
        raise CannotLearnError(f"cannot learn from {demos_path}: no segment with effects")

    monkeypatch.setattr(run_command, "learn_to_directory", cannot)
    out = tmp_path / "r"
    argv = ["run", "--env", "cover", "--demos", "2", "--tasks", "1", "--workers", "1"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"bpns: error: cannot learn from {out / 'demos.h5'}: no segment with effects"]
    assert (out / "demos.h5").exists()  # what was collected is kept
