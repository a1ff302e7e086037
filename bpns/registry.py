"""Find environments by name through the ``bpns.environments`` entry-point group.

bpns never imports a domain: packages declare theirs in their metadata, e.g.
``[project.entry-points."bpns.environments"] cover = "mj_envs.domains.cover.env:CoverEnv"``,
which is also how a user plugs in an environment built on their own MJCF. The entry
points are the single source of environment names (CLI, workers, Gymnasium ids).
"""

from __future__ import annotations

from importlib.metadata import entry_points

from bpns.environment import Environment, declaration_problem

GROUP = "bpns.environments"


class UnknownEnvironmentError(KeyError):
    def __str__(self) -> str:
        return str(self.args[0])


class EnvironmentDeclarationError(UnknownEnvironmentError):
    """The named environment exists but declares its optional part the old way (or not
    at all); the message names the fix. A subclass so that every caller that reports an
    unknown name as one line reports this alike."""


def environment_names() -> list[str]:
    return sorted(ep.name for ep in entry_points(group=GROUP))


def make_environment(name: str) -> Environment:
    matches = [ep for ep in entry_points(group=GROUP) if ep.name == name]
    if not matches:
        known = ", ".join(environment_names()) or "none installed"
        raise UnknownEnvironmentError(f"unknown environment {name!r}; known: {known}")
    env = matches[0].load()()
    if problem := declaration_problem(env):
        raise EnvironmentDeclarationError(problem)
    return env
