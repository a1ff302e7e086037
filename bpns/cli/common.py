"""Helpers shared by the ``bpns`` sub-commands: user errors, argument types, progress,
loading inputs as user errors, and the output of an evaluation (``eval`` and ``run``)."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path


class UserError(Exception):
    """Bad input from the user: reported as one line, no traceback."""


def env_by_name(name: str):
    from bpns.env.registry import PluginError, UnknownEnvironmentError, make_environment

    try:
        return make_environment(name)
    except (UnknownEnvironmentError, PluginError) as err:
        raise UserError(str(err)) from None


def path_arg(text: str) -> Path:
    """A path given on the command line; an empty one (``--out ''``) is refused instead
    of becoming ``.``, the current directory."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a path, got {text!r}")
    return Path(text)


def whole_at_least(text: str, least: int, what: str = "a whole number") -> int:
    """``text`` as an int >= ``least``, else an argparse error naming the bound."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < least:
        raise argparse.ArgumentTypeError(f"expected {what} >= {least}, got {v}")
    return v


def positive(text: str) -> int:
    return whole_at_least(text, 1, "a number")


def nonnegative(text: str) -> int:
    return whole_at_least(text, 0)


def nonnegative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not v >= 0.0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text}")
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text}")
    return v


def positive_float(text: str) -> float:
    v = nonnegative_float(text)
    if v == 0.0:
        raise argparse.ArgumentTypeError("expected a number > 0, got 0")
    return v


def tolerance_or_off(text: str) -> float | str:
    return text if text == "off" else nonnegative_float(text)


def positive_or_off(text: str) -> int | str:
    return text if text == "off" else positive(text)


def default_workers() -> int:
    return max(1, (os.cpu_count() or 1))


def progress(iterable, total: int, desc: str, unit: str = "task"):
    from tqdm import tqdm

    return tqdm(
        iterable,
        total=total,
        desc=desc,
        unit=unit,
        disable=not sys.stderr.isatty() and os.environ.get("BPNS_PROGRESS") != "1",
        leave=False,
    )


def approach_by_name(name: str):
    """The registry entry of approach ``name``; a plugin that fails to load, or an
    unknown name, is a UserError naming it."""
    from bpns.approaches import UnknownApproachError, get_approach
    from bpns.env.registry import PluginError

    try:
        return get_approach(name)
    except (UnknownApproachError, PluginError) as err:
        raise UserError(str(err)) from None


def file_env(path: Path, name: str | None):
    import h5py

    from bpns.data.datasets import not_a_demo_file

    if name is None:
        problem = not_a_demo_file(path)
        if problem is not None:
            raise UserError(problem)
        try:
            with h5py.File(path, "r") as f:
                name = str(f.attrs.get("env", ""))
        except OSError as err:
            raise UserError(
                f"{path}: not a readable HDF5 file (corrupt or truncated?): {err}"
            ) from None
        if not name:
            raise UserError(f"{path}: not a bpns demonstration file (no env attribute)")
    return env_by_name(name)


def stage_reporter():
    """A callback printing learning's stage messages to stderr, unless output is quiet
    (not a terminal and BPNS_PROGRESS is not 1)."""
    quiet = not sys.stderr.isatty() and os.environ.get("BPNS_PROGRESS") != "1"

    def report(message: str) -> None:
        if not quiet:
            print(f"  {message}", file=sys.stderr, flush=True)

    return report


def learned_in(directory: Path, env_name: str | None = None):
    """(environment, LearnedSkills) of a skills directory, errors as UserError."""
    from bpns.env.registry import PluginError, UnknownEnvironmentError
    from bpns.learning.artifacts import ArtifactError
    from bpns.learning.learned import load_learned

    try:
        return load_learned(directory, env_name)
    except (ArtifactError, UnknownEnvironmentError, PluginError) as err:
        raise UserError(str(err)) from None


def print_lines(record) -> None:
    for line in record.lines():
        print(line, flush=True)


def report_evaluation(
    env,
    reports,
    out: Path | None,
    video: Path | None,
    seed: int,
    train: bool,
    task: int | None = None,
    camera: str | None = None,
):
    """Print the table, write the results files to ``out`` and render a solved task to
    ``video`` (each when given): the end of ``bpns eval`` and of ``bpns run``."""
    from bpns.evaluation.evaluate import markdown_table
    from bpns.evaluation.reporting import render_longest_solved, write_results
    from bpns.execution.video import VideoError

    table = markdown_table(reports)
    print(table, end="")
    if out is not None:
        write_results(out, reports, table, env)
        print(f"wrote {out / 'results.json'}, {out / 'results.md'} and rollouts_<approach>.h5")
    if video is not None:
        # the first approach named that solved anything (e.g. the oracle, when skills
        # learned from a handful of demos solve nothing)
        solving = next((r for r in reports if r.num_solved), reports[0])
        if task is not None:  # the named task, solved or not, of the first approach
            solving = reports[0]
        try:
            rendered = render_longest_solved(env, solving, video, seed, train, task, camera)
        except (VideoError, ValueError) as err:
            raise UserError(str(err)) from None
        if rendered is None:
            print(f"no {solving.label} task was solved: no video", file=sys.stderr)
        else:
            print_lines(rendered)


def evaluate_approaches(
    env,
    names,
    *,
    skills_dir: Path | None,
    learned,
    base_planning,
    num_tasks: int,
    task_seed: int,
    planner_seed: int,
    train: bool,
    validate: bool,
    workers: int,
    perturbation=None,
):
    """Evaluate each named approach in turn, printing its summary line as it finishes;
    the reports in the order named (the middle of ``bpns eval`` and of ``bpns run``)."""
    from bpns.approaches import NoOracleSkillsError, SkillSource, get_approach
    from bpns.env.perturbations import NOMINAL
    from bpns.evaluation.evaluate import EvalSpec, evaluate
    from bpns.evaluation.reporting import solved_line
    from bpns.learning.artifacts import ArtifactError
    from bpns.learning.baselines import saved_baseline_seconds

    stats = learned.stats if learned is not None else None
    for name in names:  # every approach can be built (its files load) before any work
        entry = get_approach(name)
        try:
            entry.make(
                env,
                entry.planning_config(base_planning),
                skills_dir if entry.skills is SkillSource.LEARNED else None,
            )
        except (NoOracleSkillsError, ArtifactError, ValueError) as err:
            raise UserError(f"approach {name}: {err}") from None
    reports = []
    for name in names:
        approach = get_approach(name)
        learned_approach = approach.skills is SkillSource.LEARNED
        spec = EvalSpec(
            env_name=env.name,
            approach=approach.name,
            planning=approach.planning_config(base_planning),
            skills_dir=str(skills_dir) if learned_approach else None,
            task_seed=task_seed,
            planner_seed=planner_seed,
            train_tasks=train,
            validate=validate,
            perturbation=perturbation or NOMINAL,
        )
        learning_seconds = None
        if learned_approach and stats is not None and skills_dir is not None:
            learning_seconds = approach.learning_seconds(
                dict(stats.stage_seconds), saved_baseline_seconds(skills_dir)
            )
        try:
            report = evaluate(
                spec,
                num_tasks,
                workers,
                num_demos=stats.num_demos if learned_approach and stats else None,
                learning_seconds=learning_seconds,
                progress=lambda it, n, label=approach.label: progress(it, n, f"eval {label}"),
            )
        except NoOracleSkillsError as err:
            raise UserError(str(err)) from None
        reports.append(report)
        print(solved_line(report), flush=True)
    return reports
