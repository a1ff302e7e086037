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

from bpns.approaches.base import Approach, Solution, failure
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment
from bpns.execution.executor import (
    Executed,
    ExecutionTimeout,
    RolloutConfig,
    SkillExecutor,
    completion_test,
    expected_after,
)
from bpns.execution.failures import NOT_EXECUTED, FailureReason
from bpns.execution.rollouts import REACHED, rollout_of
from bpns.planning.config import PlanningConfig
from bpns.structs import GroundAtom, NoSubgoal, Object, Skill, State, Task


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
        deadline = time.monotonic() + timeout
        executor = SkillExecutor(self.env, task, RolloutConfig.of(self.config), deadline)
        state = task.init
        atoms = abstract(state, self.env.predicates)
        actions: list[np.ndarray] = []
        history: list[SkillChoice] = []
        skeleton: list[str] = []
        samples = 0

        done: list = []  # (ground operator, subgoal, actions, outcome) per executed skill

        def failed(
            reason: FailureReason, step: str | None = None, attempt: tuple | None = None
        ) -> Solution:
            out = failure(reason, self.action_dim, samples=samples, sim_steps=executor.sim_steps)
            executed = {"executed": list(skeleton), "failed_step": step}
            tried = done if attempt is None else [*done, attempt]
            rollout = rollout_of(tried, self.action_dim)
            return dataclasses.replace(out, explanation=executed, rollout=rollout)

        try:
            while not task.goal_holds(atoms):
                if time.monotonic() >= deadline:
                    return failed(FailureReason.TIMEOUT)
                if len(history) >= self.config.max_plan_length:
                    return failed(FailureReason.NO_SKILL)
                choice = self.choose(task, state, atoms, history, rng)
                if choice is None:
                    return failed(FailureReason.NO_SKILL)
                op = choice.skill.operator.ground(choice.objects)
                test = completion_test(op, expected_after(op, atoms))
                out: Executed | FailureReason = FailureReason.EXHAUSTED
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
                    out = executor.execute(
                        choice.skill, op.objects, subgoal, state, test, len(actions)
                    )
                    if not isinstance(out, FailureReason):
                        break
                if isinstance(out, FailureReason):
                    ran = out not in NOT_EXECUTED
                    attempt = (
                        op,
                        executor.last_subgoal if ran else None,
                        executor.last_actions if ran else [],
                        str(out),
                    )
                    return failed(out, str(op), attempt)
                done.append((op, subgoal, out.actions, REACHED))
                history.append(choice)
                skeleton.append(str(op))
                actions.extend(out.actions)
                state = out.states[-1]
                atoms = abstract(state, self.env.predicates)
        except ExecutionTimeout:
            return failed(FailureReason.TIMEOUT)
        return Solution(
            success=True,
            actions=np.array(actions, dtype=np.float64).reshape(len(actions), self.action_dim),
            skeleton=tuple(skeleton),
            samples=samples,
            sim_steps=executor.sim_steps,
            rollout=rollout_of(done, self.action_dim),
        )
