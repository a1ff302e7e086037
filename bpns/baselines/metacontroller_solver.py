"""The GNN Meta solving loop (paper appendix, "GNN Meta"): a learned metacontroller
instead of AI planning in the outer loop of bilevel planning.

Repeat until the goal holds: ask the metacontroller for the next ground skill given
(state, abstract state, goal); draw that skill's subgoal and roll it out in the
simulator up to ``max_samples`` times until the operator's predicted next abstract state
holds (its atoms hold and its deleted atoms do not); continue from there. Fail when
nothing is applicable, every sample fails, the task horizon or ``max_skills`` is
reached, or the deadline passes. No backtracking, no second choice of skill.

Skills without subgoals (No-Subgoal skills, ``CurrentStateSampler``) get one rollout
per step: their rollout is deterministic, so a second one would repeat the first.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.abstraction import abstract
from bpns.baselines import result as R
from bpns.baselines.result import BaselineResult
from bpns.baselines.skill_execution import RolloutLimits, execute_skill
from bpns.environment import Environment
from bpns.learning.gnn_meta import GNNMetacontroller
from bpns.learning.samplers import CurrentStateSampler
from bpns.structs import Predicate, Skill, Task


@dataclass(frozen=True)
class MetaSolveConfig:
    max_samples: int = 100  # paper: up to 100 subgoal samples per skill
    max_skills: int = 100  # most skills executed in one task
    limits: RolloutLimits = field(default_factory=RolloutLimits)

    def __post_init__(self) -> None:
        if self.max_samples < 1 or self.max_skills < 1:
            raise ValueError(f"invalid MetaSolveConfig {self}")


def solve_with_metacontroller(
    env: Environment,
    task: Task,
    rng: np.random.Generator,
    deadline: float | None,
    metacontroller: GNNMetacontroller,
    skills: Sequence[Skill],
    predicates: Collection[Predicate],
    config: MetaSolveConfig | None = None,
) -> BaselineResult:
    """Solve ``task`` with ``metacontroller`` choosing among ``skills`` (matched to its
    operators by name; their operators must be equal). ``predicates``: the abstraction
    (the environment's predicates). ``deadline`` is a ``time.monotonic()`` value."""
    config = MetaSolveConfig() if config is None else config
    by_name = {s.name: s for s in skills}
    for op in metacontroller.operators:
        if op.name not in by_name or by_name[op.name].operator != op:
            raise ValueError(f"no skill for the metacontroller's operator {op.name}")
    start = time.perf_counter()
    counts: Counter = Counter()
    failures: Counter = Counter()
    choose_seconds = 0.0
    state = task.init
    atoms = abstract(state, predicates)
    actions: list[np.ndarray] = []
    reason: str | None = None
    while not task.goal_holds(atoms):
        if deadline is not None and time.monotonic() >= deadline:
            reason = R.TIMEOUT
            break
        if counts["skills"] >= config.max_skills:
            reason = R.MAX_SKILLS
            break
        t0 = time.perf_counter()
        ground = metacontroller.choose(state, atoms, task.goal)
        choose_seconds += time.perf_counter() - t0
        if ground is None:
            reason = R.NO_APPLICABLE_SKILL
            break
        skill = by_name[ground.name]
        expected = ground.apply(atoms)
        must_hold = tuple(ground.add_effects & expected) + tuple(expected - ground.add_effects)
        must_not_hold = tuple(ground.delete_effects - expected)
        tries = 1 if isinstance(skill.sampler, CurrentStateSampler) else config.max_samples
        run = None
        step_failures: Counter = Counter()
        for _ in range(tries):
            counts["samples"] += 1
            try:
                subgoal = np.asarray(skill.sampler(state, ground.objects, rng), dtype=np.float64)
            except Exception:  # a learned sampler must never crash solving  # noqa: BLE001
                failures["sampler_error"] += 1
                continue
            if not np.isfinite(subgoal).all():
                failures["sampler_nonfinite"] += 1
                continue
            run = execute_skill(
                env,
                skill,
                ground,
                subgoal,
                state,
                must_hold,
                must_not_hold,
                task.horizon - len(actions),
                deadline,
                config.limits,
            )
            counts["sim_steps"] += len(run.actions)
            if run.success:
                break
            failures[run.reason] += 1
            step_failures[run.reason] += 1
            if run.reason == R.TIMEOUT:
                break
        if run is None or not run.success:
            if step_failures[R.TIMEOUT]:
                reason = R.TIMEOUT
            elif step_failures[R.TASK_HORIZON] == sum(step_failures.values()):
                reason = R.TASK_HORIZON  # every sample ran out of the task's steps
            else:
                reason = R.SUBGOALS_EXHAUSTED
            break
        counts["skills"] += 1
        actions.extend(run.actions)
        state = run.states[-1]
        atoms = abstract(state, predicates)
    stats = {
        **{k: float(v) for k, v in counts.items()},
        **{f"failed_{k}": float(v) for k, v in failures.items()},
        "choose_seconds": choose_seconds,
        "seconds": time.perf_counter() - start,
    }
    act = np.array(actions, dtype=np.float64).reshape(len(actions), len(env.action_low))
    return BaselineResult(reason is None, act, reason, stats)
