"""Bilevel planning with learned neuro-symbolic skills (Silver et al., CoRL 2022).

The public API in one place::

    import bpns
    env = bpns.make_environment("cover")
    learned = bpns.learn_skills(demos, env.predicates, env.contact_predicates)
    result = bpns.plan(task, learned.skills, env, bpns.PlanningConfig(), rng)

The core structs are imported eagerly (they are what everything else is built from).
The functions are resolved on first use through a module-level ``__getattr__``
(PEP 562) only so that ``import bpns.structs`` -- which every module and every worker
process does -- does not also load learning, planning and evaluation (measured: about
+40 % import time). It hides no import cycle: each name below imports directly.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from bpns.structs import (
    Demonstration,
    GivenSkill,
    GroundAtom,
    LiftedAtom,
    Object,
    Predicate,
    Skill,
    State,
    STRIPSOperator,
    Task,
    Type,
)

if TYPE_CHECKING:
    from bpns.approaches import Approach, ApproachEntry, Solution, approach_names, get_approach
    from bpns.env.environment import Capabilities, Environment
    from bpns.env.registry import environment_names, make_environment
    from bpns.evaluation.evaluate import EvalSpec, evaluate
    from bpns.execution.failures import FailureReason
    from bpns.learning import LearnedSkills, LearningConfig, learn_skills
    from bpns.learning.artifacts.skills_dir import load_skills, save_skills
    from bpns.planning import PlanningConfig, PlanResult, plan

# public name -> module that defines it
_LAZY = {
    "make_environment": "bpns.env.registry",
    "environment_names": "bpns.env.registry",
    "Environment": "bpns.env.environment",
    "Capabilities": "bpns.env.environment",
    "learn_skills": "bpns.learning",
    "LearnedSkills": "bpns.learning",
    "LearningConfig": "bpns.learning",
    "save_skills": "bpns.learning.artifacts.skills_dir",
    "load_skills": "bpns.learning.artifacts.skills_dir",
    "plan": "bpns.planning",
    "PlanResult": "bpns.planning",
    "PlanningConfig": "bpns.planning",
    "evaluate": "bpns.evaluation.evaluate",
    "EvalSpec": "bpns.evaluation.evaluate",
    "Approach": "bpns.approaches",
    "ApproachEntry": "bpns.approaches",
    "Solution": "bpns.approaches",
    "get_approach": "bpns.approaches",
    "approach_names": "bpns.approaches",
    "FailureReason": "bpns.execution.failures",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'bpns' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "Approach",
    "ApproachEntry",
    "Capabilities",
    "FailureReason",
    "Solution",
    "approach_names",
    "get_approach",
    "Demonstration",
    "Environment",
    "EvalSpec",
    "GivenSkill",
    "GroundAtom",
    "LearnedSkills",
    "LearningConfig",
    "LiftedAtom",
    "Object",
    "PlanResult",
    "PlanningConfig",
    "Predicate",
    "STRIPSOperator",
    "Skill",
    "State",
    "Task",
    "Type",
    "environment_names",
    "evaluate",
    "learn_skills",
    "load_skills",
    "make_environment",
    "plan",
    "save_skills",
]
