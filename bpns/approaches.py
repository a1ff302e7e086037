"""The approaches compared in the paper, as (where the skills come from, planning settings).

An approach is not a class hierarchy: every approach here plans with the same bilevel
planner, and they differ only in the skills it is given and in ``PlanningConfig``. The
paper's ablations are therefore one-line entries (``Samples=1`` sets ``n_samples=1``,
``AbstractPlans=1`` sets ``n_abstract=1``). Baselines that do not plan (GNN-BC ...) would
need their own solver and are not provided.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable
from dataclasses import dataclass

from bpns.planning.config import PlanningConfig


class SkillSource(str, enum.Enum):
    LEARNED = "learned"  # skills learned from demonstrations (a skills directory)
    ORACLE = "oracle"  # the environment's hand-written skills (``env.oracle_skills()``)


@dataclass(frozen=True)
class Approach:
    name: str  # command-line name
    label: str  # name in tables (the paper's)
    skills: SkillSource
    adjust: Callable[[PlanningConfig], PlanningConfig]
    description: str

    def planning_config(self, base: PlanningConfig) -> PlanningConfig:
        return self.adjust(base)


def _same(config: PlanningConfig) -> PlanningConfig:
    return config


def _one_sample(config: PlanningConfig) -> PlanningConfig:
    return dataclasses.replace(config, n_samples=1)


def _one_plan(config: PlanningConfig) -> PlanningConfig:
    return dataclasses.replace(config, n_abstract=1)


APPROACHES: dict[str, Approach] = {
    a.name: a
    for a in (
        Approach("bpns", "BPNS", SkillSource.LEARNED, _same, "learned skills, bilevel planning"),
        Approach(
            "oracle", "Oracle", SkillSource.ORACLE, _same, "hand-written skills, same planner"
        ),
        Approach(
            "samples1",
            "Samples=1",
            SkillSource.LEARNED,
            _one_sample,
            "BPNS with one subgoal sample per step (no backtracking over samples)",
        ),
        Approach(
            "abstract1",
            "AbstractPlans=1",
            SkillSource.LEARNED,
            _one_plan,
            "BPNS refining only the first abstract plan",
        ),
    )
}


class UnknownApproachError(KeyError):
    def __str__(self) -> str:
        return str(self.args[0])


def get_approach(name: str) -> Approach:
    try:
        return APPROACHES[name]
    except KeyError:
        raise UnknownApproachError(
            f"unknown approach {name!r}; known: {', '.join(APPROACHES)}"
        ) from None
