"""Evaluate an approach on held-out tasks: solve each task, check the plan, summarise.

Every solved plan is *validated*: its actions are re-simulated from the task's initial
state and the goal must hold at the end (``f`` is exact, so this only fails if the
approach or an environment breaks its contract). Test time is the wall-clock time of
the ``solve`` call alone, measured inside the process that ran it.

Any registered approach runs (:mod:`bpns.approaches`). Tasks are independent, so they
run in a process pool; each worker builds its own environment and approach from a
picklable :class:`EvalSpec` (predicates are code and need not pickle).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import statistics
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bpns.acting.config import CLOSED_LOOP, ExecutionConfig
from bpns.approaches import Approach, get_approach
from bpns.approaches import NoOracleSkillsError as NoOracleSkillsError  # re-exported
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment, eval_environment, perturbed
from bpns.env.object_counts import PAPER_SET, EvalSet
from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.env.registry import make_environment
from bpns.env.worlds import NOMINAL_MODEL, ModelSpec, WorldDistribution
from bpns.evaluation.intervals import wilson_interval
from bpns.execution.failures import FailureReason
from bpns.execution.rollouts import Event, Rollout
from bpns.planning.config import PlanningConfig
from bpns.pools import make_pool, surviving_map
from bpns.structs import Task
from bpns.timing import Stopwatch


@dataclass(frozen=True)
class EvalSpec:
    """Everything a worker needs to rebuild the environment and approach by itself."""

    env_name: str
    approach: str
    planning: PlanningConfig  # the approach's settings; ``planning.timeout`` per task
    skills_dir: str | None = None  # approaches built from learned artifacts only
    task_seed: int = 0  # seed of the eval task stream
    planner_seed: int = 0  # rng of sampling, per task: [planner_seed, task index]
    train_tasks: bool = False  # evaluate on the train distribution instead
    validate: bool = True
    # the world the tasks execute in: one physics for every task, or drawn per task
    perturbation: Perturbation | WorldDistribution = NOMINAL
    model: ModelSpec = NOMINAL_MODEL  # what the planner's simulator knows of the world
    execution: ExecutionConfig = CLOSED_LOOP  # closed loop with replanning, or open loop
    eval_set: EvalSet = PAPER_SET  # the eval distribution (named set, object counts)

    def __post_init__(self) -> None:  # worlds drawn for this task stream unless seeded
        p = self.perturbation
        if isinstance(p, WorldDistribution):
            object.__setattr__(self, "perturbation", p.seeded(self.task_seed))

    @property
    def worlds(self) -> WorldDistribution:
        p = self.perturbation
        return p if isinstance(p, WorldDistribution) else WorldDistribution.of(p)


@dataclass(frozen=True, eq=False)
class TaskOutcome:
    """The result of solving one task (``actions`` is empty unless solved; ``rollout`` is
    what was executed, solved or not: see :mod:`bpns.execution.rollouts`)."""

    index: int
    solved: bool
    seconds: float
    reason: str | None
    num_actions: int
    nodes_created: int
    abstract_plans: int
    samples: int
    sim_steps: int
    validated: bool | None  # None when validation was off or the task unsolved
    skeleton: tuple[str, ...] = ()  # the abstract plan refined, one ground skill a step
    explanation: dict | None = None  # a failed task: what was tried and why it failed
    actions: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    rollout: Rollout | None = field(repr=False, default=None)
    world: Perturbation = NOMINAL  # the physics this task executed in (drawn per task)
    replans: int = 0  # closed loop: divergences repaired
    rerefinements: int = 0  # closed loop: boundaries where the plan's rest was refined again
    world_seconds: float = 0.0  # of ``seconds``, those spent simulating the world
    # the same two in CPU seconds of the process that solved the task (bpns.timing):
    # unlike wall-clock time, not inflated by other processes sharing the machine
    cpu_seconds: float | None = None
    world_cpu_seconds: float = 0.0

    @property
    def agent_seconds(self) -> float:
        """The solving time less the world's simulation: what the agent itself spent
        (planning, checking in the model). On a robot the world runs on its own; in a
        nominal world closed loop takes the model's segments over, so this is the time
        to compare with a nominal world's."""
        return self.seconds - self.world_seconds

    @property
    def agent_cpu_seconds(self) -> float:
        """:attr:`agent_seconds` in CPU seconds (NaN where not recorded)."""
        if self.cpu_seconds is None:
            return math.nan
        return self.cpu_seconds - self.world_cpu_seconds

    @property
    def sim_steps_per_step(self) -> float:
        """Simulated control steps spent while solving per action of the final plan
        (1.0: nothing simulated in vain); NaN unless solved with at least one action."""
        return self.sim_steps / self.num_actions if self.solved and self.num_actions else math.nan

    @property
    def events(self) -> tuple[Event, ...]:
        return self.rollout.events if self.rollout is not None else ()

    def to_json(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        del d["actions"], d["rollout"]
        d["world"] = dataclasses.asdict(self.world)
        d["events"] = [e.to_json() for e in self.events]
        return d


@dataclass(frozen=True, eq=False)
class EvalReport:
    """All outcomes of one approach on one task set, plus what produced them."""

    env: str
    approach: str
    label: str
    planning: PlanningConfig
    outcomes: tuple[TaskOutcome, ...]
    task_seed: int
    num_demos: int | None = None
    learning_seconds: float | None = None
    train_tasks: bool = False  # the tasks came from the train distribution
    perturbation: Perturbation | WorldDistribution = NOMINAL  # the worlds (EvalSpec's)
    model: ModelSpec = NOMINAL_MODEL
    execution: ExecutionConfig = CLOSED_LOOP
    eval_set: EvalSet = PAPER_SET  # the eval distribution the tasks came from

    @property
    def worlds(self) -> WorldDistribution:
        p = self.perturbation
        return p if isinstance(p, WorldDistribution) else WorldDistribution.of(p)

    def task_environment(self, env: Environment) -> Environment:
        """``env`` (nominal, as built by name) drawing this report's tasks: every place
        that rebuilds a task from (index, seed) goes through it."""
        return eval_environment(env, self.eval_set)

    @property
    def mean_replans(self) -> float:
        return statistics.fmean(o.replans for o in self.outcomes) if self.outcomes else 0.0

    @property
    def num_tasks(self) -> int:
        return len(self.outcomes)

    @property
    def num_solved(self) -> int:
        return sum(o.solved for o in self.outcomes)

    @property
    def solved_percent(self) -> float:
        return 100.0 * self.num_solved / max(1, self.num_tasks)

    def _solved_times(self) -> list[float]:
        return [o.seconds for o in self.outcomes if o.solved]

    @property
    def median_seconds(self) -> float:
        """Median test time over solved tasks (as in the paper); NaN if none solved."""
        times = self._solved_times()
        return statistics.median(times) if times else math.nan

    @property
    def median_agent_seconds(self) -> float:
        """Median over solved tasks of :attr:`TaskOutcome.agent_seconds`; NaN if none."""
        times = [o.agent_seconds for o in self.outcomes if o.solved]
        return statistics.median(times) if times else math.nan

    @property
    def median_agent_cpu_seconds(self) -> float:
        """Median over solved tasks of :attr:`TaskOutcome.agent_cpu_seconds`; NaN if none
        (or not recorded)."""
        times = [t for o in self.outcomes if o.solved and math.isfinite(t := o.agent_cpu_seconds)]
        return statistics.median(times) if times else math.nan

    @property
    def mean_seconds(self) -> float:
        times = self._solved_times()
        return statistics.fmean(times) if times else math.nan

    @property
    def median_sim_steps_per_step(self) -> float:
        """Median over solved tasks of :attr:`TaskOutcome.sim_steps_per_step`: how much
        simulation planning wastes (the oracle's skills set the floor); NaN if none."""
        ratios = [r for o in self.outcomes if math.isfinite(r := o.sim_steps_per_step)]
        return statistics.median(ratios) if ratios else math.nan

    @property
    def mean_nodes(self) -> float:
        """Mean abstract-search nodes created over all tasks."""
        return statistics.fmean(o.nodes_created for o in self.outcomes) if self.outcomes else 0.0

    @property
    def failures(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for o in self.outcomes:
            if not o.solved:
                out[str(o.reason)] = out.get(str(o.reason), 0) + 1
        return out

    def to_json(self) -> dict[str, Any]:
        return {
            "env": self.env,
            "approach": self.approach,
            "label": self.label,
            "task_seed": self.task_seed,
            "train_tasks": self.train_tasks,
            "eval_set": self.eval_set.name,
            "objects": self.eval_set.objects.text(),
            "perturbation": _physics_json(self.perturbation),
            "worlds": self.worlds.label(),
            "model": self.model.label(),
            "execution": self.execution.mode,
            "num_demos": self.num_demos,
            "learning_seconds": self.learning_seconds,
            "planning": dataclasses.asdict(self.planning),
            "summary": {
                "num_tasks": self.num_tasks,
                "num_solved": self.num_solved,
                "solved_percent": self.solved_percent,
                "median_seconds": _finite_or_none(self.median_seconds),
                "mean_seconds": _finite_or_none(self.mean_seconds),
                "median_agent_seconds": _finite_or_none(self.median_agent_seconds),
                "median_agent_cpu_seconds": _finite_or_none(self.median_agent_cpu_seconds),
                "mean_nodes_created": self.mean_nodes,
                "median_sim_steps_per_step": _finite_or_none(self.median_sim_steps_per_step),
                "mean_replans": self.mean_replans,
                "failures": self.failures,
            },
            "tasks": [o.to_json() for o in self.outcomes],
        }


def _physics_json(p: Perturbation | WorldDistribution) -> dict:
    """A fixed physics as its fields (as results.json always had it); a distribution as
    its spreads."""
    if isinstance(p, Perturbation):
        return dataclasses.asdict(p)
    if p.fixed:
        return dataclasses.asdict(p.draw(0))
    return json.loads(p.to_json())


def _finite_or_none(x: float) -> float | None:
    return x if math.isfinite(x) else None


TABLE_HEADER = (
    "| Approach | Demos | Solved | Median time (s) | Mean time (s) | Median agent time (s) "
    "| Median agent CPU (s) | Nodes created | Sim steps / plan step | Learning time (s) "
    "| Solved, 95 % CI | Replans / task |\n"
    "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def table_row(report: EvalReport) -> str:
    def num(x: float | None, fmt: str) -> str:
        return "–" if x is None or not math.isfinite(x) else format(x, fmt)

    low, high = wilson_interval(report.num_solved, report.num_tasks)
    return (
        f"| {report.label} | {report.num_demos if report.num_demos is not None else '–'} "
        f"| {report.num_solved}/{report.num_tasks} ({report.solved_percent:.1f}%) "
        f"| {num(report.median_seconds, '.2f')} | {num(report.mean_seconds, '.2f')} "
        f"| {num(report.median_agent_seconds, '.2f')} "
        f"| {num(report.median_agent_cpu_seconds, '.2f')} | {report.mean_nodes:.1f} "
        f"| {num(report.median_sim_steps_per_step, '.1f')} "
        f"| {num(report.learning_seconds, '.1f')} "
        f"| {100 * low:.1f}-{100 * high:.1f} | {report.mean_replans:.2f} |"
    )


def conditions_line(reports: Sequence[EvalReport]) -> str:
    """``World: moderate; model: nominal; execution: closed-loop; eval set: large`` (of
    the first report: one evaluation runs every approach under the same conditions)."""
    r = reports[0]
    return (
        f"World: {r.worlds.label()}; model: {r.model.label()}; execution: {r.execution.mode}; "
        f"eval set: {r.eval_set.label()}"
    )


def markdown_table(reports: Sequence[EvalReport]) -> str:
    """One row per report; times and simulated steps per plan step are medians over
    solved tasks, nodes and replans are means over all tasks; the interval is Wilson's."""
    return "\n".join([TABLE_HEADER, *(table_row(r) for r in reports)]) + "\n"


# ------------------------------------------------------------------------ running tasks


def approach_for(spec: EvalSpec, env: Environment) -> Approach:
    """``spec``'s approach, built in this process."""
    return get_approach(spec.approach).make(env, spec.planning, spec.skills_dir)


def solve_task(
    approach: Approach,
    task: Task,
    index: int,
    env: Environment,
    timeout: float,
    rng: np.random.Generator,
    validate: bool = True,
    world: Environment | None = None,
    execution: ExecutionConfig | None = None,
    physics: Perturbation = NOMINAL,
) -> TaskOutcome:
    """Solve ``task`` once, time it and (optionally) validate the plan by re-simulation.

    ``env`` is the model the approach plans in. With a ``world`` (``task`` is then one
    of its tasks) the approach acts there under ``execution`` (``Approach.solve_in_world``) and
    validation re-simulates the world's actions in the world; without one the plan is
    made and checked in ``env`` alone (``Approach.solve``). ``physics`` is the world's,
    recorded with the outcome."""
    clock = Stopwatch()
    with clock.running():
        if world is None:
            world = env
            result = approach.solve(task, rng, timeout)
        else:
            execution = execution or CLOSED_LOOP
            result = approach.solve_in_world(task, env, world, rng, timeout, execution)
    validated = None
    if result.success and validate:
        validated = plan_reaches_goal(world, task, result.actions)
    return TaskOutcome(
        index=index,
        solved=bool(result.success and validated is not False),
        seconds=clock.wall,
        reason=None if result.success else str(result.reason),
        num_actions=len(result.actions),
        nodes_created=result.nodes_created,
        abstract_plans=result.abstract_plans,
        samples=result.samples,
        sim_steps=result.sim_steps,
        validated=validated,
        skeleton=result.skeleton if result.success else (),
        explanation=None if result.success else result.explanation,
        actions=result.actions,
        rollout=result.rollout if result.rollout is not None else Rollout(result.actions),
        world=physics,
        replans=result.replans,
        rerefinements=result.rerefinements,
        world_seconds=result.world_seconds,
        cpu_seconds=clock.cpu,
        world_cpu_seconds=result.world_cpu_seconds,
    )


def plan_reaches_goal(env: Environment, task: Task, actions: np.ndarray) -> bool:
    """Re-simulate ``actions`` from ``task.init``; does the goal hold at the end?"""
    state = task.init
    for action in actions:
        state = env.simulate(state, action)
    return task.goal_holds(abstract(state, env.goal_predicates))


_WORKER: dict[str, Any] = {}


def _init_worker(spec: EvalSpec) -> None:
    base = eval_environment(make_environment(spec.env_name), spec.eval_set)
    _WORKER.update(spec=spec, base=base, approaches={})


def _approach(model: Environment, physics: Perturbation) -> Approach:
    """The approach planning in ``model`` (built once per model physics in this worker)."""
    cache: dict[Perturbation, Approach] = _WORKER["approaches"]
    if physics not in cache:
        if len(cache) >= 2:  # a model that knows each task's drawn world: one per task
            cache.clear()
        cache[physics] = approach_for(_WORKER["spec"], model)
    return cache[physics]


def _run_index(index: int) -> TaskOutcome:
    spec: EvalSpec = _WORKER["spec"]
    base: Environment = _WORKER["base"]
    physics = spec.worlds.draw(index)
    world = perturbed(base, physics)
    belief = spec.model.physics(physics)
    model = perturbed(base, belief)
    task = world.task(index, spec.task_seed, spec.train_tasks)
    rng = np.random.default_rng([spec.planner_seed, index])
    return solve_task(
        _approach(model, belief),
        task,
        index,
        model,
        spec.planning.timeout,
        rng,
        spec.validate,
        world=world,
        execution=spec.execution,
        physics=physics,
    )


def run_tasks(spec: EvalSpec, indices: Sequence[int], workers: int = 1) -> Iterator[TaskOutcome]:
    """Yield one outcome per task index, in order. ``workers`` > 1 uses a process pool.

    A worker that dies (the kernel's out-of-memory killer, a crash in native code, a
    stray ``kill``) costs no other task: the tasks unfinished when its pool broke run
    again, each alone in a fresh worker, and one is a ``worker_died`` failure only if
    that worker dies too; the remaining tasks go on in a fresh pool
    (:func:`bpns.pools.surviving_map`). Each task's outcome depends on its index alone,
    so a task run again gives what it would have given."""
    if workers <= 1 or len(indices) <= 1:
        _init_worker(spec)
        try:
            yield from map(_run_index, indices)
        finally:
            _WORKER.clear()
        return

    def new_pool(n: int | None) -> Executor:
        return make_pool(n or min(workers, len(indices)), _init_worker, (spec,))

    yield from surviving_map(
        new_pool, _run_index, indices, 2 * workers, functools.partial(_worker_died, spec)
    )


def _worker_died(spec: EvalSpec, index: int) -> TaskOutcome:
    """Task ``index``'s outcome when its worker died, also when it ran alone."""
    base = eval_environment(make_environment(spec.env_name), spec.eval_set)
    return TaskOutcome(
        index=index,
        solved=False,
        seconds=0.0,
        reason=FailureReason.WORKER_DIED,
        num_actions=0,
        nodes_created=0,
        abstract_plans=0,
        samples=0,
        sim_steps=0,
        validated=None,
        actions=np.zeros((0, np.asarray(base.action_low).size)),
        world=spec.worlds.draw(index),
    )


def evaluate(
    spec: EvalSpec,
    num_tasks: int,
    workers: int = 1,
    num_demos: int | None = None,
    learning_seconds: float | None = None,
    progress: Callable[[Iterator[TaskOutcome], int], Iterator[TaskOutcome]] | None = None,
) -> EvalReport:
    """Solve tasks 0..num_tasks-1 of the seeded eval stream with ``spec``'s approach."""
    if num_tasks < 1:
        raise ValueError(f"num_tasks must be >= 1, got {num_tasks}")
    stream = run_tasks(spec, range(num_tasks), workers)
    if progress is not None:
        stream = progress(stream, num_tasks)
    outcomes = tuple(stream)
    approach = get_approach(spec.approach)
    return EvalReport(
        env=spec.env_name,
        approach=approach.name,
        label=approach.label,
        planning=spec.planning,
        outcomes=outcomes,
        task_seed=spec.task_seed,
        num_demos=num_demos,
        learning_seconds=learning_seconds,
        train_tasks=spec.train_tasks,
        perturbation=spec.perturbation,
        model=spec.model,
        execution=spec.execution,
        eval_set=spec.eval_set,
    )
