"""The paper's baselines end to end through the CLI: learned beside the skills from the
same demos (`bpns learn --baselines`), evaluated as approaches (`bpns eval --approach`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bpns.cli import main

BASELINES = ("nosubgoal", "gnn-meta", "gnn-meta-nosubgoal", "gnn-bc")


@pytest.fixture(scope="module")
def skills_with_baselines(tmp_path_factory):
    work = tmp_path_factory.mktemp("baselines")
    demos, skills = work / "demos.h5", work / "skills"
    assert main(["demos", "--env", "cover", "-n", "6", "--workers", "1", "--out", str(demos)]) == 0
    argv = ["learn", str(demos), "--out", str(skills), "--baselines", "--baseline-steps", "60"]
    assert main([*argv, "--baseline-seed", "5"]) == 0
    return skills


def test_learn_baselines_writes_the_models_and_nosubgoal_skills(skills_with_baselines):
    names = {p.name for p in skills_with_baselines.iterdir()}
    assert {"gnn_meta.npz", "gnn_bc.npz", "nosubgoal", "skills.json"} <= names
    index = json.loads((skills_with_baselines / "nosubgoal" / "skills.json").read_text())
    assert all(s["sampler"] is None for s in index["skills"])  # no subgoals, no samplers
    for model in ("gnn_meta.npz", "gnn_bc.npz"):
        with np.load(skills_with_baselines / model) as data:
            header = json.loads(str(data["meta.json"]))
        assert header["info"]["config"]["seed"] == 5  # --baseline-seed, not --seed's 0


def test_every_baseline_evaluates_as_an_approach_row(skills_with_baselines, tmp_path, capsys):
    out = tmp_path / "eval"
    argv = ["eval", "--skills", str(skills_with_baselines), "--approach", *BASELINES]
    code = main([*argv, "-n", "1", "--timeout", "5", "--workers", "1", "--out", str(out)])
    assert code in (0, 1)  # 1: some row solved nothing (few demos, few training steps)
    reports = json.loads((out / "results.json").read_text())
    assert [r["approach"] for r in reports] == list(BASELINES)
    for r in reports:
        (task,) = r["tasks"]
        assert task["solved"] or task["reason"]
    table = capsys.readouterr().out
    for label in ("BPNS No Subgoal", "GNN Meta", "GNN Meta No Subgoal", "GNN BC"):
        assert f"| {label} |" in table
    # each row is charged for what it learned: GNN Meta for its GNN on top of the BPNS
    # skills it executes, GNN BC for its GNN alone
    skills = json.loads((skills_with_baselines / "skills.json").read_text())
    pipeline = sum(t for _, t in skills["stats"]["stage_seconds"])
    learning = {r["approach"]: r["learning_seconds"] for r in reports}
    assert learning["gnn-meta"] > pipeline
    assert learning["gnn-bc"] > 0 and learning["gnn-bc"] != pytest.approx(pipeline)


def test_a_baseline_without_its_model_is_one_clear_error(tmp_path, capsys, skills_with_baselines):
    import shutil

    copy = tmp_path / "skills"
    shutil.copytree(skills_with_baselines, copy)
    (copy / "gnn_bc.npz").unlink()
    code = main(
        ["eval", "--skills", str(copy), "--approach", "gnn-bc", "-n", "1", "--workers", "1"]
    )
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--baselines" in err[0]
