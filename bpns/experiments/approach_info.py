"""The one place where experiments read the approach registry.

Experiments name approaches and need five facts about each: whether it plans with
skills learned from demonstrations (so its eval cells depend on a skills cell and on a
demo count), whether it can run on a given environment, how it adjusts the
environment's planning settings, how long learning what it uses took, and its label in
tables and figures. Everything else
goes through ``bpns.evaluation.evaluate`` by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from bpns.approaches import SkillSource, get_approach
from bpns.approaches import approach_names as _registered
from bpns.planning.config import PlanningConfig

if TYPE_CHECKING:
    from bpns.env.environment import Environment


def approach_names() -> tuple[str, ...]:
    return tuple(_registered())


def uses_learned_skills(name: str) -> bool:
    return get_approach(name).skills is SkillSource.LEARNED


def needs_baselines(name: str) -> bool:
    """Learned beside the skills by ``bpns learn --baselines`` (the paper's baselines)."""
    return get_approach(name).needs_baselines


def uses_environment_skills(name: str) -> bool:
    """Plans with the environment's hand-written skills (``capabilities.oracle_skills``)."""
    return get_approach(name).skills is SkillSource.ORACLE


def available_on(name: str, env: Environment) -> bool:
    """Can ``name`` run on ``env``? Approaches with hand-written skills need the
    environment to declare them."""
    return not uses_environment_skills(name) or env.capabilities.has_oracle_skills


def planning_config(name: str, base: PlanningConfig) -> PlanningConfig:
    return get_approach(name).planning_config(base)


def label(name: str) -> str:
    return get_approach(name).label


def learning_seconds(name: str, skills_result: Mapping[str, Any]) -> float | None:
    """Seconds spent learning what ``name`` uses, from the result of the skills cell it
    used (its per-stage and per-baseline seconds; see ``ApproachEntry.learning_seconds``).
    GNN BC trains on the demonstrations alone, so it is not charged for the BPNS skills
    stored beside it."""
    return get_approach(name).learning_seconds(
        skills_result.get("stage_seconds", {}), skills_result.get("baseline_seconds", {})
    )
