"""Turn a sweep's stored eval cells into its outputs: results.md (the command, the
table and the figures), results.json (the aggregated rows) and the figures."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bpns.atomic import atomic_path
from bpns.env.perturbations import PerturbationError
from bpns.evaluation.by_world import Trial, world_of_label, world_split_table
from bpns.experiments import approach_info
from bpns.experiments.aggregate import Row, aggregate, markdown_table
from bpns.experiments.cells import EVAL, SWEEP_GNN_SEED, Cell
from bpns.experiments.growth import growth_of, growth_table
from bpns.experiments.plots import (
    cost_vs_objects,
    save_figure,
    success_vs_demos,
    success_vs_perturbation,
    success_vs_time,
    success_vs_world,
)
from bpns.experiments.presets import PRESETS, SweepConfig
from bpns.experiments.store import CellStore

FIG_DEMOS = "success_vs_demos"
FIG_TIME = "success_vs_time"
FIG_WORLD = "success_vs_world"


def stored_eval_records(cells: Sequence[Cell], store: CellStore) -> list[dict[str, Any]]:
    return [r for c in cells if c.kind == EVAL and (r := store.load(c)) is not None]


def write_report(
    out: Path, cells: Sequence[Cell], store: CellStore, config: SweepConfig, command: str
) -> tuple[list[Row], list[Path]]:
    """Aggregate the stored eval cells of ``cells``; returns the rows and files written
    (no figures when no eval cell has finished)."""
    records = stored_eval_records(cells, store)
    rows = aggregate(records)
    missing = sum(c.kind == EVAL for c in cells) - len(records)
    table = markdown_table(rows)
    written: list[Path] = []
    figures = [(FIG_DEMOS, "success vs demonstrations"), (FIG_TIME, "success vs planning time")]
    if rows and config.axis_name is not None:  # the axis' figure instead
        figures = [(f"success_vs_{config.axis_name}", f"success vs {config.axis_name}")]
        written += save_figure(success_vs_perturbation(rows), out / figures[0][0])
        if config.objects_axis is not None:  # and how the cost grows with the count
            figures.append((f"cost_vs_{config.axis_name}", f"cost vs {config.axis_name} count"))
            written += save_figure(cost_vs_objects(rows), out / figures[1][0])
    elif rows and config.worlds:  # the demos and time figures would mix the worlds
        shown = " and ".join(e.replace("-", " ") for e in config.executions) or "closed loop"
        figures = [(FIG_WORLD, f"success by world, {shown}")]
        written += save_figure(success_vs_world(rows), out / FIG_WORLD)
    elif rows:
        written += save_figure(success_vs_demos(rows), out / FIG_DEMOS)
        written += save_figure(success_vs_time(rows, config.timeout), out / FIG_TIME)
    preset = PRESETS.get(config.name)
    overridden = "" if preset == config else " with overrides"
    text = [
        f"# Experiment: {', '.join(config.envs)}, preset `{config.name}`{overridden}",
        "",
        f"Produced by `{command}`.",
        "",
        f"{len(config.seeds)} seeds ({', '.join(map(str, config.seeds))}); each seed has its own "
        f"demonstrations, skills and {config.eval_tasks} eval tasks; planning timeout "
        f"{config.timeout:g} s per task"
        + (
            ""
            if config.perturb_axis is None
            else f", under each {config.perturb_axis[0]} of "
            f"{', '.join(format(v, 'g') for v in config.perturb_axis[1])} (`bpns eval --perturb`)"
        )
        + (
            ""
            if config.objects_axis is None
            else f", with each count of {config.objects_axis[0]} in "
            f"{', '.join(map(str, config.objects_axis[1]))} (`bpns eval --objects`)"
        )
        + ". Values are mean ± std over seeds (population std); "
        "times are over solved tasks, nodes created over all tasks; learning time is the "
        "time spent learning what the approach uses, without loading the demonstrations "
        "(BPNS and its planning ablations: the skills pipeline; No Subgoal: its own skills; "
        "GNN Meta: the GNN plus the skills it executes; GNN BC: its GNN)."
        + (
            f" The GNN baselines draw seed {SWEEP_GNN_SEED} in every seed (initial weights, "
            "batches, BC's subsample); No Subgoal's networks take the seed like BPNS's."
            if any(approach_info.needs_baselines(a) for a in config.approaches)
            else ""
        ),
        "",
    ]
    last_run = _last_run(out / "sweep.json")
    if last_run:
        text += [last_run, ""]
    if missing:
        text += [f"**{missing} eval cells are not finished; their rows are incomplete.**", ""]
    text += [table]
    split = world_split_section(rows)
    if split:
        text += ["", split]
    growth = growth_table(rows)
    if growth:
        text += [
            "",
            "Fitted growth: the least-squares exponent k of cost ∝ count^k (log-log) over the "
            "counts, on the mean over seeds of each seed's median time, its mean nodes and "
            "its median simulated steps per plan step; plan length is the median number of "
            "ground skills of the solved tasks' final plans (k ≤ 1: time grows no faster "
            "than the plans).",
            "",
            growth,
        ]
    if rows:
        text += [""]
        for stem, caption in figures:
            text += [f"![{caption}]({stem}.png)", ""]
    md = out / "results.md"
    with atomic_path(md) as tmp:
        tmp.write_text("\n".join(text))
    js = out / "results.json"
    with atomic_path(js) as tmp:
        payload = {"config": config.to_json(), "command": command, "missing_cells": missing}
        payload["rows"] = [r.to_json() for r in rows]
        if growth:
            payload["growth"] = [g.to_json() for g in growth_of(rows)]
        tmp.write_text(json.dumps(payload, indent=1) + "\n")
    return rows, [md, js, *written]


def world_split_section(rows: Sequence[Row]) -> str:
    """Per (environment, approach, demonstrations) of a worlds sweep, its perturbed rows'
    tasks pooled over seeds and split by the world each met
    (:func:`bpns.evaluation.by_world.world_split_table`), a column per world and
    execution; empty when no row's worlds varied."""
    groups: dict[tuple, list[tuple[str, list[Trial]]]] = {}
    unreadable = 0
    for row in rows:
        if row.world is None:
            continue
        trials = []
        for seed in row.seeds:
            for label, ok in seed.trials:
                try:
                    trials.append((world_of_label(label), ok))
                except PerturbationError:  # a hand-edited cell: its task is left out
                    unreadable += 1
        heading = row.world if row.execution is None else f"{row.world}, {row.execution}"
        key = (row.env, row.label, row.demos)
        groups.setdefault(key, []).append((heading, trials))
    parts = []
    for (env, label, demos), columns in groups.items():
        table = world_split_table(columns)
        if table:
            count = "" if demos is None else f", {demos} demonstrations"
            parts.append(f"{env}, {label}{count}: solved by the world each task met\n\n{table}")
    if not parts:
        return ""
    left_out = (
        f" ({unreadable} tasks whose world record is unreadable left out)" if unreadable else ""
    )
    return (
        "Each perturbed row's tasks, pooled over its seeds, binned by each world parameter "
        "that varied (scales about 1: a fifth off either way; the latency by its value), "
        f"with Wilson 95 % intervals{left_out}. The bins are marginal: the other parameters "
        "were drawn independently.\n\n" + "\n".join(parts)
    )


def _last_run(sweep_file: Path) -> str | None:
    """One line on the last run in this directory (from its ``sweep.json``), if any."""
    try:
        data = json.loads(sweep_file.read_text())
        return (
            f"Last run: {data['computed']} of {data['cells']} cells computed "
            f"({data['reused']} reused) in {data['seconds']:.0f} s."
        )
    except (OSError, ValueError, KeyError, TypeError):
        return None
