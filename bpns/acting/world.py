"""The world side of an execution: a task's state moving forward only, never reset.

:class:`WorldRun` executes skills (through the shared rollout,
:class:`bpns.execution.executor.SkillExecutor`, on the world's environment, so every
control step the policy sees the world's observation), replays actions open loop, and
keeps what happened: every action, one execution record per skill, and the monitor's
events. Unlike refinement in the model, a failed execution is not undone: the world
stays where the failed skill left it. What the robot can do about that without a plan is
the environment's back-off motion (:meth:`WorldRun.back_off`), recorded as a step named
:data:`BACK_OFF`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from bpns.acting.prediction import InFlightPredictor
from bpns.env.abstraction import abstract, ground_atoms, true_atoms
from bpns.env.environment import Environment
from bpns.execution.executor import (
    CompletionTest,
    Executed,
    ExecutionTimeout,
    RolloutConfig,
    SkillExecutor,
    checked_action,
)
from bpns.execution.failures import NOT_EXECUTED, FailureReason
from bpns.execution.rollouts import REACHED, Event, Rollout, rollout_of
from bpns.structs import GroundAtom, GroundOperator, Skill, State, Task
from bpns.timing import Stopwatch

BACK_OFF = "BackOff"  # the step name of a back-off motion in rollouts and captions


class WorldRun:
    """One task executing in ``env`` (the world), from ``task.init``."""

    def __init__(
        self,
        env: Environment,
        task: Task,
        config: RolloutConfig,
        deadline: float | None,
    ) -> None:
        self.env = env
        self.task = task
        self.executor = SkillExecutor(env, task, config, deadline)
        self.keep_for = max(1, int(env.contact_settle_steps))
        self.state = task.init
        self.actions: list[np.ndarray] = []
        self.executions: list[tuple] = []  # (ground operator, subgoal, actions, outcome)
        self.events: list[Event] = []
        self.world_steps = 0  # control steps simulated in the world (reused ones excluded)
        # time spent simulating them: on a robot the world's own time, not the agent's
        # (what an evaluation reports apart as "agent time")
        self.world_clock = Stopwatch()
        self.predictor: InFlightPredictor | None = None
        self._latency_told = False
        # its objects never change within a task: their ground atoms are built once
        # (a 6x6 Doors map has over 6,000)
        self._ground = ground_atoms(task.init.objects, env.predicates)

    @property
    def used(self) -> int:
        return len(self.actions)

    def atoms(self) -> frozenset[GroundAtom]:
        return true_atoms(self.state, self._ground)

    def goal_holds(self) -> bool:
        return self.task.goal_holds(abstract(self.state, self.env.goal_predicates))

    def event(self, kind: str, text: str) -> None:
        self.events.append(Event(self.used, kind, text))

    def execute(
        self,
        skill: Skill,
        op: GroundOperator,
        subgoal: np.ndarray,
        test: CompletionTest,
        keep: Sequence[GroundAtom] = (),
        keep_until_added: Sequence[GroundAtom] = (),
    ) -> FailureReason | None:
        """Run ``skill`` towards ``subgoal`` until ``test`` holds; None on success, else
        why it failed. Whatever it executed stays executed (the world moved).
        ``keep``: atoms it must not lose; ``keep_until_added``: atoms it must not lose
        before ``op``'s add effects hold."""
        before = self.executor.sim_steps
        with self.world_clock.running():
            out = self.executor.execute(
                skill,
                op.objects,
                subgoal,
                self.state,
                test,
                self.used,
                keep,
                self.keep_for,
                keep_until_added,
                tuple(sorted(op.add_effects, key=str)) if keep_until_added else (),
            )
        self.world_steps += self.executor.sim_steps - before
        self._tell_latency()
        if isinstance(out, Executed):
            self._advance(op, subgoal, out.actions, out.states, REACHED)
            return None
        ran = out not in NOT_EXECUTED
        actions = self.executor.last_actions if ran else []
        states = self.executor.last_states if ran else []
        self._advance(op, subgoal if ran else None, actions, states, str(out))
        return out

    @property
    def speed(self) -> float:
        """The fraction of each commanded motion skills execute with now."""
        return self.executor.config.speed

    def slow_down(self, limits: RolloutConfig, text: str) -> None:
        """Execute every later skill with ``limits`` (a slower speed), noted as an event."""
        self.executor.set_limits(limits)
        self.event("slowed", text)

    def reuse(
        self,
        op: GroundOperator,
        subgoal: np.ndarray,
        actions: Sequence[np.ndarray],
        states: Sequence[State],
    ) -> None:
        """Take over a segment the model simulated from this very state under this very
        physics: the world would reproduce it bit for bit (``f`` is deterministic)."""
        self._advance(op, subgoal, actions, states, REACHED)

    def predict_with(self, predictor: InFlightPredictor) -> None:
        """Let every later skill's policy see what ``predictor`` makes of the world's
        observation and the commands sent so far (:mod:`bpns.acting.prediction`)."""
        self.predictor = predictor
        self.executor.predict = predictor
        self.executor.sent = self.actions  # the world's commands, extended as it acts

    def _tell_latency(self) -> None:
        """An event once the predictor has identified the world's latency."""
        p = self.predictor
        if p is None or self._latency_told or not p.identified:
            return
        self._latency_told = True
        self.event(
            "latency",
            f"identified a latency of {p.latency} control steps from the first "
            f"{p.learn_steps} steps",
        )

    def back_off(self) -> bool:
        """Run the environment's back-off motion (``Capabilities.back_off``) from here
        towards the task's start, within a skill's step limit and the task's horizon;
        whether it got there. Its policy sees the world's observation, as a skill's does.
        """
        policy = self.env.capabilities.back_off
        if policy is None:
            return False
        executor = self.executor
        actions: list[np.ndarray] = []
        states: list[State] = []
        state, outcome = self.state, FailureReason.SKILL_HORIZON
        try:
            with self.world_clock.running():
                for _ in range(executor.config.max_skill_horizon):
                    if executor.deadline is not None and time.monotonic() >= executor.deadline:
                        raise ExecutionTimeout
                    if self.used + len(actions) >= self.task.horizon:
                        outcome = FailureReason.TASK_HORIZON
                        break
                    raw = policy(self.env, executor.observe(state), self.task.init)
                    if raw is None:
                        outcome = None
                        break
                    action = checked_action(raw, executor.low, executor.high)
                    if isinstance(action, FailureReason):
                        outcome = action
                        break
                    state = self.env.simulate(state, action)
                    actions.append(action)
                    states.append(state)
        finally:
            self.world_steps += len(actions)
            executor.sim_steps += len(actions)
        self._advance(BACK_OFF, None, actions, states, REACHED if outcome is None else str(outcome))
        return outcome is None

    def replay(self, actions: np.ndarray) -> None:
        """Apply ``actions`` one after the other, whatever happens (open loop)."""
        with self.world_clock.running():
            for action in actions:
                self.state = self.env.simulate(self.state, action)
                self.actions.append(np.asarray(action, dtype=np.float64))
                self.world_steps += 1

    @property
    def world_seconds(self) -> float:
        """Wall-clock seconds spent simulating the world."""
        return self.world_clock.wall

    @property
    def world_cpu_seconds(self) -> float:
        """CPU seconds of this process spent simulating the world."""
        return self.world_clock.cpu

    def _advance(self, op, subgoal, actions, states, outcome: str) -> None:
        self.executions.append((op, subgoal, list(actions), outcome))
        self.actions.extend(actions)
        if states:
            self.state = states[-1]

    def rollout(self) -> Rollout:
        dim = np.asarray(self.env.action_low).size
        if not self.executions:  # a replayed plan: the actions alone
            flat = np.array(self.actions, dtype=np.float64).reshape(len(self.actions), dim)
            return Rollout(flat, (), tuple(self.events))
        return rollout_of(self.executions, dim, self.events)

    def action_array(self) -> np.ndarray:
        dim = np.asarray(self.env.action_low).size
        return np.array(self.actions, dtype=np.float64).reshape(len(self.actions), dim)
