"""``bpns learn``, ``bpns skills show``, ``bpns eval`` and ``bpns run`` (the whole pipeline)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

from bpns.cli_common import UserError, env_by_name, file_env, positive, progress


def _nonnegative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not v >= 0.0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text}")
    return v


def _positive_float(text: str) -> float:
    v = _nonnegative_float(text)
    if v == 0.0:
        raise argparse.ArgumentTypeError("expected a number > 0, got 0")
    return v


# -- learn ------------------------------------------------------------------------------
def learn_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("demos", type=Path, help="demonstration .h5 file (from `bpns demos`)")
    p.add_argument("--out", required=True, type=Path, help="skills directory to write")
    p.add_argument("--limit", type=positive, help="learn from the first N demos only")
    p.add_argument("--seed", type=int, default=0, help="seed of all network training")
    p.add_argument(
        "--min-segment-fraction",
        type=_nonnegative_float,
        default=0.01,
        help="drop skills with fewer than this fraction of all segments (paper: 0.01)",
    )
    p.add_argument(
        "--no-subgoals",
        action="store_true",
        help="BPNS-NoSubgoal: policies without subgoals, no samplers",
    )
    p.add_argument(
        "--near-goal-scale",
        type=_tolerance_or_off,
        help="policies also see tanh(relative subgoal / this) (feature units), or 'off' as "
        "in the paper (default: the environment's, else off)",
    )
    p.add_argument(
        "--input-margin",
        type=_tolerance_or_off,
        help="networks clip their inputs into the training range widened by this fraction "
        "of it (default 0.1), or 'off' as in the paper",
    )
    p.add_argument(
        "--no-anchor",
        action="store_true",
        help="operator parameters = affected objects only, as in the paper (no anchored "
        "parameters such as the robot holding the pressing stick)",
    )
    p.add_argument(
        "--settle-steps",
        type=positive,
        help="contact changes closer than this are one event "
        "(default: the environment's contact_settle_steps, else 1)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    p.add_argument(
        "--threads",
        type=positive,
        default=1,
        help="torch threads for training (1 is fastest for these small networks)",
    )


def cmd_learn(args: argparse.Namespace) -> int:
    from bpns.datasets import DatasetError, count_demonstrations, iter_demonstrations
    from bpns.learning import learn_skills, save_skills
    from bpns.learning.config import learning_config_for
    from bpns.learning.given import given_skills_of

    if args.out.exists() and not args.overwrite:
        raise UserError(f"{args.out} exists; pass --overwrite to replace it")
    if args.min_segment_fraction > 1.0:
        raise UserError(f"--min-segment-fraction must be <= 1, got {args.min_segment_fraction}")
    if args.near_goal_scale == 0.0:
        raise UserError("--near-goal-scale must be > 0 or 'off', got 0")
    env = file_env(args.demos, None)
    try:
        total = count_demonstrations(args.demos)
        n = min(total, args.limit or total)
        t0 = time.perf_counter()
        demos = list(progress(iter_demonstrations(args.demos, env, range(n)), n, "load", "demo"))
    except DatasetError as err:
        raise UserError(str(err)) from None
    load_seconds = time.perf_counter() - t0
    import torch

    torch.set_num_threads(args.threads)
    config = learning_config_for(
        env,
        seed=args.seed,
        min_segment_fraction=args.min_segment_fraction,
        use_subgoals=False if args.no_subgoals else None,
        anchor_parameters=False if args.no_anchor else None,
        settle_steps=args.settle_steps,
    )
    if args.near_goal_scale is not None:
        near = None if args.near_goal_scale == "off" else args.near_goal_scale
        config = dataclasses.replace(config, near_goal_scale=near)
    if args.input_margin is not None:
        margin = None if args.input_margin == "off" else args.input_margin
        config = dataclasses.replace(
            config,
            **{
                name: dataclasses.replace(getattr(config, name), input_margin=margin)
                for name in ("policy", "generator", "classifier")
            },
        )
    quiet = not sys.stderr.isatty() and os.environ.get("BPNS_PROGRESS") != "1"

    def report(message: str) -> None:
        if not quiet:
            print(f"  {message}", file=sys.stderr, flush=True)

    try:
        learned = learn_skills(
            demos, env.predicates, env.contact_predicates, config, report, given_skills_of(env)
        )
    except ValueError as err:
        raise UserError(f"cannot learn from {args.demos}: {err}") from None
    save_skills(learned, args.out, overwrite=True, env_name=env.name)
    assert learned.stats is not None
    print(
        f"learned {len(learned.skills)} skills from {n} demonstrations of {env.name} in "
        f"{learned.stats.total_seconds:.1f} s (+{load_seconds:.1f} s loading) -> {args.out}"
    )
    print(f"  {learned.stats}")
    return 0


# -- skills show ------------------------------------------------------------------------
def skills_args(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="skills_command", required=True, metavar="ACTION")
    show = sub.add_parser("show", help="print the learned operators, readably")
    show.add_argument("directory", type=Path, help="skills directory (from `bpns learn`)")
    show.add_argument("--env", help="environment (default: the one recorded in the skills)")
    show.add_argument("--pddl", action="store_true", help="print the PDDL domain instead")


def load_learned(directory: Path, env_name: str | None = None):
    """(environment, LearnedSkills) of a skills directory, errors as UserError."""
    from bpns.learning.artifacts import ArtifactError, load_skills, saved_env_name
    from bpns.learning.given import given_skills_of

    try:
        name = env_name or saved_env_name(directory)
        if name is None:
            raise UserError(f"{directory} does not record its environment; pass --env")
        env = env_by_name(name)
        return env, load_skills(directory, env.predicates, env.types, given_skills_of(env))
    except ArtifactError as err:
        raise UserError(str(err)) from None


def cmd_skills(args: argparse.Namespace) -> int:
    from bpns.learning import describe
    from bpns.pddl import domain_pddl

    env, learned = load_learned(args.directory, args.env)
    if args.pddl:
        print(domain_pddl(env.name, learned.types, learned.predicates, learned.operators), end="")
    else:
        print(describe(learned))
    return 0


# -- eval -------------------------------------------------------------------------------
def eval_args(p: argparse.ArgumentParser) -> None:
    from bpns.approaches import APPROACHES

    p.add_argument("--env", help="environment (default: the one recorded in --skills)")
    p.add_argument("--skills", type=Path, help="skills directory (for learned approaches)")
    p.add_argument(
        "--approach",
        nargs="+",
        default=["bpns"],
        choices=list(APPROACHES),
        help="approaches to evaluate, one table row each (default: bpns)",
    )
    p.add_argument("-n", "--tasks", type=positive, default=50, help="number of eval tasks")
    p.add_argument("--seed", type=int, default=0, help="seed of the eval task stream")
    p.add_argument("--planner-seed", type=int, default=0, help="seed of subgoal sampling")
    p.add_argument("--train", action="store_true", help="evaluate on train tasks instead")
    p.add_argument(
        "--timeout",
        type=_positive_float,
        default=300.0,
        help="seconds per task (default: the paper's 300)",
    )
    p.add_argument(
        "--n-abstract", type=positive, help="abstract plans to try (default: the env's or 8)"
    )
    p.add_argument(
        "--n-samples", type=positive, help="samples per plan step (default: the env's or 10)"
    )
    p.add_argument(
        "--nogood-atol",
        type=_tolerance_or_off,
        help="tolerance (feature units) of refuted-state matching in refinement, or 'off' "
        "for the paper's plain backtracking (default: the env's or 0.005)",
    )
    p.add_argument("--out", type=Path, help="output directory (results.json, results.md)")
    p.add_argument("--workers", type=positive, default=max(1, (os.cpu_count() or 1)))
    p.add_argument(
        "--video",
        type=Path,
        help="render a solved task to this .mp4: the one with the longest plan, which shows "
        "the most skills",
    )
    p.add_argument("--no-validate", action="store_true", help="skip re-simulating plans")


def _tolerance_or_off(text: str) -> float | str:
    return text if text == "off" else _nonnegative_float(text)


def cmd_eval(args: argparse.Namespace) -> int:
    from bpns.approaches import APPROACHES, SkillSource
    from bpns.evaluation import EvalSpec, NoOracleSkillsError, evaluate, markdown_table
    from bpns.planning.config import planning_config_for

    approaches = [APPROACHES[a] for a in dict.fromkeys(args.approach)]
    learned_needed = any(a.skills is SkillSource.LEARNED for a in approaches)
    num_demos = learning_seconds = None
    if learned_needed:
        if args.skills is None:
            raise UserError("learned approaches need --skills DIR (from `bpns learn`)")
        env, learned = load_learned(args.skills, args.env)
        if learned.stats is not None:
            num_demos, learning_seconds = learned.stats.num_demos, learned.stats.total_seconds
    elif args.env is None:
        raise UserError("pass --env (or --skills) to say which environment to evaluate on")
    else:
        env = env_by_name(args.env)
    if any(a.skills is SkillSource.ORACLE for a in approaches) and not hasattr(
        env, "oracle_skills"
    ):
        raise UserError(f"environment {env.name!r} declares no oracle skills")
    try:
        base = planning_config_for(
            env,
            timeout=args.timeout,
            n_abstract=args.n_abstract,
            n_samples=args.n_samples,
            nogood_atol=None if args.nogood_atol == "off" else args.nogood_atol,
        )
        if args.nogood_atol == "off":
            base = dataclasses.replace(base, nogood_atol=None)
    except (TypeError, ValueError) as err:
        raise UserError(f"bad planning settings: {err}") from None
    reports = []
    for approach in approaches:
        learned_approach = approach.skills is SkillSource.LEARNED
        spec = EvalSpec(
            env_name=env.name,
            approach=approach.name,
            planning=approach.planning_config(base),
            skills_dir=str(args.skills) if learned_approach else None,
            task_seed=args.seed,
            planner_seed=args.planner_seed,
            train_tasks=args.train,
            validate=not args.no_validate,
        )
        try:
            report = evaluate(
                spec,
                args.tasks,
                args.workers,
                num_demos=num_demos if learned_approach else None,
                learning_seconds=learning_seconds if learned_approach else None,
                progress=lambda it, n, label=approach.label: progress(it, n, f"eval {label}"),
            )
        except NoOracleSkillsError as err:
            raise UserError(str(err)) from None
        reports.append(report)
        print(
            f"{approach.label}: solved {report.num_solved}/{report.num_tasks} "
            f"{env.name} eval tasks"
            + (f" (failures: {report.failures})" if report.failures else ""),
            flush=True,
        )
    table = markdown_table(reports)
    print(table, end="")
    if args.out is not None:
        write_results(args.out, reports, table)
        print(f"wrote {args.out / 'results.json'} and {args.out / 'results.md'}")
    if args.video is not None:
        # the first approach named that solved anything (e.g. the oracle, when skills
        # learned from a handful of demos solve nothing)
        solving = next((r for r in reports if r.num_solved), reports[0])
        render_longest_solved(env, solving, args.video, args.seed, args.train)
    return 0 if all(r.num_solved for r in reports) else 1


def write_results(out: Path, reports, table: str) -> None:
    from bpns.atomic import atomic_path
    from bpns.evaluation import save_plans

    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "results.json") as tmp:
        tmp.write_text(json.dumps([r.to_json() for r in reports], indent=2) + "\n")
    with atomic_path(out / "results.md") as tmp:
        tmp.write_text(table)
    for r in reports:
        save_plans(out / f"plans_{r.approach}.npz", r)


def render_longest_solved(env, report, video: Path, seed: int, train: bool) -> None:
    """Re-simulate the solved task with the longest abstract plan (the first of those) and
    render it with a PNG of its end: the longest plan shows the most skills at work."""
    from bpns.commands import render_video

    solved = [o for o in report.outcomes if o.solved]
    if not solved:
        print(f"no {report.label} task was solved: no video", file=sys.stderr)
        return
    outcome = max(solved, key=lambda o: len(o.skeleton))  # max keeps the first of ties
    task = env.task(outcome.index, seed, train)
    states = [task.init]
    for action in outcome.actions:
        states.append(env.simulate(states[-1], action))
    png = video.with_suffix(".png")
    n = render_video(env, states, video, "overview", 640, 480, png)
    print(
        f"wrote {video} ({n} frames: {report.label} solving eval task {outcome.index} in "
        f"{len(outcome.actions)} steps) and {png}\n  plan: " + ", ".join(outcome.skeleton)
    )


# -- run --------------------------------------------------------------------------------
def run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", required=True, help="environment name (e.g. cover)")
    p.add_argument("--demos", type=positive, default=50, help="number of demonstrations")
    p.add_argument("--tasks", type=positive, default=10, help="number of eval tasks")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--timeout", type=_positive_float, default=60.0, help="seconds per task")
    p.add_argument("--out", type=Path, help="output directory (default: outputs/<env>)")
    p.add_argument("--workers", type=positive, default=max(1, (os.cpu_count() or 1)))
    p.add_argument(
        "--approach",
        nargs="+",
        default=["bpns", "oracle"],
        help="approaches to evaluate (default: bpns oracle)",
    )


def cmd_run(args: argparse.Namespace) -> int:
    """demos -> replay check -> learn -> eval -> table -> video of a solved eval task."""
    from bpns.cli import main as cli_main

    env = env_by_name(args.env)
    out: Path = args.out or Path("outputs") / env.name
    out.mkdir(parents=True, exist_ok=True)
    demos_path, skills_dir = out / "demos.h5", out / "skills"
    approaches = list(args.approach)
    if not hasattr(env, "oracle_skills") and "oracle" in approaches:
        approaches.remove("oracle")
    seed = str(args.seed)
    common = ["--seed", seed, "--workers", str(args.workers)]
    steps = [
        ["demos", "--env", env.name, "-n", str(args.demos), "--out", str(demos_path), *common],
        ["replay", str(demos_path), "--limit", "5"],
        ["learn", str(demos_path), "--out", str(skills_dir), "--overwrite", "--seed", seed],
        ["skills", "show", str(skills_dir)],
        [
            "eval",
            "--skills",
            str(skills_dir),
            "--approach",
            *approaches,
            "-n",
            str(args.tasks),
            "--timeout",
            str(args.timeout),
            "--out",
            str(out / "eval"),
            "--video",
            str(out / "eval_solved.mp4"),
            *common,
        ],
    ]
    t0 = time.perf_counter()
    for argv in steps:
        print(f"$ bpns {' '.join(argv)}", flush=True)
        code = cli_main(argv)
        if code != 0:
            return code
    print(f"done in {time.perf_counter() - t0:.0f} s; everything is in {out}/")
    return 0
