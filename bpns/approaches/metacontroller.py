"""A metacontroller: pick one ground skill at a time and execute it (no planning).

:class:`Metacontroller` runs the loop; a subclass says which ground skill to execute
next from the current state and abstract state (:meth:`Metacontroller.choose`, e.g. a
GNN trained on demonstrations' skill sequences), with a subgoal of its own or one drawn
from the skill's sampler. Each chosen skill is executed by the shared rollout
(:class:`bpns.execution.executor.SkillExecutor`) until the abstract state its operator predicts
holds; any failure of an execution ends the attempt with that failure's reason.
"""

from __future__ import annotations

import abc
import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.acting.world import WorldRun
from bpns.approaches.base import Approach, Solution, failure, open_loop
from bpns.env.environment import Environment, adopt_state
from bpns.execution.executor import (
    CompletionTest,
    Executed,
    ExecutionTimeout,
    RolloutConfig,
    SkillExecutor,
    completion_test,
    expected_after,
)
from bpns.execution.failures import NOT_EXECUTED, FailureReason
from bpns.execution.rollouts import rollout_of
from bpns.planning.config import PlanningConfig
from bpns.structs import GroundAtom, GroundOperator, NoSubgoal, Object, Skill, State, Task


@dataclass(frozen=True, eq=False)
class SkillChoice:
    """Execute ``skill`` with ``objects`` (its operator's parameter order) towards
    ``subgoal``; None draws the subgoal from the skill's sampler."""

    skill: Skill
    objects: tuple[Object, ...]
    subgoal: np.ndarray | None = None


class Metacontroller(Approach):
    """Choose-and-execute loop until the goal holds; at most ``config.max_plan_length``
    skills, each limited like a refinement step (``config``'s rollout fields), each
    tried with up to ``max_samples`` drawn subgoals (no backtracking to earlier ones)."""

    def __init__(self, env: Environment, config: PlanningConfig, max_samples: int = 1) -> None:
        if max_samples < 1:
            raise ValueError(f"max_samples must be >= 1, got {max_samples}")
        self.env = env
        self.config = config
        self.max_samples = max_samples
        self.action_dim = np.asarray(env.action_low).size

    def samples_for(self, choice: SkillChoice) -> int:
        """How many subgoals to draw for ``choice`` until one's rollout reaches the
        operator's predicted abstract state (the attempt fails when none does)."""
        return self.max_samples

    @abc.abstractmethod
    def choose(
        self,
        task: Task,
        state: State,
        atoms: frozenset[GroundAtom],
        history: Sequence[SkillChoice],
        rng: np.random.Generator,
    ) -> SkillChoice | None:
        """The next ground skill to execute, or None when there is none to try."""

    def solve(self, task: Task, rng: np.random.Generator, timeout: float) -> Solution:
        return self._run(task, None, rng, timeout, None)

    def solve_in_world(
        self,
        task: Task,
        model: Environment,
        world: Environment,
        rng: np.random.Generator,
        timeout: float,
        execution: ExecutionConfig,
    ) -> Solution:
        """Closed loop: choose from the world's state, find each choice's subgoal in the
        model (as :meth:`solve` does), execute it in the world; a choice that fails there
        is a divergence, and the next choice starts from where the world is."""
        if not execution.closed_loop:
            return open_loop(self, task, model, world, rng, timeout)
        return self._run(task, world, rng, timeout, execution)

    def _subgoal(
        self,
        choice: SkillChoice,
        op: GroundOperator,
        test: CompletionTest,
        state: State,
        executor: SkillExecutor,
        used: int,
        rng: np.random.Generator,
    ) -> tuple[np.ndarray | None, Executed | FailureReason, int]:
        """Draw subgoals until one's rollout from ``state`` (in the model) reaches the
        operator's predicted atoms: (subgoal, what ran, samples drawn)."""
        out: Executed | FailureReason = FailureReason.EXHAUSTED
        subgoal = choice.subgoal
        samples = 0
        for _ in range(1 if choice.subgoal is not None else self.samples_for(choice)):
            subgoal = choice.subgoal
            if subgoal is None:
                samples += 1
                try:
                    subgoal = np.asarray(
                        choice.skill.sampler(state, op.objects, rng), dtype=np.float64
                    )
                except NoSubgoal:
                    out = FailureReason.NO_SUBGOAL
                    continue
                except Exception:
                    out = FailureReason.SAMPLER_ERROR
                    continue
                if not np.isfinite(subgoal).all():
                    out = FailureReason.SAMPLER_NONFINITE
                    continue
            out = executor.execute(choice.skill, op.objects, subgoal, state, test, used)
            if not isinstance(out, FailureReason):
                break
        return subgoal, out, samples

    def _run(
        self,
        task: Task,
        world_env: Environment | None,
        rng: np.random.Generator,
        timeout: float,
        execution: ExecutionConfig | None,
    ) -> Solution:
        """The choose-and-execute loop, in the model alone (``world_env`` None) or acting
        in ``world_env``."""
        deadline = time.monotonic() + timeout
        config = RolloutConfig.of(self.config)
        executor = SkillExecutor(self.env, task, config, deadline)
        world_config = config
        if world_env is not None and execution is not None:
            world_config = execution.world_limits(config)
        run = WorldRun(world_env or self.env, task, world_config, deadline)
        history: list[SkillChoice] = []
        samples = replans = 0

        def failed(reason: FailureReason, step: str | None = None, attempt=None) -> Solution:
            sim = executor.sim_steps + (run.world_steps if world_env is not None else 0)
            out = failure(reason, self.action_dim, samples=samples, sim_steps=sim)
            executed = {"executed": [str(e[0]) for e in run.executions], "failed_step": step}
            tried = run.executions if attempt is None else [*run.executions, attempt]
            rollout = rollout_of(tried, self.action_dim, run.events)
            return dataclasses.replace(
                out,
                explanation=executed,
                rollout=rollout,
                replans=replans,
                world_seconds=run.world_seconds,
                world_cpu_seconds=run.world_cpu_seconds,
            )

        try:
            while not run.goal_holds():
                if time.monotonic() >= deadline:
                    return failed(FailureReason.TIMEOUT)
                if len(history) >= self.config.max_plan_length:
                    return failed(FailureReason.NO_SKILL)
                atoms = run.atoms()
                choice = self.choose(task, run.state, atoms, history, rng)
                if choice is None:
                    return failed(FailureReason.NO_SKILL)
                op = choice.skill.operator.ground(choice.objects)
                test = completion_test(op, expected_after(op, atoms))
                state = run.state if world_env is None else adopt_state(self.env, run.state)
                subgoal, out, drawn = self._subgoal(
                    choice, op, test, state, executor, run.used, rng
                )
                samples += drawn
                if isinstance(out, FailureReason):
                    return failed(out, str(op), _failed_attempt(op, out, executor))
                assert subgoal is not None
                if world_env is None or state is run.state:  # the world is the model
                    run.reuse(op, subgoal, out.actions, out.states)
                else:
                    reason = run.execute(choice.skill, op, subgoal, test)
                    if reason is not None:
                        replans += 1
                        run.event(
                            "skill_failed", f"replan {replans}: {op} failed in the world: {reason}"
                        )
                        assert execution is not None
                        if replans > execution.max_replans:
                            return failed(FailureReason.REPLAN_BUDGET)
                        continue
                history.append(choice)
        except ExecutionTimeout:
            return failed(FailureReason.TIMEOUT)
        sim = executor.sim_steps + (run.world_steps if world_env is not None else 0)
        return Solution(
            success=True,
            actions=run.action_array(),
            skeleton=tuple(str(e[0]) for e in run.executions),
            samples=samples,
            sim_steps=sim,
            rollout=run.rollout(),
            replans=replans,
            world_seconds=run.world_seconds,
            world_cpu_seconds=run.world_cpu_seconds,
        )


def _failed_attempt(
    op: GroundOperator, reason: FailureReason, executor: SkillExecutor
) -> tuple[GroundOperator, np.ndarray | None, list[np.ndarray], str]:
    """The failed execution as the rollout records it: what the executor last ran, or
    nothing when the failure came before anything was executed (``NOT_EXECUTED``)."""
    ran = reason not in NOT_EXECUTED
    return (
        op,
        executor.last_subgoal if ran else None,
        executor.last_actions if ran else [],
        str(reason),
    )
