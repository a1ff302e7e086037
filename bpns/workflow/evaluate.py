"""Evaluate approaches on held-out tasks: the middle of ``bpns eval`` and ``bpns run``.

Every approach named is built once in this process before any task runs, so a skills
directory that does not load, or an approach the environment cannot run, is refused
before work starts (:class:`ApproachUnavailableError`); then each is evaluated in turn.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from bpns.acting.config import CLOSED_LOOP, ExecutionConfig
from bpns.approaches import NoOracleSkillsError, SkillSource, get_approach
from bpns.baselines.learn import saved_baseline_seconds
from bpns.env.environment import Environment
from bpns.env.object_counts import PAPER_SET, EvalSet
from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.env.worlds import NOMINAL_MODEL, ModelSpec, WorldDistribution
from bpns.errors import BpnsError
from bpns.evaluation.evaluate import EvalReport, EvalSpec, TaskOutcome, evaluate
from bpns.learning.artifacts import ArtifactError
from bpns.learning.pipeline import LearnedSkills
from bpns.planning.config import PlanningConfig

# (outcomes as they finish, how many, a label) -> the same outcomes (e.g. a progress bar)
TaskProgress = Callable[[Iterator[TaskOutcome], int, str], Iterator[TaskOutcome]]


class ApproachUnavailableError(BpnsError, ValueError):
    """An approach asked for cannot be built here (its files, or the environment)."""


def _no_progress(outcomes: Iterator[TaskOutcome], total: int, label: str):
    return outcomes


@dataclass(frozen=True)
class EvalRequest:
    """Which tasks, seeds and settings every approach of one evaluation runs under."""

    num_tasks: int
    task_seed: int = 0
    planner_seed: int = 0
    train: bool = False
    validate: bool = True
    workers: int = 1
    perturbation: Perturbation | WorldDistribution = NOMINAL  # the world, fixed or per task
    model: ModelSpec = NOMINAL_MODEL  # what the planner simulates
    execution: ExecutionConfig = CLOSED_LOOP
    eval_set: EvalSet = PAPER_SET  # the eval distribution (checked by the caller)


def check_approaches(
    env: Environment,
    names: Sequence[str],
    base_planning: PlanningConfig,
    skills_dir: Path | None,
) -> None:
    """Build every approach once, here: one that cannot be built (its files do not load,
    the environment has no oracle skills) is an :class:`ApproachUnavailableError`."""
    for name in names:
        entry = get_approach(name)
        try:
            entry.make(
                env,
                entry.planning_config(base_planning),
                skills_dir if entry.skills is SkillSource.LEARNED else None,
            )
        except (NoOracleSkillsError, ArtifactError, ValueError) as err:
            raise ApproachUnavailableError(f"approach {name}: {err}") from None


def evaluate_approaches(
    env: Environment,
    names: Sequence[str],
    request: EvalRequest,
    base_planning: PlanningConfig,
    skills_dir: Path | None = None,
    learned: LearnedSkills | None = None,
    progress: TaskProgress = _no_progress,
    finished: Callable[[EvalReport], None] | None = None,
) -> list[EvalReport]:
    """Evaluate each named approach in turn (``finished`` hears of each report as it is
    done); the reports in the order named. ``learned`` (the skills' record) supplies the
    demonstration count and learning time of the approaches that learn."""
    check_approaches(env, names, base_planning, skills_dir)
    stats = learned.stats if learned is not None else None
    reports = []
    for name in names:
        approach = get_approach(name)
        learns = approach.skills is SkillSource.LEARNED
        spec = EvalSpec(
            env_name=env.name,
            approach=approach.name,
            planning=approach.planning_config(base_planning),
            skills_dir=str(skills_dir) if learns else None,
            task_seed=request.task_seed,
            planner_seed=request.planner_seed,
            train_tasks=request.train,
            validate=request.validate,
            perturbation=request.perturbation,
            model=request.model,
            execution=request.execution,
            eval_set=request.eval_set,
        )
        learning_seconds = None
        if learns and stats is not None and skills_dir is not None:
            learning_seconds = approach.learning_seconds(
                dict(stats.stage_seconds), saved_baseline_seconds(skills_dir)
            )
        try:
            report = evaluate(
                spec,
                request.num_tasks,
                request.workers,
                num_demos=stats.num_demos if learns and stats else None,
                learning_seconds=learning_seconds,
                progress=lambda it, n, label=approach.label: progress(it, n, f"eval {label}"),
            )
        except NoOracleSkillsError as err:
            raise ApproachUnavailableError(str(err)) from None
        reports.append(report)
        if finished is not None:
            finished(report)
    return reports
