"""Backtracking refinement of one abstract plan into actions (paper §5, Alg. 1 line 3).

For step i the ground skill's sampler proposes a subgoal and its policy is rolled out in
the exact simulator (:class:`bpns.execution.SkillExecutor`) until the step's expected
abstract state holds (and the operator's delete effects no longer do). A sample fails
when the sampler misbehaves (exception or non-finite output) or the execution fails
(skill horizon, stuck, task horizon, policy errors: see :mod:`bpns.execution`).
After ``n_samples`` failed samples at step i we backtrack and resample step i - 1.

Only the atoms the step's test needs are evaluated, once per simulated state, and adds
(the atoms most likely still false) first, so the test usually stops at the first atom.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.environment import Environment
from bpns.execution import (
    CompletionTest,
    Executed,
    ExecutionTimeout,
    RolloutConfig,
    SkillExecutor,
    completion_test,
    state_features,
)
from bpns.failures import NOT_EXECUTED, FailureReason
from bpns.planning.config import PlanningConfig
from bpns.planning.nogoods import NogoodMemo, PrefixCache
from bpns.planning.search import AbstractPlan
from bpns.rollouts import REACHED, Rollout, further, rollout_of
from bpns.structs import GroundOperator, Skill, State, Task


@dataclass(frozen=True)
class RefinementStats:
    samples: int = 0
    sim_steps: int = 0
    backtracks: int = 0
    sample_failures: tuple[tuple[FailureReason, int], ...] = ()
    # per step of the skeleton: successful samples and failed ones by reason (what
    # `bpns eval --explain` shows of a failed task)
    step_successes: tuple[int, ...] = ()
    step_failures: tuple[tuple[tuple[FailureReason, int], ...], ...] = ()

    def failures(self, reason: str) -> int:
        return dict(self.sample_failures).get(reason, 0)


@dataclass(frozen=True, eq=False)
class RefinementResult:
    """Outcome of refining one skeleton.

    On success ``actions`` (k x action_dim) take ``states[0]`` = the task's initial state
    to ``states[-1]``; step i of the skeleton used ``actions[step_starts[i]:step_starts[i+1]]``
    with ``subgoals[i]``. On failure the sequences are empty and ``reason`` says why
    (``EXHAUSTED`` or ``TIMEOUT``).
    """

    success: bool
    actions: np.ndarray
    states: tuple[State, ...]
    skills: tuple[Skill, ...]
    operators: tuple[GroundOperator, ...]
    subgoals: tuple[np.ndarray, ...]
    step_starts: tuple[int, ...]
    reason: FailureReason | None
    stats: RefinementStats = field(default_factory=RefinementStats)
    # a failed refinement: the deepest refined prefix and the failed sample after it
    furthest: Rollout | None = None


@dataclass
class _Counters:
    steps: int
    samples: int = 0
    backtracks: int = 0
    failures: Counter = field(default_factory=Counter)
    step_successes: list[int] = field(default_factory=list)
    step_failures: list[Counter] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.step_successes = [0] * self.steps
        self.step_failures = [Counter() for _ in range(self.steps)]

    def failed(self, step: int, reason: FailureReason) -> None:
        self.failures[reason] += 1
        self.step_failures[step][reason] += 1

    def freeze(self, sim_steps: int) -> RefinementStats:
        return RefinementStats(
            self.samples,
            sim_steps,
            self.backtracks,
            tuple(sorted(self.failures.items())),
            tuple(self.step_successes),
            tuple(tuple(sorted(c.items())) for c in self.step_failures),
        )


@dataclass
class _Segment:
    """What one successful sample produced."""

    subgoal: np.ndarray
    actions: list[np.ndarray]
    states: list[State]  # states after each action


def _sample(
    executor: SkillExecutor,
    counters: _Counters,
    nogood_atol: float | None,
    skill: Skill,
    op: GroundOperator,
    test: CompletionTest,
    state: State,
    used_steps: int,
    rng: np.random.Generator,
    refuted: list[np.ndarray] | None = None,
) -> _Segment | FailureReason:
    """One sample of one step: a segment on success, else the failure reason.

    A subgoal within ``nogood_atol`` of one in ``refuted`` (subgoals that succeeded from
    this very state but whose continuation was refuted) is not simulated again: policy
    and physics are deterministic, so it would reach the same dead end. Subgoals that
    failed themselves are not remembered: a learned policy's success can hinge on
    millimetres, so a neighbour deserves its own try."""
    counters.samples += 1
    objects = op.objects
    try:
        subgoal = np.asarray(skill.sampler(state, objects, rng), dtype=np.float64)
    except Exception:
        return FailureReason.SAMPLER_ERROR
    if not np.isfinite(subgoal).all():
        return FailureReason.SAMPLER_NONFINITE
    if refuted is not None:
        for old in refuted:
            if (
                old.shape == subgoal.shape
                and np.max(np.abs(old - subgoal), initial=0) <= nogood_atol
            ):
                return FailureReason.NOGOOD
    out = executor.execute(skill, objects, subgoal, state, test, used_steps)
    if isinstance(out, Executed):
        return _Segment(subgoal, out.actions, out.states)
    return out


def _attempt(
    plan: AbstractPlan,
    segments: Sequence[_Segment | None],
    i: int,
    executor: SkillExecutor,
    reason: FailureReason,
) -> Rollout:
    """Steps 0..i-1 as refined, then step i's failed sample (its actions, if it ran)."""
    done = [
        (op, seg.subgoal, seg.actions, REACHED)
        for op, seg in zip(plan.operators[:i], segments[:i], strict=True)
        if seg is not None
    ]
    ran = reason not in NOT_EXECUTED
    failed = (
        plan.operators[i],
        executor.last_subgoal if ran else None,
        executor.last_actions if ran else [],
        str(reason),
    )
    return rollout_of([*done, failed], executor.low.size)


def _flat(state: State) -> np.ndarray:
    return state_features(state)[1]


def refine(
    plan: AbstractPlan,
    skills: Sequence[Skill],
    task: Task,
    env: Environment,
    config: PlanningConfig,
    rng: np.random.Generator,
    deadline: float | None = None,
    memo: NogoodMemo | None = None,
    prefixes: PrefixCache | None = None,
) -> RefinementResult:
    """Backtracking search over subgoal samples for ``plan``.

    ``skills[i]`` is the skill whose operator ``plan.operators[i]`` grounds; its sampler
    and policy receive ``plan.operators[i].objects``. ``deadline`` is a
    ``time.monotonic()`` value, checked before every simulation step. ``memo`` (shared by
    the skeletons of one ``plan`` call) refutes steps and suffixes already refuted from a
    matching state and records new refutations (see :mod:`bpns.planning.nogoods`);
    ``prefixes`` lets the refinement start after the deepest prefix already refined.
    """
    if len(skills) != len(plan.operators):
        raise ValueError(
            f"need one skill per plan step: {len(skills)} skills, {len(plan.operators)} steps"
        )
    for skill, op in zip(skills, plan.operators, strict=True):
        if skill.operator != op.operator:
            raise ValueError(f"skill {skill.name} does not match plan step {op}")
    tests = [
        completion_test(op, nxt) for op, nxt in zip(plan.operators, plan.atoms[1:], strict=True)
    ]
    counters = _Counters(len(plan.operators))
    executor = SkillExecutor(env, task, RolloutConfig.of(config), deadline)
    n = len(plan.operators)
    keys = [
        NogoodMemo.step_key(op, t.must_hold, t.must_not_hold)
        for op, t in zip(plan.operators, tests, strict=True)
    ]
    segments: list[_Segment | None] = [None] * n
    tries = [0] * n
    successes = [0] * n  # successful samples since the current arrival at step i
    horizon_hit = [False] * n  # a failure that depends on the prefix's length
    # successful subgoals since the current arrival at step i (their continuations failed
    # whenever refinement is back at step i)
    refuted: list[list[np.ndarray] | None] = [[] if memo is not None else None for _ in range(n)]
    starts: list[State] = [task.init] * (n + 1)  # state at the start of step i
    used = [0] * (n + 1)  # actions taken before step i
    i = 0
    for seg in prefixes.longest(keys) if prefixes is not None else ():
        segments[i], tries[i], successes[i] = seg, 1, 1
        if refuted[i] is not None:
            refuted[i].append(seg.subgoal)
        starts[i + 1] = seg.states[-1]
        used[i + 1] = used[i] + len(seg.actions)
        i += 1
    reason: FailureReason | None = None
    furthest: Rollout | None = None
    try:
        while i < n:
            exhausted = tries[i] >= config.n_samples
            if exhausted and memo is not None and not horizon_hit[i]:
                memo.add(keys[i] if successes[i] == 0 else tuple(keys[i:]), _flat(starts[i]))
            elif tries[i] == 0 and memo is not None:  # a fresh arrival at step i
                x = _flat(starts[i])
                if memo.refuted(keys[i], x) or memo.refuted(tuple(keys[i:]), x):
                    counters.failed(i, FailureReason.NOGOOD)
                    exhausted = True
            if exhausted:
                if i > 0:  # a suffix refuted only for lack of time steps is not recorded
                    horizon_hit[i - 1] |= horizon_hit[i]
                tries[i], successes[i], horizon_hit[i] = 0, 0, False
                if refuted[i] is not None:
                    refuted[i] = []
                if i == 0:
                    reason = FailureReason.EXHAUSTED
                    break
                i -= 1
                counters.backtracks += 1
                continue
            tries[i] += 1
            out = _sample(
                executor,
                counters,
                config.nogood_atol,
                skills[i],
                plan.operators[i],
                tests[i],
                starts[i],
                used[i],
                rng,
                refuted[i],
            )
            if isinstance(out, FailureReason):
                counters.failed(i, out)
                horizon_hit[i] |= out is FailureReason.TASK_HORIZON
                ran = len(executor.last_actions) if out not in NOT_EXECUTED else 0
                reached = (i, used[i] + ran)
                if furthest is None or reached > furthest.progress:
                    furthest = further(furthest, _attempt(plan, segments, i, executor, out))
                continue
            successes[i] += 1
            counters.step_successes[i] += 1
            if refuted[i] is not None:
                refuted[i].append(out.subgoal)
            segments[i] = out
            starts[i + 1] = out.states[-1]
            used[i + 1] = used[i] + len(out.actions)
            i += 1
            if prefixes is not None:
                prefixes.add(keys[:i], segments[:i])
    except ExecutionTimeout:
        counters.failed(min(i, n - 1), FailureReason.TIMEOUT)
        reason = FailureReason.TIMEOUT
        if i < n:
            timed_out = _attempt(plan, segments, i, executor, FailureReason.TIMEOUT)
            furthest = further(furthest, timed_out)
    stats = counters.freeze(executor.sim_steps)
    if reason is not None:
        return RefinementResult(
            False, np.zeros((0, executor.low.size)), (), (), (), (), (), reason, stats, furthest
        )
    segs = [s for s in segments if s is not None]
    actions = [a for s in segs for a in s.actions]
    return RefinementResult(
        success=True,
        actions=np.array(actions, dtype=np.float64).reshape(len(actions), executor.low.size),
        states=(task.init, *(x for s in segs for x in s.states)),
        skills=tuple(skills),
        operators=plan.operators,
        subgoals=tuple(s.subgoal for s in segs),
        step_starts=tuple(used[:n]),
        reason=None,
        stats=stats,
    )
