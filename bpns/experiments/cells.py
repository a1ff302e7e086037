"""The cells of a sweep and their dependencies.

``demos(env, seed)`` collects the largest demo count once; ``skills(env, count, seed)``
learns from the first ``count`` train tasks of it; ``eval(env, approach, count, seed)``
plans the seed's eval tasks with those skills. Approaches that plan with the
environment's own skills do not depend on demonstrations: one eval cell per (env, seed).

A cell's *settings* are everything that decides its result; a stored cell is reused
only if its settings equal the sweep's.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from bpns.data.demo_attempts import demo_noise_of
from bpns.env.environment import Environment
from bpns.env.perturbations import Perturbation
from bpns.experiments import approach_info
from bpns.experiments.presets import SweepConfig, SweepConfigError, level_label
from bpns.learning.config import LearningConfig, learning_config_for
from bpns.planning.config import PlanningConfig, planning_config_for

DEMOS, SKILLS, EVAL = "demos", "skills", "eval"

#: The GNN baselines' seed in every skills cell, whatever the cell's seed: a sweep's
#: spread over seeds is over demonstrations, tasks and the BPNS networks' seeds, while
#: the GNNs start from the same weights (the stored sweeps were computed so, and the
#: seed is not in a cell's settings). `bpns learn --seed S --baselines` seeds them with S.
SWEEP_GNN_SEED = 0


@dataclass(frozen=True)
class Cell:
    """One unit of work. ``count`` is the number of train tasks collected (demos), the
    demo count learned from (skills, learned eval) or None (eval with env skills)."""

    kind: str
    env: str
    seed: int
    count: int | None
    approach: str | None = None
    deps: tuple[str, ...] = ()  # keys of the cells whose results this one reads
    learning: LearningConfig | None = None  # skills cells
    baselines: bool = False  # skills cells: also learn the paper's baselines beside them
    planning: PlanningConfig | None = None  # eval cells
    eval_tasks: int | None = None  # eval cells
    demo_noise: float = 0.0  # demos cells: DART noise scale (bpns.data.demo_attempts)
    perturbation: Perturbation | None = None  # eval cells of a perturbation axis
    perturb_axis: str | None = None  # the axis' perturbation name
    world: str | None = None  # eval cells of swept worlds: "moderate", "latency=0,1", ...
    execution: str | None = None  # "closed-loop" or "open-loop" (None: not swept)
    model: str = "nominal"  # what the planner simulates, when worlds are swept
    objects: str | None = None  # eval cells of an object axis: "button=5" (bpns eval --objects)
    world_speed: float = 1.0  # closed-loop eval cells: ExecutionConfig.world_speed
    slow_from: str = "start"  # and ExecutionConfig.slow_from (with a world_speed below 1)
    predict_latency: bool = False  # closed-loop eval cells: ExecutionConfig.predict_latency
    check_ahead: int | None = None  # closed-loop eval cells: ExecutionConfig.check_ahead
    watch_releases: bool = False  # closed-loop eval cells: ExecutionConfig.watch_releases
    # skills cells and their eval cells: policies retrained on corrections in these worlds
    # (``bpns learn --corrections``), over ``correction_rounds`` rounds
    corrections: str | None = None
    correction_rounds: int = 2

    @property
    def corrected(self) -> str:
        """The part of a key that says the skills were corrected ("" when not)."""
        if self.corrections is None:
            return ""
        return f"-corr{_slug(self.corrections)}x{self.correction_rounds}"

    @property
    def key(self) -> str:
        """Unique in a sweep, usable as a relative file path (``kind/name``)."""
        count = "" if self.count is None else f"-n{self.count}"
        if self.kind == EVAL:
            level = ""
            if self.perturbation is not None and self.perturb_axis is not None:
                value = getattr(self.perturbation, self.perturb_axis)
                level = f"-{self.perturb_axis}{level_label(value)}"
            if self.world is not None or self.execution is not None:
                level += f"-{_slug(self.world or 'nominal')}-{self.execution or 'closed-loop'}"
                if self.model != "nominal":
                    level += f"-model-{_slug(self.model)}"
            if self.objects is not None:
                level += f"-{self.objects.replace('=', '')}"
            if self.world_speed != 1.0:
                level += f"-speed{level_label(self.world_speed)}"
                if self.slow_from != "start":
                    level += f"-from{self.slow_from}"
            if self.predict_latency:
                level += "-predict"
            if self.check_ahead is not None:
                level += f"-ahead{self.check_ahead}"
            if self.watch_releases:
                level += "-releases"
            corrected = self.corrected
            return f"{EVAL}/{self.env}-{self.approach}{count}{corrected}{level}-seed{self.seed}"
        if self.kind == SKILLS:
            return f"{SKILLS}/{self.env}{count}{self.corrected}-seed{self.seed}"
        return f"{DEMOS}/{self.env}-seed{self.seed}"

    @property
    def settings(self) -> dict[str, Any]:
        """JSON-normalised (tuples become lists) so it compares equal to a stored copy."""
        s: dict[str, Any] = {"kind": self.kind, "env": self.env, "seed": self.seed}
        if self.kind == DEMOS:
            s["train_tasks"] = self.count
            if self.demo_noise:  # (absent when 0: cells stored before keep matching)
                s["demo_noise"] = self.demo_noise
        elif self.kind == SKILLS:
            s["demo_count"] = self.count
            s["learning"] = dataclasses.asdict(self.learning)  # type: ignore[arg-type]
            if self.baselines:  # (absent when False: cells stored before keep matching)
                s["baselines"] = True
            if self.corrections is not None:  # (absent when none, likewise)
                s["corrections"] = {"worlds": self.corrections, "rounds": self.correction_rounds}
        else:
            s.update(
                approach=self.approach,
                demo_count=self.count,
                eval_tasks=self.eval_tasks,
                task_seed=self.seed,
                planner_seed=self.seed,
                planning=_planning_settings(self.planning),  # type: ignore[arg-type]
            )
            if self.perturbation is not None:  # (absent: cells stored before keep matching)
                s["perturbation"] = dataclasses.asdict(self.perturbation)
                s["perturb_axis"] = self.perturb_axis
            if self.perturbation is not None or self.world is not None or self.execution:
                # the world only is perturbed and execution closes the loop unless said
                s["world"] = self.world
                s["execution"] = self.execution or "closed-loop"
                s["model"] = self.model
            if self.world is not None:  # (absent: cells whose worlds all came from seed 0)
                s["world_draws"] = "per-seed"
            if self.objects is not None:  # (absent: cells stored before keep matching)
                s["objects"] = self.objects
            if self.corrections is not None:  # (absent when none, likewise)
                s["corrections"] = {"worlds": self.corrections, "rounds": self.correction_rounds}
            if self.world_speed != 1.0:  # (absent at full speed, likewise)
                s["world_speed"] = self.world_speed
                if self.slow_from != "start":
                    s["slow_from"] = self.slow_from
            if self.predict_latency:  # (absent when off, likewise)
                s["predict_latency"] = True
            if self.check_ahead is not None:  # (absent when checking all, likewise)
                s["check_ahead"] = self.check_ahead
            if self.watch_releases:  # (absent when off, likewise)
                s["watch_releases"] = True
        return json.loads(json.dumps(s))

    def describe(self) -> str:
        parts = [self.kind, self.env]
        if self.approach is not None:
            parts.append(approach_info.label(self.approach))
        if self.kind == DEMOS:
            parts.append(f"{self.count} tasks")
        elif self.count is not None:
            parts.append(f"{self.count} demos")
        if self.perturbation is not None and self.perturb_axis is not None:
            parts.append(
                f"{self.perturb_axis}={level_label(getattr(self.perturbation, self.perturb_axis))}"
            )
        if self.world is not None or self.execution is not None:
            parts.append(f"world {self.world or 'nominal'} {self.execution or 'closed-loop'}")
        if self.objects is not None:
            parts.append(self.objects)
        if self.world_speed != 1.0:
            parts.append(f"world speed {self.world_speed:g}")
            if self.slow_from != "start":
                parts.append(f"from the first {self.slow_from}")
        if self.predict_latency:
            parts.append("predicting the commands in flight")
        if self.check_ahead is not None:
            parts.append(f"checking {self.check_ahead} step(s) ahead")
        if self.watch_releases:
            parts.append("watching releases")
        if self.corrections is not None:
            parts.append(f"corrected in {self.corrections} x{self.correction_rounds}")
        parts.append(f"seed {self.seed}")
        return " ".join(parts)


def plan_cells(config: SweepConfig, envs: Mapping[str, Environment]) -> list[Cell]:
    """All cells of ``config`` in an order that respects dependencies (demos, skills,
    evals; cheap, informative cells first). ``envs`` maps each name to an instance that
    supplies the environment's learning and planning defaults. Approaches needing
    hand-written skills are left out for environments that declare none."""
    demos: list[Cell] = []
    skills: list[Cell] = []
    evals: list[Cell] = []
    for name in config.envs:
        env = envs[name]
        base = planning_config_for(
            env, timeout=config.timeout, demote_refuted=config.demote_refuted
        )
        for seed in config.seeds:
            demo_cell = Cell(DEMOS, name, seed, config.max_demos, demo_noise=demo_noise_of(env))
            demos.append(demo_cell)
            for approach in config.approaches:
                if approach_info.uses_learned_skills(approach):
                    continue
                if not approach_info.available_on(approach, env):
                    continue
                evals += _eval_cells(name, seed, None, approach, base, config, ())
            for count in config.demo_counts:
                skill_cell = Cell(
                    SKILLS,
                    name,
                    seed,
                    count,
                    deps=(demo_cell.key,),
                    learning=learning_config_for(env, seed=seed),
                    baselines=any(approach_info.needs_baselines(a) for a in config.approaches),
                    **_corrections(config),
                )
                if any(approach_info.uses_learned_skills(a) for a in config.approaches):
                    skills.append(skill_cell)
                for approach in config.approaches:
                    if approach_info.uses_learned_skills(approach):
                        deps = (skill_cell.key,)
                        cells = _eval_cells(name, seed, count, approach, base, config, deps)
                        evals += [dataclasses.replace(c, **_corrections(config)) for c in cells]
    if not skills:  # nothing learns: no demonstrations needed
        demos = []
    cells = demos + skills + evals
    seen: dict[str, Cell] = {}
    for cell in cells:  # two cells in one file would overwrite each other's results
        other = seen.setdefault(cell.key, cell)
        if other is not cell:
            raise SweepConfigError(
                f"{other.describe()!r} and {cell.describe()!r} would be stored as the same "
                f"cell {cell.key}; sweep values that differ in their names"
            )
    return cells


def _eval_cells(
    env: str,
    seed: int,
    count: int | None,
    approach: str,
    base: PlanningConfig,
    config: SweepConfig,
    deps: tuple[str, ...],
) -> list[Cell]:
    """One eval cell per level of the sweep's perturbation or object axis (one without
    an axis)."""
    axis = None if config.perturb_axis is None else config.perturb_axis[0]
    return [
        Cell(
            EVAL,
            env,
            seed,
            count,
            approach=approach,
            deps=deps,
            planning=approach_info.planning_config(approach, base),
            eval_tasks=config.eval_tasks,
            perturbation=physics,
            perturb_axis=axis if physics is not None else None,
            world=world,
            execution=execution,
            model=config.model,
            objects=objects,
            world_speed=_world_speed(config, execution),
            slow_from=config.slow_from or "start",
            predict_latency=config.predict_latency and _closed_loop(execution),
            check_ahead=config.check_ahead if _closed_loop(execution) else None,
            watch_releases=config.watch_releases and _closed_loop(execution),
        )
        for physics in config.levels()
        for world, execution in config.conditions()
        for objects in config.object_levels()
    ]


def _corrections(config: SweepConfig) -> dict[str, Any]:
    """The corrections fields of a skills cell and of the eval cells of its skills."""
    if config.corrections is None:
        return {}
    rounds = 2 if config.correction_rounds is None else config.correction_rounds
    return {"corrections": config.corrections, "correction_rounds": rounds}


def _world_speed(config: SweepConfig, execution: str | None) -> float:
    """The sweep's world speed for a closed-loop cell (open loop replays at full speed)."""
    if config.world_speed is None or not _closed_loop(execution):
        return 1.0
    return config.world_speed


def _closed_loop(execution: str | None) -> bool:
    """Does a cell of this execution (None: not swept, so the default) close the loop?"""
    return (execution or "closed-loop") == "closed-loop"


def _slug(text: str) -> str:
    """``latency=0,1 mass_scale=0.5:2`` as a file-name part."""
    return "".join(c if c.isalnum() or c in ".-_" else "_" for c in text.replace(" ", "+"))


def skipped_approaches(config: SweepConfig, envs: Mapping[str, Environment]) -> list[str]:
    """(env, approach) pairs left out because the approach cannot run on the environment
    (it needs hand-written skills the environment does not declare)."""
    return [
        f"{approach} on {name}"
        for name in config.envs
        for approach in config.approaches
        if not approach_info.available_on(approach, envs[name])
    ]


def _planning_settings(planning: PlanningConfig) -> dict[str, Any]:
    """The planning config as stored; settings added since that are off are left out,
    so cells stored before keep matching."""
    d = dataclasses.asdict(planning)
    if d.get("demote_refuted") is None:
        d.pop("demote_refuted", None)
    return d
