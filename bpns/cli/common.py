"""Helpers shared by the ``bpns`` sub-commands: user errors, argument types, progress
bars and loading inputs named on the command line."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import h5py
from tqdm import tqdm

from bpns.approaches import UnknownApproachError, get_approach
from bpns.data.datasets import not_a_demo_file
from bpns.env.environment import eval_set_of, perturbed
from bpns.env.object_counts import PAPER, EvalSet, ObjectCountError, ObjectCounts
from bpns.env.perturbations import PerturbationError
from bpns.env.registry import PluginError, UnknownEnvironmentError, make_environment
from bpns.env.worlds import parse_world
from bpns.errors import BpnsError
from bpns.execution.executor import NotSlowableError, motion_index
from bpns.learning.artifacts.learned import load_learned
from bpns.learning.artifacts.skills_dir import ArtifactError


class UserError(BpnsError):
    """Bad input from the user: reported as one line, no traceback."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a batch scheduler's stop), raised where the command is so that it
    unwinds as Ctrl-C does: temporary files removed, worker processes stopped, every
    finished output kept. Left to its default a SIGTERM killed the process on the spot,
    and worker processes it had started could outlive it. Its message, if any, is a hint
    printed after ``bpns: terminated`` (e.g. that a sweep resumes)."""


def env_by_name(name: str):
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


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def nonnegative_float(text: str) -> float:
    v = _float(text)
    if not (math.isfinite(v) and v >= 0.0):  # nan fails every comparison: refused here
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return v


def positive_float(text: str) -> float:
    v = _float(text)
    if not (math.isfinite(v) and v > 0.0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return v


def fraction(text: str) -> float:
    """A number in (0, 1] (e.g. ``--world-speed``)."""
    v = _float(text)
    if not 0.0 < v <= 1.0:  # nan fails every comparison: refused here
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {text}")
    return v


def checked_worlds(env, worlds: list[str], flag: str):
    """The worlds ``flag`` names, parsed and checked against ``env`` (it can be perturbed
    so), before any work."""
    try:
        parsed = parse_world(worlds)
        perturbed(env, parsed.draw(0))  # an environment without perturbations says so now
    except PerturbationError as err:
        raise UserError(f"{flag}: {err}") from None
    return parsed


def check_correctable(env, worlds: list[str], flag: str, expert: str = "oracle"):
    """The worlds ``flag`` corrects skills in, checked as :func:`checked_worlds` checks
    them and against the expert ``env`` must declare, before any work."""
    parsed = checked_worlds(env, worlds, flag)
    if expert == "oracle" and not env.capabilities.has_oracle_skills:
        raise UserError(
            f"{flag}: environment {env.name!r} declares no oracle skills to label "
            "corrections; label with its demonstrator (`bpns learn --correction-expert "
            "demonstrator`)"
        )
    return parsed


def check_slowable(env, speed: float) -> None:
    """A world speed below 1 needs the environment's ``motion_dims``: said before any work."""
    if speed == 1.0:
        return
    try:
        motion_index(env)
    except NotSlowableError as err:
        raise UserError(f"--world-speed: environment {env.name!r}: {err}") from None


def tolerance_or_off(text: str) -> float | str:
    return text if text == "off" else nonnegative_float(text)


def steps_or_all(text: str) -> int | None:
    """A whole number >= 1, or ``all`` (None: no limit)."""
    return None if text == "all" else positive(text)


def cost_or_off(text: str) -> float | str:
    return text if text == "off" else positive_float(text)


def positive_or_off(text: str) -> int | str:
    return text if text == "off" else positive(text)


def default_workers() -> int:
    return max(1, (os.cpu_count() or 1))


def progress(iterable, total: int, desc: str, unit: str = "task"):
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
    try:
        return get_approach(name)
    except (UnknownApproachError, PluginError) as err:
        raise UserError(str(err)) from None


def file_env(path: Path, name: str | None):
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
    try:
        return load_learned(directory, env_name)
    except (ArtifactError, UnknownEnvironmentError, PluginError) as err:
        raise UserError(str(err)) from None


def print_lines(record) -> None:
    for line in record.lines():
        print(line, flush=True)


def task_progress(outcomes, total: int, label: str):
    """A progress bar over an evaluation's task outcomes (``bpns.workflow.evaluate``)."""
    return progress(outcomes, total, label)


def add_eval_set_arguments(p: argparse.ArgumentParser) -> None:
    """``--eval-set`` and ``--objects``: which eval distribution tasks come from
    (docs/SCALING.md); checked against the environment by :func:`eval_set_from`."""
    p.add_argument(
        "--eval-set",
        default=PAPER,
        metavar="NAME",
        help="the eval distribution: paper (default: the environment's own) or one it "
        "declares, e.g. large (more objects); train tasks are unchanged",
    )
    p.add_argument(
        "--objects",
        nargs="+",
        metavar="KIND=N|KIND=LO:HI",
        default=[],
        help="eval tasks with these object counts (inclusive ranges), over --eval-set's, "
        "e.g. button=6 or cup=4:6",
    )


def eval_set_from(args: argparse.Namespace, env) -> EvalSet:
    """``--eval-set``/``--objects`` checked against ``env`` (a UserError naming the known
    sets, the kinds or the limits) before any work starts."""
    try:
        objects = ObjectCounts.parse(args.objects)
        chosen = eval_set_of(env, args.eval_set, objects)
    except ObjectCountError as err:
        flag = "--objects" if args.objects and args.eval_set in _known_sets(env) else "--eval-set"
        raise UserError(f"{flag}: {err}") from None
    if getattr(args, "train", False) and not chosen.is_paper:
        raise UserError("--eval-set/--objects choose eval tasks: drop them or --train")
    return chosen


def _known_sets(env) -> set[str]:
    return {PAPER, *env.capabilities.eval_sets}
