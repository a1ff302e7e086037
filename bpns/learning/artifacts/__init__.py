"""A skills directory on disk: writing and reading it (:mod:`.skills_dir`), checks on its
untrusted content (:mod:`.checks`), the operators as PDDL (:mod:`.pddl`) and a directory
bound to its environment (:mod:`.learned`)."""

from bpns.learning.artifacts.skills_dir import (
    ArtifactError,
    describe,
    load_skills,
    save_skills,
    saved_env_name,
)

__all__ = ["ArtifactError", "describe", "load_skills", "save_skills", "saved_env_name"]
