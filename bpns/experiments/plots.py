"""The paper's figures from aggregated rows, drawn with matplotlib's Agg canvas (no
display, no pyplot state) and written atomically as PNG and SVG.

- success vs demonstrations (the paper's Figure 3): one panel per environment, one line
  per learning approach with ± std error bars over seeds; approaches that learn nothing
  are a horizontal line with a ± std band. Approaches are drawn side by side at each
  count (a small offset on the log axis) so that equal values stay visible.
- success vs a perturbation (a sweep with ``--perturb-axis``): per environment, solved
  at each level of the axis, one line per approach.
- success vs world (a sweep with ``--worlds``): per environment, the pooled share of
  eval tasks solved in each world with its Wilson 95 % interval, one line per approach
  (and demo count) and execution: closed loop solid, open loop dashed.
- cost vs object count (a sweep with ``--objects-axis``): per environment, median
  planning time, nodes created and simulated steps per plan step at each count on log-log
  axes (mean ± std over seeds), one line per approach, the fitted exponent in the legend.
- success vs planning time: per environment, the percentage of eval tasks solved within
  t seconds, mean over seeds with a ± std band; learning approaches at their largest
  demo count.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from bpns.atomic import atomic_path
from bpns.env.perturbations import AXIS_LABELS
from bpns.experiments.aggregate import Row
from bpns.experiments.growth import growth_of

FORMATS = ("png", "svg")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def _colours(rows: Sequence[Row]) -> dict[str, str]:
    """The same colour for an approach in every panel and figure."""
    approaches = list(dict.fromkeys(r.approach for r in rows))
    return {a: f"C{i % 10}" for i, a in enumerate(approaches)}


def _panels(n: int, title: str) -> tuple[Figure, list]:
    fig = Figure(figsize=(4.6 * n + 1.2, 3.6), layout="constrained")
    axes = fig.subplots(1, n, squeeze=False)[0]
    fig.suptitle(title)
    return fig, list(axes)


def success_vs_demos(rows: Sequence[Row]) -> Figure:
    envs = list(dict.fromkeys(r.env for r in rows))
    colours = _colours(rows)
    fig, axes = _panels(len(envs), "Success vs demonstrations (mean ± std over seeds)")
    for ax, env in zip(axes, envs, strict=True):
        mine = [r for r in rows if r.env == env]
        counts = sorted({r.demos for r in mine if r.demos is not None})
        learners = list(dict.fromkeys(r.approach for r in mine if r.demos is not None))
        for approach in dict.fromkeys(r.approach for r in mine):
            lines = [r for r in mine if r.approach == approach]
            label = f"{lines[0].label} ({len(lines[0].seeds)} seeds)"
            if lines[0].demos is None:  # learns nothing: a level across the panel
                s = lines[0].solved_percent
                assert s.mean is not None and s.std is not None
                ax.axhline(s.mean, color=colours[approach], ls="--", label=label)
                ax.axhspan(s.mean - s.std, s.mean + s.std, color=colours[approach], alpha=0.12)
                continue
            # approaches side by side at each count, so equal values do not hide each other
            i = learners.index(approach)
            dodge = float(np.exp(0.04 * (i - (len(learners) - 1) / 2)))
            stats = [r.solved_percent for r in lines]
            ax.errorbar(
                [r.demos * dodge for r in lines],  # type: ignore[operator]
                [s.mean for s in stats],
                yerr=[s.std for s in stats],
                color=colours[approach],
                marker=MARKERS[i % len(MARKERS)],
                capsize=4,
                label=label,
            )
        if counts:
            ax.set_xscale("log")
            ax.set_xticks(counts, [str(c) for c in counts])
            ax.minorticks_off()
        ax.set_ylim(-3, 103)
        ax.set_xlabel("demonstrations")
        ax.set_ylabel("eval tasks solved (%)")
        ax.set_title(env)
        ax.grid(alpha=0.3)
    _legend_below(fig, axes)
    return fig


def success_vs_time(rows: Sequence[Row], timeout: float) -> Figure:
    envs = list(dict.fromkeys(r.env for r in rows))
    colours = _colours(rows)
    fig, axes = _panels(len(envs), "Success vs planning time (mean ± std over seeds)")
    for ax, env in zip(axes, envs, strict=True):
        mine = [r for r in rows if r.env == env]
        shown = []
        for approach in dict.fromkeys(r.approach for r in mine):
            lines = [r for r in mine if r.approach == approach]
            shown.append(max(lines, key=lambda r: -1 if r.demos is None else r.demos))
        fastest = min((t for r in shown for s in r.seeds for t in s.solved_seconds), default=1e-2)
        grid = np.geomspace(max(min(fastest, timeout) * 0.8, 1e-4), timeout, 300)
        for row in shown:
            per_seed = np.array(
                [[100.0 * s.fraction_solved_within(t) for t in grid] for s in row.seeds]
            )
            mean, std = per_seed.mean(axis=0), per_seed.std(axis=0)
            label = row.label + ("" if row.demos is None else f" ({row.demos} demos)")
            colour = colours[row.approach]
            ax.step(grid, mean, where="post", color=colour, label=label)
            ax.fill_between(grid, mean - std, mean + std, step="post", color=colour, alpha=0.12)
        ax.set_xscale("log")
        ax.set_xlim(grid[0], timeout)
        ax.set_ylim(-3, 103)
        ax.set_xlabel("planning time t (s)")
        ax.set_ylabel("eval tasks solved within t (%)")
        ax.set_title(env)
        ax.grid(alpha=0.3)
    _legend_below(fig, axes)
    return fig


def success_vs_perturbation(rows: Sequence[Row]) -> Figure:
    """Robustness: per environment, eval tasks solved (mean ± std over seeds) at each
    level of the sweep's perturbation axis, one line per approach (and demo count)."""
    envs = list(dict.fromkeys(r.env for r in rows))
    axis = next(r.axis for r in rows if r.axis is not None)
    colours = _colours(rows)
    fig, axes = _panels(len(envs), f"Success vs {axis} (mean ± std over seeds)")
    for ax, env in zip(axes, envs, strict=True):
        mine = [r for r in rows if r.env == env and r.level is not None]
        lines = list(dict.fromkeys((r.approach, r.demos) for r in mine))
        levels = sorted({r.level for r in mine})  # type: ignore[type-var]
        span = (max(levels) - min(levels)) or 1.0
        for i, (approach, demos) in enumerate(lines):
            line = sorted(
                (r for r in mine if (r.approach, r.demos) == (approach, demos)),
                key=lambda r: r.level,  # type: ignore[arg-type, return-value]
            )
            stats = [r.solved_percent for r in line]
            dodge = 0.012 * span * (i - (len(lines) - 1) / 2)  # equal values stay visible
            label = line[0].label + ("" if demos is None else f" ({demos} demos)")
            ax.errorbar(
                [r.level + dodge for r in line],  # type: ignore[operator]
                [s.mean for s in stats],
                yerr=[s.std for s in stats],
                color=colours[approach],
                marker=MARKERS[i % len(MARKERS)],
                capsize=4,
                label=f"{label} ({len(line[0].seeds)} seeds)",
            )
        ax.set_xticks(levels, [f"{v:g}" for v in levels])
        ax.set_ylim(-3, 103)
        ax.set_xlabel(AXIS_LABELS.get(axis, axis))
        ax.set_ylabel("eval tasks solved (%)")
        ax.set_title(env)
        ax.grid(alpha=0.3)
    _legend_below(fig, axes)
    return fig


COST_PANELS = (
    ("median planning time (s)", "median_seconds"),
    ("nodes created", "nodes_created"),
    ("simulated steps / plan step", "sim_steps_per_step"),
)


def cost_vs_objects(rows: Sequence[Row]) -> Figure:
    """Issue 38's scaling figure: one row of panels per environment (time, nodes,
    simulated steps per plan step against the object count, log-log), one line per
    approach and demo count; the legend carries time's fitted exponent."""
    mine = [r for r in rows if r.axis_of == "objects" and r.level is not None]
    envs = list(dict.fromkeys(r.env for r in mine))
    axis = next(r.axis for r in mine)
    colours = _colours(mine)
    exponents = {(g.env, g.label, g.demos): g.time_vs_count for g in growth_of(mine)}
    fig = Figure(figsize=(13.0, 3.2 * len(envs) + 0.6), layout="constrained")
    grid = fig.subplots(len(envs), len(COST_PANELS), squeeze=False)
    fig.suptitle(f"Cost vs {axis} count (mean ± std over seeds; k: time ∝ count^k)")
    for panels, env in zip(grid, envs, strict=True):
        lines = list(dict.fromkeys((r.approach, r.demos) for r in mine if r.env == env))
        for i, (approach, demos) in enumerate(lines):
            line = sorted(
                (r for r in mine if (r.env, r.approach, r.demos) == (env, approach, demos)),
                key=lambda r: r.level,  # type: ignore[arg-type, return-value]
            )
            k = exponents.get((env, line[0].label, demos))
            label = line[0].label + ("" if demos is None else f" ({demos} demos)")
            label += "" if k is None else f", k={k:.2f}"
            for ax, (_, field) in zip(panels, COST_PANELS, strict=True):
                stats = [getattr(r, field) for r in line]
                xs = [r.level for r, s in zip(line, stats, strict=True) if s.mean is not None]
                kept = [s for s in stats if s.mean is not None]
                if not kept:
                    continue
                ax.errorbar(
                    xs,
                    [s.mean for s in kept],
                    yerr=[s.std for s in kept],
                    color=colours[approach],
                    marker=MARKERS[i % len(MARKERS)],
                    capsize=3,
                    label=label,
                )
        counts = sorted({r.level for r in mine if r.env == env})  # type: ignore[type-var]
        for ax, (ylabel, _) in zip(panels, COST_PANELS, strict=True):
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xticks(counts, [f"{c:g}" for c in counts])
            ax.minorticks_off()
            ax.set_xlabel(f"{axis} count")
            ax.set_ylabel(ylabel)
            ax.set_title(env)
            ax.grid(alpha=0.3, which="both")
    _legend_below(fig, list(grid.flat))
    return fig


def success_vs_world(rows: Sequence[Row]) -> Figure:
    """Model against world: per environment, tasks solved (pooled over seeds, Wilson 95 %
    interval) in each swept world, closed loop solid and open loop dashed."""
    envs = list(dict.fromkeys(r.env for r in rows))
    colours = _colours(rows)
    fig, axes = _panels(len(envs), "Success by world (pooled over seeds, Wilson 95 % interval)")
    for ax, env in zip(axes, envs, strict=True):
        mine = [r for r in rows if r.env == env and r.world is not None]
        worlds = list(dict.fromkeys(r.world for r in mine))
        lines = list(dict.fromkeys((r.approach, r.demos, r.execution) for r in mine))
        for i, (approach, demos, execution) in enumerate(lines):
            line = {
                r.world: r
                for r in mine
                if (r.approach, r.demos, r.execution) == (approach, demos, execution)
            }
            xs = [k for k, w in enumerate(worlds) if w in line]
            dodge = 0.06 * (i - (len(lines) - 1) / 2)  # equal values stay visible
            ys, lows, highs = [], [], []
            for k in xs:
                r = line[worlds[k]]
                solved, trials = r.pooled
                low, high = r.pooled_interval
                y = 100.0 * solved / trials if trials else float("nan")
                ys.append(y)
                # n of n: Wilson's upper bound is 1 only up to rounding
                lows.append(max(0.0, y - 100.0 * low))
                highs.append(max(0.0, 100.0 * high - y))
            first = line[worlds[xs[0]]]
            label = first.label + ("" if demos is None else f" ({demos} demos)")
            ax.errorbar(
                [k + dodge for k in xs],
                ys,
                yerr=[lows, highs],
                color=colours[approach],
                ls="--" if execution == "open-loop" else "-",
                marker=MARKERS[i % len(MARKERS)],
                capsize=4,
                label=f"{label}, {execution or 'closed-loop'} ({len(first.seeds)} seeds)",
            )
        ax.set_xticks(range(len(worlds)), worlds)
        ax.set_ylim(-3, 103)
        ax.set_xlabel("world")
        ax.set_ylabel("eval tasks solved (%)")
        ax.set_title(env)
        ax.grid(alpha=0.3)
    _legend_below(fig, axes)
    return fig


def _legend_below(fig: Figure, axes: Sequence) -> None:
    """One legend for every panel, below them: inside a panel it hid the very points
    (eight approaches leave no empty corner)."""
    entries: dict[str, object] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    if not entries:
        return
    width, height = fig.get_size_inches()
    # as many columns as the longest label lets fit across the figure (8 pt text: about
    # 0.07 in a character, plus the marker), so long labels are not cut at the edges
    entry_width = 0.07 * max(len(label) for label in entries) + 0.6
    columns = max(1, min(2 * len(axes), len(entries), int(width // entry_width)))
    rows = -(-len(entries) // columns)
    fig.set_size_inches(width, height + 0.2 * rows + 0.1)
    fig.legend(
        list(entries.values()),
        list(entries),
        loc="outside lower center",
        ncols=columns,
        fontsize=8,
        frameon=False,
    )


def save_figure(fig: Figure, stem: Path) -> list[Path]:
    """``stem``.png and ``stem``.svg, each written atomically; the same figure gives the
    same bytes (no date, fixed SVG ids), so a rebuilt report only changes where a number
    did."""
    written = []
    for fmt in FORMATS:
        path = stem.with_suffix(f".{fmt}")
        metadata = {"Date": None} if fmt == "svg" else {}
        with matplotlib.rc_context({"svg.hashsalt": "bpns"}), atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=150, metadata=metadata)
        written.append(path)
    return written
