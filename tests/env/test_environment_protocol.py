"""Contracts every registered environment keeps, whatever its domain."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import mj_envs  # noqa: F401  (selects the GL backend before mujoco loads)
from bpns.env.environment import observation_of, perturbed
from bpns.env.perturbations import Perturbation
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


@pytest.mark.parametrize("name", environment_names())
def test_declared_perturbed_physics_changes_what_policies_see_and_nominal_does_not(name):
    env = make_env(name)
    noisy = perturbed(env, Perturbation(obs_noise=0.01, seed=1))
    state = noisy.task(0, 0, True).init
    seen = observation_of(noisy)(state)
    assert seen.sim is state.sim  # the simulation itself is untouched
    assert any(not np.array_equal(seen.data[o], state.data[o]) for o in state.data)
    assert observation_of(env)(state) is state
