"""The second worked example package (examples/bpns_drawer): the plugin is found by its
name, keeps the environment contract, its demonstrator solves tasks whose demos replay
exactly, and its oracle skills solve a task through the bilevel planner.

`make test` installs the example (`pip install --no-deps -e examples/bpns_drawer`); where
it is not installed (nor on the path) the tests are skipped, saying so.
"""

from __future__ import annotations

import numpy as np
import pytest

import mj_envs  # noqa: F401
from bpns.approaches.bilevel import oracle_skills
from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demo_attempts import attempt_demonstration
from bpns.data.demos import replay
from bpns.env.registry import environment_names, make_environment
from bpns.planning.bilevel import plan
from bpns.planning.config import planning_config_for
from bpns.workflow.contract import check_environment

pytestmark = pytest.mark.skipif(
    "drawer" not in environment_names(),
    reason="the drawer example is not installed: pip install --no-deps -e examples/bpns_drawer",
)


@pytest.fixture(scope="module")
def drawer():
    return make_environment("drawer")


def test_drawer_plugin_found_by_name(drawer):
    from bpns_drawer.env import DrawerEnv

    assert isinstance(drawer, DrawerEnv)
    assert drawer.name == "drawer"


def test_drawer_keeps_the_contract(drawer):
    # what `bpns check-env drawer --tasks 2` checks, Gymnasium's check_env included
    violations = check_environment(drawer, n_tasks=2)
    assert violations == [], [str(v) for v in violations]


def test_drawer_demonstrator_solves_tasks_and_replays_exactly(drawer, tmp_path):
    attempts = [attempt_demonstration(drawer, drawer.task(i, 0, True), [0, i]) for i in range(2)]
    assert all(a.solved for a in attempts), [a.explain() for a in attempts if not a.solved]
    path = tmp_path / "drawer.h5"
    save_demonstrations(path, drawer, [a.demo for a in attempts])
    demos = load_demonstrations(path, drawer)
    assert len(demos) == 2
    replays = [replay(drawer, d, i) for i, d in enumerate(demos)]
    assert all(r.exact and r.goal_reached for r in replays), [r.max_state_diff for r in replays]


def test_drawer_oracle_skills_solve_a_task_through_the_planner(drawer):
    task = drawer.task(0, 0, False)
    config = planning_config_for(drawer, timeout=30.0)
    result = plan(task, oracle_skills(drawer), drawer, config, np.random.default_rng([0, 0]))
    assert result.success, result.reason
    steps = [op.operator.name for op in result.skeleton.operators]
    assert steps == ["GraspHandle", "OpenDrawer", "Pick", "PlaceInDrawer", "GraspHandle",
                     "CloseDrawer"]  # fmt: skip
    state = task.init  # the plan's actions, simulated again, reach the goal
    for action in result.actions:
        state = drawer.simulate(state, action)
    assert all(atom.holds(state) for atom in task.goal)
