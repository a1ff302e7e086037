"""``bpns run``: the whole pipeline, demos -> replay check -> learn -> eval -> table ->
video, by calling the library functions each step's command calls."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bpns.cli.common import (
    UserError,
    approach_by_name,
    default_workers,
    env_by_name,
    evaluate_approaches,
    learned_in,
    nonnegative,
    path_arg,
    positive,
    positive_float,
    print_lines,
    progress,
    report_evaluation,
    stage_reporter,
)
from bpns.cli.paths import (
    capped_to_cores,
    check_demos_fit,
    check_eval_outputs,
    check_output_dir,
    check_output_file,
    check_skills_dir,
    writing,
)

HELP = "the whole pipeline: demos -> learn -> eval -> table -> video"
REPLAY_CHECKED = 5  # demonstrations re-simulated to check the simulator is exact


def configure(p: argparse.ArgumentParser) -> None:
    from bpns.approaches import approach_names

    p.add_argument("--env", required=True, help="environment name (e.g. cover)")
    p.add_argument("--demos", type=positive, default=50, help="number of demonstrations")
    p.add_argument("--tasks", type=positive, default=10, help="number of eval tasks")
    p.add_argument("--seed", type=nonnegative, default=0)
    p.add_argument("--timeout", type=positive_float, default=60.0, help="seconds per task")
    p.add_argument("--out", type=path_arg, help="output directory (default: outputs/<env>)")
    p.add_argument("--workers", type=positive, default=default_workers())
    p.add_argument(
        "--approach",
        nargs="+",
        choices=approach_names(),
        help="approaches to evaluate (default: bpns, and oracle where the environment has "
        "hand-written skills); the baselines they need are learned beside the skills",
    )
    p.add_argument(
        "--baseline-steps",
        type=positive,
        help="at most this many gradient steps per GNN baseline learned (default 20000)",
    )
    p.add_argument(
        "--overwrite", action="store_true", help="replace the outputs of an earlier run in --out"
    )


def _step(title: str) -> None:
    print(f"== {title}", flush=True)


def approaches_to_run(env, asked: list[str] | None) -> list:
    """The registry entries of the approaches ``asked`` (default: bpns, and oracle where
    ``env`` has hand-written skills), each checked to be able to run on ``env``: an
    impossible combination is refused before any work."""
    from bpns.approaches import SkillSource

    if asked is None:
        asked = ["bpns", "oracle"] if env.capabilities.has_oracle_skills else ["bpns"]
    entries = []
    for name in dict.fromkeys(asked):
        entry = approach_by_name(name)
        if entry.skills is SkillSource.ORACLE and not env.capabilities.has_oracle_skills:
            raise UserError(
                f"--approach {name}: plans with hand-written skills, and environment "
                f"{env.name!r} declares none"
            )
        entries.append(entry)
    return entries


def _baselines_config(stages: tuple[str, ...], steps: int | None):
    from bpns.learning.baselines import BaselinesConfig

    base = BaselinesConfig() if steps is None else BaselinesConfig.with_max_steps(steps)
    return base.only(stages)


def run(args: argparse.Namespace) -> int:
    from bpns.workflow import baselines_needed

    env = env_by_name(args.env)
    out: Path = args.out or Path("outputs") / env.name
    demos_path, skills_dir = out / "demos.h5", out / "skills"
    video = out / "eval_solved.mp4"
    entries = approaches_to_run(env, args.approach)
    names = [e.name for e in entries]
    stages = baselines_needed(entries)
    if args.baseline_steps is not None and not stages:
        raise UserError(
            f"--baseline-steps applies to the baselines, and none of {', '.join(names)} uses one"
        )
    check_output_dir(out, "--out")
    check_output_file(demos_path, "--out", args.overwrite)
    check_skills_dir(skills_dir, "--out", args.overwrite)
    check_eval_outputs(out / "eval", video, names, args.overwrite)
    check_demos_fit(env, args.demos, args.seed, demos_path, "--out")
    workers = capped_to_cores(args.workers, "--workers")
    with writing(out):
        out.mkdir(parents=True, exist_ok=True)
        return _pipeline(args, env, entries, stages, out, workers)


def _pipeline(args, env, entries, stages: tuple[str, ...], out: Path, workers: int) -> int:
    from bpns.learning import describe
    from bpns.learning.config import learning_config_for
    from bpns.planning.config import planning_config_for
    from bpns.workflow import check_replay, collect_demos, learn_to_directory

    names = [e.name for e in entries]
    demos_path, skills_dir = out / "demos.h5", out / "skills"
    video = out / "eval_solved.mp4"
    t0 = time.perf_counter()

    _step(f"demos: {args.demos} demonstrations of {env.name}")
    written = collect_demos(
        env, args.demos, args.seed, demos_path, workers=workers, progress=progress
    )
    print_lines(written)
    if not written.num_written:
        return 1

    _step(f"replay: the first {REPLAY_CHECKED} demonstrations")
    checked = check_replay(env, demos_path, REPLAY_CHECKED, progress)
    print_lines(checked)
    if not checked.ok:
        return 1

    _step("learn" + (f" (and the baselines {', '.join(stages)})" if stages else ""))
    config = learning_config_for(env, seed=args.seed)
    learned_run = learn_to_directory(
        env,
        demos_path,
        skills_dir,
        config,
        progress=progress,
        report=stage_reporter(),
        baselines=_baselines_config(stages, args.baseline_steps) if stages else None,
    )
    print_lines(learned_run)
    _, learned = learned_in(skills_dir)
    print(describe(learned))

    _step(f"eval: {', '.join(names)} on {args.tasks} tasks")
    base = planning_config_for(env, timeout=args.timeout)
    reports = evaluate_approaches(
        env,
        names,
        skills_dir=skills_dir,
        learned=learned,
        base_planning=base,
        num_tasks=args.tasks,
        task_seed=args.seed,
        planner_seed=0,
        train=False,
        validate=True,
        workers=workers,
    )
    report_evaluation(env, reports, out / "eval", video, args.seed, train=False)
    if not all(r.num_solved for r in reports):
        return 1
    print(f"done in {time.perf_counter() - t0:.0f} s; everything is in {out}/")
    return 0
