"""Load a skills directory together with the environment it was learned in."""

from __future__ import annotations

import os

from bpns.env.environment import Environment
from bpns.env.registry import make_environment
from bpns.learning.artifacts.skills_dir import ArtifactError, load_skills, saved_env_name
from bpns.learning.given import given_skills_of
from bpns.learning.pipeline import LearnedSkills


def load_learned(
    directory: str | os.PathLike, env_name: str | None = None
) -> tuple[Environment, LearnedSkills]:
    """(environment, skills) of ``directory``; the environment is ``env_name`` or the one
    the directory records. Raises ``ArtifactError`` (a bad directory, or no recorded
    environment and none given) or ``bpns.env.registry.UnknownEnvironmentError``."""
    name = env_name or saved_env_name(directory)
    if name is None:
        raise ArtifactError(f"{directory} does not record its environment; pass --env")
    env = make_environment(name)
    return env, load_skills(directory, env.predicates, env.types, given_skills_of(env))
