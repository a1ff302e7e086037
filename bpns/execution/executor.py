"""Executing a skill in the exact simulator: the rollout every approach shares.

:class:`SkillExecutor` runs one ground skill's policy towards a given subgoal until an
expected abstract state holds (its :class:`CompletionTest`), or fails with a
:class:`~bpns.execution.failures.FailureReason`: the skill's horizon is hit, the world stops
changing (``stuck``), a contact atom changes although the test does not hold yet, the
task's step budget would be exceeded, or the policy misbehaves (exception, wrong
shape, non-finite output): learned networks must never crash an approach. Actions are
clipped into the environment's bounds. A deadline (``time.monotonic()``) is checked
before every step and raises :class:`ExecutionTimeout`.

Bilevel refinement calls it once per subgoal sample; a metacontroller calls it once
per skill it picks; :func:`checked_action` is the per-step check of a policy that acts
every control step.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from bpns.env.abstraction import object_tuples
from bpns.env.environment import Environment, observation_of
from bpns.errors import BpnsError
from bpns.execution.failures import FailureReason
from bpns.structs import GroundAtom, GroundOperator, Object, Skill, State, Task


@dataclass(frozen=True)
class RolloutConfig:
    """Limits of one skill execution (``PlanningConfig`` documents each field)."""

    max_skill_horizon: int = 200
    stuck_steps: int = 10
    stuck_atol: float = 1e-3
    end_on_contact_change: bool = False
    end_at_dead_end: bool = True
    # multiplies a skill's own horizon (learned from its demonstrations); the world may
    # give a skill still moving more time than refinement in the model does
    horizon_scale: float = 1.0
    # the fraction of each commanded motion (the environment's ``motion_dims``) applied:
    # a skill slowed in the world, where a delayed command overshoots (1.0: as commanded)
    speed: float = 1.0

    @classmethod
    def of(cls, config: object) -> RolloutConfig:
        """The rollout fields of any config that has them (e.g. a ``PlanningConfig``)."""
        return cls(
            max_skill_horizon=config.max_skill_horizon,  # type: ignore[attr-defined]
            stuck_steps=config.stuck_steps,  # type: ignore[attr-defined]
            stuck_atol=config.stuck_atol,  # type: ignore[attr-defined]
            end_on_contact_change=config.end_on_contact_change,  # type: ignore[attr-defined]
            end_at_dead_end=config.end_at_dead_end,  # type: ignore[attr-defined]
        )


@dataclass(frozen=True)
class CompletionTest:
    """A skill execution is complete when every ``must_hold`` atom holds and no
    ``must_not_hold`` atom does."""

    must_hold: tuple[GroundAtom, ...]
    must_not_hold: tuple[GroundAtom, ...]


def completion_test(op: GroundOperator, expected: frozenset[GroundAtom]) -> CompletionTest:
    """The test for ``op`` to have reached the abstract state ``expected``.

    Add effects come first: they are usually the ones still false, so the conjunction
    short-circuits after one classifier call on most simulated states. Only the atoms
    the step can change are tested: those ``expected`` and the delete effects that must
    be gone.
    """
    adds = op.add_effects & expected
    return CompletionTest(tuple(adds) + tuple(expected - adds), tuple(op.delete_effects - expected))


def expected_after(op: GroundOperator, atoms: frozenset[GroundAtom]) -> frozenset[GroundAtom]:
    """The abstract state ``op``'s effects predict from ``atoms``."""
    return op.apply(atoms)


class ExecutionTimeout(BpnsError):
    """The deadline passed during an execution."""


@dataclass(frozen=True, eq=False)
class Executed:
    """A successful execution: ``actions[i]`` led to ``states[i]`` (the start excluded)."""

    actions: list[np.ndarray]
    states: list[State]


def checked_action(raw: object, low: np.ndarray, high: np.ndarray) -> np.ndarray | FailureReason:
    """A policy's output as a float action clipped into [low, high], or why it is unusable
    (wrong shape: ``POLICY_ERROR``, NaN/inf: ``POLICY_NONFINITE``)."""
    try:
        action = np.asarray(raw, dtype=np.float64)
    except Exception:  # whatever a learned policy returned, it must not crash the caller
        return FailureReason.POLICY_ERROR
    if action.shape != low.shape:
        return FailureReason.POLICY_ERROR
    if not np.isfinite(action).all():
        return FailureReason.POLICY_NONFINITE
    return np.minimum(np.maximum(action, low), high)


Features = tuple[tuple[Object, ...], np.ndarray]


def state_features(state: State) -> Features:
    """Objects in dict order and all features concatenated (no per-object lookups)."""
    data = state.data
    keys = tuple(data)
    return keys, (np.concatenate(tuple(data.values())) if keys else np.zeros(0))


class SkillExecutor:
    """Executes ground skills for one task. Holds what is constant across executions
    (bounds, the task's horizon, the contact atoms to watch, the deadline) and counts
    every simulated step in ``sim_steps``. ``last_actions`` are the actions of the latest
    execution, also of a failed one (what a rollouts file shows of a failed step).
    Policies see states through the environment's observation (``env.observe``: e.g.
    noisy features); completion tests see the true state."""

    def __init__(
        self,
        env: Environment,
        task: Task,
        config: RolloutConfig,
        deadline: float | None = None,
    ) -> None:
        self.env = env
        self.low = np.asarray(env.action_low, dtype=np.float64)
        self.high = np.asarray(env.action_high, dtype=np.float64)
        self.set_limits(config)
        self.horizon = task.horizon
        self.deadline = deadline
        self.sim_steps = 0
        self.last_actions: list[np.ndarray] = []
        self.last_states: list[State] = []  # the states those actions led to
        self.last_subgoal: np.ndarray | None = None
        self.observe = observation_of(env)
        # what policies see may be advanced by the commands still in flight
        # (bpns.acting.prediction); ``sent`` holds the commands of earlier executions
        self.predict: Callable[..., State] | None = None
        self.sent: list[np.ndarray] = []
        self.dead_end = env.capabilities.dead_end if config.end_at_dead_end else None
        # every ground contact-related atom over the task's objects (segmentation's set)
        self.contact_watch: list = []
        if config.end_on_contact_change:
            self.contact_watch = [
                (p.classifier, objs)
                for p in sorted(env.contact_predicates)
                for objs in object_tuples(task.init.objects, p.types)
            ]

    def set_limits(self, config: RolloutConfig) -> None:
        """Execute from now on with ``config`` (e.g. a world that slows its skills once
        it showed it differs from the model)."""
        self.config = config
        self.slowed = motion_index(self.env) if config.speed != 1.0 else None

    def contact_values(self, state: State) -> tuple[bool, ...]:
        return tuple(bool(c(state, o)) for c, o in self.contact_watch)

    def unchanged(self, old: Features, new: Features) -> bool:
        """Is every feature of ``new`` within ``stuck_atol`` of ``old``?"""
        atol = self.config.stuck_atol
        if old[0] != new[0]:  # rare: other dict order (align by object) or other objects
            if set(old[0]) != set(new[0]):
                return False
            parts = _split(old)
            a = np.concatenate([parts[o] for o in new[0]])
            return a.shape == new[1].shape and bool((np.abs(a - new[1]) <= atol).all())
        if old[1].shape != new[1].shape:
            return False
        return bool((np.abs(old[1] - new[1]) <= atol).all())

    def execute(
        self,
        skill: Skill,
        objects: Sequence[Object],
        subgoal: np.ndarray,
        state: State,
        test: CompletionTest,
        used_steps: int = 0,
        keep: Sequence[GroundAtom] = (),
        keep_for: int = 1,
        keep_until: Sequence[GroundAtom] = (),
        until: Sequence[GroundAtom] = (),
    ) -> Executed | FailureReason:
        """Roll ``skill``'s policy out from ``state`` towards ``subgoal`` until ``test``
        holds; ``used_steps`` actions of the task's horizon are already spent. ``keep``:
        atoms that must go on holding (an execution monitor's); one that stays false
        ``keep_for`` steps in a row ends the execution (``ATOM_LOST``). ``keep_until``:
        atoms that must go on holding likewise until every ``until`` atom holds."""
        must_hold = [(a.predicate.classifier, a.objects) for a in test.must_hold]
        must_not_hold = [(a.predicate.classifier, a.objects) for a in test.must_not_hold]
        policy = skill.policy
        simulate = self.env.simulate
        low, high = self.low, self.high
        deadline = self.deadline
        stuck_steps = self.config.stuck_steps
        observe = self.observe
        dead_end = self.dead_end
        actions: list[np.ndarray] = []
        states: list[State] = []
        self.last_actions, self.last_states, self.last_subgoal = actions, states, subgoal
        feats = state_features(state)
        unchanged = 0
        watch = self.contact_values(state) if self.contact_watch else None
        kept = [(a.predicate.classifier, a.objects) for a in keep]
        kept_until = [(a.predicate.classifier, a.objects) for a in keep_until]
        released = [(a.predicate.classifier, a.objects) for a in until]
        lost = 0
        slowed, speed = self.slowed, self.config.speed
        limit = self.config.max_skill_horizon
        if skill.horizon is not None:
            limit = min(limit, math.ceil(skill.horizon * self.config.horizon_scale))
        for t in range(limit):
            if deadline is not None and time.monotonic() >= deadline:
                raise ExecutionTimeout
            if used_steps + t >= self.horizon:
                return FailureReason.TASK_HORIZON
            seen = observe(state)
            if self.predict is not None:
                seen = self.predict(state, seen, self.sent, actions)
            try:
                raw = policy(seen, objects, subgoal)
            except Exception:
                return FailureReason.POLICY_ERROR
            action = checked_action(raw, low, high)
            if isinstance(action, FailureReason):
                return action
            if slowed is not None:
                action[slowed] *= speed
            state = simulate(state, action)
            self.sim_steps += 1
            actions.append(action)
            states.append(state)
            if _complete(state, must_hold, must_not_hold):
                return Executed(actions, states)
            if dead_end is not None and dead_end(state):
                return FailureReason.DEAD_END
            if watch is not None and self.contact_values(state) != watch:
                return FailureReason.CONTACT_CHANGED
            if kept or kept_until:
                held = all(c(state, o) for c, o in kept) and (
                    not kept_until
                    or all(c(state, o) for c, o in kept_until)
                    or all(c(state, o) for c, o in released)
                )
                lost = 0 if held else lost + 1
                if lost >= keep_for:
                    return FailureReason.ATOM_LOST
            # ``feats`` is an anchor: the state where the world last stood still. Comparing
            # with it, not with the previous step, also catches a limit cycle (an arm
            # chattering at its reach limit moves every step but goes nowhere).
            new_feats = state_features(state)
            if self.unchanged(feats, new_feats):
                unchanged += 1
                if unchanged >= stuck_steps:
                    return FailureReason.STUCK
            else:
                unchanged = 0
                feats = new_feats
        return FailureReason.SKILL_HORIZON


class NotSlowableError(BpnsError, ValueError):
    """A speed below 1 asked of an environment that declares no ``motion_dims``."""


def motion_index(env: Environment) -> np.ndarray:
    """The action indices a speed scales (the environment's ``motion_dims``), checked
    against its action's size."""
    dims = env.capabilities.motion_dims
    size = np.asarray(env.action_low).size
    if dims is None:
        raise NotSlowableError(
            "this environment declares no motion_dims (Capabilities), so its skills cannot "
            "be slowed: leave the world speed at 1"
        )
    if max(dims) >= size:
        raise NotSlowableError(
            f"motion_dims {dims} name an action index beyond the action's {size} dims"
        )
    return np.asarray(dims, dtype=np.intp)


def _split(f: Features) -> dict[Object, np.ndarray]:
    out, k = {}, 0
    for o in f[0]:
        out[o] = f[1][k : k + o.type.dim]
        k += o.type.dim
    return out


def _complete(state: State, must_hold: list, must_not_hold: list) -> bool:
    for classifier, objs in must_hold:
        if not classifier(state, objs):
            return False
    for classifier, objs in must_not_hold:
        if classifier(state, objs):
            return False
    return True
