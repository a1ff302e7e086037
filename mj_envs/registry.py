"""Environment names -> classes. The one place that knows every domain by name."""

from __future__ import annotations

from collections.abc import Callable

from mj_envs.base import MujocoEnv
from mj_envs.cover import CoverEnv

ENVIRONMENTS: dict[str, Callable[[], MujocoEnv]] = {
    "cover": CoverEnv,
}


class UnknownEnvironmentError(KeyError):
    def __str__(self) -> str:
        return str(self.args[0])


def make_env(name: str) -> MujocoEnv:
    try:
        factory = ENVIRONMENTS[name]
    except KeyError:
        raise UnknownEnvironmentError(
            f"unknown environment {name!r}; known: {', '.join(sorted(ENVIRONMENTS))}"
        ) from None
    return factory()
