"""What a worker process does for one cell. Runs anywhere the package is installed and
the sweep's output directory is reachable (a shared filesystem on a cluster).

A job carries everything the cell needs (configs, artifact paths), so a worker builds
its own environment and reads nothing from the process that scheduled it.
"""

from __future__ import annotations

import platform
import time
import traceback
from dataclasses import dataclass
from typing import Any

from bpns.atomic import storage_problem
from bpns.experiments.cells import DEMOS, EVAL, SKILLS, SWEEP_GNN_SEED, Cell


@dataclass(frozen=True)
class CellJob:
    cell: Cell
    output: str  # this cell's artifact path
    inputs: tuple[str, ...] = ()  # artifact paths of the cells it depends on
    num_demos: int | None = None  # skills: demos to load (the solved train tasks < count)
    learning_seconds: float | None = None  # learned eval: copied into the result


@dataclass(frozen=True)
class CellOutcome:
    result: dict[str, Any] | None  # None if the cell raised
    error: str | None  # the traceback if it did
    seconds: float
    host: str
    # one line when it raised because the output filesystem refused a write (full disk,
    # read-only): every further cell would fail alike, so the sweep stops
    storage_problem: str | None = None


def run_cell_safely(job: CellJob) -> CellOutcome:
    """Run ``job``; an exception becomes an outcome with its traceback (a failed cell
    must not take the sweep down: its dependents are skipped, the rest goes on)."""
    t0 = time.perf_counter()
    problem = None
    try:
        result, error = run_cell(job), None
    except Exception as err:  # noqa: BLE001  reported to the scheduler, which reports it
        result, error = None, traceback.format_exc()
        problem = storage_problem(err, job.output)
    return CellOutcome(result, error, time.perf_counter() - t0, platform.node(), problem)


def run_cell(job: CellJob) -> dict[str, Any]:
    kind = job.cell.kind
    if kind == DEMOS:
        return _collect(job)
    if kind == SKILLS:
        return _learn(job)
    if kind == EVAL:
        return _evaluate(job)
    raise ValueError(f"unknown cell kind {kind!r}")


def _collect(job: CellJob) -> dict[str, Any]:
    from bpns.datasets import save_demonstrations
    from bpns.demos import collect_demonstrations
    from bpns.registry import make_environment

    cell = job.cell
    env = make_environment(cell.env)
    solved: list[int] = []
    failed: list[int] = []

    def successful():
        demos = collect_demonstrations(
            env.name, cell.count, cell.seed, workers=1, noise=cell.demo_noise
        )
        for index, demo in demos:
            if demo is None:
                failed.append(index)
            else:
                solved.append(index)
                yield demo

    n = save_demonstrations(job.output, env, successful())
    if n == 0:
        raise RuntimeError(f"the demonstrator solved none of {cell.count} {env.name} tasks")
    return {"num_demos": n, "solved_tasks": solved, "failed_tasks": failed}


def _learn(job: CellJob) -> dict[str, Any]:
    import torch

    from bpns.datasets import iter_demonstrations
    from bpns.learning import learn_skills, save_skills
    from bpns.learning.given import given_skills_of
    from bpns.registry import make_environment

    assert job.cell.learning is not None and job.num_demos is not None
    env = make_environment(job.cell.env)
    torch.set_num_threads(1)  # small networks: one thread is fastest, and cells run in parallel
    t0 = time.perf_counter()
    demos = list(iter_demonstrations(job.inputs[0], env, range(job.num_demos), features_only=True))
    load_seconds = time.perf_counter() - t0
    learned = learn_skills(
        demos,
        env.predicates,
        env.contact_predicates,
        job.cell.learning,
        given=given_skills_of(env),
    )
    save_skills(learned, job.output, overwrite=True, env_name=env.name)
    baseline_seconds: dict[str, float] = {}
    if job.cell.baselines:
        from bpns.learning.baselines import BaselinesConfig, learn_baselines_into

        # after the skills: saving them replaces the directory
        baseline_seconds = dict(
            learn_baselines_into(
                job.output, env, demos, learned, BaselinesConfig(seed=SWEEP_GNN_SEED)
            )
        )
    assert learned.stats is not None
    return {
        "baseline_seconds": baseline_seconds,
        "num_demos": job.num_demos,
        "num_skills": len(learned.skills),
        "skills": [s.name for s in learned.skills],
        "learning_seconds": learned.stats.total_seconds,
        "stage_seconds": dict(learned.stats.stage_seconds),
        "load_seconds": load_seconds,
        "stats": str(learned.stats),
    }


def _evaluate(job: CellJob) -> dict[str, Any]:
    from bpns.evaluation import EvalSpec, evaluate, save_plans
    from bpns.perturbations import NOMINAL

    cell = job.cell
    assert cell.planning is not None and cell.approach is not None and cell.eval_tasks
    spec = EvalSpec(
        env_name=cell.env,
        approach=cell.approach,
        planning=cell.planning,
        skills_dir=job.inputs[0] if job.inputs else None,
        task_seed=cell.seed,
        planner_seed=cell.seed,
        perturbation=cell.perturbation or NOMINAL,
    )
    report = evaluate(spec, cell.eval_tasks, workers=1)
    save_plans(job.output, report)
    summary = report.to_json()["summary"]
    tasks = [
        {
            "index": o.index,
            "solved": o.solved,
            "seconds": o.seconds,
            "reason": o.reason,
            "nodes_created": o.nodes_created,
            "samples": o.samples,
            "num_actions": o.num_actions,
        }
        for o in report.outcomes
    ]
    return {
        **summary,
        "num_demos": job.num_demos,
        "learning_seconds": job.learning_seconds,
        "tasks": tasks,
    }
