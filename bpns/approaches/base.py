"""What an approach is: something that solves one task of one environment at a time.

An :class:`Approach` is built inside the process that runs it (an evaluation worker)
from its registry entry (:class:`ApproachEntry`): the environment, the planning/rollout
settings and, for approaches that need learned artifacts, the skills directory. Then
``solve(task, rng, timeout)`` is called once per task and returns a :class:`Solution`:
the actions (replayable in the environment from the task's initial state), why it
failed, and what it cost.

Three kinds fit: bilevel planning with learned or oracle skills
(:mod:`bpns.approaches.bilevel`), a metacontroller that picks and executes one ground
skill at a time (:mod:`bpns.approaches.metacontroller`), and a model-free policy that
acts every control step (:mod:`bpns.approaches.policy`).
"""

from __future__ import annotations

import abc
import dataclasses
import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment, adopt_state
from bpns.errors import BpnsError
from bpns.execution.failures import FailureReason
from bpns.execution.rollouts import Rollout
from bpns.planning.config import PlanningConfig
from bpns.structs import Task
from bpns.timing import Stopwatch


class NoOracleSkillsError(BpnsError, ValueError):
    """The environment declares no hand-written skills."""


@dataclass(frozen=True, eq=False)
class Solution:
    """The outcome of one ``solve`` call.

    ``actions`` (k x action_dim) take the task's initial state to the goal when
    ``success``, else they are empty and ``reason`` says why. ``skeleton`` names the
    ground skills the actions execute, in order (empty for a policy without skills).
    The counts are what the attempt cost: abstract search nodes created, abstract plans
    tried, subgoal samples drawn and simulator steps taken (0 where they do not apply).
    """

    success: bool
    actions: np.ndarray
    reason: FailureReason | None = None
    skeleton: tuple[str, ...] = ()
    nodes_created: int = 0
    abstract_plans: int = 0
    samples: int = 0
    sim_steps: int = 0
    details: object = field(default=None, repr=False)  # e.g. the planner's PlanResult
    # why a failed attempt failed, JSON-ready (abstract plans tried and, per step,
    # samples that failed and why): written to results.json, shown by `bpns eval --explain`
    explanation: dict | None = field(default=None, repr=False)
    # what was executed (bpns.execution.rollouts): the plan when solved, else the attempt that got
    # furthest; None when the approach does not say
    rollout: Rollout | None = field(default=None, repr=False)
    # closed-loop execution in a world that differs from the model (``Approach.solve_in_world``):
    # divergences repaired, and boundaries where the plan's rest was refined again
    replans: int = 0
    rerefinements: int = 0
    # of the solving time, the wall-clock seconds spent simulating the world (not the
    # model): a robot's world runs in real time on its own; 0 when nothing was simulated
    # apart from planning, or the approach does not tell them apart
    world_seconds: float = 0.0
    world_cpu_seconds: float = 0.0  # the same in this process's CPU seconds


def failure(reason: FailureReason, action_dim: int, **counts: int) -> Solution:
    """A failed :class:`Solution` with no actions."""
    return Solution(False, np.zeros((0, action_dim)), reason, **counts)


class Approach(abc.ABC):
    """Solves tasks of the environment it was built for (the planner's *model*), one
    ``solve`` call per task; ``solve_in_world`` executes in a *world* that may differ from it."""

    @abc.abstractmethod
    def solve(self, task: Task, rng: np.random.Generator, timeout: float) -> Solution:
        """Solve ``task`` within ``timeout`` wall-clock seconds, drawing randomness from
        ``rng`` only. Must not raise for a task it cannot solve: return a failed
        Solution (``FailureReason.TIMEOUT`` when the time ran out)."""

    def solve_in_world(
        self,
        task: Task,
        model: Environment,
        world: Environment,
        rng: np.random.Generator,
        timeout: float,
        execution: ExecutionConfig,
    ) -> Solution:
        """Solve ``task`` (a task of ``world``) acting in ``world``, planning in ``model``
        (the environment this approach was built for); the Solution's actions are those
        the world executed. This default plans once with :meth:`solve` and replays the
        plan open loop (:func:`open_loop`); the built-in approaches execute closed loop
        when ``execution.closed_loop`` (their own ``solve_in_world``)."""
        return open_loop(self, task, model, world, rng, timeout)


def open_loop(
    approach: Approach,
    task: Task,
    model: Environment,
    world: Environment,
    rng: np.random.Generator,
    timeout: float,
) -> Solution:
    """Plan ``task`` in ``model`` from the world's initial state, then replay the actions
    in ``world`` whatever happens; solved when the goal holds at the end there
    (``GOAL_NOT_REACHED`` otherwise). Under the very physics of the model the replay is
    the plan itself and is not simulated again."""
    init = adopt_state(model, task.init)
    solution = approach.solve(Task(init, task.goal, task.horizon), rng, timeout)
    same_physics = model is world or (task.init.sim is not None and init is task.init)
    if not solution.success or same_physics:
        return solution
    state, clock = task.init, Stopwatch()
    with clock.running():
        for action in solution.actions:
            state = world.simulate(state, action)
    solution = dataclasses.replace(solution, world_seconds=clock.wall, world_cpu_seconds=clock.cpu)
    if task.goal_holds(abstract(state, world.goal_predicates)):
        return solution
    rollout = solution.rollout or Rollout(solution.actions)
    return dataclasses.replace(
        solution,
        success=False,
        actions=np.zeros((0, solution.actions.shape[1])),
        reason=FailureReason.GOAL_NOT_REACHED,
        rollout=rollout,
    )


class SkillSource(str, enum.Enum):
    """What an approach is built from, besides the environment."""

    LEARNED = "learned"  # artifacts learned from demonstrations: a skills directory
    ORACLE = "oracle"  # the environment's hand-written skills (``env.capabilities.oracle_skills``)
    NONE = "none"  # nothing else


# (environment, planning and rollout settings, skills directory or None) -> approach
Builder = Callable[[Environment, PlanningConfig, "Path | None"], Approach]


def _same(config: PlanningConfig) -> PlanningConfig:
    return config


@dataclass(frozen=True)
class ApproachEntry:
    """One named approach in the registry (see :mod:`bpns.approaches.registry`).

    ``adjust`` derives this approach's settings from the common ones (the paper's
    ablations are one-line entries: ``Samples=1`` sets ``n_samples=1``); ``build`` makes
    the approach inside the worker process (entries must pickle: use module-level
    functions)."""

    name: str  # command-line name
    label: str  # name in tables (the paper's)
    description: str
    skills: SkillSource
    build: Builder
    adjust: Callable[[PlanningConfig], PlanningConfig] = _same
    # learned by `bpns learn --baselines` beside the skills (bpns.baselines.learn)
    needs_baselines: bool = False
    # the learning stages whose time is this approach's learning time: names from the
    # skills pipeline (bpns.learning.pipeline.STAGES) and the baselines
    # (bpns.baselines.learn); None: the whole skills pipeline
    learned_stages: tuple[str, ...] | None = None

    def planning_config(self, base: PlanningConfig) -> PlanningConfig:
        return self.adjust(base)

    def learning_seconds(
        self, pipeline: Mapping[str, float], baselines: Mapping[str, float]
    ) -> float | None:
        """Seconds spent learning what this approach uses, from the seconds of each stage
        of the skills pipeline and of each baseline learned; None if a stage it uses was
        not recorded (or it learns nothing)."""
        if self.skills is not SkillSource.LEARNED:
            return None
        if self.learned_stages is None:
            return sum(pipeline.values()) if pipeline else None
        stages = {**pipeline, **baselines}
        if any(s not in stages for s in self.learned_stages):
            return None
        return sum(stages[s] for s in self.learned_stages)

    def make(
        self, env: Environment, planning: PlanningConfig, skills_dir: str | Path | None = None
    ) -> Approach:
        """Build the approach for ``env``; ``skills_dir`` is required when it learns."""
        if self.skills is SkillSource.LEARNED and skills_dir is None:
            raise ValueError(f"approach {self.name!r} needs a skills directory")
        if self.skills is SkillSource.ORACLE and not env.capabilities.has_oracle_skills:
            raise NoOracleSkillsError(f"environment {env.name!r} declares no oracle skills")
        return self.build(env, planning, None if skills_dir is None else Path(skills_dir))


def with_timeout(config: PlanningConfig, timeout: float) -> PlanningConfig:
    """``config`` with ``timeout`` (the same object when it already has it)."""
    return config if config.timeout == timeout else dataclasses.replace(config, timeout=timeout)
