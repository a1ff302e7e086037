"""Bilevel planning (paper Alg. 1) as an approach, with learned or oracle skills, and
the paper's rows that use it: BPNS, Oracle, and the ablations Samples=1 and
AbstractPlans=1 (planner settings of the same learned skills)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.acting.replanning import ClosedLoopPlanner, ClosedLoopResult, world_run
from bpns.approaches.base import (
    Approach,
    ApproachEntry,
    NoOracleSkillsError,
    SkillSource,
    Solution,
    open_loop,
    with_timeout,
)
from bpns.env.environment import Environment
from bpns.execution.rollouts import REACHED, Rollout, rollout_of
from bpns.learning.artifacts.skills_dir import load_skills
from bpns.learning.given import given_skills_of
from bpns.planning.bilevel import PlanningStats, PlanResult, plan
from bpns.planning.config import PlanningConfig
from bpns.structs import Skill, Task


class BilevelPlanning(Approach):
    """Plan each task with ``skills`` by bilevel planning under ``config``."""

    def __init__(self, env: Environment, skills: Sequence[Skill], config: PlanningConfig):
        self.env = env
        self.skills = list(skills)
        self.config = config

    def solve(self, task: Task, rng: np.random.Generator, timeout: float) -> Solution:
        result = plan(task, self.skills, self.env, with_timeout(self.config, timeout), rng)
        s = result.stats
        return Solution(
            success=result.success,
            actions=result.actions,
            reason=result.reason,
            skeleton=(
                tuple(str(op) for op in result.skeleton.operators)
                if result.success and result.skeleton is not None
                else ()
            ),
            nodes_created=s.nodes_created,
            abstract_plans=s.abstract_plans_tried,
            samples=s.samples_drawn,
            sim_steps=s.sim_steps,
            details=result,
            explanation=None if result.success else planning_explanation(result.stats),
            rollout=_rollout(result, np.asarray(self.env.action_low).size),
        )

    def solve_in_world(
        self,
        task: Task,
        model: Environment,
        world: Environment,
        rng: np.random.Generator,
        timeout: float,
        execution: ExecutionConfig,
    ) -> Solution:
        """Closed loop (:mod:`bpns.acting.replanning`): plan in ``model``, execute in
        ``world`` step by step, repair the plan on divergence; open loop otherwise."""
        if not execution.closed_loop:
            return open_loop(self, task, model, world, rng, timeout)
        deadline = time.monotonic() + timeout
        config = with_timeout(self.config, timeout)
        planner = ClosedLoopPlanner(self.skills, model, config, execution, planning_explanation)
        out = planner.run(world_run(world, task, config, deadline, execution), rng, deadline)
        return closed_loop_solution(out)


def closed_loop_solution(out: ClosedLoopResult) -> Solution:
    """A :class:`Solution` of what the closed loop did: the world's actions and rollout."""
    run, s = out.world, out.stats
    rollout = run.rollout()
    if not run.actions and s.furthest is not None:  # nothing reached the world
        rollout = dataclasses.replace(s.furthest, events=rollout.events)
    actions = run.action_array()
    return Solution(
        success=out.success,
        actions=actions if out.success else np.zeros((0, actions.shape[1])),
        reason=out.reason,
        skeleton=out.skeleton if out.success else (),
        nodes_created=s.nodes_created,
        abstract_plans=s.abstract_plans,
        samples=s.samples,
        sim_steps=s.model_steps + run.world_steps,
        explanation=None if out.success else (s.explanation or {"reason": str(out.reason)}),
        rollout=rollout,
        replans=s.replans,
        rerefinements=s.rerefinements,
        world_seconds=run.world_seconds,
        world_cpu_seconds=run.world_cpu_seconds,
    )


def _rollout(result: PlanResult, action_dim: int) -> Rollout | None:
    """The plan executed (solved), else the refinement attempt that got furthest."""
    if not result.success:
        return result.furthest
    if result.skeleton is None:
        return None
    ends = (*result.step_starts[1:], len(result.actions))
    return rollout_of(
        [
            (op, subgoal, result.actions[start:end], REACHED)
            for op, subgoal, start, end in zip(
                result.skeleton.operators, result.subgoals, result.step_starts, ends, strict=True
            )
        ],
        action_dim,
    )


def planning_explanation(stats: PlanningStats) -> dict:
    """Why planning failed: failures by reason, and the first skeletons step by step."""
    return {
        "abstract_plans": stats.abstract_plans_tried,
        "failures": {str(r): n for r, n in stats.sample_failures},
        "skeletons": [a.to_json() for a in stats.attempts],
    }


def oracle_skills(env: Environment) -> list[Skill]:
    """The environment's hand-written skills."""
    make = env.capabilities.oracle_skills
    if make is None:
        raise NoOracleSkillsError(f"environment {env.name!r} declares no oracle skills")
    return list(make())


def learned_skills(env: Environment, skills_dir: str | Path) -> list[Skill]:
    """The skills saved in ``skills_dir``, bound to ``env``'s predicates and types."""
    return list(load_skills(skills_dir, env.predicates, env.types, given_skills_of(env)).skills)


def _with_learned(env: Environment, config: PlanningConfig, skills_dir: Path | None) -> Approach:
    assert skills_dir is not None  # ApproachEntry.make checks it
    return BilevelPlanning(env, learned_skills(env, skills_dir), config)


def _with_oracle(env: Environment, config: PlanningConfig, skills_dir: Path | None) -> Approach:
    return BilevelPlanning(env, oracle_skills(env), config)


def _one_sample(config: PlanningConfig) -> PlanningConfig:
    return dataclasses.replace(config, n_samples=1)


def _one_plan(config: PlanningConfig) -> PlanningConfig:
    return dataclasses.replace(config, n_abstract=1)


BPNS = ApproachEntry(
    "bpns", "BPNS", "learned skills, bilevel planning", SkillSource.LEARNED, _with_learned
)
ORACLE = ApproachEntry(
    "oracle", "Oracle", "hand-written skills, same planner", SkillSource.ORACLE, _with_oracle
)
SAMPLES1 = ApproachEntry(
    "samples1",
    "Samples=1",
    "BPNS with one subgoal sample per step (no backtracking over samples)",
    SkillSource.LEARNED,
    _with_learned,
    _one_sample,
)
ABSTRACT1 = ApproachEntry(
    "abstract1",
    "AbstractPlans=1",
    "BPNS refining only the first abstract plan",
    SkillSource.LEARNED,
    _with_learned,
    _one_plan,
)
