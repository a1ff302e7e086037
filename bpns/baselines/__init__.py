"""The paper's baselines that do not plan with the bilevel planner: GNN Meta (with or
without subgoals) and GNN BC. Each is one solving function over (env, task, rng,
deadline) plus its learned model; models are learned in :mod:`bpns.learning.baselines`.
"""

from bpns.baselines.metacontroller_solver import MetaSolveConfig, solve_with_metacontroller
from bpns.baselines.policy_solver import solve_with_policy
from bpns.baselines.result import BaselineResult
from bpns.baselines.skill_execution import RolloutLimits, SkillRun, execute_skill

__all__ = [
    "BaselineResult",
    "MetaSolveConfig",
    "RolloutLimits",
    "SkillRun",
    "execute_skill",
    "solve_with_metacontroller",
    "solve_with_policy",
]
