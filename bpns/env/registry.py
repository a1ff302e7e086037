"""Find environments by name through the ``bpns.environments`` entry-point group.

bpns never imports a domain: packages declare theirs in their metadata, e.g.
``[project.entry-points."bpns.environments"] cover = "mj_envs.domains.cover.env:CoverEnv"``,
which is also how a user plugs in an environment built on their own MJCF. The entry
points are the single source of environment names (CLI, workers, Gymnasium ids).
"""

from __future__ import annotations

from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points
from typing import TypeVar

from bpns.env.environment import Environment, declaration_problem
from bpns.errors import BpnsError

GROUP = "bpns.environments"
T = TypeVar("T")


class UnknownEnvironmentError(BpnsError, KeyError):
    def __str__(self) -> str:
        return str(self.args[0])


class EnvironmentDeclarationError(UnknownEnvironmentError):
    """The named environment exists but declares its optional part the old way (or not
    at all); the message names the fix. A subclass so that every caller that reports an
    unknown name as one line reports this alike."""


class PluginError(BpnsError, RuntimeError):
    """An installed entry point (an environment or approach plugin) that fails to load or
    to build: its import raised, it names nothing, or constructing it raised."""


def load_plugin(ep: EntryPoint, what: str, make: Callable[[object], T]) -> T:
    """``make(ep.load())``; any exception raised by the plugin's code becomes a
    :class:`PluginError` naming the plugin, its entry point and the error (one line)."""
    try:
        return make(ep.load())
    except Exception as err:  # noqa: BLE001  plugin code may raise anything
        detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise PluginError(
            f"{what} plugin {ep.name!r} (entry point {ep.name} = {ep.value}) cannot be "
            f"loaded: {type(err).__name__}" + (f": {detail}" if detail else "")
        ) from err


def environment_names() -> list[str]:
    return sorted(ep.name for ep in entry_points(group=GROUP))


def make_environment(name: str) -> Environment:
    matches = [ep for ep in entry_points(group=GROUP) if ep.name == name]
    if not matches:
        known = ", ".join(environment_names()) or "none installed"
        raise UnknownEnvironmentError(f"unknown environment {name!r}; known: {known}")
    env = load_plugin(matches[0], "environment", lambda factory: factory())
    if problem := declaration_problem(env):
        raise EnvironmentDeclarationError(problem)
    return env
