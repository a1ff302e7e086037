"""``bpns eval``: solve held-out tasks with one or more approaches; results JSON + table."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
from collections.abc import Sequence

from bpns.acting.config import MODES, SLOW_FROM, ExecutionConfig
from bpns.approaches import ApproachEntry, SkillSource, approach_names
from bpns.atomic import staged
from bpns.cli.common import (
    UserError,
    add_eval_set_arguments,
    approach_by_name,
    check_slowable,
    cost_or_off,
    default_workers,
    env_by_name,
    eval_set_from,
    fraction,
    learned_in,
    nonnegative,
    path_arg,
    positive,
    positive_float,
    positive_or_off,
    print_lines,
    steps_or_all,
    task_progress,
    tolerance_or_off,
)
from bpns.cli.paths import (
    capped_to_cores,
    check_eval_outputs,
    check_not_inside,
    check_output_dir,
    check_output_file,
    claimed,
    writing,
)
from bpns.env.environment import Environment, perturbed
from bpns.env.perturbations import PerturbationError
from bpns.env.worlds import ModelSpec, WorldDistribution, parse_model, parse_world
from bpns.evaluation.evaluate import EvalReport
from bpns.evaluation.reporting import explain_lines, solved_line
from bpns.inspect.extras import require
from bpns.inspect.html_report import PAGE
from bpns.learning.pipeline import LearnedSkills
from bpns.planning.config import PlanningConfig, planning_config_for
from bpns.workflow.evaluate import EvalRequest, evaluate_approaches
from bpns.workflow.inspect import RERUN_TASKS, record_evaluation, recording_name
from bpns.workflow.report import report_evaluation
from bpns.workflow.report_page import REPORT_VIDEOS, PageRequest

HELP = "solve held-out tasks by bilevel planning; results JSON + markdown table"


def configure(p: argparse.ArgumentParser) -> None:
    """The flags by concern; the order of the calls is the order ``--help`` lists them."""
    _add_task_arguments(p)
    _add_planning_arguments(p)
    _add_output_arguments(p)
    add_world_arguments(p)
    _add_diagnosis_arguments(p)
    _add_report_arguments(p)


def _add_task_arguments(p: argparse.ArgumentParser) -> None:
    """What is evaluated: the environment, the skills, the approaches and the task
    stream (``--seed``) with the planner's own seed."""
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
    add_eval_set_arguments(p)


def _add_planning_arguments(p: argparse.ArgumentParser) -> None:
    """The planner's budget and refinement settings; unset ones fall back to the
    environment's (``planning_config_for``)."""
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
        "--demote-refuted",
        type=cost_or_off,
        help="once a way of achieving some atoms has failed every sample from an arrival "
        "(and never succeeded), charge the abstract search this much more for it, so "
        "skeletons that achieve them otherwise come first; 'off' for unit costs, the "
        "paper's (default: the env's or off)",
    )
    p.add_argument(
        "--run-past-dead-ends",
        action="store_true",
        help="simulate a rollout on in a state the environment declares a dead end (e.g. "
        "Coffee's spilled coffee) until its horizon, as the paper's planner does "
        "(default: it fails there at once)",
    )


def _add_output_arguments(p: argparse.ArgumentParser) -> None:
    """Where results go (``--out``, with the ``--workers`` that produce them) and the
    ``--video`` of one task."""
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


def _add_diagnosis_arguments(p: argparse.ArgumentParser) -> None:
    """Re-simulating plans, and explaining failed tasks."""
    p.add_argument("--no-validate", action="store_true", help="skip re-simulating plans")
    p.add_argument(
        "--explain",
        action="store_true",
        help="print why each failed task failed: the abstract plans tried and, per step, the "
        "samples that failed and why (also in results.json, `explanation`)",
    )


def _add_report_arguments(p: argparse.ArgumentParser) -> None:
    """What report.html shows, Rerun recordings, and whether outputs are replaced."""
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


def add_world_arguments(p: argparse.ArgumentParser) -> None:
    """The world the tasks execute in, the model the planner believes, and how plans
    meet the world (docs/WORLDS.md)."""
    p.add_argument(
        "--perturb",
        nargs="+",
        metavar="PRESET|NAME=VALUE",
        default=[],
        help="execute in a perturbed world: a preset (moderate, hard) and/or NAME=VALUE items "
        "with NAME one of mass_scale, friction_scale, gain_scale (arm kp), action_noise (std, "
        "fraction of the action range), obs_noise (std on the policies' features, m/rad), "
        "latency (control steps), seed; VALUE a number, a range LOW:HIGH or a set A,B,C, "
        "drawn per task from --seed (or the seed=K given; docs/WORLDS.md)",
    )
    p.add_argument(
        "--model",
        nargs="+",
        metavar="nominal|world|NAME=VALUE",
        default=["nominal"],
        help="what planning simulates: the nominal physics (default), the world itself "
        "(the paper's closed world: the planner knows every perturbation), or a belief "
        "given as NAME=VALUE items",
    )
    p.add_argument(
        "--execution",
        choices=MODES,
        default=MODES[0],
        help="closed-loop (default): execute skill by skill in the world, monitor, replan on "
        "divergence; open-loop: replay the model's plan in the world",
    )
    p.add_argument(
        "--max-replans",
        type=nonnegative,
        default=ExecutionConfig().max_replans,
        help="closed loop: divergences repaired per task before it fails (default: %(default)s)",
    )
    p.add_argument(
        "--rerefine-atol",
        type=tolerance_or_off,
        default=ExecutionConfig().rerefine_atol,
        help="closed loop: refine the rest of the plan again at a skill boundary where the "
        "world's features left the model's by more than this (m/rad), or 'off' "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--check-ahead",
        type=steps_or_all,
        default=ExecutionConfig().check_ahead,
        metavar="N|all",
        help="closed loop: at such a boundary, simulate this many steps of the rest again "
        "in the model (later ones are checked at their own boundaries), or all of them "
        "(default: all)",
    )
    p.add_argument(
        "--horizon-scale",
        type=float,
        default=ExecutionConfig().horizon_scale,
        help="closed loop: a skill executing in the world may take this many times its "
        "learned horizon (>= 1; default: %(default)s)",
    )
    p.add_argument(
        "--world-speed",
        type=fraction,
        default=ExecutionConfig().world_speed,
        help="closed loop: a skill executing in the world applies this fraction of each "
        "commanded motion (in (0, 1]; slower is steadier under latency; default: %(default)s)",
    )
    p.add_argument(
        "--slow-from",
        choices=SLOW_FROM,
        default=ExecutionConfig().slow_from,
        help="closed loop: --world-speed takes effect from the task's start, or from the "
        "first deviation of the world from the model (default: %(default)s)",
    )
    p.add_argument(
        "--no-resume",
        dest="resume_stopped",
        action="store_false",
        help="closed loop: when a replan finds no abstract plan, fail, instead of planning "
        "again with a first step that finishes a skill the world stopped midway",
    )
    p.add_argument(
        "--predict-latency",
        action="store_true",
        help="closed loop: skills see their observation advanced in the model by the "
        "commands the world has not applied yet, its latency identified from each task's "
        "first 20 control steps (a Smith predictor; off by default)",
    )
    p.add_argument(
        "--watch-releases",
        action="store_true",
        help="closed loop: also end a skill when a contact precondition it deletes (a grip "
        "it lets go of at its end) stops holding before its effects appear, where the "
        "model's rollout kept it until then (off by default)",
    )
    p.add_argument(
        "--no-back-off",
        dest="back_off",
        action="store_false",
        help="closed loop: when a replan finds no plan, fail, instead of running the "
        "environment's back-off motion (e.g. the hand raised and returned to its start) "
        "and planning once more",
    )


def world_settings(
    args: argparse.Namespace,
) -> tuple[WorldDistribution, ModelSpec, ExecutionConfig]:
    """The checked ``--perturb``, ``--model`` and execution flags."""
    try:
        worlds = parse_world(args.perturb)
    except PerturbationError as err:
        raise UserError(f"--perturb: {err}") from None
    try:
        model = parse_model(args.model)
    except PerturbationError as err:
        raise UserError(f"--model: {err}") from None
    atol = None if args.rerefine_atol == "off" else args.rerefine_atol
    if atol == 0:
        raise UserError("--rerefine-atol: expected a number > 0 or 'off', got 0")
    scale = args.horizon_scale
    if not (1.0 <= scale < float("inf")):
        raise UserError(f"--horizon-scale: expected a finite number >= 1, got {scale:g}")
    execution = ExecutionConfig.of_mode(
        args.execution,
        max_replans=args.max_replans,
        rerefine_atol=atol,
        check_ahead=args.check_ahead,
        horizon_scale=scale,
        world_speed=args.world_speed,
        slow_from=args.slow_from,
        resume_stopped=args.resume_stopped,
        back_off=args.back_off,
        predict_latency=args.predict_latency,
        watch_releases=args.watch_releases,
    )
    return worlds, model, execution


def run(args: argparse.Namespace) -> int:
    worlds, model, execution = world_settings(args)
    _check_video_flags(args)
    names = list(dict.fromkeys(args.approach))
    approaches = [approach_by_name(a) for a in names]
    check_eval_outputs(args.out, args.video, names, args.overwrite, args.skills)
    check_inspect_outputs(args, names)
    workers = capped_to_cores(args.workers, "--workers")
    env, learned = _evaluated_environment(args, approaches)
    _check_environment_supports(env, worlds, model, approaches)
    check_slowable(env, execution.world_speed)
    base = _planning_settings(args, env)
    request = EvalRequest(
        num_tasks=args.tasks,
        task_seed=args.seed,
        planner_seed=args.planner_seed,
        train=args.train,
        validate=not args.no_validate,
        workers=workers,
        perturbation=worlds,
        model=model,
        execution=execution,
        eval_set=eval_set_from(args, env),
    )
    with (
        claimed("--out", args.out),
        claimed("--video", args.video, args.video and args.video.with_suffix(".png")),
        claimed("--rerun", args.rerun),
    ):
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
        _write_outputs(args, env, reports)
    if args.explain:
        for report in reports:
            for line in explain_lines(report):
                print(line)
    return 0 if all(r.num_solved for r in reports) else 1


def _check_video_flags(args: argparse.Namespace) -> None:
    """--task and --camera only mean something for --video, and --task must be a task
    that is evaluated: said before any task runs."""
    if args.video is None and (args.task is not None or args.camera is not None):
        raise UserError("--task and --camera choose what --video renders: pass --video too")
    if args.task is not None and args.task >= args.tasks:
        raise UserError(f"--task {args.task}: only tasks 0..{args.tasks - 1} are evaluated")


def _evaluated_environment(
    args: argparse.Namespace, approaches: Sequence[ApproachEntry]
) -> tuple[Environment, LearnedSkills | None]:
    """The environment (--env, else the one --skills records) and the learned skills,
    loaded only when a learned approach needs them."""
    if any(a.skills is SkillSource.LEARNED for a in approaches):
        if args.skills is None:
            raise UserError("learned approaches need --skills DIR (from `bpns learn`)")
        return learned_in(args.skills, args.env)
    if args.env is None and args.skills is None:
        raise UserError("pass --env (or --skills) to say which environment to evaluate on")
    if args.env is None:
        env, _ = learned_in(args.skills)  # the environment the skills record
        return env, None
    return env_by_name(args.env), None


def _check_environment_supports(
    env: Environment,
    worlds: WorldDistribution,
    model: ModelSpec,
    approaches: Sequence[ApproachEntry],
) -> None:
    """An environment without perturbations, or without the oracle skills an approach
    needs, says so now rather than after the first task."""
    try:
        perturbed(env, worlds.draw(0))
        perturbed(env, model.belief)
    except PerturbationError as err:
        raise UserError(f"--perturb: {err}") from None
    if (
        any(a.skills is SkillSource.ORACLE for a in approaches)
        and not env.capabilities.has_oracle_skills
    ):
        raise UserError(f"environment {env.name!r} declares no oracle skills")


def _planning_settings(args: argparse.Namespace, env: Environment) -> PlanningConfig:
    """The planning flags over the environment's settings; 'off' turns a setting off
    even where the environment sets it."""
    try:
        base = planning_config_for(
            env,
            timeout=args.timeout,
            n_abstract=args.n_abstract,
            n_samples=args.n_samples,
            nogood_atol=None if args.nogood_atol == "off" else args.nogood_atol,
            set_aside_after=None if args.set_aside_after == "off" else args.set_aside_after,
            demote_refuted=None if args.demote_refuted == "off" else args.demote_refuted,
            end_at_dead_end=False if args.run_past_dead_ends else None,
        )
        if args.nogood_atol == "off":
            base = dataclasses.replace(base, nogood_atol=None)
        if args.set_aside_after == "off":
            base = dataclasses.replace(base, set_aside_after=None)
        if args.demote_refuted == "off":
            base = dataclasses.replace(base, demote_refuted=None)
    except (TypeError, ValueError) as err:
        raise UserError(f"bad planning settings: {err}") from None
    return base


def _write_outputs(args: argparse.Namespace, env: Environment, reports: list[EvalReport]) -> None:
    """The Rerun recordings, the results files, report.html and the video, then what
    was written (the page links the recordings, so they come first)."""
    recorded = []
    # the recordings are put in place with the results (after them), or not at all: an
    # interrupted `eval --overwrite` leaves the earlier recordings as they were
    with contextlib.ExitStack() as stack:
        if args.rerun is not None:
            stack.enter_context(writing(args.rerun, "--rerun"))
        staging = stack.enter_context(staged(args.rerun))
        if args.rerun is not None:
            recorded = record_evaluation(env, reports, args.rerun, args.rerun_tasks, print, staging)
        page = PageRequest(
            args.report_videos, args.report_video_budget, args.camera, tuple(recorded)
        )
        with writing(args.out or args.video):
            reported = report_evaluation(
                env,
                reports,
                args.out,
                args.video,
                args.seed,
                args.train,
                args.task,
                args.camera,
                page,
            )
    print_lines(reported)
    if reported.no_video_of is not None:
        print(f"no {reported.no_video_of} task was solved: no video", file=sys.stderr)
