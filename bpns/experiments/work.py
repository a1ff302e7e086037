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
from pathlib import Path
from typing import Any

from bpns.acting.config import ExecutionConfig
from bpns.atomic import storage_problem
from bpns.baselines.learn import BaselinesConfig
from bpns.env.object_counts import PAPER_SET, EvalSet, ObjectCounts
from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.env.registry import make_environment
from bpns.env.worlds import WorldDistribution, parse_model, parse_world
from bpns.evaluation.evaluate import EvalSpec, evaluate
from bpns.evaluation.reporting import save_plans
from bpns.experiments.cells import DEMOS, EVAL, SKILLS, SWEEP_GNN_SEED, Cell
from bpns.learning.corrections import CorrectionConfig
from bpns.workflow import collect_demos, learn_to_directory


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
    """Demos of the cell's train tasks, as ``bpns demos`` collects them."""
    cell = job.cell
    env = make_environment(cell.env)
    written = collect_demos(
        env, cell.count, cell.seed, Path(job.output), workers=1, noise=cell.demo_noise
    )
    if written.num_written == 0:
        raise RuntimeError(f"the demonstrator solved none of {cell.count} {env.name} tasks")
    failed = set(written.failed)
    solved = [i for i in range(cell.count) if i not in failed]
    return {
        "num_demos": written.num_written,
        "solved_tasks": solved,
        "failed_tasks": sorted(failed),
    }


def _learn(job: CellJob) -> dict[str, Any]:
    """Skills (and the baselines, if the cell asks) as ``bpns learn`` learns them, on one
    torch thread: small networks, and cells run in parallel."""
    assert job.cell.learning is not None and job.num_demos is not None
    env = make_environment(job.cell.env)
    baselines = BaselinesConfig(seed=SWEEP_GNN_SEED) if job.cell.baselines else None
    corrections = None
    if job.cell.corrections is not None:
        corrections = CorrectionConfig(
            parse_world(job.cell.corrections.split()),
            rounds=job.cell.correction_rounds,
            seed=job.cell.seed,
        )
    run = learn_to_directory(
        env,
        Path(job.inputs[0]),
        Path(job.output),
        job.cell.learning,
        limit=job.num_demos,
        threads=1,
        baselines=baselines,
        corrections=corrections,
    )
    stats = run.learned.stats
    assert stats is not None
    return {
        "baseline_seconds": dict(run.baseline_seconds or ()),
        "num_demos": run.num_demos,
        "num_skills": len(run.learned.skills),
        "skills": [s.name for s in run.learned.skills],
        "learning_seconds": stats.total_seconds,
        "stage_seconds": dict(stats.stage_seconds),
        "load_seconds": run.load_seconds,
        "stats": str(stats),
        "corrections": [r.to_json() for r in run.corrections],
    }


def _evaluate(job: CellJob) -> dict[str, Any]:
    cell = job.cell
    assert cell.planning is not None and cell.approach is not None and cell.eval_tasks
    spec = EvalSpec(
        env_name=cell.env,
        approach=cell.approach,
        planning=cell.planning,
        skills_dir=job.inputs[0] if job.inputs else None,
        task_seed=cell.seed,
        planner_seed=cell.seed,
        perturbation=_world_of(cell),
        model=parse_model(cell.model.split()),
        execution=ExecutionConfig.of_mode(
            cell.execution or "closed-loop",
            world_speed=cell.world_speed,
            slow_from=cell.slow_from,
            predict_latency=cell.predict_latency,
            check_ahead=cell.check_ahead,
            watch_releases=cell.watch_releases,
        ),
        eval_set=_eval_set_of(cell),
    )
    report = evaluate(spec, cell.eval_tasks, workers=1)
    save_plans(job.output, report)
    summary = report.to_json()["summary"]
    tasks = [
        {
            "index": o.index,
            "solved": o.solved,
            "seconds": o.seconds,
            "world_seconds": o.world_seconds,  # of seconds, simulating the world
            "cpu_seconds": o.cpu_seconds,  # the same two in CPU seconds (bpns.timing)
            "world_cpu_seconds": o.world_cpu_seconds,
            "reason": o.reason,
            "nodes_created": o.nodes_created,
            "samples": o.samples,
            "sim_steps": o.sim_steps,
            "num_actions": o.num_actions,
            "plan_steps": len(o.skeleton),  # ground skills of the final plan (0: unsolved)
            "replans": o.replans,
            "world": o.world.label(),
        }
        for o in report.outcomes
    ]
    return {
        **summary,
        "num_demos": job.num_demos,
        "learning_seconds": job.learning_seconds,
        "tasks": tasks,
    }


def _eval_set_of(cell: Cell) -> EvalSet:
    """The eval tasks of a cell: its object counts on an object axis, else the paper's."""
    return PAPER_SET if cell.objects is None else EvalSet(objects=ObjectCounts.parse(cell.objects))


def _world_of(cell: Cell) -> Perturbation | WorldDistribution:
    """The worlds an eval cell runs in: its perturbation level, else its swept world."""
    if cell.perturbation is not None:
        return cell.perturbation
    if cell.world is not None:
        return parse_world(cell.world.split())
    return NOMINAL
