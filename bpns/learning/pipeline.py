"""The whole learning pipeline: segment -> partition -> operators -> policies -> samplers.

Each stage is a plain function in its own module and can be run alone; this module only
chains them, derives one seed per network from the config seed, and records counts and
wall-clock time per stage. Same demos, predicates and config give identical weights
(for a fixed torch thread count).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Collection, Iterator, Sequence
from concurrent.futures import Executor, Future
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from bpns.learning.config import LearningConfig
from bpns.learning.demo_checks import check_demonstrations
from bpns.learning.given import BoundPolicy, BoundSampler, GivenSkill, match_given
from bpns.learning.jobs import (
    POLICIES,
    SAMPLERS,
    NetworkJob,
    TrainedNetwork,
    assemble_sampler,
    policy_data,
    policy_job,
    sampler_fit,
    sampler_jobs,
    torch_threads,
    train_network,
)
from bpns.learning.operators import SkillDataset, learn_operators
from bpns.learning.partition import SegmentGroup, partition_segments
from bpns.learning.samplers import SamplerFit
from bpns.learning.segmentation import segment_demonstration
from bpns.learning.sharing import shared_data
from bpns.pools import make_pool, result_of, submit
from bpns.structs import Demonstration, Predicate, Segment, Skill, STRIPSOperator, Type

STAGES = ("segment", "partition", "operators", "policies", "samplers")


@dataclass(frozen=True)
class SkillStats:
    """What one skill was learned from."""

    name: str
    num_segments: int
    num_policy_samples: int
    num_sampler_negatives: int


@dataclass(frozen=True)
class LearningStats:
    """Counts and per-stage wall-clock seconds of one learning run."""

    num_demos: int
    num_transitions: int
    num_segments: int
    num_groups: int
    num_dropped_groups: int
    num_dropped_segments: int
    skills: tuple[SkillStats, ...]
    stage_seconds: tuple[tuple[str, float], ...]

    @property
    def total_seconds(self) -> float:
        return sum(t for _, t in self.stage_seconds)

    def __str__(self) -> str:
        times = ", ".join(f"{k} {v:.1f}s" for k, v in self.stage_seconds)
        return (
            f"{self.num_demos} demos, {self.num_transitions} transitions "
            f"-> {self.num_segments} segments "
            f"-> {self.num_groups} groups, {self.num_dropped_groups} dropped "
            f"({self.num_dropped_segments} segments) -> {len(self.skills)} skills; {times}"
        )


@dataclass(frozen=True, eq=False)
class LearnedSkills:
    """The result of learning: skills plus what is needed to save and describe them."""

    skills: tuple[Skill, ...]
    predicates: frozenset[Predicate]
    config: LearningConfig
    stats: LearningStats | None = None
    #: per demonstration, in order, the segments the skills were learned from, so the
    #: baselines label the same segmentation instead of redoing it; () for skills loaded
    #: from disk or built by hand (never saved: it holds the demonstrations' states)
    segments: tuple[tuple[Segment, ...], ...] = ()

    @property
    def operators(self) -> tuple[STRIPSOperator, ...]:
        return tuple(s.operator for s in self.skills)

    @property
    def types(self) -> frozenset[Type]:
        """Types of the predicates and of the operators' parameters."""
        found = {t for p in self.predicates for t in p.types}
        found |= {v.type for op in self.operators for v in op.parameters}
        return frozenset(found)

    def skill(self, name: str) -> Skill:
        for s in self.skills:
            if s.name == name:
                return s
        raise KeyError(f"no skill named {name!r}; skills: {[s.name for s in self.skills]}")


def derive_seed(seed: int, skill_index: int, role: int) -> int:
    """Independent, reproducible seed per (skill, network role)."""
    return int(np.random.SeedSequence([seed, skill_index, role]).generate_state(1)[0])


_POLICY, _SAMPLER = 0, 1


def policy_seed(seed: int, skill_index: int) -> int:
    """The seed skill ``skill_index``'s policy is trained with (learning seed ``seed``)."""
    return derive_seed(seed, skill_index, _POLICY)


class _Timer:
    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0

    def share(self, trained: Sequence[TrainedNetwork], wall: float) -> None:
        """Charge each stage its networks' share of the ``wall`` time spent training:
        training overlaps preparing (and runs in parallel), so job times overcount it."""
        busy = sum(t.seconds for t in trained) or 1.0
        for t in trained:
            share = wall * t.seconds / busy
            self.seconds[t.stage] = self.seconds.get(t.stage, 0.0) + share


def learn_skills(
    demos: Sequence[Demonstration],
    predicates: Collection[Predicate],
    contact_predicates: Collection[Predicate],
    config: LearningConfig | None = None,
    report: Callable[[str], None] | None = None,
    given: Sequence[GivenSkill] = (),
    workers: int = 1,
) -> LearnedSkills:
    """Learn neuro-symbolic skills from demonstrations (paper §4).

    ``report``, if given, receives one short progress message per stage and per skill
    (for a CLI progress display); learning itself prints nothing. ``given``: the
    environment's given skills (:mod:`bpns.learning.given`); a learned operator one of
    them produces keeps its policy and sampler instead of trained networks. ``workers``
    > 1 trains the skills' networks in that many processes (:func:`train_network`: the
    same weights, bit for bit, as in one process).
    """
    config = LearningConfig() if config is None else config
    check_demonstrations(demos)  # one NaN would silently poison every weight
    if report is not None:
        report(f"segmenting {len(demos)} demonstrations")
    t0 = time.perf_counter()
    per_demo = tuple(
        tuple(segment_demonstration(demo, predicates, contact_predicates, config.settle_steps))
        for demo in demos
    )
    return learn_from_segments(
        demos,
        per_demo,
        predicates,
        config,
        report,
        given,
        workers,
        segment_seconds=time.perf_counter() - t0,
    )


def learn_from_segments(
    demos: Sequence[Demonstration],
    per_demo: Sequence[Sequence[Segment]],
    predicates: Collection[Predicate],
    config: LearningConfig | None = None,
    report: Callable[[str], None] | None = None,
    given: Sequence[GivenSkill] = (),
    workers: int = 1,
    segment_seconds: float = 0.0,
) -> LearnedSkills:
    """:func:`learn_skills` from ``demos`` already checked and cut into ``per_demo``
    segments (per demo, in order: ``LearnedSkills.segments``), so that other settings
    (e.g. the No-Subgoal baseline's) learn from one segmentation instead of redoing it;
    ``config.settle_steps`` is not used again. ``segment_seconds``, what cutting them
    took, is recorded as the segment stage."""
    config = LearningConfig() if config is None else config
    say = report or (lambda message: None)
    if len(per_demo) != len(demos):
        raise ValueError(f"segments of {len(per_demo)} demonstrations given for {len(demos)}")
    timer = _Timer()
    timer.seconds["segment"] = segment_seconds
    segments = [seg for segs in per_demo for seg in segs]  # in demo order
    if not segments:
        raise ValueError("the demonstrations contain no segment with effects: nothing to learn")
    say(f"partitioning {len(segments)} segments")
    with timer.stage("partition"):
        groups = partition_segments(segments)
    with timer.stage("operators"):
        datasets = learn_operators(
            groups, config.min_segment_fraction, config.anchor_parameters, config.index_names
        )
    say(f"{len(datasets)} operators from {len(groups)} groups")
    skills, skill_stats = _skills_of(datasets, groups, config, given, workers, timer, say)
    kept = sum(len(d) for d in datasets)
    stats = LearningStats(
        num_demos=len(demos),
        num_transitions=sum(len(d.actions) for d in demos),
        num_segments=len(segments),
        num_groups=len(groups),
        num_dropped_groups=len(groups) - len(datasets),
        num_dropped_segments=len(segments) - kept,
        skills=skill_stats,
        stage_seconds=tuple((s, timer.seconds.get(s, 0.0)) for s in STAGES),
    )
    return LearnedSkills(
        skills,
        frozenset(predicates),
        config,
        stats,
        tuple(tuple(segs) for segs in per_demo),
    )


def _skills_of(
    datasets: Sequence[SkillDataset],
    groups: Sequence[SegmentGroup],
    config: LearningConfig,
    given: Sequence[GivenSkill],
    workers: int,
    timer: _Timer,
    say: Callable[[str], None],
) -> tuple[tuple[Skill, ...], tuple[SkillStats, ...]]:
    """A skill per operator, in the operators' order: a given skill's policy and sampler
    where one produces the operator, else trained networks."""
    skills: list[Skill | None] = []
    skill_stats: list[SkillStats] = []
    pending: list[_PendingSkill] = []
    learnable = sum(match_given(d.operator, given) is None for d in datasets)
    threads = torch_threads()
    # each network starts training as soon as its data is ready, while the next is prepared
    with _Trainer(workers if learnable > 1 else 1) as trainer:
        submitter = _Submitter(trainer, datasets, groups, config, threads, timer, say)
        for k, dataset in enumerate(datasets):
            produced_by = match_given(dataset.operator, given)
            if produced_by is not None:  # a given skill: its policy and sampler, nothing trained
                say(f"{dataset.operator.name}: given skill {produced_by[0].name}")
                skills.append(_given_skill(dataset, produced_by, config))
                skill_stats.append(SkillStats(dataset.operator.name, len(dataset), 0, 0))
                continue
            waiting, stats = submitter.submit(k, slot=len(skills))
            pending.append(waiting)
            skills.append(None)  # trained below
            skill_stats.append(stats)
        say(f"training the networks of {len(pending)} skills")
        trained = trainer.results()
    for p in pending:
        skills[p.slot] = _assemble(p, trained, config)
    timer.share(trained, trainer.seconds)
    return tuple(s for s in skills if s is not None), tuple(skill_stats)


@dataclass(frozen=True, eq=False)
class _Submitter:
    """Prepares a learnable skill's training data and submits its networks to
    ``trainer``; what every skill of one learning run shares."""

    trainer: _Trainer
    datasets: Sequence[SkillDataset]
    groups: Sequence[SegmentGroup]
    config: LearningConfig
    threads: int
    timer: _Timer
    say: Callable[[str], None]

    def submit(self, k: int, slot: int) -> tuple[_PendingSkill, SkillStats]:
        """Skill ``k``'s jobs (its policy, then its sampler's networks) waiting in
        ``slot`` of the learned list, and what it learns from."""
        dataset, config = self.datasets[k], self.config
        shared = shared_data(self.datasets, k) if config.share_effect_data else None
        lent = "" if shared is None else f" + {len(shared.segments) - len(dataset)} lent"
        self.say(
            f"preparing {dataset.operator.name} ({k + 1}/{len(self.datasets)}, "
            f"{len(dataset)} segments{lent})"
        )
        with self.timer.stage(POLICIES):
            scopes, dims, actions = policy_data(dataset, shared, config)
        policy = self.trainer.submit(
            policy_job(scopes, actions, dims, config, policy_seed(config.seed, k), self.threads)
        )
        fit = generator = classifier = None
        negatives = 0
        if config.use_subgoals:
            seed = derive_seed(config.seed, k, _SAMPLER)
            lenders = () if shared is None else shared.segments
            others = _other_segments(self.groups, dataset, exclude=lenders)
            with self.timer.stage(SAMPLERS):
                fit, negatives = sampler_fit(dataset, scopes, dims, others, config, seed)
            if fit is not None:
                generator_job, classifier_job = sampler_jobs(fit, config, seed, self.threads)
                generator = self.trainer.submit(generator_job)
                if classifier_job is not None:
                    classifier = self.trainer.submit(classifier_job)
        waiting = _PendingSkill(slot, dataset, policy, fit, generator, classifier)
        stats = SkillStats(dataset.operator.name, len(dataset), _num_samples(dataset), negatives)
        return waiting, stats


def _given_skill(
    dataset: SkillDataset,
    produced_by: tuple[GivenSkill, tuple[int, ...]],
    config: LearningConfig,
) -> Skill:
    """A learned operator that a given skill produces keeps that skill's policy and
    sampler (bound to the operator's parameters): nothing to train."""
    g, binding = produced_by
    return Skill(
        dataset.operator,
        BoundPolicy(g, binding),
        BoundSampler(g, binding),
        _horizon(dataset, config),
    )


def _assemble(p: _PendingSkill, trained: Sequence[TrainedNetwork], config: LearningConfig) -> Skill:
    """The skill whose networks ``p`` waited for, from the trained networks."""
    generator = None if p.generator is None else trained[p.generator].network
    classifier = None if p.classifier is None else trained[p.classifier].network
    sampler = assemble_sampler(p.fit, generator, classifier)
    return Skill(
        p.dataset.operator, trained[p.policy].network, sampler, _horizon(p.dataset, config)
    )


@dataclass(frozen=True, eq=False)
class _PendingSkill:
    """A skill whose networks are being trained: the handles of its jobs."""

    slot: int  # its place in the learned list
    dataset: SkillDataset
    policy: int
    fit: SamplerFit | None  # None: no sampler to train (CurrentStateSampler)
    generator: int | None
    classifier: int | None


class _Trainer:
    """Trains submitted jobs in this process (one worker: at once, in order) or in a pool
    of ``workers`` processes (in the background, while the caller prepares the next job).
    ``seconds``: the wall time the caller spent training or waiting for the training."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self.seconds = 0.0
        self._pool: Executor | None = None
        # each job's network (or its future) and its stage, for an error that names it
        self._pending: list[tuple[Future[TrainedNetwork] | TrainedNetwork, str]] = []

    def __enter__(self) -> _Trainer:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def submit(self, job: NetworkJob) -> int:
        """Start ``job``; its index in :meth:`results`."""
        t0 = time.perf_counter()
        if self.workers <= 1:
            self._pending.append((train_network(job), job.stage))
        else:
            if self._pool is None:
                self._pool = make_pool(self.workers)
            n = len(self._pending) + 1
            future = submit(self._pool, train_network, job, f"network {n} ({job.stage})")
            self._pending.append((future, job.stage))
        self.seconds += time.perf_counter() - t0
        return len(self._pending) - 1

    def results(self) -> list[TrainedNetwork]:
        """Every submitted job's network, in submission order."""
        t0 = time.perf_counter()
        n = len(self._pending)
        out = [
            result_of(p, f"network {i + 1} of {n} ({stage})") if isinstance(p, Future) else p
            for i, (p, stage) in enumerate(self._pending)
        ]
        self.seconds += time.perf_counter() - t0
        return out


def _other_segments(
    groups: Sequence[SegmentGroup], dataset: SkillDataset, exclude: Sequence[Segment] = ()
) -> list[Segment]:
    """Every segment, dropped groups included, except ``dataset``'s own and ``exclude``
    (segments lent to it as positives must not also be its negatives)."""
    own = {id(s) for s in dataset.segments} | {id(s) for s in exclude}
    return [s for g in groups for s in g.segments if id(s) not in own]


def _horizon(dataset: SkillDataset, config: LearningConfig) -> int | None:
    if config.skill_horizon_factor is None:
        return None
    longest = max(len(s.actions) for s in dataset.segments)
    return max(1, math.ceil(config.skill_horizon_factor * longest))


def _num_samples(dataset: SkillDataset) -> int:
    return sum(len(s.actions) for s in dataset.segments)
