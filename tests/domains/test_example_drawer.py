"""The articulated worked example (examples/bpns_drawer: open a drawer by its handle, put
a cube in, close it) against the contracts a user's task must meet: found by name, the
environment contract, a demonstrator whose demonstrations replay exactly, and oracle
skills that solve eval tasks through the planner.

`make test` installs the example (`pip install -e examples/bpns_drawer`); run alone, this
test installs it into the running virtual environment first.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import mj_envs  # noqa: F401
from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demo_attempts import attempt_demonstration
from bpns.data.demos import replay
from bpns.env.abstraction import abstract
from bpns.env.registry import environment_names, make_environment
from bpns.workflow.contract import check_environment
from bpns.workflow.demo_check import check_demonstrations

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "bpns_drawer"


def _install_example() -> None:
    if "drawer" not in environment_names():
        subprocess.run(
            [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "-e", str(EXAMPLE)],
            check=True,
        )
    if str(EXAMPLE) not in sys.path:  # an editable install's .pth is read at start-up only
        sys.path.insert(0, str(EXAMPLE))


@pytest.fixture(scope="module")
def drawer():
    _install_example()
    return make_environment("drawer")


def test_the_drawer_plugin_is_registered_and_meets_the_environment_contract(drawer):
    assert "drawer" in environment_names()
    assert check_environment(drawer, n_tasks=2, seed=0) == []


def test_the_drawer_demonstrations_open_fill_and_close_and_replay_exactly(drawer, tmp_path):
    attempts = [attempt_demonstration(drawer, drawer.task(i, 0, True), [0, i]) for i in range(3)]
    assert all(a.solved for a in attempts), [a.explain() for a in attempts if not a.solved]
    path = tmp_path / "drawer.h5"
    save_demonstrations(path, drawer, [a.demo for a in attempts])
    demos = load_demonstrations(path, drawer)
    assert all(replay(drawer, d, i).exact for i, d in enumerate(demos))
    for demo in demos:  # the goal (the cube in the drawer, the drawer closed) holds at the end
        assert demo.task.goal_holds(abstract(demo.states[-1], drawer.predicates))


def test_the_drawer_oracle_skills_solve_eval_tasks_through_the_planner(drawer):
    report = check_demonstrations(drawer, n_tasks=2, seed=0, timeout=30.0)
    oracle = [r for r in report.rows if r.who == "oracle"]
    assert len(oracle) == 2
    assert report.failed == 0, "\n".join(report.lines())
