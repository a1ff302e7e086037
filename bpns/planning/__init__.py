"""Bilevel planning with neuro-symbolic skills (paper §5).

- :mod:`~bpns.planning.strips`: grounding with relaxed reachability, bitmask states.
- :mod:`~bpns.planning.heuristics`: hAdd, hMax, hFF, LM-cut as callables ``h(state)``.
- :mod:`~bpns.planning.search`: lazy top-k skeleton generator, strategy = ordering function.
- :mod:`~bpns.planning.refinement`: backtracking sampling + simulation of one skeleton.
- :mod:`~bpns.planning.bilevel`: ``plan(task, skills, env, config, rng)``.
"""

from bpns.execution.failures import FailureReason
from bpns.planning.bilevel import PlanningStats, PlanResult, plan
from bpns.planning.config import PlanningConfig
from bpns.planning.heuristics import HFF, HAdd, Heuristic, HMax, LMCut, make_heuristic
from bpns.planning.refinement import RefinementResult, RefinementStats, refine
from bpns.planning.search import (
    STRATEGIES,
    AbstractPlan,
    SearchStats,
    astar,
    gbfs,
    skeletons,
    uniform_cost,
)
from bpns.planning.strips import GroundProblem, SearchTimeout, ground

__all__ = [
    "STRATEGIES",
    "AbstractPlan",
    "FailureReason",
    "GroundProblem",
    "HAdd",
    "HFF",
    "HMax",
    "Heuristic",
    "LMCut",
    "PlanResult",
    "PlanningConfig",
    "PlanningStats",
    "RefinementResult",
    "RefinementStats",
    "SearchStats",
    "SearchTimeout",
    "astar",
    "gbfs",
    "ground",
    "make_heuristic",
    "plan",
    "refine",
    "skeletons",
    "uniform_cost",
]
