"""The GNN BC solving loop: model-free, one policy query per control step.

From the task's initial state: abstract the state, stop if the goal holds, else ask the
policy for an action, clip it into the action bounds and step the environment. Fails
at the task horizon, the deadline, or on a non-finite action. The simulator is used
only as the world being acted in, never to look ahead.
"""

from __future__ import annotations

import time
from collections.abc import Collection

import numpy as np

from bpns.abstraction import abstract
from bpns.baselines import result as R
from bpns.baselines.result import BaselineResult
from bpns.environment import Environment
from bpns.learning.gnn_bc import GNNPolicy
from bpns.structs import Predicate, Task


def solve_with_policy(
    env: Environment,
    task: Task,
    rng: np.random.Generator,
    deadline: float | None,
    policy: GNNPolicy,
    predicates: Collection[Predicate],
) -> BaselineResult:
    """Run ``policy`` on ``task`` until the goal holds or the task horizon; ``rng`` is
    unused (the policy is deterministic) and kept for the common solver signature."""
    start = time.perf_counter()
    low = np.asarray(env.action_low, dtype=np.float64)
    high = np.asarray(env.action_high, dtype=np.float64)
    state = task.init
    actions: list[np.ndarray] = []
    policy_seconds = 0.0
    reason: str | None = R.TASK_HORIZON
    for _ in range(task.horizon + 1):
        atoms = abstract(state, predicates)
        if task.goal_holds(atoms):
            reason = None
            break
        if len(actions) >= task.horizon:
            break
        if deadline is not None and time.monotonic() >= deadline:
            reason = R.TIMEOUT
            break
        t0 = time.perf_counter()
        action = policy(state, atoms, task.goal)
        policy_seconds += time.perf_counter() - t0
        if action.shape != low.shape or not np.isfinite(action).all():
            reason = R.POLICY_NONFINITE
            break
        action = np.minimum(np.maximum(action, low), high)
        state = env.simulate(state, action)
        actions.append(action)
    stats = {
        "steps": float(len(actions)),
        "policy_seconds": policy_seconds,
        "seconds": time.perf_counter() - start,
    }
    act = np.array(actions, dtype=np.float64).reshape(len(actions), len(low))
    return BaselineResult(reason is None, act, reason, stats)
