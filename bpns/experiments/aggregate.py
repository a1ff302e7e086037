"""Means and standard deviations over seeds, per (environment, approach, demo count).

Each seed is one replicate: its own demonstrations, skills and eval tasks. The spread
reported is the population standard deviation of the per-seed values (``ddof=0``, as
``numpy.std``), so a single seed shows ``± 0.0``. Times are over each seed's solved
tasks; a seed that solved nothing has no time and is left out of the time columns (the
``seeds`` column counts all seeds).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from bpns.env.object_counts import ObjectCounts
from bpns.evaluation.intervals import wilson_interval
from bpns.experiments import approach_info


@dataclass(frozen=True)
class Stat:
    """Mean and population std of the values that exist; ``n`` of them."""

    mean: float | None
    std: float | None
    n: int

    @classmethod
    def of(cls, values: Iterable[float | None]) -> Stat:
        present = [float(v) for v in values if v is not None and math.isfinite(v)]
        if not present:
            return cls(None, None, 0)
        return cls(statistics.fmean(present), statistics.pstdev(present), len(present))

    def format(self, spec: str) -> str:
        if self.mean is None or self.std is None:
            return "–"
        return f"{format(self.mean, spec)} ± {format(self.std, spec)}"

    def to_json(self) -> dict[str, Any]:
        return {"mean": self.mean, "std": self.std, "n": self.n}


@dataclass(frozen=True)
class SeedResult:
    """One eval cell's numbers."""

    seed: int
    num_tasks: int
    solved_percent: float
    median_seconds: float | None
    mean_seconds: float | None
    nodes_created: float
    learning_seconds: float | None
    solved_seconds: tuple[float, ...]  # test time of every solved task
    # median over solved tasks of simulated steps per action of the final plan
    sim_steps_per_step: float | None = None
    num_solved: int = 0
    mean_replans: float = 0.0  # closed loop: divergences repaired per task
    # median over solved tasks of the final plan's ground skills (None: not recorded)
    median_plan_steps: float | None = None
    # median over solved tasks of the time less the world's simulation (None: not recorded)
    median_agent_seconds: float | None = None
    # the same in CPU seconds (bpns.timing; None: not recorded)
    median_agent_cpu_seconds: float | None = None
    # each task's world (``Perturbation.label()``) and whether it was solved
    trials: tuple[tuple[str, bool], ...] = ()

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> SeedResult:
        r = record["result"]
        return cls(
            seed=record["settings"]["seed"],
            num_tasks=r["num_tasks"],
            solved_percent=r["solved_percent"],
            median_seconds=r["median_seconds"],
            mean_seconds=r["mean_seconds"],
            nodes_created=r["mean_nodes_created"],
            learning_seconds=r.get("learning_seconds"),
            solved_seconds=tuple(t["seconds"] for t in r["tasks"] if t["solved"]),
            sim_steps_per_step=r.get("median_sim_steps_per_step", _median_sim_ratio(r["tasks"])),
            num_solved=int(r.get("num_solved", sum(bool(t["solved"]) for t in r["tasks"]))),
            mean_replans=float(r.get("mean_replans", 0.0)),
            median_plan_steps=_median_plan_steps(r["tasks"]),
            median_agent_seconds=_median_agent_seconds(r["tasks"]),
            median_agent_cpu_seconds=_median_agent_seconds(
                r["tasks"], "cpu_seconds", "world_cpu_seconds"
            ),
            trials=tuple((str(t["world"]), bool(t["solved"])) for t in r["tasks"] if "world" in t),
        )

    def fraction_solved_within(self, seconds: float) -> float:
        return sum(t <= seconds for t in self.solved_seconds) / max(1, self.num_tasks)


def _median_sim_ratio(tasks: Iterable[dict[str, Any]]) -> float | None:
    """From the per-task records (so older cells have it too); records without step
    counts are left out."""
    ratios = [
        t["sim_steps"] / t["num_actions"]
        for t in tasks
        if t["solved"] and t.get("num_actions") and "sim_steps" in t
    ]
    return statistics.median(ratios) if ratios else None


def _median_agent_seconds(
    tasks: Iterable[dict[str, Any]], total: str = "seconds", world: str = "world_seconds"
) -> float | None:
    """Median over solved tasks of ``total`` less ``world``: the solving time less the
    world's simulation (TaskOutcome.agent_seconds; pass the ``cpu_seconds`` keys for CPU
    seconds); None when nothing was solved or a cell predates the times being recorded."""
    solved = [t for t in tasks if t["solved"]]
    if not solved or any(t.get(total) is None or world not in t for t in solved):
        return None
    return statistics.median(t[total] - t[world] for t in solved)


def _median_plan_steps(tasks: Iterable[dict[str, Any]]) -> float | None:
    """Cells stored before plan lengths were recorded have none."""
    steps = [t["plan_steps"] for t in tasks if t["solved"] and t.get("plan_steps")]
    return statistics.median(steps) if steps else None


@dataclass(frozen=True)
class Row:
    env: str
    approach: str
    demos: int | None  # None: the approach learns nothing
    seeds: tuple[SeedResult, ...]
    level: float | None = None  # the perturbation axis' value (None: no axis)
    axis: str | None = None  # the perturbation axis' name
    world: str | None = None  # the swept world (None: not swept)
    execution: str | None = None  # closed-loop / open-loop (None: not swept)
    axis_of: str = "perturbation"  # what the axis sweeps: "perturbation" or "objects"
    # skills retrained on corrections (``bpns experiment --corrections``): "moderate x2"
    corrections: str | None = None

    @property
    def pooled(self) -> tuple[int, int]:
        """(tasks solved, tasks) over every seed: the trials of a Wilson interval."""
        return sum(s.num_solved for s in self.seeds), sum(s.num_tasks for s in self.seeds)

    @property
    def pooled_interval(self) -> tuple[float, float]:
        return wilson_interval(*self.pooled)

    @property
    def replans(self) -> Stat:
        return Stat.of(s.mean_replans for s in self.seeds)

    @property
    def label(self) -> str:
        label = approach_info.label(self.approach)
        return label if self.corrections is None else f"{label} + corrections ({self.corrections})"

    @property
    def solved_percent(self) -> Stat:
        return Stat.of(s.solved_percent for s in self.seeds)

    @property
    def median_seconds(self) -> Stat:
        return Stat.of(s.median_seconds for s in self.seeds)

    @property
    def mean_seconds(self) -> Stat:
        return Stat.of(s.mean_seconds for s in self.seeds)

    @property
    def median_agent_seconds(self) -> Stat:
        return Stat.of(s.median_agent_seconds for s in self.seeds)

    @property
    def median_agent_cpu_seconds(self) -> Stat:
        return Stat.of(s.median_agent_cpu_seconds for s in self.seeds)

    @property
    def nodes_created(self) -> Stat:
        return Stat.of(s.nodes_created for s in self.seeds)

    @property
    def learning_seconds(self) -> Stat:
        return Stat.of(s.learning_seconds for s in self.seeds)

    @property
    def sim_steps_per_step(self) -> Stat:
        return Stat.of(s.sim_steps_per_step for s in self.seeds)

    @property
    def plan_steps(self) -> Stat:
        return Stat.of(s.median_plan_steps for s in self.seeds)

    def to_json(self) -> dict[str, Any]:
        return {
            "env": self.env,
            "approach": self.approach,
            "label": self.label,
            "demos": self.demos,
            **({} if self.corrections is None else {"corrections": self.corrections}),
            **({} if self.axis is None else {self.axis_of: {self.axis: self.level}}),
            **({} if self.world is None else {"world": self.world}),
            **({} if self.execution is None else {"execution": self.execution}),
            "pooled_solved": list(self.pooled),
            "pooled_interval": list(self.pooled_interval),
            "replans": self.replans.to_json(),
            "seeds": [s.seed for s in self.seeds],
            "eval_tasks": [s.num_tasks for s in self.seeds],
            "solved_percent": self.solved_percent.to_json(),
            "median_seconds": self.median_seconds.to_json(),
            "mean_seconds": self.mean_seconds.to_json(),
            "median_agent_seconds": self.median_agent_seconds.to_json(),
            "median_agent_cpu_seconds": self.median_agent_cpu_seconds.to_json(),
            "nodes_created": self.nodes_created.to_json(),
            "learning_seconds": self.learning_seconds.to_json(),
            "sim_steps_per_step": self.sim_steps_per_step.to_json(),
            "plan_steps": self.plan_steps.to_json(),
        }


def aggregate(eval_records: Iterable[dict[str, Any]]) -> list[Row]:
    """One row per (env, approach, demo count, perturbation level, world, execution), in
    the order first seen for env, approach, world and execution, then by increasing demo
    count and level; seeds sorted."""
    groups: dict[tuple, list[SeedResult]] = {}
    axes: dict[tuple, tuple[str | None, str]] = {}
    order: dict[str, dict[object, int]] = {"env": {}, "approach": {}, "world": {}, "exec": {}}
    for record in eval_records:
        s = record["settings"]
        axis, level = _axis_level(s)
        axis_of = "objects" if "objects" in s else "perturbation"
        world, execution = s.get("world"), s.get("execution") if "world" in s else None
        if axis is not None:  # a perturbation level is its world; execution is shown
            execution = s.get("execution")
        for name, value in (
            ("env", s["env"]),
            ("approach", s["approach"]),
            ("world", world),
            ("exec", execution),
        ):
            order[name].setdefault(value, len(order[name]))
        fix = s.get("corrections")
        corrections = None if fix is None else f"{fix['worlds']} x{fix['rounds']}"
        key = (s["env"], s["approach"], s["demo_count"], level, world, execution, corrections)
        axes[key] = (axis, axis_of)
        groups.setdefault(key, []).append(SeedResult.from_record(record))
    keys = sorted(
        groups,
        key=lambda k: (
            order["env"][k[0]],
            order["approach"][k[1]],
            -1 if k[2] is None else k[2],
            0.0 if k[3] is None else k[3],
            order["world"][k[4]],
            order["exec"][k[5]],
            k[6] or "",
        ),
    )
    return [
        Row(
            *(k[0], k[1], k[2], tuple(sorted(groups[k], key=_seed)), k[3], axes[k][0], k[4], k[5]),
            axis_of=axes[k][1],
            corrections=k[6],
        )
        for k in keys
    ]


def _axis_level(settings: dict[str, Any]) -> tuple[str | None, float | None]:
    """(the swept axis' name, this cell's value): a perturbation's, or an object kind and
    its count; (None, None) without an axis."""
    axis = settings.get("perturb_axis")
    if axis is not None:
        return axis, settings["perturbation"][axis]
    if "objects" in settings:
        ((kind, count, _),) = ObjectCounts.parse(settings["objects"]).ranges
        return kind, float(count)
    return None, None


def _seed(result: SeedResult) -> int:
    return result.seed


TABLE_HEADER = (
    "| Environment | Approach | Demos | Seeds | Solved (%) | Median time (s) | Mean time (s) "
    "| Nodes created | Sim steps / plan step | Learning time (s) |\n"
    "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def markdown_table(rows: Sequence[Row]) -> str:
    """Mean ± std over seeds of each row's per-seed values (a perturbation axis adds a
    column after Demos; swept worlds and executions their own table)."""
    if any(r.world is not None or r.execution is not None for r in rows):
        return robustness_table(rows)
    axis = next((r.axis for r in rows if r.axis is not None), None)
    header = TABLE_HEADER
    if axis is not None:
        head, rule = TABLE_HEADER.split("\n")
        header = head.replace("| Demos |", f"| Demos | {axis} |") + "\n"
        header += rule.replace("|---:|", "|---:|---:|", 1)
    lines = [header]
    for row in rows:
        level = "" if axis is None else f"| {'–' if row.level is None else format(row.level, 'g')} "
        lines.append(
            f"| {row.env} | {row.label} | {'–' if row.demos is None else row.demos} {level}"
            f"| {len(row.seeds)} | {row.solved_percent.format('.1f')} "
            f"| {row.median_seconds.format('.2f')} | {row.mean_seconds.format('.2f')} "
            f"| {row.nodes_created.format('.1f')} | {row.sim_steps_per_step.format('.1f')} "
            f"| {row.learning_seconds.format('.1f')} |"
        )
    return "\n".join(lines) + "\n"


ROBUSTNESS_HEADER = (
    "| Environment | Approach | Demos | World | Execution | Seeds | Solved (%) "
    "| Pooled solved, 95 % CI | Replans / task | Median time (s) | Time vs nominal "
    "| Agent time vs nominal | Agent CPU vs nominal |\n"
    "|---|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
)


def robustness_table(rows: Sequence[Row]) -> str:
    """Each world beside the nominal one on the same tasks (rows of one environment,
    approach and demo count share their seeds' tasks): solved % as mean ± std over seeds,
    the pooled rate with its Wilson 95 % interval, replans per task and the median time
    over the nominal world's (same approach, demos and execution), in all and without the
    world's own simulation (the agent's time: planning and checking in the model), the
    latter also in CPU seconds, which other processes sharing the machine do not inflate."""

    def paired(r: Row) -> tuple:  # rows that share their seeds' tasks
        return (r.env, r.approach, r.demos, r.execution, r.corrections)

    def ratio(x: float | None, base: float | None) -> str:
        return "–" if not base or x is None else f"{x / base:.2f}x"

    nominal = {paired(r): r for r in rows if r.world in (None, "nominal") and r.axis is None}
    lines = [ROBUSTNESS_HEADER]
    for r in rows:
        solved, tasks = r.pooled
        low, high = r.pooled_interval
        base = nominal.get(paired(r))
        time_ratio = ratio(r.median_seconds.mean, base and base.median_seconds.mean)
        agent_ratio = ratio(r.median_agent_seconds.mean, base and base.median_agent_seconds.mean)
        cpu_ratio = ratio(
            r.median_agent_cpu_seconds.mean, base and base.median_agent_cpu_seconds.mean
        )
        world = r.world or (f"{r.axis}={r.level:g}" if r.axis is not None else "nominal")
        lines.append(
            f"| {r.env} | {r.label} | {'–' if r.demos is None else r.demos} | {world} "
            f"| {r.execution or 'closed-loop'} | {len(r.seeds)} | {r.solved_percent.format('.1f')} "
            f"| {solved}/{tasks} [{100 * low:.1f}, {100 * high:.1f}] "
            f"| {r.replans.format('.2f')} | {r.median_seconds.format('.2f')} | {time_ratio} "
            f"| {agent_ratio} | {cpu_ratio} |"
        )
    return "\n".join(lines) + "\n"
