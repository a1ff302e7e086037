"""``bpns eval``: solve held-out tasks with one or more approaches; results JSON + table."""

from __future__ import annotations

import argparse
import dataclasses
import sys

from bpns.cli.common import (
    UserError,
    approach_by_name,
    default_workers,
    env_by_name,
    learned_in,
    nonnegative,
    path_arg,
    positive,
    positive_float,
    positive_or_off,
    print_lines,
    task_progress,
    tolerance_or_off,
)
from bpns.cli.paths import (
    capped_to_cores,
    check_eval_outputs,
    check_not_inside,
    check_output_dir,
    check_output_file,
    writing,
)
from bpns.env.perturbations import PerturbationError, parse_perturbation
from bpns.evaluation.reporting import solved_line
from bpns.inspect.extras import require
from bpns.inspect.html_report import PAGE
from bpns.workflow.evaluate import EvalRequest, evaluate_approaches
from bpns.workflow.inspect import RERUN_TASKS, record_evaluation, recording_name
from bpns.workflow.report import report_evaluation
from bpns.workflow.report_page import REPORT_VIDEOS, PageRequest

HELP = "solve held-out tasks by bilevel planning; results JSON + markdown table"


def configure(p: argparse.ArgumentParser) -> None:
    from bpns.approaches import approach_names

    p.add_argument("--env", help="environment (default: the one recorded in --skills)")
    p.add_argument("--skills", type=path_arg, help="skills directory (for learned approaches)")
    p.add_argument(
        "--approach",
        nargs="+",
        default=["bpns"],
        choices=approach_names(),
        help="approaches to evaluate, one table row each (default: bpns)",
    )
    p.add_argument("-n", "--tasks", type=positive, default=50, help="number of eval tasks")
    p.add_argument("--seed", type=nonnegative, default=0, help="seed of the eval task stream")
    p.add_argument("--planner-seed", type=nonnegative, default=0, help="seed of subgoal sampling")
    p.add_argument("--train", action="store_true", help="evaluate on train tasks instead")
    p.add_argument(
        "--timeout",
        type=positive_float,
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
        type=tolerance_or_off,
        help="tolerance (feature units) of refuted-state matching in refinement, or 'off' "
        "for the paper's plain backtracking (default: the env's or 0.005)",
    )
    p.add_argument(
        "--set-aside-after",
        type=positive_or_off,
        help="set an abstract plan aside (refined again after the others) once one step "
        "failed every sample from this many arrivals, or 'off' for the paper's "
        "backtracking (default: the env's or 3)",
    )
    p.add_argument(
        "--run-past-dead-ends",
        action="store_true",
        help="simulate a rollout on in a state the environment declares a dead end (e.g. "
        "Coffee's spilled coffee) until its horizon, as the paper's planner does "
        "(default: it fails there at once)",
    )
    p.add_argument("--out", type=path_arg, help="output directory (results.json, results.md)")
    p.add_argument("--workers", type=positive, default=default_workers())
    p.add_argument(
        "--video",
        type=path_arg,
        help="render a task to this .mp4 with captions (skill and objects; the outcome at "
        "the end): --task, or the solved task with the longest plan, which shows the most "
        "skills",
    )
    p.add_argument(
        "--task",
        type=nonnegative,
        help="with --video: render this eval task of the first approach, solved or failed",
    )
    p.add_argument(
        "--camera",
        help="with --video: a camera of the scene, or 'all' (every camera tiled); "
        "default: the environment's (Doors: follow)",
    )
    p.add_argument(
        "--perturb",
        nargs="+",
        metavar="NAME=VALUE",
        default=[],
        help="evaluate under perturbed physics: mass_scale, friction_scale, gain_scale (arm "
        "kp), action_noise (std, fraction of the action range), obs_noise (std on the "
        "policies' features), latency (control steps), seed (of the noises); see README",
    )
    p.add_argument("--no-validate", action="store_true", help="skip re-simulating plans")
    p.add_argument(
        "--explain",
        action="store_true",
        help="print why each failed task failed: the abstract plans tried and, per step, the "
        "samples that failed and why (also in results.json, `explanation`)",
    )
    p.add_argument(
        "--report-videos",
        choices=REPORT_VIDEOS,
        default="failed",
        help="with --out: the tasks whose videos report.html shows (failed: every failed task "
        "and the solved one with the longest plan; default: %(default)s)",
    )
    p.add_argument(
        "--report-video-budget",
        type=positive_float,
        default=60.0,
        metavar="SECONDS",
        help="with --out: seconds of rendering report.html's videos, at most (default: "
        "%(default)s)",
    )
    p.add_argument(
        "--rerun",
        type=path_arg,
        metavar="DIR",
        help="write Rerun recordings (<approach>_task<i>.rrd) of the tasks --rerun-tasks "
        "names into DIR (pip install 'bpns[viz]')",
    )
    p.add_argument(
        "--rerun-tasks",
        choices=RERUN_TASKS,
        default="failed",
        help="with --rerun: every task, or the failed ones and the solved one with the "
        "longest plan (default: %(default)s)",
    )
    p.add_argument(
        "--overwrite", action="store_true", help="replace existing results and video files"
    )


def check_inspect_outputs(args: argparse.Namespace, names: list[str]) -> None:
    """report.html in --out and the recordings --rerun may write, checked up front (and
    that the viz extra is there, before any task runs)."""
    if args.out is not None:
        check_output_file(args.out / PAGE, "--out", args.overwrite)
    if args.rerun is None:
        return
    require("rerun", "--rerun")
    check_not_inside(args.rerun, "--rerun", args.skills, "the skills directory")
    check_output_dir(args.rerun, "--rerun")
    for name in names:
        for task in range(args.tasks):
            check_output_file(args.rerun / recording_name(name, task), "--rerun", args.overwrite)


def run(args: argparse.Namespace) -> int:
    from bpns.approaches import SkillSource
    from bpns.env.environment import perturbed
    from bpns.planning.config import planning_config_for

    try:
        perturbation = parse_perturbation(args.perturb)
    except PerturbationError as err:
        raise UserError(f"--perturb: {err}") from None
    if args.video is None and (args.task is not None or args.camera is not None):
        raise UserError("--task and --camera choose what --video renders: pass --video too")
    if args.task is not None and args.task >= args.tasks:
        raise UserError(f"--task {args.task}: only tasks 0..{args.tasks - 1} are evaluated")
    names = list(dict.fromkeys(args.approach))
    approaches = [approach_by_name(a) for a in names]
    check_eval_outputs(args.out, args.video, names, args.overwrite, args.skills)
    check_inspect_outputs(args, names)
    workers = capped_to_cores(args.workers, "--workers")
    learned = None
    if any(a.skills is SkillSource.LEARNED for a in approaches):
        if args.skills is None:
            raise UserError("learned approaches need --skills DIR (from `bpns learn`)")
        env, learned = learned_in(args.skills, args.env)
    elif args.env is None and args.skills is None:
        raise UserError("pass --env (or --skills) to say which environment to evaluate on")
    elif args.env is None:
        env, _ = learned_in(args.skills)  # the environment the skills record
    else:
        env = env_by_name(args.env)
    try:
        perturbed(env, perturbation)  # an environment without perturbations says so now
    except PerturbationError as err:
        raise UserError(f"--perturb: {err}") from None
    if (
        any(a.skills is SkillSource.ORACLE for a in approaches)
        and not env.capabilities.has_oracle_skills
    ):
        raise UserError(f"environment {env.name!r} declares no oracle skills")
    try:
        base = planning_config_for(
            env,
            timeout=args.timeout,
            n_abstract=args.n_abstract,
            n_samples=args.n_samples,
            nogood_atol=None if args.nogood_atol == "off" else args.nogood_atol,
            set_aside_after=None if args.set_aside_after == "off" else args.set_aside_after,
            end_at_dead_end=False if args.run_past_dead_ends else None,
        )
        if args.nogood_atol == "off":
            base = dataclasses.replace(base, nogood_atol=None)
        if args.set_aside_after == "off":
            base = dataclasses.replace(base, set_aside_after=None)
    except (TypeError, ValueError) as err:
        raise UserError(f"bad planning settings: {err}") from None
    request = EvalRequest(
        num_tasks=args.tasks,
        task_seed=args.seed,
        planner_seed=args.planner_seed,
        train=args.train,
        validate=not args.no_validate,
        workers=workers,
        perturbation=perturbation,
    )
    reports = evaluate_approaches(
        env,
        names,
        request,
        base,
        skills_dir=args.skills,
        learned=learned,
        progress=task_progress,
        finished=lambda report: print(solved_line(report), flush=True),
    )
    recorded = []
    if args.rerun is not None:
        with writing(args.rerun, "--rerun"):
            recorded = record_evaluation(env, reports, args.rerun, args.rerun_tasks, print)
    page = PageRequest(args.report_videos, args.report_video_budget, args.camera, tuple(recorded))
    with writing(args.out or args.video):
        reported = report_evaluation(
            env, reports, args.out, args.video, args.seed, args.train, args.task, args.camera, page
        )
    print_lines(reported)
    if reported.no_video_of is not None:
        print(f"no {reported.no_video_of} task was solved: no video", file=sys.stderr)
    if args.explain:
        from bpns.evaluation.reporting import explain_lines

        for report in reports:
            for line in explain_lines(report):
                print(line)
    return 0 if all(r.num_solved for r in reports) else 1
