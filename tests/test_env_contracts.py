"""Contracts every registered environment keeps, whatever its domain."""

from __future__ import annotations

import pickle

import pytest

import mj_envs  # noqa: F401  (selects the GL backend before mujoco loads)
from bpns.env.registry import environment_names
from bpns.env.registry import make_environment as make_env


@pytest.mark.parametrize("name", environment_names())
def test_tasks_and_states_pickle_so_worker_processes_can_receive_them(name):
    env = make_env(name)
    task = env.eval_tasks(1, seed=0)[0]
    clone = pickle.loads(pickle.dumps(task))
    assert {str(a) for a in clone.goal} == {str(a) for a in task.goal}
    assert [a.holds(clone.init) for a in sorted(clone.goal, key=str)] == [
        a.holds(task.init) for a in sorted(task.goal, key=str)
    ]
