"""One episode to inspect: a demonstration or an eval rollout, with what it was for.

An :class:`Episode` holds the states (re-loaded exactly from the file, or re-simulated
from an evaluation's report), the skills executed (:class:`PlanStep`), the outcome, the
execution monitor's events (a rollouts row's optional ``events`` attribute: JSON list of
``{"at": action index, "kind": ..., "text": ...}``) and, for a failed task, the
planner's explanation (the row's optional ``explanation`` attribute, else the
``results.json`` beside the file). Its symbolic timelines are computed here.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpns.data.datasets import DatasetError, load_demonstrations, read_attributes
from bpns.env.abstraction import ground_atoms
from bpns.env.environment import Environment, perturbed
from bpns.evaluation.evaluate import EvalReport, TaskOutcome
from bpns.evaluation.rollout_files import RolloutsFile, demonstration_of, is_rollouts_file
from bpns.execution.rollouts import Event, PlanStep, Rollout
from bpns.structs import Demonstration, GroundAtom


@dataclass(frozen=True, eq=False)
class Episode:
    """A demonstration (``solved`` None) or an eval task's rollout, ready to inspect."""

    env: Environment  # the environment it ran in (its physics applied)
    demo: Demonstration
    title: str
    index: int  # the demo's index, or the eval task's
    steps: tuple[PlanStep, ...] = ()
    solved: bool | None = None
    reason: str = ""
    events: tuple[Event, ...] = ()
    explanation: Mapping | None = None
    approach: str = ""

    @property
    def is_rollout(self) -> bool:
        return self.solved is not None

    @property
    def outcome(self) -> str:
        if self.solved is None:
            return "demonstration"
        return "solved" if self.solved else f"failed: {self.reason}"


def read_episode(
    path: str | os.PathLike, env: Environment, task: int | None = None, demo: int | None = None
) -> Episode:
    """Task ``task`` of a rollouts file, or demonstration ``demo`` (default 0) of a
    demonstration file; :class:`DatasetError` for a file of neither kind, an index it
    does not hold, or a ``task`` asked of demonstrations."""
    if not is_rollouts_file(path):
        if task is not None:
            raise DatasetError(f"{path}: --task needs a rollouts file (`bpns eval --out`)")
        i = 0 if demo is None else demo
        (d,) = load_demonstrations(path, env, [i])
        return Episode(env, d, f"{env.name} demonstration {i}", i)
    if demo is not None:
        raise DatasetError(f"{path}: a rollouts file: say which task with --task, not --demo")
    rollouts = RolloutsFile.read(path)
    if task is None:
        raise DatasetError(f"{path}: a rollouts file: say which task with --task I")
    row = rollouts.row(task)
    d = rollouts.demonstration(env, row)  # in the task's own world
    _, rows = read_attributes(path)
    try:
        explanation = json.loads(str(rows[row.position].get("explanation", "null")))
    except ValueError as err:
        raise DatasetError(f"{path}: task {task}: damaged explanation: {err}") from None
    if explanation is None and not row.solved:
        explanation = _explanation_beside(Path(path), rollouts.approach, task)
    return Episode(
        rollouts.environment(env, row),
        d,
        f"{env.name} {rollouts.label} task {task}",
        task,
        row.steps,
        row.solved,
        row.reason,
        row.events,
        explanation,
        rollouts.approach,
    )


def _explanation_beside(path: Path, approach: str, task: int) -> Mapping | None:
    """The explanation ``results.json`` next to a rollouts file keeps for ``task``."""
    results = path.parent / "results.json"
    try:
        reports = json.loads(results.read_text())
        report = next(r for r in reports if r.get("approach") == approach)
        return next(t for t in report["tasks"] if t.get("index") == task).get("explanation")
    except (OSError, ValueError, TypeError, KeyError, StopIteration, AttributeError):
        return None  # no results beside it, or not this evaluation's: nothing to add


def episode_of_outcome(env: Environment, report: EvalReport, outcome: TaskOutcome) -> Episode:
    """``outcome``'s rollout re-simulated (exactly) from its task in the world it ran
    in: what its rollouts file row holds, without reading it back."""
    world = perturbed(report.task_environment(env), outcome.world)
    task = world.task(outcome.index, report.task_seed, report.train_tasks)
    rollout = outcome.rollout if outcome.rollout is not None else Rollout(outcome.actions)
    return Episode(
        world,
        demonstration_of(world, task, rollout.actions),
        f"{env.name} {report.label} task {outcome.index}",
        outcome.index,
        rollout.steps,
        outcome.solved,
        "" if outcome.solved else str(outcome.reason),
        rollout.events,
        outcome.explanation,
        report.approach,
    )


def atom_timeline(episode: Episode) -> tuple[tuple[GroundAtom, ...], np.ndarray]:
    """Every ground atom over the episode's objects and its truth per state: (atoms,
    bool array (states, atoms))."""
    states = episode.demo.states
    atoms = ground_atoms(states[0].objects, episode.env.predicates)
    truth = np.array(
        [[a.predicate.classifier(s, a.objects) for a in atoms] for s in states], dtype=bool
    ).reshape(len(states), len(atoms))
    return atoms, truth


def skill_per_state(steps: Sequence[PlanStep], num_states: int) -> np.ndarray:
    """Per state, the index of the skill being executed (-1: none). State ``i`` follows
    action ``i - 1``; the initial state shows the first skill."""
    out = np.full(num_states, -1, dtype=np.int64)
    if not steps:
        return out
    starts = np.array([s.start for s in steps])
    actions = np.maximum(0, np.arange(num_states) - 1)
    return np.searchsorted(starts, actions, side="right").clip(1) - 1


def atom_label(atom: GroundAtom) -> str:
    return f"{atom.predicate.name}({', '.join(o.name for o in atom.objects)})"
