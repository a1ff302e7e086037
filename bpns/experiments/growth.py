"""How cost grows along an object-count axis: power laws fitted to a sweep's rows.

For each line of an objects sweep (environment, approach, demo count) and a cost y
measured at counts x (the mean over seeds of each seed's median), the exponent ``k`` of
``y ∝ x^k`` is the least-squares slope of ``log y`` on ``log x``. ``k = 1`` is linear
growth, ``k = 2`` quadratic. Points without a value (no task solved at that count) or
with a non-positive one are left out; fewer than two points, or a single distinct ``x``,
give no exponent. Planning time is also fitted against the final plan's length (median
ground skills per solved task), which is what issue 38 bounds: bigger tasks should cost
about what their longer plans cost and no more (``k <= 1``). The same fit in CPU seconds
(the agent's, ``bpns.timing``) is given beside it: a sweep's cells run beside different
neighbours on a shared machine, which wall-clock time counts and CPU time does not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from bpns.experiments.aggregate import Row


def power_law_exponent(xs: Sequence[float | None], ys: Sequence[float | None]) -> float | None:
    """The least-squares ``k`` of ``log y = k log x + c`` over the pairs where both
    values exist and are > 0; None when fewer than two distinct ``x`` remain."""
    if len(xs) != len(ys):
        raise ValueError(f"xs and ys differ in length: {len(xs)} vs {len(ys)}")
    points = [
        (math.log(x), math.log(y))
        for x, y in zip(xs, ys, strict=True)
        if x is not None and y is not None and x > 0 and y > 0
        if math.isfinite(x) and math.isfinite(y)
    ]
    if len({px for px, _ in points}) < 2:
        return None
    mx = sum(px for px, _ in points) / len(points)
    my = sum(py for _, py in points) / len(points)
    sxx = sum((px - mx) ** 2 for px, _ in points)
    sxy = sum((px - mx) * (py - my) for px, py in points)
    return sxy / sxx


@dataclass(frozen=True)
class Growth:
    """One line of an objects sweep and its fitted exponents (None: not enough points)."""

    env: str
    label: str
    demos: int | None
    counts: tuple[float, ...]
    time_vs_count: float | None
    time_vs_plan_steps: float | None
    nodes_vs_count: float | None
    sim_steps_vs_count: float | None  # simulated steps per plan step
    # the agent's CPU seconds against plan length (None: cells without CPU records)
    cpu_time_vs_plan_steps: float | None = None

    def to_json(self) -> dict[str, object]:
        return {
            "env": self.env,
            "label": self.label,
            "demos": self.demos,
            "counts": list(self.counts),
            "time_vs_count": self.time_vs_count,
            "time_vs_plan_steps": self.time_vs_plan_steps,
            "nodes_vs_count": self.nodes_vs_count,
            "sim_steps_vs_count": self.sim_steps_vs_count,
            "cpu_time_vs_plan_steps": self.cpu_time_vs_plan_steps,
        }


def growth_of(rows: Sequence[Row]) -> list[Growth]:
    """One ``Growth`` per (env, approach, demos) of the rows swept over object counts,
    in the rows' order."""
    lines: dict[tuple[str, str, int | None], list[Row]] = {}
    for row in rows:
        if row.axis_of == "objects" and row.level is not None:
            lines.setdefault((row.env, row.approach, row.demos), []).append(row)
    result = []
    for (env, _, demos), line in lines.items():
        line = sorted(line, key=lambda r: r.level)  # type: ignore[arg-type, return-value]
        counts = [r.level for r in line]
        times = [r.median_seconds.mean for r in line]
        plan_steps = [r.plan_steps.mean for r in line]
        result.append(
            Growth(
                env=env,
                label=line[0].label,
                demos=demos,
                counts=tuple(c for c in counts if c is not None),
                time_vs_count=power_law_exponent(counts, times),
                time_vs_plan_steps=power_law_exponent(plan_steps, times),
                nodes_vs_count=power_law_exponent(counts, [r.nodes_created.mean for r in line]),
                sim_steps_vs_count=power_law_exponent(
                    counts, [r.sim_steps_per_step.mean for r in line]
                ),
                cpu_time_vs_plan_steps=power_law_exponent(
                    plan_steps, [r.median_agent_cpu_seconds.mean for r in line]
                ),
            )
        )
    return result


GROWTH_HEADER = (
    "| Environment | Approach | Demos | Counts | Time ∝ count^k | Time ∝ plan length^k "
    "| Agent CPU ∝ plan length^k | Nodes ∝ count^k | Sim steps / plan step ∝ count^k |\n"
    "|---|---|---:|---|---:|---:|---:|---:|---:|"
)


def growth_table(rows: Sequence[Row]) -> str:
    """The fitted exponents as a markdown table ("" when no row sweeps object counts)."""
    growth = growth_of(rows)
    if not growth:
        return ""

    def k(value: float | None) -> str:
        return "–" if value is None else f"{value:.2f}"

    lines = [GROWTH_HEADER]
    for g in growth:
        counts = ", ".join(format(c, "g") for c in g.counts)
        lines.append(
            f"| {g.env} | {g.label} | {'–' if g.demos is None else g.demos} | {counts} "
            f"| {k(g.time_vs_count)} | {k(g.time_vs_plan_steps)} "
            f"| {k(g.cpu_time_vs_plan_steps)} | {k(g.nodes_vs_count)} "
            f"| {k(g.sim_steps_vs_count)} |"
        )
    return "\n".join(lines) + "\n"
