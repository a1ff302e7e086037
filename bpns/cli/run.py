"""``bpns run``: the whole pipeline, demos -> replay check -> learn -> eval -> table ->
video, by calling the library functions each step's command calls.

``run`` parses and checks its arguments once, into a :class:`RunConfig`, before any work;
then it calls the steps one after the other, each with the config and what the step
before it produced."""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from bpns.approaches import ApproachEntry, SkillSource, approach_names
from bpns.baselines.learn import BaselinesConfig
from bpns.cli.common import (
    UserError,
    add_eval_set_arguments,
    approach_by_name,
    checked_worlds,
    default_workers,
    env_by_name,
    eval_set_from,
    nonnegative,
    path_arg,
    positive,
    positive_float,
    print_lines,
    progress,
    stage_reporter,
    task_progress,
)
from bpns.cli.learn import add_correction_arguments, correction_config_from
from bpns.cli.paths import (
    capped_to_cores,
    check_eval_outputs,
    check_output_dir,
    check_output_file,
    check_skills_dir,
    claimed,
    writing,
)
from bpns.data.datasets import DatasetError
from bpns.data.demos import check_replay
from bpns.env.environment import Environment
from bpns.env.object_counts import PAPER_SET, EvalSet
from bpns.env.worlds import WorldDistribution
from bpns.evaluation.evaluate import EvalReport
from bpns.evaluation.reporting import solved_line
from bpns.learning import LearnedSkills, LearningConfig, describe
from bpns.learning.config import learning_config_for
from bpns.learning.corrections import CorrectionConfig
from bpns.planning.config import PlanningConfig, planning_config_for
from bpns.workflow import (
    CannotLearnError,
    baselines_needed,
    collect_demos,
    learn_to_directory,
)
from bpns.workflow.evaluate import EvalRequest, evaluate_approaches
from bpns.workflow.report import report_evaluation

HELP = "the whole pipeline: demos -> learn -> eval -> table -> video"
REPLAY_CHECKED = 5  # demonstrations re-simulated to check the simulator is exact


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", required=True, help="environment name (e.g. cover)")
    p.add_argument("--demos", type=positive, default=50, help="number of demonstrations")
    p.add_argument("--tasks", type=positive, default=10, help="number of eval tasks")
    p.add_argument("--seed", type=nonnegative, default=0)
    p.add_argument("--timeout", type=positive_float, default=60.0, help="seconds per task")
    p.add_argument("--out", type=path_arg, help="output directory (default: outputs/<env>)")
    p.add_argument("--workers", type=positive, default=default_workers())
    add_eval_set_arguments(p)
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
        "--perturb",
        nargs="+",
        metavar="PRESET|NAME=VALUE",
        help="evaluate the same tasks a second time, each in its own world drawn as "
        "`bpns eval --perturb` draws them (e.g. moderate), closed loop, the planner's model "
        "nominal: a second table, beside the nominal one, in --out/eval_perturbed",
    )
    add_correction_arguments(p)
    p.add_argument(
        "--overwrite", action="store_true", help="replace the outputs of an earlier run in --out"
    )


def _step(title: str) -> None:
    print(f"== {title}", flush=True)


def approaches_to_run(env, asked: list[str] | None) -> list:
    """The registry entries of the approaches ``asked`` (default: bpns, and oracle where
    ``env`` has hand-written skills), each checked to be able to run on ``env``: an
    impossible combination is refused before any work."""
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


@dataclass(frozen=True)
class RunConfig:
    """What ``bpns run`` was asked to do, checked, with the configs each step runs with:
    refused input (or an environment's bad declaration) never starts work."""

    env: Environment
    entries: tuple[ApproachEntry, ...]  # in the order asked
    stages: tuple[str, ...]  # the baselines they need, learned beside the skills
    out: Path
    num_demos: int
    num_tasks: int
    seed: int
    workers: int
    learning: LearningConfig
    baselines: BaselinesConfig | None  # None: no approach asked needs a baseline
    planning: PlanningConfig  # the approaches' base, with the --timeout
    eval_set: EvalSet = PAPER_SET  # the eval distribution (--eval-set, --objects)
    worlds: WorldDistribution | None = None  # --perturb: a second evaluation in these
    corrections: CorrectionConfig | None = None  # --corrections: DAgger after learning

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.entries]

    @property
    def demos_path(self) -> Path:
        return self.out / "demos.h5"

    @property
    def skills_dir(self) -> Path:
        return self.out / "skills"

    @property
    def video(self) -> Path:
        return self.out / "eval_solved.mp4"

    @property
    def perturbed_eval(self) -> Path:
        return self.out / "eval_perturbed"

    @property
    def perturbed_video(self) -> Path:
        return self.out / "eval_perturbed_solved.mp4"


def parse_run(args: argparse.Namespace) -> RunConfig:
    """``args`` as a :class:`RunConfig`; a UserError for anything ``run`` must refuse."""
    env = env_by_name(args.env)
    out: Path = args.out or Path("outputs") / env.name
    entries = approaches_to_run(env, args.approach)
    names = [e.name for e in entries]
    stages = baselines_needed(entries)
    if args.baseline_steps is not None and not stages:
        raise UserError(
            f"--baseline-steps applies to the baselines, and none of {', '.join(names)} uses one"
        )
    eval_set = eval_set_from(args, env)
    planning = planning_config_for(env, timeout=args.timeout)
    learning = learning_config_for(env, seed=args.seed)
    baselines = None
    if stages:
        steps = args.baseline_steps
        base = BaselinesConfig() if steps is None else BaselinesConfig.with_max_steps(steps)
        baselines = base.only(stages)
    worlds = None if args.perturb is None else checked_worlds(env, args.perturb, "--perturb")
    # the demonstrations are collected by this run, which records their tasks
    corrections = correction_config_from(args, env)
    check_output_dir(out, "--out")
    check_output_file(out / "demos.h5", "--out", args.overwrite)
    check_skills_dir(out / "skills", "--out", args.overwrite)
    check_eval_outputs(out / "eval", out / "eval_solved.mp4", names, args.overwrite)
    if worlds is not None:
        check_eval_outputs(
            out / "eval_perturbed", out / "eval_perturbed_solved.mp4", names, args.overwrite
        )
    return RunConfig(
        env=env,
        entries=tuple(entries),
        stages=stages,
        out=out,
        num_demos=args.demos,
        num_tasks=args.tasks,
        seed=args.seed,
        workers=capped_to_cores(args.workers, "--workers"),
        learning=learning,
        baselines=baselines,
        planning=planning,
        eval_set=eval_set,
        worlds=worlds,
        corrections=corrections,
    )


def run(args: argparse.Namespace) -> int:
    config = parse_run(args)
    # each file's write creates the directories it needs
    with claimed("--out", config.out), writing(config.out, "--out"):
        t0 = time.perf_counter()
        if not collect(config):
            return 1
        learned = learn(config)
        reports = evaluate(config, learned=learned)
        report(config, reports=reports)
        if config.worlds is not None:
            reports += evaluate(config, learned=learned, worlds=config.worlds)
            report(config, reports=reports[len(config.names) :], perturbed=True)
        if not all(r.num_solved for r in reports):
            return 1
        print(f"done in {time.perf_counter() - t0:.0f} s; everything is in {config.out}/")
        return 0


def collect(config: RunConfig) -> bool:
    """Collect the demonstrations and re-simulate the first few; False when there are
    none or replay is not exact (each says why)."""
    env = config.env
    _step(f"demos: {config.num_demos} demonstrations of {env.name}")
    written = collect_demos(
        env,
        config.num_demos,
        config.seed,
        config.demos_path,
        workers=config.workers,
        progress=progress,
    )
    checked = None
    if written.num_written:
        checked = check_replay(env, config.demos_path, REPLAY_CHECKED, progress)
    print_lines(written)
    if checked is None:
        return False
    _step(f"replay: the first {REPLAY_CHECKED} demonstrations")
    print_lines(checked)
    return checked.ok


def learn(config: RunConfig) -> LearnedSkills:
    """Learn the skills (and the baselines the approaches need) into ``skills/``; what
    was learned, described (evaluation loads the saved directory, as ``bpns eval``)."""
    stages = config.stages
    _step("learn" + (f" (and the baselines {', '.join(stages)})" if stages else ""))
    try:
        learned_run = learn_to_directory(
            config.env,
            config.demos_path,
            config.skills_dir,
            config.learning,
            progress=progress,
            report=stage_reporter(),
            baselines=config.baselines,
            workers=config.workers,
            corrections=config.corrections,
        )
    except (DatasetError, CannotLearnError) as err:  # as `bpns learn` says it
        raise UserError(str(err)) from None
    print_lines(learned_run)
    print(describe(learned_run.learned))
    return learned_run.learned


def evaluate(
    config: RunConfig, *, learned: LearnedSkills, worlds: WorldDistribution | None = None
) -> list[EvalReport]:
    """Evaluate every approach asked on held-out tasks, in the nominal world or in
    ``worlds`` (closed loop, the model nominal); the reports, in that order."""
    where = "" if worlds is None else f" in {worlds.label()} worlds (closed loop)"
    _step(f"eval: {', '.join(config.names)} on {config.num_tasks} tasks{where}")
    return evaluate_approaches(
        config.env,
        config.names,
        EvalRequest(
            num_tasks=config.num_tasks,
            task_seed=config.seed,
            workers=config.workers,
            eval_set=config.eval_set,
            **({} if worlds is None else {"perturbation": worlds}),
        ),
        config.planning,
        skills_dir=config.skills_dir,
        learned=learned,
        progress=task_progress,
        finished=lambda report: print(solved_line(report), flush=True),
    )


def report(config: RunConfig, *, reports: list[EvalReport], perturbed: bool = False) -> None:
    """The table, the results files and a video of a solved task (of the perturbed
    evaluation into its own directory and video)."""
    out, video = (
        (config.perturbed_eval, config.perturbed_video)
        if perturbed
        else (config.out / "eval", config.video)
    )
    reported = report_evaluation(config.env, reports, out, video, config.seed, train=False)
    print_lines(reported)
    if reported.no_video_of is not None:
        print(f"no {reported.no_video_of} task was solved: no video", file=sys.stderr)
