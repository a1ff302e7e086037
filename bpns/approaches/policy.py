"""A model-free policy acting every control step (e.g. behavioural cloning).

:class:`ClosedLoopPolicy` runs the loop; a subclass maps the current state to an action
(:meth:`ClosedLoopPolicy.act`). Its outputs get the same checks as a skill's policy
(:func:`bpns.execution.executor.checked_action`: an exception, a wrong shape or NaN fails the
attempt, actions are clipped into bounds). The goal is tested after every step; the
attempt fails when the task's horizon is used up or the time runs out.
"""

from __future__ import annotations

import abc
import dataclasses
import time

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.approaches.base import Approach, Solution, failure, open_loop
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment, observation_of
from bpns.execution.executor import checked_action, motion_index
from bpns.execution.failures import FailureReason
from bpns.execution.rollouts import Rollout
from bpns.structs import State, Task


class ClosedLoopPolicy(Approach):
    def __init__(self, env: Environment) -> None:
        self.env = env
        self.low = np.asarray(env.action_low, dtype=np.float64)
        self.high = np.asarray(env.action_high, dtype=np.float64)

    def reset(self, task: Task, rng: np.random.Generator) -> None:
        """Called before the first step of each task (e.g. to clear a history)."""

    @abc.abstractmethod
    def act(self, task: Task, state: State) -> np.ndarray:
        """The action to take in ``state`` (the task gives objects and goal)."""

    def solve(self, task: Task, rng: np.random.Generator, timeout: float) -> Solution:
        return self._run(self.env, task, rng, timeout)

    def solve_in_world(
        self,
        task: Task,
        model: Environment,
        world: Environment,
        rng: np.random.Generator,
        timeout: float,
        execution: ExecutionConfig,
    ) -> Solution:
        """A policy acting every control step needs no model: closed loop, it acts in
        ``world`` on the world's observation itself, at ``execution.world_speed`` from the
        start (with ``slow_from="deviation"`` never: there is no model's prediction to
        leave)."""
        if not execution.closed_loop:
            return open_loop(self, task, model, world, rng, timeout)
        return self._run(world, task, rng, timeout, execution.starting_speed)

    def _run(
        self,
        env: Environment,
        task: Task,
        rng: np.random.Generator,
        timeout: float,
        speed: float = 1.0,
    ) -> Solution:
        deadline = time.monotonic() + timeout
        self.reset(task, rng)
        state = task.init
        actions: list[np.ndarray] = []

        def failed(reason: FailureReason) -> Solution:
            out = failure(reason, self.low.size, sim_steps=len(actions))
            return dataclasses.replace(out, rollout=_rollout(actions, self.low.size))

        goal_predicates = env.goal_predicates
        observe = observation_of(env)  # what the policy sees (e.g. noisy features)
        slowed = motion_index(env) if speed != 1.0 else None
        while not task.goal_holds(abstract(state, goal_predicates)):
            if len(actions) >= task.horizon:
                return failed(FailureReason.TASK_HORIZON)
            if time.monotonic() >= deadline:
                return failed(FailureReason.TIMEOUT)
            try:
                raw = self.act(task, observe(state))
            except Exception:
                return failed(FailureReason.POLICY_ERROR)
            action = checked_action(raw, self.low, self.high)
            if isinstance(action, FailureReason):
                return failed(action)
            if slowed is not None:
                action[slowed] *= speed
            state = env.simulate(state, action)
            actions.append(action)
        return Solution(
            success=True,
            actions=np.array(actions, dtype=np.float64).reshape(len(actions), self.low.size),
            sim_steps=len(actions),
            rollout=_rollout(actions, self.low.size),
        )


def _rollout(actions: list[np.ndarray], action_dim: int) -> Rollout:
    """Every action taken; a per-step policy executes no skills."""
    return Rollout(np.array(actions, dtype=np.float64).reshape(len(actions), action_dim))
