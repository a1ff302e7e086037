"""A worker killed mid-eval costs no other task: the harness runs the unfinished task again
alone and goes on; a task whose worker dies again is that task's failure."""

from __future__ import annotations

import os
import signal
import threading
import time

from bpns.evaluation import evaluate as evaluation
from bpns.evaluation.evaluate import EvalSpec, run_tasks
from bpns.execution.failures import FailureReason
from bpns.planning.config import PlanningConfig

SPEC = EvalSpec("cover", "oracle", PlanningConfig(timeout=30.0), task_seed=7)


def kill_a_worker_once_started(pool) -> None:
    """SIGKILL the pool's first worker as soon as it exists (what the OOM killer does)."""

    def kill() -> None:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            pids = list(getattr(pool, "_processes", None) or ())
            if pids:
                os.kill(pids[0], signal.SIGKILL)
                return
            time.sleep(0.01)

    threading.Thread(target=kill, daemon=True).start()


def _recording_pools(monkeypatch, kill_alone: bool) -> list:
    pools: list = []
    real = evaluation.make_pool

    def make_pool(workers, *args, **kwargs):
        pool = real(workers, *args, **kwargs)
        pools.append((workers, pool))
        if kill_alone and workers == 1 and [w for w, _ in pools].count(1) == 1:
            kill_a_worker_once_started(pool)  # the first task run alone dies again
        return pool

    monkeypatch.setattr(evaluation, "make_pool", make_pool)
    return pools


def test_a_worker_killed_mid_eval_costs_no_task(monkeypatch):
    pools = _recording_pools(monkeypatch, kill_alone=False)
    stream = run_tasks(SPEC, range(8), workers=2)
    first = next(stream)
    _, pool = pools[0]
    os.kill(next(iter(pool._processes)), signal.SIGKILL)
    outcomes = [first, *stream]
    assert [o.index for o in outcomes] == list(range(8))
    assert all(o.solved for o in outcomes), [o.reason for o in outcomes]
    # the unfinished task ran again alone, the rest in a fresh pool
    assert [w for w, _ in pools][:2] == [2, 1] and len(pools) >= 3


def test_a_task_whose_worker_dies_again_alone_is_that_tasks_failure(monkeypatch):
    pools = _recording_pools(monkeypatch, kill_alone=True)
    stream = run_tasks(SPEC, range(5), workers=2)
    first = next(stream)
    _, pool = pools[0]
    os.kill(next(iter(pool._processes)), signal.SIGKILL)
    outcomes = [first, *stream]
    assert [o.index for o in outcomes] == list(range(5))
    died = [o for o in outcomes if o.reason == FailureReason.WORKER_DIED]
    assert len(died) == 1 and not died[0].solved and died[0].actions.shape[0] == 0
    assert all(o.solved for o in outcomes if o is not died[0])
