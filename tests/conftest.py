"""Shared fixtures: one Cover environment and a few seeded tasks/demos per session."""

from __future__ import annotations

import numpy as np
import pytest

import mj_envs  # noqa: F401  (selects the GL backend before mujoco loads)
from bpns.data.demos import run_demonstrator
from bpns.env.registry import make_environment as make_env


@pytest.fixture(scope="session")
def cover_env():
    return make_env("cover")


@pytest.fixture(scope="session")
def cover_demos(cover_env):
    demos = [run_demonstrator(cover_env, cover_env.task(i, 7, True), seed=[7, i]) for i in range(3)]
    assert all(d is not None for d in demos), "the oracle must solve these seeded tasks"
    return demos


@pytest.fixture
def rng():
    return np.random.default_rng(0)


@pytest.fixture(scope="session")
def cover_demo_file(tmp_path_factory, cover_env, cover_demos):
    """A valid 2-demo Cover file, written once per session (copy it before mutating)."""
    from bpns.data.datasets import save_demonstrations

    path = tmp_path_factory.mktemp("demos") / "cover2.h5"
    save_demonstrations(path, cover_env, cover_demos[:2])
    return path
