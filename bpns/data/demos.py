"""Collect demonstrations by running an environment's scripted demonstrator in physics,
and replay stored demonstrations to check that they reproduce exactly (one, or the
first of a file: :func:`check_replay`)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

from bpns.data.datasets import (
    DatasetError,
    count_demonstrations,
    iter_demonstrations,
    read_attributes,
)
from bpns.data.demo_attempts import DemoAttempt, attempt_demonstration
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment, perturbed
from bpns.env.perturbations import NOMINAL, Perturbation, PerturbationError
from bpns.env.registry import make_environment
from bpns.env.worlds import NOMINAL_WORLD, WorldDistribution
from bpns.pools import WORKER_DIED_ALONE, capped_workers, make_pool, surviving_map
from bpns.structs import Demonstration, Task

T = TypeVar("T")
# (items, total, description, unit) -> the same items (e.g. wrapped in a progress bar)
Progress = Callable[[Iterable[T], int, str, str], Iterator[T]]


def no_progress(items: Iterable[T], total: int, desc: str, unit: str) -> Iterator[T]:
    return iter(items)


def run_demonstrator(env: Environment, task: Task, seed: int | list[int]) -> Demonstration | None:
    """Roll the env's demonstrator out from ``task.init``; None if the goal was not reached
    (:func:`bpns.data.demo_attempts.attempt_demonstration` says why)."""
    return attempt_demonstration(env, task, seed).demo


@dataclass(frozen=True)
class DemoJob:
    env_name: str
    seed: int
    index: int
    train: bool = True
    noise: float = 0.0
    worlds: str = ""  # JSON of the WorldDistribution the task's physics is drawn from


def _attempt_one(job: DemoJob) -> tuple[int, DemoAttempt]:
    env = _ENV_CACHE.get(job.env_name) or _ENV_CACHE.setdefault(
        job.env_name, make_environment(job.env_name)
    )
    if job.worlds:
        physics = WorldDistribution.from_json(job.worlds).draw(job.index)
        if not physics.nominal:
            env = perturbed(env, physics)
    task = env.task(job.index, job.seed, job.train)
    return job.index, attempt_demonstration(env, task, [job.seed, job.index], noise=job.noise)


_ENV_CACHE: dict[str, Environment] = {}


def collect_attempts(
    env_name: str,
    n: int,
    seed: int,
    workers: int = 1,
    train: bool = True,
    noise: float = 0.0,
    worlds: WorldDistribution = NOMINAL_WORLD,
) -> Iterator[tuple[int, DemoAttempt]]:
    """Yield (task index, attempt) for tasks 0..n-1 of the seeded stream, in order; a
    failed attempt says why (exception, or the goal atoms missing at the horizon).
    Task ``i`` is demonstrated in the world ``worlds.draw(i)`` (:func:`demo_physics`):
    demonstrations under randomised physics show the skills the states a world that
    differs from the model leads to.

    Jobs are made lazily and at most a few per worker are in flight, so memory does not
    grow with ``n``; ``workers`` is capped at the CPU count (:mod:`bpns.pools`)."""
    if n < 0:
        raise ValueError(f"number of demonstrations must be >= 0, got {n}")
    spec = "" if worlds.nominal else worlds.to_json()
    jobs = (DemoJob(env_name, seed, i, train, noise, spec) for i in range(n))
    workers = capped_workers(workers)
    if workers <= 1:
        yield from map(_attempt_one, jobs)
        return
    yield from surviving_map(
        lambda k: make_pool(k or workers), _attempt_one, jobs, 4 * workers, _worker_died
    )


def _worker_died(job: DemoJob) -> tuple[int, DemoAttempt]:
    """Task ``job.index``'s attempt when its worker died, also when it ran alone."""
    return job.index, DemoAttempt(None, 0, error=f"WorkerDiedError: {WORKER_DIED_ALONE}")


def collect_demonstrations(
    env_name: str, n: int, seed: int, workers: int = 1, train: bool = True, noise: float = 0.0
) -> Iterator[tuple[int, Demonstration | None]]:
    """Yield (task index, demo or None) for tasks 0..n-1 of the seeded stream, in order."""
    for index, attempt in collect_attempts(env_name, n, seed, workers, train, noise):
        yield index, attempt.demo


@dataclass(frozen=True)
class ReplayReport:
    demo: int
    steps: int
    max_state_diff: float
    max_feature_diff: float
    goal_reached: bool

    @property
    def exact(self) -> bool:
        return self.max_state_diff == 0.0 and self.max_feature_diff == 0.0


def replay(env: Environment, demo: Demonstration, index: int = 0) -> ReplayReport:
    """Re-simulate ``demo``'s actions from its first state; compare with stored states."""
    state = demo.states[0]
    max_state = max_feat = 0.0
    for action, stored in zip(demo.actions, demo.states[1:], strict=True):
        state = env.simulate(state, action)
        max_state = _worse(max_state, state.sim.flat - stored.sim.flat)
        for obj, v in stored.data.items():
            max_feat = _worse(max_feat, state.data[obj] - v)
    goal = demo.task.goal_holds(abstract(state, env.goal_predicates))
    return ReplayReport(index, len(demo.actions), max_state, max_feat, goal)


def _worse(worst: float, diff: np.ndarray) -> float:
    """The larger of ``worst`` and max |diff|, where a NaN anywhere counts as infinitely
    different (Python's ``max`` would drop it, and a NaN state would replay "exactly")."""
    d = np.abs(np.asarray(diff, dtype=np.float64))
    if d.size and not np.all(np.isfinite(d)):
        return math.inf
    return max(worst, float(d.max())) if d.size else worst


@dataclass(frozen=True)
class ReplayCheck:
    reports: tuple[ReplayReport, ...]

    @property
    def bad(self) -> list[ReplayReport]:
        return [r for r in self.reports if not r.exact or not r.goal_reached]

    @property
    def ok(self) -> bool:
        return not self.bad

    def lines(self) -> list[str]:
        reports, bad = self.reports, self.bad
        worst = max((r.max_state_diff for r in reports), default=0.0)
        out = [
            f"replayed {len(reports)} demonstrations ({sum(r.steps for r in reports)} steps): "
            f"max |state diff| = {worst:.3g}, "
            f"{len(reports) - len(bad)}/{len(reports)} exact and reaching their goal"
        ]
        for r in bad:
            out.append(
                f"  demo_{r.demo}: max state diff {r.max_state_diff:.3g}, feature diff "
                f"{r.max_feature_diff:.3g}, goal "
                + ("reached" if r.goal_reached else "NOT reached")
            )
        return out


def check_replay(
    env: Environment, path: Path, limit: int | None = None, progress: Progress = no_progress
) -> ReplayCheck:
    """Re-simulate the first ``limit`` (default: all) demonstrations of ``path``, each in
    the physics it was collected in (``env`` is the nominal environment).
    Raises ``bpns.data.datasets.DatasetError`` for a file that is not a readable dataset."""
    total = count_demonstrations(path)
    n = min(total, limit or total)
    physics = demo_physics(path)[:n]  # each demo loads into its own world; simulate it there
    demos = progress(iter_demonstrations(path, env, range(n)), n, "replay", "task")
    return ReplayCheck(
        tuple(
            replay(perturbed(env, p), d, i)
            for i, (d, p) in enumerate(zip(demos, physics, strict=True))
        )
    )


def demo_physics(path: str | os.PathLike) -> list[Perturbation]:
    """Each demonstration's physics, in file order: its ``physics`` attribute (written by
    ``bpns demos --perturb``), else nominal. A record that does not parse raises
    :class:`bpns.data.datasets.DatasetError` naming the demonstration."""
    _, per_demo = read_attributes(path)
    out = []
    for i, attrs in enumerate(per_demo):
        text = attrs.get("physics")
        if text is None:
            out.append(NOMINAL)
            continue
        try:
            out.append(Perturbation.from_json(str(text)))
        except (PerturbationError, ValueError, TypeError) as err:
            raise DatasetError(
                f"{path}: demo_{i} has an unusable 'physics' record: {err}"
            ) from None
    return out
