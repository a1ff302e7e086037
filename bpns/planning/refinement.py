"""Backtracking refinement of one abstract plan into actions (paper §5, Alg. 1 line 3).

For step i the ground skill's sampler proposes a subgoal and its policy is rolled out in
the exact simulator (:class:`bpns.execution.executor.SkillExecutor`) until the step's expected
abstract state holds (and the operator's delete effects no longer do). A sample fails
when the sampler misbehaves (exception or non-finite output) or the execution fails
(skill horizon, stuck, task horizon, policy errors: see :mod:`bpns.execution.executor`).
After ``n_samples`` failed samples at step i we backtrack and resample step i - 1; once
step i has failed that way from ``config.set_aside_after`` different arrivals the
skeleton is set aside (:func:`bpns.planning.bilevel.plan` refines it again later).

Only the atoms the step's test needs are evaluated, once per simulated state, and adds
(the atoms most likely still false) first, so the test usually stops at the first atom.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.env.environment import Environment
from bpns.execution.executor import (
    CompletionTest,
    Executed,
    ExecutionTimeout,
    RolloutConfig,
    SkillExecutor,
    completion_test,
    state_features,
)
from bpns.execution.failures import NOT_EXECUTED, FailureReason
from bpns.execution.rollouts import REACHED, Rollout, further, rollout_of
from bpns.planning.config import PlanningConfig
from bpns.planning.nogoods import NogoodMemo, PrefixCache, SetAsidePrefixes, StepKey
from bpns.planning.search import AbstractPlan
from bpns.structs import GroundOperator, NoSubgoal, Skill, State, Task


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
    # per step: arrivals from which every sample failed (not for lack of time steps)
    step_refutations: tuple[int, ...] = ()

    def failures(self, reason: str) -> int:
        return dict(self.sample_failures).get(reason, 0)


@dataclass(frozen=True, eq=False)
class RefinementResult:
    """Outcome of refining one skeleton.

    On success ``actions`` (k x action_dim) take ``states[0]`` = the task's initial state
    to ``states[-1]``; step i of the skeleton used ``actions[step_starts[i]:step_starts[i+1]]``
    with ``subgoals[i]``. On failure the sequences are empty and ``reason`` says why
    (``EXHAUSTED``, ``SET_ASIDE`` or ``TIMEOUT``).
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

    def freeze(self, sim_steps: int, refutations: Sequence[int] = ()) -> RefinementStats:
        return RefinementStats(
            self.samples,
            sim_steps,
            self.backtracks,
            tuple(sorted(self.failures.items())),
            tuple(self.step_successes),
            tuple(tuple(sorted(c.items())) for c in self.step_failures),
            tuple(refutations),
        )


@dataclass
class _Segment:
    """What one successful sample produced."""

    subgoal: np.ndarray
    actions: list[np.ndarray]
    states: list[State]  # states after each action


def _flat(state: State) -> np.ndarray:
    return state_features(state)[1]


@dataclass
class _Step:
    """Step i of the skeleton and where the backtracking search stands at it."""

    skill: Skill
    op: GroundOperator
    test: CompletionTest
    key: StepKey  # the step as the nogood memo and the prefix cache know it
    start: State  # the state the step starts from (the previous step's end)
    used: int = 0  # actions taken before the step
    segment: _Segment | None = None  # the current successful sample
    tries: int = 0  # samples since the current arrival at the step
    successes: int = 0  # successful ones among them
    horizon_hit: bool = False  # a failure that depends on the prefix's length
    refuted_arrivals: int = 0  # arrivals from which every sample failed (never reset)
    # successful subgoals since the current arrival (their continuations failed whenever
    # refinement is back here); None without a nogood memo
    refuted: list[np.ndarray] | None = None

    def succeeded(self, segment: _Segment) -> None:
        self.successes += 1
        if self.refuted is not None:
            self.refuted.append(segment.subgoal)
        self.segment = segment

    def leave(self) -> None:
        """Backtracking leaves the step: the next arrival starts afresh."""
        self.tries, self.successes, self.horizon_hit = 0, 0, False
        if self.refuted is not None:
            self.refuted = []


def _sample(
    executor: SkillExecutor,
    counters: _Counters,
    nogood_atol: float | None,
    step: _Step,
    rng: np.random.Generator,
) -> _Segment | FailureReason:
    """One sample of one step: a segment on success, else the failure reason.

    A subgoal within ``nogood_atol`` of one in ``step.refuted`` (subgoals that succeeded
    from this very state but whose continuation was refuted) is not simulated again:
    policy and physics are deterministic, so it would reach the same dead end. Subgoals
    that failed themselves are not remembered: a learned policy's success can hinge on
    millimetres, so a neighbour deserves its own try."""
    counters.samples += 1
    objects = step.op.objects
    try:
        subgoal = np.asarray(step.skill.sampler(step.start, objects, rng), dtype=np.float64)
    except NoSubgoal:
        return FailureReason.NO_SUBGOAL
    except Exception:
        return FailureReason.SAMPLER_ERROR
    if not np.isfinite(subgoal).all():
        return FailureReason.SAMPLER_NONFINITE
    if step.refuted is not None:
        for old in step.refuted:
            if (
                old.shape == subgoal.shape
                and np.max(np.abs(old - subgoal), initial=0) <= nogood_atol
            ):
                return FailureReason.NOGOOD
    out = executor.execute(step.skill, objects, subgoal, step.start, step.test, step.used)
    if isinstance(out, Executed):
        return _Segment(subgoal, out.actions, out.states)
    return out


def _steps(
    plan: AbstractPlan, skills: Sequence[Skill], task: Task, memo: NogoodMemo | None
) -> list[_Step]:
    if len(skills) != len(plan.operators):
        raise ValueError(
            f"need one skill per plan step: {len(skills)} skills, {len(plan.operators)} steps"
        )
    steps = []
    for skill, op, nxt in zip(skills, plan.operators, plan.atoms[1:], strict=True):
        if skill.operator != op.operator:
            raise ValueError(f"skill {skill.name} does not match plan step {op}")
        test = completion_test(op, nxt)
        key = NogoodMemo.step_key(op, test.must_hold, test.must_not_hold)
        steps.append(
            _Step(skill, op, test, key, task.init, refuted=[] if memo is not None else None)
        )
    return steps


def _advance(steps: list[_Step], i: int, segment: _Segment) -> int:
    """Step i succeeded with ``segment``: the next step starts where it ended."""
    step = steps[i]
    step.succeeded(segment)
    if i + 1 < len(steps):
        steps[i + 1].start = segment.states[-1]
        steps[i + 1].used = step.used + len(segment.actions)
    return i + 1


def _exhausted(
    steps: list[_Step], i: int, n_samples: int, memo: NogoodMemo | None, counters: _Counters
) -> bool:
    """Has step i no sample left? Records a step (or, when it had successes, the suffix
    from it) refuted from its start, or refutes a fresh arrival the memo already knows."""
    step = steps[i]
    if step.tries >= n_samples:
        if step.successes == 0 and not step.horizon_hit:
            step.refuted_arrivals += 1
        if memo is not None and not step.horizon_hit:
            suffix = tuple(s.key for s in steps[i:])
            memo.add(step.key if step.successes == 0 else suffix, _flat(step.start))
        return True
    if step.tries == 0 and memo is not None:  # a fresh arrival at step i
        x = _flat(step.start)
        if memo.refuted(step.key, x) or memo.refuted(tuple(s.key for s in steps[i:]), x):
            counters.failed(i, FailureReason.NOGOOD)
            return True
    return False


def _set_aside(step: _Step, after: int | None) -> bool:
    """Give up on the skeleton for now? Its step failed every sample from ``after``
    different arrivals: what the earlier steps' samples change does not decide it, so
    resampling them in every combination would mostly simulate failures."""
    return after is not None and step.refuted_arrivals >= after


def _backtrack(steps: list[_Step], i: int) -> None:
    """Leave step i for step i - 1 (a suffix refuted only for lack of time steps is not
    recorded by the step before either)."""
    if i > 0:
        steps[i - 1].horizon_hit |= steps[i].horizon_hit
    steps[i].leave()


def _attempt(
    steps: Sequence[_Step], i: int, executor: SkillExecutor, reason: FailureReason
) -> Rollout:
    """Steps 0..i-1 as refined, then step i's failed sample (its actions, if it ran)."""
    done = [(s.op, s.segment.subgoal, s.segment.actions, REACHED) for s in steps[:i] if s.segment]
    ran = reason not in NOT_EXECUTED
    failed = (
        steps[i].op,
        executor.last_subgoal if ran else None,
        executor.last_actions if ran else [],
        str(reason),
    )
    return rollout_of([*done, failed], executor.low.size)


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
    set_aside: SetAsidePrefixes | None = None,
) -> RefinementResult:
    """Backtracking search over subgoal samples for ``plan``.

    ``skills[i]`` is the skill whose operator ``plan.operators[i]`` grounds; its sampler
    and policy receive ``plan.operators[i].objects``. ``deadline`` is a
    ``time.monotonic()`` value, checked before every simulation step. ``memo`` (shared by
    the skeletons of one ``plan`` call) refutes steps and suffixes already refuted from a
    matching state and records new refutations (see :mod:`bpns.planning.nogoods`);
    ``prefixes`` lets the refinement start after the deepest prefix already refined;
    ``set_aside`` (with ``config.set_aside_after``) sets the skeleton aside at once when
    it starts with a prefix set aside before, and records the prefixes it sets aside.
    """
    steps = _steps(plan, skills, task, memo)
    n = len(steps)
    counters = _Counters(n)
    executor = SkillExecutor(env, task, RolloutConfig.of(config), deadline)
    keys = [s.key for s in steps]
    limited = set_aside is not None and config.set_aside_after is not None
    doomed = set_aside.covering(keys) if limited else None
    if doomed is not None:
        counters.failed(doomed, FailureReason.SET_ASIDE)
        return _failed(FailureReason.SET_ASIDE, counters.freeze(0), executor.low.size, None)
    i = 0
    for seg in prefixes.longest(keys) if prefixes is not None else ():
        steps[i].tries = 1
        i = _advance(steps, i, seg)
    reason: FailureReason | None = None
    furthest: Rollout | None = None
    try:
        while i < n:
            step = steps[i]
            if _exhausted(steps, i, config.n_samples, memo, counters):
                _backtrack(steps, i)
                if i == 0:
                    reason = FailureReason.EXHAUSTED
                    break
                if _set_aside(step, config.set_aside_after):
                    reason = FailureReason.SET_ASIDE
                    if set_aside is not None:
                        set_aside.add(keys[: i + 1])
                    break
                i -= 1
                counters.backtracks += 1
                continue
            step.tries += 1
            out = _sample(executor, counters, config.nogood_atol, step, rng)
            if isinstance(out, FailureReason):
                counters.failed(i, out)
                step.horizon_hit |= out is FailureReason.TASK_HORIZON
                ran = len(executor.last_actions) if out not in NOT_EXECUTED else 0
                if furthest is None or (i, step.used + ran) > furthest.progress:
                    furthest = further(furthest, _attempt(steps, i, executor, out))
                continue
            counters.step_successes[i] += 1
            i = _advance(steps, i, out)
            if prefixes is not None:
                prefixes.add(keys[:i], [s.segment for s in steps[:i]])
    except ExecutionTimeout:
        counters.failed(min(i, n - 1), FailureReason.TIMEOUT)
        reason = FailureReason.TIMEOUT
        if i < n:
            furthest = further(furthest, _attempt(steps, i, executor, FailureReason.TIMEOUT))
    stats = counters.freeze(executor.sim_steps, [s.refuted_arrivals for s in steps])
    if reason is not None:
        return _failed(reason, stats, executor.low.size, furthest)
    return _refined(steps, skills, plan, task, executor.low.size, stats)


def _failed(
    reason: FailureReason, stats: RefinementStats, action_dim: int, furthest: Rollout | None
) -> RefinementResult:
    return RefinementResult(
        False, np.zeros((0, action_dim)), (), (), (), (), (), reason, stats, furthest
    )


def _refined(
    steps: list[_Step],
    skills: Sequence[Skill],
    plan: AbstractPlan,
    task: Task,
    action_dim: int,
    stats: RefinementStats,
) -> RefinementResult:
    """The successful result: every step's segment, one after the other."""
    segs = [s.segment for s in steps if s.segment is not None]
    actions = [a for s in segs for a in s.actions]
    return RefinementResult(
        success=True,
        actions=np.array(actions, dtype=np.float64).reshape(len(actions), action_dim),
        states=(task.init, *(x for s in segs for x in s.states)),
        skills=tuple(skills),
        operators=plan.operators,
        subgoals=tuple(s.subgoal for s in segs),
        step_starts=tuple(s.used for s in steps),
        reason=None,
        stats=stats,
    )
