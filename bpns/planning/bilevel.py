"""Bilevel planning (paper Alg. 1): lazily generated abstract plans, each refined in turn.

A skeleton whose refinement is set aside (one step failed from several arrivals, see
``PlanningConfig.set_aside_after``) is refined again, without that limit, after the
search has produced its last skeleton: setting aside reorders the work, it never drops
a skeleton the paper's planner would have refined.

``plan`` never lets a timeout escape: once the wall-clock budget is spent (checked in the
grounding and search loops and before every simulation step) it returns a failed
:class:`PlanResult` with reason ``"timeout"``.
"""

from __future__ import annotations

import dataclasses
import time
from collections import Counter
from collections.abc import Collection, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.env.abstraction import abstract
from bpns.env.environment import Environment
from bpns.execution.failures import FailureReason
from bpns.execution.rollouts import Rollout, further
from bpns.planning.config import PlanningConfig
from bpns.planning.heuristics import make_heuristic
from bpns.planning.nogoods import NogoodMemo, PrefixCache, RefutedAchievers, SetAsidePrefixes
from bpns.planning.refinement import RefinementResult, RefinementStats, refine
from bpns.planning.search import STRATEGIES, AbstractPlan, SearchStats, skeletons
from bpns.planning.strips import GroundProblem, SearchTimeout, ground
from bpns.structs import GroundAtom, GroundOperator, Skill, State, STRIPSOperator, Task


@dataclass(frozen=True)
class PlanningStats:
    nodes_created: int = 0
    nodes_expanded: int = 0
    ground_operators: int = 0
    abstract_plans_tried: int = 0
    samples_drawn: int = 0
    sim_steps: int = 0
    backtracks: int = 0
    search_time: float = 0.0  # grounding + heuristic search (s)
    refinement_time: float = 0.0  # sampling + simulation (s)
    total_time: float = 0.0
    sample_failures: tuple[tuple[FailureReason, int], ...] = ()
    # the first MAX_RECORDED_ATTEMPTS skeletons refined, step by step (for explanations)
    attempts: tuple[SkeletonAttempt, ...] = ()


MAX_RECORDED_ATTEMPTS = 20


@dataclass(frozen=True)
class SkeletonAttempt:
    """One abstract plan's refinement: per step, successful samples and failures by
    reason; ``reason`` is why the refinement failed (None: it succeeded)."""

    steps: tuple[str, ...]
    reason: FailureReason | None
    step_successes: tuple[int, ...]
    step_failures: tuple[tuple[tuple[FailureReason, int], ...], ...]

    def to_json(self) -> dict:
        return {
            "plan": list(self.steps),
            "reason": None if self.reason is None else str(self.reason),
            "steps": [
                {"step": step, "successes": ok, "failures": {str(r): n for r, n in failed}}
                for step, ok, failed in zip(
                    self.steps, self.step_successes, self.step_failures, strict=True
                )
            ],
        }


@dataclass(frozen=True, eq=False)
class PlanResult:
    """Outcome of :func:`plan`.

    On success ``actions`` (k x action_dim) take ``states[0]`` (the task's initial state)
    to ``states[-1]`` where the goal holds; ``skeleton`` is the abstract plan refined and
    ``skills`` the skill used at each of its steps. On failure ``actions`` is empty,
    ``states`` is ``(init,)`` and ``reason`` says why (``TIMEOUT``, ``NO_ABSTRACT_PLAN``
    or ``REFINEMENT_FAILED``).
    """

    success: bool
    actions: np.ndarray
    states: tuple[State, ...]
    skeleton: AbstractPlan | None
    skills: tuple[Skill, ...]
    reason: FailureReason | None
    stats: PlanningStats = field(default_factory=PlanningStats)
    step_starts: tuple[int, ...] = ()
    subgoals: tuple[np.ndarray, ...] = ()
    # a failed plan: the refinement attempt that got furthest (bpns.execution.rollouts)
    furthest: Rollout | None = None


def plan(
    task: Task,
    skills: Sequence[Skill],
    env: Environment,
    config: PlanningConfig,
    rng: np.random.Generator,
    *,
    resume_from: frozenset[GroundAtom] | None = None,
    tried: Collection[tuple[GroundOperator, ...]] = (),
) -> PlanResult:
    """Solve ``task`` with ``skills`` by bilevel planning within ``config.timeout`` seconds.

    ``resume_from`` (atoms seen true earlier in the same run): plan from a state where a
    skill was stopped midway, which the learned operators need not describe (the
    demonstrations never stop one); the first step may be an operator that lacks only
    preconditions it deletes itself (:func:`bpns.planning.search.skeletons`'s
    ``resume``), grounded as if the atoms seen earlier still held. Refinement in the
    model decides whether the skill really finishes from there.

    ``tried``: abstract plans the caller already refined from this very state and saw
    fail (a closed loop's repair of the rest of its plan). They are passed over, as the
    search passes over the skeletons it yielded itself: a skeleton is refined once per
    call, and the caller's attempt was that once."""
    start = time.monotonic()
    deadline = start + config.timeout
    by_operator = _skills_by_operator(skills)
    action_dim = np.asarray(env.action_low).size
    acc = _Accumulator(start)

    init_atoms = abstract(task.init, env.predicates)
    if task.goal <= init_atoms:
        return acc.result(True, task, action_dim, None, AbstractPlan((), (init_atoms,), 0.0))

    try:
        generator = _Skeletons(
            task, by_operator, init_atoms, config, deadline, acc, resume_from, tried
        )
        refiner = _Refiner(
            task,
            by_operator,
            env,
            rng,
            deadline,
            None if config.nogood_atol is None else NogoodMemo(config.nogood_atol),
            PrefixCache() if config.reuse_prefixes else None,
            SetAsidePrefixes(),
        )
        solved = _refine_in_turn(generator, refiner, config, acc)
    except SearchTimeout:
        return acc.result(False, task, action_dim, FailureReason.TIMEOUT, None)
    if solved is not None:
        return solved
    # a plan passed over because the caller had tried it was still an abstract plan
    tried_any = acc.plans_tried or acc.search.skipped
    reason = FailureReason.REFINEMENT_FAILED if tried_any else FailureReason.NO_ABSTRACT_PLAN
    return acc.result(False, task, action_dim, reason, None)


def _skills_by_operator(skills: Sequence[Skill]) -> dict[STRIPSOperator, Skill]:
    """Each skeleton step names an operator: it must pick out exactly one skill."""
    by_operator: dict[STRIPSOperator, Skill] = {}
    for s in skills:
        if s.operator in by_operator:
            raise ValueError(f"two skills share the operator {s.operator.name}")
        by_operator[s.operator] = s
    return by_operator


class _Skeletons:
    """The lazy abstract-plan search over the grounded task, restarted with new operator
    costs when refinement demotes an achiever (``PlanningConfig.demote_refuted``);
    skeletons already yielded are not yielded again, and at most ``n_abstract`` are
    yielded in all. Grounding counts as search time; raises ``SearchTimeout`` past
    ``deadline``."""

    def __init__(
        self,
        task: Task,
        by_operator: dict[STRIPSOperator, Skill],
        init_atoms: frozenset[GroundAtom],
        config: PlanningConfig,
        deadline: float,
        acc: _Accumulator,
        resume_from: frozenset[GroundAtom] | None = None,
        tried: Collection[tuple[GroundOperator, ...]] = (),
    ) -> None:
        t0 = time.monotonic()
        try:
            operators = list(by_operator)
            if resume_from is None:
                self.problem = ground(operators, task.objects, init_atoms, task.goal, deadline)
            else:  # a stopped skill's operator needs atoms no longer true to be grounded
                reached = ground(
                    operators, task.objects, init_atoms | resume_from, task.goal, deadline
                )
                self.problem = GroundProblem.from_ground_operators(
                    reached.operators, init_atoms, task.goal
                )
            self.heuristic = (
                None if config.search == "ucs" else make_heuristic(config.heuristic, self.problem)
            )
        finally:
            acc.search_time += time.monotonic() - t0
        acc.ground_operators = len(self.problem.operators)
        self.config = config
        self.max_length = min(config.max_plan_length, task.horizon)  # each skill acts >= once
        self.deadline = deadline
        self.acc = acc
        self.resume = resume_from is not None
        self.skip = set(tried)  # passed over: yielded here or refined by the caller
        self.yielded = 0
        self.demotions = (
            None if config.demote_refuted is None else RefutedAchievers(config.demote_refuted)
        )
        self._search = self._start()

    def _start(self) -> Iterator[AbstractPlan]:
        extra = (
            None
            if self.demotions is None or not self.demotions.demoted
            else self.demotions.extra_cost(self.problem.operators)
        )
        return skeletons(
            self.problem,
            self.heuristic,
            STRATEGIES[self.config.search],
            max_skeletons=self.config.n_abstract,
            max_length=self.max_length,
            max_repeats=self.config.max_state_repeats,
            deadline=self.deadline,
            stats=self.acc.search,
            extra_cost=extra,
            skip=self.skip,
            resume=self.resume,
        )

    def next(self) -> AbstractPlan | None:
        if self.yielded >= self.config.n_abstract:
            return None
        skeleton = next(self._search, None)
        if skeleton is not None:
            self.yielded += 1
            self.skip.add(skeleton.operators)
        return skeleton

    def refined(self, skeleton: AbstractPlan, stats: RefinementStats) -> None:
        """Learn from a skeleton's refinement; restart the search if demotions changed."""
        if self.demotions is not None and self.demotions.observe(
            skeleton.operators, stats.step_successes, stats.step_refutations
        ):
            self._search = self._start()


@dataclass(frozen=True, eq=False)
class _Refiner:
    """What every skeleton's refinement shares within one call of :func:`plan`: the
    task, the skills, the clock and the memories of refuted states and prefixes."""

    task: Task
    by_operator: dict[STRIPSOperator, Skill]
    env: Environment
    rng: np.random.Generator
    deadline: float
    memo: NogoodMemo | None
    prefixes: PrefixCache | None
    doomed: SetAsidePrefixes

    def refine(self, skeleton: AbstractPlan, config: PlanningConfig) -> RefinementResult:
        return refine(
            skeleton,
            [self.by_operator[op.operator] for op in skeleton.operators],
            self.task,
            self.env,
            config,
            self.rng,
            self.deadline,
            self.memo,
            self.prefixes,
            self.doomed,
        )


def _refine_in_turn(
    generator: _Skeletons,
    refiner: _Refiner,
    config: PlanningConfig,
    acc: _Accumulator,
) -> PlanResult | None:
    """Refine each skeleton as the search yields it, then those set aside without the
    limit; the first refined is the plan (None: none was). Raises ``SearchTimeout``."""
    set_aside: list[AbstractPlan] = []  # refined again, without the limit, at the end
    patient = dataclasses.replace(config, set_aside_after=None)
    while True:
        t0 = time.monotonic()
        try:
            skeleton = generator.next()
        finally:
            acc.search_time += time.monotonic() - t0
        refining = config
        if skeleton is None:
            if not set_aside:
                return None
            skeleton, refining = set_aside.pop(0), patient
        acc.plans_tried += 1
        t0 = time.monotonic()
        ref = refiner.refine(skeleton, refining)
        acc.refinement_time += time.monotonic() - t0
        acc.add(ref.stats, skeleton, ref.reason)
        t0 = time.monotonic()
        try:
            generator.refined(skeleton, ref.stats)
        finally:
            acc.search_time += time.monotonic() - t0
        acc.furthest = further(acc.furthest, ref.furthest)
        if ref.success:
            return _solved(ref, skeleton, acc)
        if ref.reason is FailureReason.TIMEOUT:
            raise SearchTimeout
        if ref.reason is FailureReason.SET_ASIDE:
            set_aside.append(skeleton)


def _solved(ref: RefinementResult, skeleton: AbstractPlan, acc: _Accumulator) -> PlanResult:
    """The plan of a refined ``skeleton``, with the statistics of the whole search."""
    return PlanResult(
        success=True,
        actions=ref.actions,
        states=ref.states,
        skeleton=skeleton,
        skills=ref.skills,
        reason=None,
        stats=acc.freeze(),
        step_starts=ref.step_starts,
        subgoals=ref.subgoals,
    )


class _Accumulator:
    """Sums statistics over the skeletons tried; frozen into PlanningStats at the end."""

    def __init__(self, start: float) -> None:
        self.start = start
        self.plans_tried = 0
        self.ground_operators = 0
        self.search_time = 0.0
        self.refinement_time = 0.0
        self.samples = 0
        self.sim_steps = 0
        self.backtracks = 0
        self.failures: Counter = Counter()
        self.attempts: list[SkeletonAttempt] = []
        self.search = SearchStats()  # updated in place by the skeleton generator
        self.furthest: Rollout | None = None

    def add(self, s: RefinementStats, skeleton: AbstractPlan, reason: FailureReason | None) -> None:
        self.samples += s.samples
        self.sim_steps += s.sim_steps
        self.backtracks += s.backtracks
        self.failures.update(dict(s.sample_failures))
        if len(self.attempts) < MAX_RECORDED_ATTEMPTS:
            steps = tuple(str(op) for op in skeleton.operators)
            self.attempts.append(SkeletonAttempt(steps, reason, s.step_successes, s.step_failures))

    def freeze(self) -> PlanningStats:
        return PlanningStats(
            nodes_created=self.search.nodes_created,
            nodes_expanded=self.search.nodes_expanded,
            ground_operators=self.ground_operators,
            abstract_plans_tried=self.plans_tried,
            samples_drawn=self.samples,
            sim_steps=self.sim_steps,
            backtracks=self.backtracks,
            search_time=self.search_time,
            refinement_time=self.refinement_time,
            total_time=time.monotonic() - self.start,
            sample_failures=tuple(sorted(self.failures.items())),
            attempts=tuple(self.attempts),
        )

    def result(
        self,
        success: bool,
        task: Task,
        action_dim: int,
        reason: FailureReason | None,
        skeleton: AbstractPlan | None,
    ) -> PlanResult:
        return PlanResult(
            success,
            np.zeros((0, action_dim)),
            (task.init,),
            skeleton,
            (),
            reason,
            self.freeze(),
            furthest=self.furthest,
        )
