"""Rollouts files: every task an evaluation ran, solved or failed, as data.

A rollouts file *is* a demonstration file (:mod:`bpns.data.datasets`: the same writer and
reader; ``demo_<i>`` holds task i's initial state, actions, states, features, goal and
MJCF), with attributes that say what the rows are:

- root: ``kind`` = ``rollouts``, ``approach``, ``label``, ``task_seed``, ``train_tasks``,
  ``perturbation`` (JSON of :class:`bpns.env.perturbations.Perturbation`: the physics the
  rollouts ran under, needed to replay them exactly);
- per demo: ``task`` (the eval task index), ``solved`` (0/1), ``reason`` (why it
  failed, "" when solved), ``plan`` (JSON list of :class:`bpns.execution.rollouts.PlanStep`)
  and, for a failed task, ``explanation`` (JSON: what the planner tried, as results.json).

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
from bpns.env.environment import Environment, perturbed
from bpns.env.perturbations import Perturbation, PerturbationError
from bpns.evaluation.evaluate import EvalReport, TaskOutcome
from bpns.execution.rollouts import PlanStep, Rollout
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
    """Every task of ``report`` with what its approach executed, atomically; ``env`` is
    the nominal environment (the report's perturbation is applied here)."""
    world = perturbed(env, report.perturbation)

    def items() -> Iterator[tuple[Demonstration, dict]]:
        for o in report.outcomes:
            task = world.task(o.index, report.task_seed, report.train_tasks)
            demo = demonstration_of(world, task, _rollout(o).actions)
            yield demo, _outcome_attrs(o)

    root = {
        "kind": KIND,
        "approach": report.approach,
        "label": report.label,
        "task_seed": report.task_seed,
        "train_tasks": int(report.train_tasks),
        "perturbation": report.perturbation.to_json(),
    }
    return write_demonstrations(path, world, items(), root)


def _rollout(o: TaskOutcome) -> Rollout:
    return o.rollout if o.rollout is not None else Rollout(o.actions)


def _outcome_attrs(o: TaskOutcome) -> dict:
    return {
        "task": o.index,
        "solved": int(o.solved),
        "reason": "" if o.solved else str(o.reason),
        "plan": json.dumps([s.to_json() for s in _rollout(o).steps]),
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


@dataclass(frozen=True)
class RolloutsFile:
    """A rollouts file's header and rows (their demonstrations load on demand)."""

    path: str
    approach: str
    label: str
    perturbation: Perturbation
    rows: tuple[RolloutInfo, ...]

    @classmethod
    def read(cls, path: str | os.PathLike) -> RolloutsFile:
        root, demos = read_attributes(path)
        if root.get("kind") != KIND:
            raise DatasetError(f"{path}: not a rollouts file (written by `bpns eval --out`)")
        try:
            perturbation = Perturbation.from_json(str(root.get("perturbation", "{}")))
            rows = tuple(
                RolloutInfo(
                    i,
                    int(d["task"]),
                    bool(d["solved"]),
                    str(d["reason"]),
                    tuple(PlanStep.from_json(s) for s in json.loads(str(d["plan"]))),
                )
                for i, d in enumerate(demos)
            )
        except (KeyError, TypeError, ValueError, PerturbationError) as err:
            raise DatasetError(f"{path}: damaged rollout records: {err}") from None
        return cls(str(path), str(root["approach"]), str(root["label"]), perturbation, rows)

    def row(self, task: int) -> RolloutInfo:
        for r in self.rows:
            if r.task == task:
                return r
        tasks = ", ".join(str(r.task) for r in self.rows)
        raise DatasetError(f"{self.path}: has no rollout of task {task} (tasks: {tasks})")

    def environment(self, env: Environment) -> Environment:
        """``env`` under the physics the rollouts ran under."""
        return perturbed(env, self.perturbation)

    def demonstration(self, env: Environment, row: RolloutInfo) -> Demonstration:
        """Row ``row``'s demonstration, loaded into ``self.environment(env)``."""
        (demo,) = load_demonstrations(self.path, self.environment(env), [row.position])
        return demo


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
    """Re-simulate the first ``limit`` (default: all) rollouts of ``path`` (``env``
    nominal: the file's perturbation is applied)."""
    f = RolloutsFile.read(path)
    world = f.environment(env)
    rows = f.rows[: limit or len(f.rows)]
    demos = load_demonstrations(path, world, [r.position for r in rows])
    checked = tuple((r, replay(world, d, r.position)) for r, d in zip(rows, demos, strict=True))
    return RolloutReplay(f.perturbation.label(), checked)
