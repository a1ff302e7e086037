"""A skill's networks as jobs: the one way a skill is trained.

Each network of a skill (its policy, its sampler's generator and classifier) is trained as
a :class:`NetworkJob`: a module-level training function and its plain arguments (arrays
and configs), so that the pipeline's worker pool (:mod:`bpns.learning.pipeline`) can run
it in another process while the demonstrations stay in the parent. :func:`learn_policy`
and :func:`learn_sampler` build the very same jobs for one skill and run them here, so what
a study of one skill trains is bit for bit what the pipeline trains.

Seeds: the policy's job takes its seed; the sampler's training data (its negatives) and
its generator take the sampler's seed, its classifier that seed + 1.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bpns.learning.config import LearningConfig
from bpns.learning.operators import SkillDataset
from bpns.learning.policies import LearnedPolicy, ScopeDims, scope_trajectories, train_policy
from bpns.learning.samplers import (
    CurrentStateSampler,
    LearnedSampler,
    SamplerFit,
    sampler_training_data,
)
from bpns.learning.sharing import SharedData
from bpns.nets.mlp import MLPParams, train_classifier, train_gaussian
from bpns.structs import Segment

POLICIES, SAMPLERS = "policies", "samplers"  # the learning stages their time counts towards


@dataclass(frozen=True, eq=False)
class NetworkJob:
    """One network to train: a module-level training function and its arguments (plain
    arrays and configs), so that a worker process can run it while the demonstrations
    stay in the parent. A skill's policy, generator and classifier are three jobs: on
    two cores, eight skills of three unequal networks balance better than eight jobs of
    one skill each. ``stage``: the learning stage its time counts towards."""

    stage: str
    train: Callable[..., Any]
    args: tuple[Any, ...]
    threads: int  # torch threads, as in the caller


@dataclass(frozen=True, eq=False)
class TrainedNetwork:
    network: Any  # what ``NetworkJob.train`` returned
    stage: str
    seconds: float


def train_network(job: NetworkJob) -> TrainedNetwork:
    """Train one network. Seeded (by its arguments) and on ``job.threads`` torch
    threads, so a worker process returns bit-identical weights to the caller's own."""
    import torch  # heavy; `bpns` commands that learn nothing never load it

    torch.set_num_threads(job.threads)
    t0 = time.perf_counter()
    network = job.train(*job.args)
    return TrainedNetwork(network, job.stage, time.perf_counter() - t0)


def torch_threads() -> int:
    """The caller's torch thread count, which every job trains with."""
    import torch  # heavy: only when training (see train_network)

    return torch.get_num_threads()


# -- a policy ---------------------------------------------------------------------------
def policy_data(
    dataset: SkillDataset, shared: SharedData | None, config: LearningConfig
) -> tuple[list[np.ndarray], ScopeDims, list[np.ndarray]]:
    """(scope trajectories, scope dims, actions) a skill's policy learns from: its own
    segments, or with ``shared`` (:func:`bpns.learning.sharing.shared_data`) also those
    lent by operators with the same effects."""
    if shared is None:
        scopes = scope_trajectories(dataset)
        params = dataset.operator.parameters[: dataset.scope_size]
        dims = ScopeDims.from_scopes(
            scopes, config.change_tolerance, dataset.scope_size, types=[v.type for v in params]
        )
        return scopes, dims, [seg.actions for seg in dataset.segments]
    scopes = [
        np.stack([s.vec(objs) for s in seg.states])
        for seg, objs in zip(shared.segments, shared.objects, strict=True)
    ]
    dims = ScopeDims.from_scopes(
        scopes,
        config.change_tolerance,
        objects=shared.scope,
        types=[dataset.operator.parameters[i].type for i in shared.scope],
    )
    return scopes, dims, [seg.actions for seg in shared.segments]


def policy_job(
    scopes: Sequence[np.ndarray],
    actions: Sequence[np.ndarray],
    dims: ScopeDims,
    config: LearningConfig,
    seed: int,
    threads: int,
) -> NetworkJob:
    """The job that behaviour-clones a policy from ``scopes`` and ``actions``."""
    return NetworkJob(
        POLICIES,
        train_policy,
        (
            tuple(scopes),
            tuple(actions),
            dims,
            config.policy,
            seed,
            config.use_subgoals,
            config.near_goal_scale,
            config.linear_policy_base,
        ),
        threads,
    )


# -- a sampler --------------------------------------------------------------------------
def sampler_fit(
    dataset: SkillDataset,
    scopes: Sequence[np.ndarray],
    dims: ScopeDims,
    other_segments: Sequence[Segment],
    config: LearningConfig,
    seed: int,
) -> tuple[SamplerFit | None, int]:
    """A sampler's training data (None: its scope never changes, nothing to sample) and
    how many negative examples its classifier gets. ``other_segments``: the segments
    that are not the skill's (negatives of kind (b))."""
    gen_x, gen_y, cls_data = sampler_training_data(
        dataset, scopes, dims, other_segments, config.max_negative_bindings_per_segment, seed
    )
    negatives = int((cls_data[:, -1] == 0).sum())
    fit = SamplerFit.of(
        gen_x,
        gen_y,
        cls_data,
        dims,
        config.generator,
        config.max_rejection_tries,
        config.linear_sampler_base,
        config.novelty_floor if config.refuse_novel_starts else None,
        config.correlated_subgoal_noise,
    )
    return fit, negatives


def sampler_jobs(
    fit: SamplerFit, config: LearningConfig, seed: int, threads: int
) -> tuple[NetworkJob, NetworkJob | None]:
    """The generator's job (``seed``) and, where the fit has negatives, the classifier's
    (``seed + 1``); :meth:`SamplerFit.assemble` makes the sampler of their networks."""
    generator = NetworkJob(
        SAMPLERS, train_gaussian, (fit.gen_x, fit.gen_target, config.generator, seed), threads
    )
    if fit.classifier_labels is None:
        return generator, None
    classifier = NetworkJob(
        SAMPLERS,
        train_classifier,
        (fit.classifier_x, fit.classifier_labels, config.classifier, seed + 1),
        threads,
    )
    return generator, classifier


def assemble_sampler(
    fit: SamplerFit | None, generator: MLPParams | None, classifier: MLPParams | None
) -> LearnedSampler | CurrentStateSampler:
    """The sampler of a fit and its trained networks (no fit: the current state)."""
    if fit is None or generator is None:
        return CurrentStateSampler()
    return fit.assemble(generator, classifier)


# -- one skill, here ---------------------------------------------------------------------
def learn_policy(dataset: SkillDataset, config: LearningConfig, seed: int) -> LearnedPolicy:
    """Behaviour-clone one skill's policy from its own segments: the pipeline's job,
    trained in this process."""
    scopes, dims, actions = policy_data(dataset, None, config)
    job = policy_job(scopes, actions, dims, config, seed, torch_threads())
    return train_network(job).network


def learn_sampler(
    dataset: SkillDataset,
    other_segments: Sequence[Segment],
    config: LearningConfig,
    seed: int,
) -> LearnedSampler | CurrentStateSampler:
    """Learn one skill's sampler (``other_segments``: every segment not in ``dataset``,
    the negatives of kind (b)): the pipeline's jobs, trained in this process."""
    scopes, dims, _ = policy_data(dataset, None, config)
    fit, _ = sampler_fit(dataset, scopes, dims, other_segments, config, seed)
    if fit is None:
        return CurrentStateSampler()
    generator_job, classifier_job = sampler_jobs(fit, config, seed, torch_threads())
    generator = train_network(generator_job).network
    classifier = None if classifier_job is None else train_network(classifier_job).network
    return fit.assemble(generator, classifier)
