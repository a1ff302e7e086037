"""The Gymnasium view passes Gymnasium's own environment checker."""

from __future__ import annotations

import gymnasium as gym
from gymnasium.utils.env_checker import check_env

import mj_envs  # noqa: F401  (registers bpns/*-v0)


def test_cover_gym_env_passes_check_env():
    env = gym.make("bpns/Cover-v0")
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert info["goal"]
