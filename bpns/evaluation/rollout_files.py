"""Rollouts files: every task an evaluation ran, solved or failed, as data.

A rollouts file *is* a demonstration file (:mod:`bpns.data.datasets`: the same writer and
reader; ``demo_<i>`` holds task i's initial state, actions, states, features, goal and
MJCF), with attributes that say what the rows are:

- root: ``kind`` = ``rollouts``, ``approach``, ``label``, ``task_seed``, ``train_tasks``,
  ``eval_set`` (JSON of :class:`bpns.env.object_counts.EvalSet`: the eval distribution;
  files without it came from the paper set),
  ``worlds`` (JSON of :class:`bpns.env.worlds.WorldDistribution`: the worlds the tasks
  were drawn from), ``model`` (JSON of :class:`bpns.env.worlds.ModelSpec`),
  ``execution`` (``closed-loop`` or ``open-loop``) and, when every task met the same
  physics, ``perturbation`` (JSON of :class:`bpns.env.perturbations.Perturbation`);
- per demo: ``task`` (the eval task index), ``solved`` (0/1), ``reason`` (why it
  failed, "" when solved), ``plan`` (JSON list of :class:`bpns.execution.rollouts.PlanStep`),
  ``physics`` (JSON of the task's own world: what replay needs to be exact), ``events``
  (JSON list of :class:`bpns.execution.rollouts.Event`: the monitor's divergences and
  replans), ``replans`` and, for a failed task, ``explanation``
  (JSON: what the planner tried, as in results.json).

Files written before per-task worlds carry no ``physics`` per row: their root
``perturbation`` is every row's.

For a failed task the rows are the attempt that got furthest (bilevel planning: the
deepest refined prefix, then the failed sample after it, with its failure reason), so
the video of a failed task ends where and how its skill failed.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from bpns.data.datasets import (
    DatasetError,
    load_demonstrations,
    read_attributes,
    write_demonstrations,
)
from bpns.data.demos import ReplayReport, replay
from bpns.env.environment import Environment, eval_environment, perturbed
from bpns.env.object_counts import PAPER_SET, EvalSet, ObjectCountError
from bpns.env.perturbations import NOMINAL, Perturbation, PerturbationError
from bpns.env.worlds import NOMINAL_WORLD, WORLD_MODEL, ModelSpec, WorldDistribution
from bpns.evaluation.evaluate import EvalReport, TaskOutcome
from bpns.execution.rollouts import Event, PlanStep, Rollout
from bpns.structs import Demonstration, Task

KIND = "rollouts"


def rollouts_name(approach: str) -> str:
    return f"rollouts_{approach}.h5"


def demonstration_of(env: Environment, task: Task, actions: np.ndarray) -> Demonstration:
    """``actions`` re-simulated from ``task.init`` (exact), as a demonstration."""
    states = [task.init]
    for action in actions:
        states.append(env.simulate(states[-1], action))
    return Demonstration(task=task, states=tuple(states), actions=np.asarray(actions))


def save_rollouts(path: str | os.PathLike, env: Environment, report: EvalReport) -> int:
    """Every task of ``report`` with what its approach executed, re-simulated in the
    task's own world, atomically; ``env`` is the nominal environment."""

    tasks_env = report.task_environment(env)

    def items() -> Iterator[tuple[Demonstration, dict]]:
        for o in report.outcomes:
            world = perturbed(tasks_env, o.world)
            task = world.task(o.index, report.task_seed, report.train_tasks)
            demo = demonstration_of(world, task, _rollout(o).actions)
            yield demo, _outcome_attrs(o)

    root = {
        "kind": KIND,
        "approach": report.approach,
        "label": report.label,
        "task_seed": report.task_seed,
        "train_tasks": int(report.train_tasks),
        "worlds": report.worlds.to_json(),
        "model": report.model.to_json(),
        "execution": report.execution.mode,
        "eval_set": report.eval_set.to_json(),
    }
    if report.worlds.fixed:
        root["perturbation"] = report.worlds.draw(0).to_json()
    return write_demonstrations(path, env, items(), root)


def _rollout(o: TaskOutcome) -> Rollout:
    return o.rollout if o.rollout is not None else Rollout(o.actions)


def _outcome_attrs(o: TaskOutcome) -> dict:
    rollout = _rollout(o)
    return {
        "task": o.index,
        "solved": int(o.solved),
        "reason": "" if o.solved else str(o.reason),
        "plan": json.dumps([s.to_json() for s in rollout.steps]),
        "physics": o.world.to_json(),
        "events": json.dumps([e.to_json() for e in rollout.events]),
        "replans": int(o.replans),
        # a failed task: what the planner tried (bpns view shows it)
        **({"explanation": json.dumps(o.explanation)} if o.explanation else {}),
    }


@dataclass(frozen=True)
class RolloutInfo:
    """What a rollouts file says of one row besides its demonstration."""

    position: int  # demo_<position>
    task: int
    solved: bool
    reason: str
    steps: tuple[PlanStep, ...]
    physics: Perturbation = NOMINAL  # the world it executed in
    events: tuple[Event, ...] = ()
    replans: int = 0


@dataclass(frozen=True)
class RolloutsFile:
    """A rollouts file's header and rows (their demonstrations load on demand)."""

    path: str
    approach: str
    label: str
    perturbation: Perturbation  # every row's physics when they share one (older files)
    rows: tuple[RolloutInfo, ...]
    worlds: WorldDistribution = NOMINAL_WORLD
    model: ModelSpec = WORLD_MODEL
    execution: str = "open-loop"
    eval_set: EvalSet = PAPER_SET  # the eval distribution its tasks came from

    @classmethod
    def read(cls, path: str | os.PathLike) -> RolloutsFile:
        root, demos = read_attributes(path)
        if root.get("kind") != KIND:
            raise DatasetError(f"{path}: not a rollouts file (written by `bpns eval --out`)")
        _require(path, "the file", root, ROOT_ATTRIBUTES)
        # a file that records its worlds records each row's: a row without one would
        # replay in the file's nominal physics though it ran in a perturbed world (rows
        # fall back to the file's perturbation only in files older than per-task worlds)
        row_attributes = ROW_ATTRIBUTES + (("physics",) if "worlds" in root else ())
        for i, d in enumerate(demos):
            _require(path, f"row demo_{i}", d, row_attributes)
        try:
            perturbation = Perturbation.from_json(str(root.get("perturbation", "{}")))
            worlds = (
                WorldDistribution.from_json(str(root["worlds"]))
                if "worlds" in root
                else WorldDistribution.of(perturbation)
            )
            model = ModelSpec.from_json(str(root["model"])) if "model" in root else WORLD_MODEL
            eval_set = EvalSet.from_json(str(root["eval_set"])) if "eval_set" in root else PAPER_SET
        except (KeyError, TypeError, ValueError, PerturbationError, ObjectCountError) as err:
            raise DatasetError(
                f"{path}: damaged rollout records: {err}; write it again with `bpns eval --out DIR`"
            ) from None
        rows = []
        for i, d in enumerate(demos):
            try:
                rows.append(_row(i, d, perturbation))
            except (AttributeError, KeyError, TypeError, ValueError, PerturbationError) as err:
                raise DatasetError(
                    f"{path}: row demo_{i} is damaged: {err}; write it again with "
                    "`bpns eval --out DIR`"
                ) from None
        return cls(
            str(path),
            str(root["approach"]),
            str(root["label"]),
            perturbation,
            tuple(rows),
            worlds,
            model,
            str(root.get("execution", "open-loop")),
            eval_set,
        )

    def row(self, task: int) -> RolloutInfo:
        for r in self.rows:
            if r.task == task:
                return r
        tasks = ", ".join(str(r.task) for r in self.rows)
        raise DatasetError(f"{self.path}: has no rollout of task {task} (tasks: {tasks})")

    def environment(self, env: Environment, row: RolloutInfo | None = None) -> Environment:
        """``env`` (nominal, built by name) drawing the file's eval set, under the physics
        ``row`` ran under (the file's, without a row)."""
        tasks_env = eval_environment(env, self.eval_set)
        return perturbed(tasks_env, self.perturbation if row is None else row.physics)

    def demonstration(self, env: Environment, row: RolloutInfo) -> Demonstration:
        """Row ``row``'s demonstration, loaded into its own world."""
        (demo,) = load_demonstrations(self.path, self.environment(env, row), [row.position])
        return demo


ROOT_ATTRIBUTES = ("approach", "label")
ROW_ATTRIBUTES = ("task", "solved", "reason", "plan")


def _require(path: str | os.PathLike, where: str, attrs: dict, names: tuple[str, ...]) -> None:
    """A missing attribute is named with its row (a KeyError would name neither)."""
    missing = [n for n in names if n not in attrs]
    if missing:
        raise DatasetError(
            f"{path}: {where} lacks the attribute {', '.join(repr(n) for n in missing)}: "
            "not a complete rollouts file; write it again with `bpns eval --out DIR`"
        )


def _row(position: int, d: dict, fallback: Perturbation) -> RolloutInfo:
    physics = Perturbation.from_json(str(d["physics"])) if "physics" in d else fallback
    events = tuple(Event.from_json(e) for e in json.loads(str(d.get("events", "[]"))))
    return RolloutInfo(
        position,
        int(d["task"]),
        bool(d["solved"]),
        str(d["reason"]),
        tuple(PlanStep.from_json(s) for s in json.loads(str(d["plan"]))),
        physics,
        events,
        int(d.get("replans", 0)),
    )


def is_rollouts_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a readable demonstration file that holds rollouts."""
    try:
        root, _ = read_attributes(path)
    except DatasetError:
        return False
    return root.get("kind") == KIND


@dataclass(frozen=True)
class RolloutReplay:
    """Each row re-simulated under the file's physics: exact, and the goal reached at the
    end exactly when the row says the task was solved."""

    physics: str
    rows: tuple[tuple[RolloutInfo, ReplayReport], ...]

    @property
    def bad(self) -> list[tuple[RolloutInfo, ReplayReport]]:
        return [(i, r) for i, r in self.rows if not r.exact or r.goal_reached != i.solved]

    @property
    def ok(self) -> bool:
        return not self.bad

    def lines(self) -> list[str]:
        worst = max((r.max_state_diff for _, r in self.rows), default=0.0)
        solved = sum(i.solved for i, _ in self.rows)
        out = [
            f"replayed {len(self.rows)} rollouts ({solved} solved, "
            f"{sum(r.steps for _, r in self.rows)} steps, physics: {self.physics}): "
            f"max |state diff| = {worst:.3g}, {len(self.rows) - len(self.bad)}/{len(self.rows)} "
            "exact with the recorded outcome"
        ]
        for info, r in self.bad:
            out.append(
                f"  task {info.task}: max state diff {r.max_state_diff:.3g}, feature diff "
                f"{r.max_feature_diff:.3g}, goal {'reached' if r.goal_reached else 'not reached'}"
                f" (recorded: {'solved' if info.solved else info.reason})"
            )
        return out


def replay_rollouts(
    env: Environment, path: str | os.PathLike, limit: int | None = None
) -> RolloutReplay:
    """Re-simulate the first ``limit`` (default: all) rollouts of ``path``, each in its
    own world (``env`` nominal: every row's physics is applied)."""
    f = RolloutsFile.read(path)
    rows = f.rows[: limit or len(f.rows)]
    checked = tuple(
        (r, replay(f.environment(env, r), f.demonstration(env, r), r.position)) for r in rows
    )
    return RolloutReplay(f.worlds.label(), checked)
