"""Backtracking refinement of one abstract plan into actions (paper §5, Alg. 1 line 3).

For step i the ground skill's sampler proposes a subgoal and its policy is rolled out in
the exact simulator until the step's expected abstract state holds (and the operator's
delete effects no longer do). A sample fails when the skill horizon is hit, the state
stops changing, the task horizon would be exceeded, or the learned sampler/policy
misbehaves (exception or non-finite output): learned networks must never crash planning.
After ``n_samples`` failed samples at step i we backtrack and resample step i - 1.

Only the atoms the step's test needs are evaluated, once per simulated state, and adds
(the atoms most likely still false) first, so the test usually stops at the first atom.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.abstraction import object_tuples
from bpns.environment import Environment
from bpns.planning.config import PlanningConfig
from bpns.planning.nogoods import NogoodMemo, PrefixCache
from bpns.planning.search import AbstractPlan
from bpns.structs import GroundAtom, GroundOperator, Object, Skill, State, Task

# Why one sample failed (keys of RefinementStats.sample_failures).
SAMPLER_ERROR = "sampler_error"
SAMPLER_NONFINITE = "sampler_nonfinite"
POLICY_ERROR = "policy_error"
POLICY_NONFINITE = "policy_nonfinite"
SKILL_HORIZON = "skill_horizon"
STUCK = "stuck"
CONTACT_CHANGED = "unexpected_contact_change"
TASK_HORIZON = "task_horizon"
TIMEOUT = "timeout"
NOGOOD = "nogood"  # a fresh arrival at a step refuted by the memo (no sample drawn)
# Why a whole refinement failed.
EXHAUSTED = "exhausted"


@dataclass(frozen=True)
class RefinementStats:
    samples: int = 0
    sim_steps: int = 0
    backtracks: int = 0
    sample_failures: tuple[tuple[str, int], ...] = ()

    def failures(self, reason: str) -> int:
        return dict(self.sample_failures).get(reason, 0)


@dataclass(frozen=True, eq=False)
class RefinementResult:
    """Outcome of refining one skeleton.

    On success ``actions`` (k x action_dim) take ``states[0]`` = the task's initial state
    to ``states[-1]``; step i of the skeleton used ``actions[step_starts[i]:step_starts[i+1]]``
    with ``subgoals[i]``. On failure the sequences are empty and ``reason`` says why
    ("exhausted" or "timeout").
    """

    success: bool
    actions: np.ndarray
    states: tuple[State, ...]
    skills: tuple[Skill, ...]
    operators: tuple[GroundOperator, ...]
    subgoals: tuple[np.ndarray, ...]
    step_starts: tuple[int, ...]
    reason: str | None
    stats: RefinementStats = field(default_factory=RefinementStats)


@dataclass
class _Counters:
    samples: int = 0
    sim_steps: int = 0
    backtracks: int = 0
    failures: Counter = field(default_factory=Counter)

    def freeze(self) -> RefinementStats:
        return RefinementStats(
            self.samples, self.sim_steps, self.backtracks, tuple(sorted(self.failures.items()))
        )


@dataclass
class _Segment:
    """What one successful sample produced."""

    subgoal: np.ndarray
    actions: list[np.ndarray]
    states: list[State]  # states after each action


class _Timeout(Exception):
    pass


class _Rollout:
    """Everything constant across the samples of one refinement."""

    def __init__(
        self,
        task: Task,
        env: Environment,
        config: PlanningConfig,
        deadline: float | None,
        counters: _Counters,
    ) -> None:
        self.env = env
        self.low = np.asarray(env.action_low, dtype=np.float64)
        self.high = np.asarray(env.action_high, dtype=np.float64)
        self.config = config
        self.horizon = task.horizon
        self.deadline = deadline
        self.counters = counters
        # every ground contact-related atom over the task's objects (segmentation's set)
        self.contact_watch: list = []
        if config.end_on_contact_change:
            contact = getattr(env, "contact_predicates", frozenset())
            self.contact_watch = [
                (p.classifier, objs)
                for p in sorted(contact)
                for objs in object_tuples(task.init.objects, p.types)
            ]

    def contact_values(self, state: State) -> tuple[bool, ...]:
        return tuple(bool(c(state, o)) for c, o in self.contact_watch)

    @staticmethod
    def features(state: State) -> tuple[tuple[Object, ...], np.ndarray]:
        """Objects in dict order and all features concatenated (no per-object lookups)."""
        data = state.data
        keys = tuple(data)
        return keys, (np.concatenate(tuple(data.values())) if keys else np.zeros(0))

    def unchanged(
        self, old: tuple[tuple[Object, ...], np.ndarray], new: tuple[tuple[Object, ...], np.ndarray]
    ) -> bool:
        if old[0] != new[0]:  # rare: other dict order (align by object) or other objects
            if set(old[0]) != set(new[0]):
                return False
            parts = self._split(old)
            a = np.concatenate([parts[o] for o in new[0]])
            return a.shape == new[1].shape and bool(
                (np.abs(a - new[1]) <= self.config.stuck_atol).all()
            )
        if old[1].shape != new[1].shape:
            return False
        return bool((np.abs(old[1] - new[1]) <= self.config.stuck_atol).all())

    @staticmethod
    def _split(f: tuple[tuple[Object, ...], np.ndarray]) -> dict[Object, np.ndarray]:
        out, k = {}, 0
        for o in f[0]:
            out[o] = f[1][k : k + o.type.dim]
            k += o.type.dim
        return out

    def sample(
        self,
        skill: Skill,
        op: GroundOperator,
        test: tuple[tuple[GroundAtom, ...], tuple[GroundAtom, ...]],
        state: State,
        used_steps: int,
        rng: np.random.Generator,
        refuted: list[np.ndarray] | None = None,
    ) -> _Segment | str:
        """One sample of one step: a segment on success, else the failure reason.

        A subgoal within ``nogood_atol`` of one in ``refuted`` (subgoals that succeeded from
        this very state but whose continuation was refuted) is not simulated again: policy
        and physics are deterministic, so it would reach the same dead end. Subgoals that
        failed themselves are not remembered: a learned policy's success can hinge on
        millimetres, so a neighbour deserves its own try."""
        c = self.counters
        c.samples += 1
        objects = op.objects
        try:
            subgoal = np.asarray(skill.sampler(state, objects, rng), dtype=np.float64)
        except Exception:
            return SAMPLER_ERROR
        if not np.isfinite(subgoal).all():
            return SAMPLER_NONFINITE
        if refuted is not None:
            atol = self.config.nogood_atol
            for old in refuted:
                if old.shape == subgoal.shape and np.max(np.abs(old - subgoal), initial=0) <= atol:
                    return NOGOOD
        must_hold = [(a.predicate.classifier, a.objects) for a in test[0]]
        must_not_hold = [(a.predicate.classifier, a.objects) for a in test[1]]
        policy = skill.policy
        simulate = self.env.simulate
        low, high = self.low, self.high
        deadline = self.deadline
        stuck_steps = self.config.stuck_steps
        actions: list[np.ndarray] = []
        states: list[State] = []
        feats = self.features(state)
        unchanged = 0
        watch = self.contact_values(state) if self.contact_watch else None
        limit = self.config.max_skill_horizon
        if skill.horizon is not None:
            limit = min(limit, skill.horizon)
        for t in range(limit):
            if deadline is not None and time.monotonic() >= deadline:
                raise _Timeout
            if used_steps + t >= self.horizon:
                return TASK_HORIZON
            try:
                action = np.asarray(policy(state, objects, subgoal), dtype=np.float64)
            except Exception:
                return POLICY_ERROR
            if action.shape != low.shape:
                return POLICY_ERROR
            if not np.isfinite(action).all():
                return POLICY_NONFINITE
            action = np.minimum(np.maximum(action, low), high)
            state = simulate(state, action)
            c.sim_steps += 1
            actions.append(action)
            states.append(state)
            if _complete(state, must_hold, must_not_hold):
                return _Segment(subgoal, actions, states)
            if watch is not None and self.contact_values(state) != watch:
                return CONTACT_CHANGED
            # ``feats`` is an anchor: the state where the world last stood still. Comparing
            # with it, not with the previous step, also catches a limit cycle (an arm
            # chattering at its reach limit moves every step but goes nowhere).
            new_feats = self.features(state)
            if self.unchanged(feats, new_feats):
                unchanged += 1
                if unchanged >= stuck_steps:
                    return STUCK
            else:
                unchanged = 0
                feats = new_feats
        return SKILL_HORIZON


def _flat(state: State) -> np.ndarray:
    return _Rollout.features(state)[1]


def _complete(state: State, must_hold: list, must_not_hold: list) -> bool:
    for classifier, objs in must_hold:
        if not classifier(state, objs):
            return False
    for classifier, objs in must_not_hold:
        if classifier(state, objs):
            return False
    return True


def _step_test(
    op: GroundOperator, expected: frozenset[GroundAtom]
) -> tuple[tuple[GroundAtom, ...], tuple[GroundAtom, ...]]:
    """(atoms that must hold, atoms that must not) for a step to be complete.

    Add effects come first: they are usually the ones still false, so the conjunction
    short-circuits after one classifier call on most simulated states.
    """
    adds = op.add_effects & expected
    return tuple(adds) + tuple(expected - adds), tuple(op.delete_effects - expected)


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
    tests = [_step_test(op, nxt) for op, nxt in zip(plan.operators, plan.atoms[1:], strict=True)]
    counters = _Counters()
    roll = _Rollout(task, env, config, deadline, counters)
    n = len(plan.operators)
    keys = [NogoodMemo.step_key(op, *t) for op, t in zip(plan.operators, tests, strict=True)]
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
    reason: str | None = None
    try:
        while i < n:
            exhausted = tries[i] >= config.n_samples
            if exhausted and memo is not None and not horizon_hit[i]:
                memo.add(keys[i] if successes[i] == 0 else tuple(keys[i:]), _flat(starts[i]))
            elif tries[i] == 0 and memo is not None:  # a fresh arrival at step i
                x = _flat(starts[i])
                if memo.refuted(keys[i], x) or memo.refuted(tuple(keys[i:]), x):
                    counters.failures[NOGOOD] += 1
                    exhausted = True
            if exhausted:
                if i > 0:  # a suffix refuted only for lack of time steps is not recorded
                    horizon_hit[i - 1] |= horizon_hit[i]
                tries[i], successes[i], horizon_hit[i] = 0, 0, False
                if refuted[i] is not None:
                    refuted[i] = []
                if i == 0:
                    reason = EXHAUSTED
                    break
                i -= 1
                counters.backtracks += 1
                continue
            tries[i] += 1
            out = roll.sample(
                skills[i], plan.operators[i], tests[i], starts[i], used[i], rng, refuted[i]
            )
            if isinstance(out, str):
                counters.failures[out] += 1
                horizon_hit[i] |= out == TASK_HORIZON
                continue
            successes[i] += 1
            if refuted[i] is not None:
                refuted[i].append(out.subgoal)
            segments[i] = out
            starts[i + 1] = out.states[-1]
            used[i + 1] = used[i] + len(out.actions)
            i += 1
            if prefixes is not None:
                prefixes.add(keys[:i], segments[:i])
    except _Timeout:
        counters.failures[TIMEOUT] += 1
        reason = TIMEOUT
    stats = counters.freeze()
    if reason is not None:
        return RefinementResult(
            False, np.zeros((0, roll.low.size)), (), (), (), (), (), reason, stats
        )
    segs = [s for s in segments if s is not None]
    actions = [a for s in segs for a in s.actions]
    return RefinementResult(
        success=True,
        actions=np.array(actions, dtype=np.float64).reshape(len(actions), roll.low.size),
        states=(task.init, *(x for s in segs for x in s.states)),
        skills=tuple(skills),
        operators=plan.operators,
        subgoals=tuple(s.subgoal for s in segs),
        step_starts=tuple(used[:n]),
        reason=None,
        stats=stats,
    )
