"""``bpns run``: the whole pipeline, demos -> replay check -> learn -> eval -> table ->
video, by calling the library functions each step's command calls."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bpns.cli.common import (
    default_workers,
    env_by_name,
    evaluate_approaches,
    learned_in,
    nonnegative,
    positive,
    positive_float,
    print_lines,
    progress,
    report_evaluation,
    stage_reporter,
)
from bpns.cli.paths import (
    capped_to_cores,
    check_eval_outputs,
    check_output_dir,
    check_output_file,
    check_skills_dir,
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
    p.add_argument("--out", type=Path, help="output directory (default: outputs/<env>)")
    p.add_argument("--workers", type=positive, default=default_workers())
    p.add_argument(
        "--approach",
        nargs="+",
        default=["bpns", "oracle"],
        choices=approach_names(),
        help="approaches to evaluate (default: bpns oracle)",
    )
    p.add_argument(
        "--overwrite", action="store_true", help="replace the outputs of an earlier run in --out"
    )


def _step(title: str) -> None:
    print(f"== {title}", flush=True)


def run(args: argparse.Namespace) -> int:
    from bpns.learning import describe
    from bpns.learning.config import learning_config_for
    from bpns.planning.config import planning_config_for
    from bpns.workflow import check_replay, collect_demos, learn_to_directory

    env = env_by_name(args.env)
    out: Path = args.out or Path("outputs") / env.name
    demos_path, skills_dir = out / "demos.h5", out / "skills"
    video = out / "eval_solved.mp4"
    names = list(dict.fromkeys(args.approach))
    if not env.capabilities.has_oracle_skills and "oracle" in names:
        names.remove("oracle")
    check_output_dir(out, "--out")
    check_output_file(demos_path, "--out", args.overwrite)
    check_skills_dir(skills_dir, "--out", args.overwrite)
    check_eval_outputs(out / "eval", video, names, args.overwrite)
    workers = capped_to_cores(args.workers, "--workers")
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()

    _step(f"demos: {args.demos} demonstrations of {env.name}")
    written = collect_demos(env, args.demos, args.seed, demos_path, workers, progress)
    print_lines(written)
    if not written.num_written:
        return 1

    _step(f"replay: the first {REPLAY_CHECKED} demonstrations")
    checked = check_replay(env, demos_path, REPLAY_CHECKED, progress)
    print_lines(checked)
    if not checked.ok:
        return 1

    _step("learn")
    config = learning_config_for(env, seed=args.seed)
    print_lines(
        learn_to_directory(env, demos_path, skills_dir, config, None, 1, progress, stage_reporter())
    )
    _, learned = learned_in(skills_dir)
    print(describe(learned))

    _step(f"eval: {', '.join(names)} on {args.tasks} tasks")
    base = planning_config_for(env, timeout=args.timeout)
    reports = evaluate_approaches(
        env, names, skills_dir, learned, base, args.tasks, args.seed, 0, False, True, workers
    )
    report_evaluation(env, reports, out / "eval", video, args.seed, False)
    if not all(r.num_solved for r in reports):
        return 1
    print(f"done in {time.perf_counter() - t0:.0f} s; everything is in {out}/")
    return 0
