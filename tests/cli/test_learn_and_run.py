"""`bpns run` end to end on Cover (demos -> learn -> eval -> table -> video), and the
learning/evaluation commands' one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import imageio.v2 as imageio
import numpy as np
import pytest

from bpns.cli import main


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    code = main(
        [
            "run",
            "--env",
            "cover",
            "--demos",
            "20",
            "--tasks",
            "3",
            "--timeout",
            "20",
            "--workers",
            "2",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    return out


def test_run_writes_demos_skills_results_and_a_video(run_dir):
    for name in ("demos.h5", "skills/skills.json", "skills/domain.pddl", "eval_solved.mp4"):
        assert (run_dir / name).is_file(), name
    results = json.loads((run_dir / "eval" / "results.json").read_text())
    assert [r["label"] for r in results] == ["BPNS", "Oracle"]
    for r in results:
        assert r["summary"]["num_tasks"] == 3 and len(r["tasks"]) == 3
    table = (run_dir / "eval" / "results.md").read_text()
    rows = [line for line in table.splitlines() if line.startswith("|")]
    assert len(rows) == 4 and "| BPNS | 20 |" in table
    assert table.startswith("World: nominal; model: nominal; execution: closed-loop")
    reader = imageio.get_reader(str(run_dir / "eval_solved.mp4"))
    frames = [f for f in reader]
    assert len(frames) > 10 and frames[-1].std() > 5


def test_skills_learned_from_twenty_demos_solve_eval_tasks(run_dir):
    bpns, oracle = json.loads((run_dir / "eval" / "results.json").read_text())
    assert bpns["num_demos"] == 20 and bpns["learning_seconds"] > 0
    assert bpns["summary"]["num_solved"] >= 2
    assert all(t["validated"] for t in bpns["tasks"] if t["solved"])
    assert oracle["summary"]["num_solved"] == 3
    # each solved task names the abstract plan it refined (Pick then Place per block)
    for t in bpns["tasks"]:
        assert bool(t["skeleton"]) == t["solved"]
        assert len(t["skeleton"]) % 2 == 0


def test_learned_cover_operators_are_pick_and_place_and_the_pddl_parses(run_dir, capsys):
    from pddl import parse_domain

    assert main(["skills", "show", str(run_dir / "skills")]) == 0
    text = capsys.readouterr().out
    assert text.startswith("2 skills learned from 20 demonstrations")
    assert "add: Holding(?block0)" in text and "add: Covers(?block0, ?target0)" in text
    domain = parse_domain(run_dir / "skills" / "domain.pddl")
    assert len(domain.actions) == 2
    assert main(["skills", "show", str(run_dir / "skills"), "--pddl"]) == 0
    assert "(:action" in capsys.readouterr().out


def test_eval_ablations_report_in_the_same_table(run_dir, capsys):
    code = main(
        [
            "eval",
            "--skills",
            str(run_dir / "skills"),
            "--approach",
            "samples1",
            "abstract1",
            "-n",
            "1",
            "--timeout",
            "30",
            "--workers",
            "1",
        ]
    )
    assert code in (0, 1)  # 1 = an approach solved nothing: allowed for one task
    out = capsys.readouterr().out
    assert "| Samples=1 | 20 |" in out and "| AbstractPlans=1 | 20 |" in out


def test_eval_records_whether_rollouts_end_in_dead_ends(run_dir, tmp_path):
    """The default ends them; --run-past-dead-ends (the paper's) is recorded as such."""
    for flag, expected in (((), True), (("--run-past-dead-ends",), False)):
        out = tmp_path / f"ends{expected}"
        argv = ["eval", "--skills", str(run_dir / "skills"), "-n", "1", "--workers", "1"]
        code = main([*argv, "--timeout", "30", "--out", str(out), *flag])
        assert code in (0, 1)
        planning = json.loads((out / "results.json").read_text())[0]["planning"]
        assert planning["end_at_dead_end"] is expected


def _cli(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "bpns.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (("learn", "missing.h5", "--out", "sk"), "no such demonstration file"),
        (("learn", "d.h5", "--out", "sk", "--near-goal-scale", "0"), "must be > 0 or 'off'"),
        (("learn", "d.h5", "--out", "sk", "--near-goal-scale", "x"), "--near-goal-scale"),
        (("learn", "d.h5", "--out", "sk", "--input-margin", "-1"), "--input-margin"),
        (("learn", "d.h5", "--out", "sk", "--baseline-seed", "3"), "add --baselines"),
        (("skills", "show", "nowhere"), "not a skills directory"),
        (("eval", "--approach", "oracle"), "pass --env (or --skills)"),
        (("eval", "--env", "cover"), "learned approaches need --skills"),
        (("eval", "--env", "nope", "--approach", "oracle"), "unknown environment 'nope'"),
        (("eval", "--env", "cover", "--approach", "magic"), "invalid choice: 'magic'"),
        (("eval", "--env", "cover", "--approach", "oracle", "--timeout", "0"), "> 0"),
    ],
)
def test_bad_learning_and_eval_input_is_one_line(tmp_path, args, message):
    proc = _cli(*args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "sk").exists()


def test_learning_settings_come_from_the_environment_unless_given(run_dir, tmp_path, cover_env):
    from bpns.cli import build_parser
    from bpns.cli.learn import learning_config_from

    def learned_config(*extra: str) -> dict:  # what `bpns learn` writes in skills.json
        out = tmp_path / "sk"
        args = ["learn", str(run_dir / "demos.h5"), "--limit", "4", "--out", str(out)]
        assert main([*args, "--overwrite", *extra]) == 0
        return json.loads((out / "skills.json").read_text())["config"]

    def config(*extra: str):  # the same arguments' settings, without learning
        argv = ["learn", str(run_dir / "demos.h5"), "--out", str(tmp_path / "unused"), *extra]
        args = build_parser().parse_args(argv)
        return learning_config_from(args, cover_env)

    cover = learned_config()  # Cover declares contact settling and correlated draws
    assert cover["settle_steps"] == 4 and cover["near_goal_scale"] is None
    assert cover["correlated_subgoal_noise"] is True
    assert cover["anchor_parameters"] is True
    nets = ("policy", "generator", "classifier")
    assert all(cover[n]["input_margin"] == 0.1 for n in nets)
    flags = ("--near-goal-scale", "0.02", "--no-anchor", "--settle-steps", "2")
    given = learned_config(*flags, "--input-margin", "0.3")
    assert given["near_goal_scale"] == 0.02 and given["anchor_parameters"] is False
    assert given["settle_steps"] == 2
    assert all(given[n]["input_margin"] == 0.3 for n in nets)
    assert config().near_goal_scale is None and config().settle_steps == 4
    assert config("--near-goal-scale", "off").near_goal_scale is None
    assert all(getattr(config("--input-margin", "off"), n).input_margin is None for n in nets)
    assert config("--subgoal-noise", "independent").correlated_subgoal_noise is False
    assert config("--subgoal-noise", "correlated").correlated_subgoal_noise is True


def test_learn_with_corrections_retrains_policies_and_records_how(run_dir, tmp_path, capsys):
    """`bpns learn --corrections`: the demonstrations' tasks replayed by the learned skills
    in perturbed worlds, the oracle's labels learned; the record beside the skills, a
    line in the summary and in `bpns skills show`; samplers and operators unchanged."""
    demos = str(run_dir / "demos.h5")
    plain, corrected = tmp_path / "plain", tmp_path / "corrected"
    assert main(["learn", demos, "--limit", "4", "--out", str(plain)]) == 0
    args = ["learn", demos, "--limit", "4", "--out", str(corrected)]
    flags = ["--corrections", "latency=1", "--correction-rounds", "1", "--keep-last-round"]
    assert main([*args, *flags]) == 0
    out = capsys.readouterr().out
    assert "corrections round 1: " in out and " rollouts completed every segment" in out
    record = json.loads((corrected / "corrections.json").read_text())
    assert record["worlds"] == "latency=1" and record["expert"] == "oracle"
    assert record["relabel"] is True  # the oracle labels the demonstrations' states too
    assert record["keep"] == "last"
    (only,) = record["per_round"]
    assert only["rollouts"] == 4 and sum(only["corrections"].values()) > 0
    index = {p.name: json.loads((p / "skills.json").read_text()) for p in (plain, corrected)}
    assert index["plain"]["skills"] == index["corrected"]["skills"]  # the same operators

    def same(name: str | None) -> bool:  # the same weights in both directories
        if name is None:
            return True
        a, b = np.load(plain / name), np.load(corrected / name)
        return a.files == b.files and all(np.array_equal(a[k], b[k]) for k in a.files)

    entries = index["plain"]["skills"]
    assert all(same(e["sampler"]) for e in entries)
    changed = [e["name"] for e in entries if not same(e["policy"])]
    assert changed and set(n for n, k in only["corrections"].items() if k > 0) <= set(changed)
    assert main(["skills", "show", str(corrected)]) == 0
    assert "policies retrained on " in capsys.readouterr().out
    assert not (plain / "corrections.json").exists()


def test_a_damaged_skills_directory_is_reported_not_raised(run_dir, tmp_path):
    import shutil

    broken = tmp_path / "skills"
    shutil.copytree(run_dir / "skills", broken)
    next(broken.glob("*.policy.npz")).write_bytes(b"not a zip file")
    proc = _cli("skills", "show", str(broken))
    assert proc.returncode == 2 and "damaged skills directory" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_learned_policy_with_nan_weights_fails_its_samples_not_the_planner(run_dir, cover_env):
    import dataclasses

    import numpy as np

    from bpns.learning.artifacts.skills_dir import load_skills
    from bpns.learning.policies import LearnedPolicy
    from bpns.nets.mlp import MLPParams
    from bpns.planning.bilevel import plan
    from bpns.planning.config import PlanningConfig

    learned = load_skills(run_dir / "skills", cover_env.predicates, cover_env.types)
    broken = []
    for skill in learned.skills:
        p = skill.policy.params
        nan_params = MLPParams(
            tuple(np.full_like(w, np.nan) for w in p.weights),
            p.biases,
            p.input_mean,
            p.input_std,
            p.output_mean,
            p.output_std,
        )
        policy = LearnedPolicy(skill.policy.dims, nan_params, skill.policy.use_subgoals)
        broken.append(dataclasses.replace(skill, policy=policy))
    config = PlanningConfig(n_samples=3, n_abstract=2, timeout=30.0)
    result = plan(cover_env.task(0, 0, False), broken, cover_env, config, np.random.default_rng(0))
    assert not result.success and str(result.reason) == "refinement_failed"
    failures = dict(result.stats.sample_failures)
    failures.pop("nogood", None)  # later skeletons' first step: refuted without sampling
    assert failures == {"policy_nonfinite": result.stats.samples_drawn}
    assert result.stats.sim_steps == 0


def test_run_with_perturb_and_corrections_adds_a_perturbed_table_beside_the_nominal_one(
    tmp_path, capsys
):
    out = tmp_path / "r"
    argv = ["run", "--env", "cover", "--approach", "oracle", "--demos", "3", "--tasks", "2"]
    argv += ["--workers", "1", "--out", str(out), "--perturb", "moderate"]
    argv += ["--corrections", "latency=1", "--correction-rounds", "1"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "in moderate worlds (closed loop)" in printed and "corrections round 1: " in printed
    assert (out / "skills" / "corrections.json").is_file()
    (nominal,) = json.loads((out / "eval" / "results.json").read_text())
    (perturbed,) = json.loads((out / "eval_perturbed" / "results.json").read_text())
    assert nominal["worlds"] == "nominal" and perturbed["worlds"] == "moderate"
    assert [t["index"] for t in perturbed["tasks"]] == [t["index"] for t in nominal["tasks"]]
    assert all(t["world"]["latency"] in (0, 1) for t in perturbed["tasks"])
    table = (out / "eval_perturbed" / "results.md").read_text()
    assert table.startswith("World: moderate; model: nominal; execution: closed-loop")
    assert (out / "eval_perturbed_solved.mp4").is_file()
    # the perturbed table is split by the world each task met; the nominal one is not
    assert "Solved by the world each task met" in table and "| mass_scale | " in table
    assert "Solved by the world" not in (out / "eval" / "results.md").read_text()
    page = (out / "eval_perturbed" / "report.html").read_text()
    assert '<table class="world-split">' in page and "<td>mass_scale</td>" in page
    assert "world-split" not in (out / "eval" / "report.html").read_text()
