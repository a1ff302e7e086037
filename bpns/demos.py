"""Collect demonstrations by running an environment's scripted demonstrator in physics,
and replay stored demonstrations to check that they reproduce exactly."""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from bpns.abstraction import abstract
from bpns.demo_attempts import attempt_demonstration
from bpns.environment import Environment
from bpns.structs import Demonstration, Task


def run_demonstrator(env: Environment, task: Task, seed: int | list[int]) -> Demonstration | None:
    """Roll the env's demonstrator out from ``task.init``; None if the goal was not reached
    (:func:`bpns.demo_attempts.attempt_demonstration` says why)."""
    return attempt_demonstration(env, task, seed).demo


@dataclass(frozen=True)
class DemoJob:
    env_name: str
    seed: int
    index: int
    train: bool = True


def _collect_one(job: DemoJob) -> tuple[int, Demonstration | None]:
    from bpns.registry import make_environment

    env = _ENV_CACHE.get(job.env_name) or _ENV_CACHE.setdefault(
        job.env_name, make_environment(job.env_name)
    )
    task = env.task(job.index, job.seed, job.train)
    return job.index, run_demonstrator(env, task, seed=[job.seed, job.index])


_ENV_CACHE: dict[str, Environment] = {}


def collect_demonstrations(
    env_name: str, n: int, seed: int, workers: int = 1, train: bool = True
) -> Iterator[tuple[int, Demonstration | None]]:
    """Yield (task index, demo or None) for tasks 0..n-1 of the seeded stream, in order."""
    jobs = [DemoJob(env_name, seed, i, train) for i in range(n)]
    if workers <= 1:
        yield from map(_collect_one, jobs)
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        yield from pool.map(_collect_one, jobs, chunksize=4)


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
        max_state = max(max_state, float(np.max(np.abs(state.sim.flat - stored.sim.flat))))
        for obj, v in stored.data.items():
            max_feat = max(max_feat, float(np.max(np.abs(state.data[obj] - v))))
    goal = demo.task.goal_holds(abstract(state, env.goal_predicates))
    return ReplayReport(index, len(demo.actions), max_state, max_feat, goal)
