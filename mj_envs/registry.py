"""Environment names -> classes for code inside mj_envs (bpns uses entry points)."""

from __future__ import annotations

from collections.abc import Callable

from bpns.registry import UnknownEnvironmentError
from mj_envs.base import MujocoEnv
from mj_envs.coffee import CoffeeEnv
from mj_envs.cover import CoverEnv
from mj_envs.doors.env import DoorsEnv
from mj_envs.stick_button import StickButtonEnv

ENVIRONMENTS: dict[str, Callable[[], MujocoEnv]] = {
    "coffee": CoffeeEnv,
    "cover": CoverEnv,
    "doors": DoorsEnv,
    "stick_button": StickButtonEnv,
}


def make_env(name: str) -> MujocoEnv:
    try:
        factory = ENVIRONMENTS[name]
    except KeyError:
        raise UnknownEnvironmentError(
            f"unknown environment {name!r}; known: {', '.join(sorted(ENVIRONMENTS))}"
        ) from None
    return factory()
