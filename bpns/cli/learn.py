"""``bpns learn``: learn neuro-symbolic skills from demonstrations."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from bpns.baselines.learn import BaselinesConfig
from bpns.cli.common import (
    UserError,
    check_correctable,
    file_env,
    nonnegative,
    nonnegative_float,
    path_arg,
    positive,
    print_lines,
    progress,
    stage_reporter,
    tolerance_or_off,
)
from bpns.cli.paths import capped_to_cores, check_skills_dir, claimed, usable_cores, writing
from bpns.data.datasets import DatasetError, task_origins
from bpns.env.environment import Environment
from bpns.learning.config import LearningConfig, learning_config_for
from bpns.learning.corrections import EXPERTS, CorrectionConfig
from bpns.workflow import CannotLearnError, learn_to_directory

HELP = "learn neuro-symbolic skills from demonstrations"


def configure(p: argparse.ArgumentParser) -> None:
    """The flags by concern; the order of the calls is the order ``--help`` lists them."""
    _add_data_arguments(p)
    _add_skill_arguments(p)
    _add_paper_arguments(p)
    _add_operator_arguments(p)
    _add_baseline_arguments(p)
    add_correction_arguments(p)
    _add_run_arguments(p)


def _add_data_arguments(p: argparse.ArgumentParser) -> None:
    """The demonstrations learned from, the skills directory written, and the seed that
    makes the weights reproducible."""
    p.add_argument("demos", type=path_arg, help="demonstration .h5 file (from `bpns demos`)")
    p.add_argument("--out", required=True, type=path_arg, help="skills directory to write")
    p.add_argument("--limit", type=positive, help="learn from the first N demos only")
    p.add_argument("--seed", type=nonnegative, default=0, help="seed of all network training")


def _add_skill_arguments(p: argparse.ArgumentParser) -> None:
    """Which skills are kept and what their networks see (subgoals, near-goal inputs,
    input clipping)."""
    p.add_argument(
        "--min-segment-fraction",
        type=nonnegative_float,
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
        type=tolerance_or_off,
        help="policies also see tanh(relative subgoal / this) (feature units), or 'off' as "
        "in the paper (default: the environment's, else off)",
    )
    p.add_argument(
        "--input-margin",
        type=tolerance_or_off,
        help="networks clip their inputs into the training range widened by this fraction "
        "of it (default 0.1), or 'off' as in the paper",
    )


def _add_paper_arguments(p: argparse.ArgumentParser) -> None:
    """Switches back to the paper's choices where the defaults depart from it, for
    ablations."""
    p.add_argument(
        "--no-anchor",
        action="store_true",
        help="operator parameters = affected objects only, as in the paper (no anchored "
        "parameters such as the robot holding the pressing stick)",
    )
    p.add_argument(
        "--no-share",
        action="store_true",
        help="each skill's networks learn from its own operator's segments only, as in the "
        "paper (default: also from operators whose add effects include its own, the "
        "variants of one motion that segmentation split)",
    )
    p.add_argument(
        "--no-linear-base",
        action="store_true",
        help="subgoal generators and policies are networks alone, as in the paper "
        "(default: a ridge-regression map under each generator, and under each policy "
        "where the environment declares it, with the network learning the residual)",
    )
    p.add_argument(
        "--subgoal-noise",
        choices=("correlated", "independent"),
        default=None,
        help="how subgoal generators draw their dims: correlated (with the correlation "
        "their training residuals had: a held block and the hand holding it move "
        "together) or independent (the paper); default: what the environment declares "
        "in its learning_defaults (independent where it declares nothing)",
    )
    p.add_argument(
        "--no-novelty-check",
        action="store_true",
        help="simulate every sample, as in the paper (default: a skill's sampler refuses to "
        "start where none of its demonstrations started, e.g. a hand press at a button "
        "farther than any pressed by hand, and the planner moves on without simulating)",
    )


def _add_operator_arguments(p: argparse.ArgumentParser) -> None:
    """How contact events are cut into segments and how the operators are named."""
    p.add_argument(
        "--settle-steps",
        type=positive,
        help="contact changes closer than this are one event "
        "(default: the environment's contact_settle_steps)",
    )
    p.add_argument(
        "--index-names",
        action="store_true",
        help="name operators Op0, Op1, ... as in the paper instead of after their effects",
    )


def _add_baseline_arguments(p: argparse.ArgumentParser) -> None:
    """The paper's baselines, learned from the same demonstrations when asked."""
    p.add_argument(
        "--baselines",
        action="store_true",
        help="also learn the paper's baselines from the same demos (No-Subgoal skills, GNN "
        "metacontroller, GNN BC) into --out, for `bpns eval --approach nosubgoal gnn-meta "
        "gnn-meta-nosubgoal gnn-bc`",
    )
    p.add_argument(
        "--baseline-steps",
        type=positive,
        help="with --baselines: at most this many gradient steps per GNN (default 20000)",
    )
    p.add_argument(
        "--baseline-seed",
        type=nonnegative,
        help="with --baselines: seed of the GNNs (default: --seed), e.g. to measure how "
        "much their initial weights matter on fixed skills",
    )


def add_correction_arguments(p: argparse.ArgumentParser) -> None:
    """Corrections on the states the learned skills reach in perturbed worlds (DAgger)."""
    p.add_argument(
        "--corrections",
        nargs="+",
        metavar="PRESET|NAME=VALUE",
        help="then replay every demonstration with the learned skills in worlds drawn as "
        "`bpns eval --perturb` draws them, ask the expert on every state they reach, and "
        "retrain the policies on its answers too (DAgger; e.g. `--corrections moderate`; "
        "default: off). Needs demonstrations from `bpns demos` that record their tasks",
    )
    p.add_argument(
        "--correction-rounds",
        type=positive,
        help="with --corrections: rounds of replaying and retraining (default 2)",
    )
    p.add_argument(
        "--correction-expert",
        choices=EXPERTS,
        help="with --corrections: who labels, the environment's hand-written skills "
        "(oracle, the default) or its scripted demonstrator",
    )
    p.add_argument(
        "--keep-last-round",
        action="store_true",
        help="with --corrections: keep the last round's policies (default: replay them "
        "once more and keep whichever policies, the plain ones included, carried the "
        "most demonstrations through every segment)",
    )
    p.add_argument(
        "--keep-demonstrator-labels",
        action="store_true",
        help="with --corrections by the oracle: the demonstrations keep the demonstrator's "
        "commands as labels, so the policies learn from two experts that disagree "
        "(default: the oracle labels the demonstrations' states too)",
    )


def _add_run_arguments(p: argparse.ArgumentParser) -> None:
    """How the run treats an existing --out and how much of the machine it uses."""
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    p.add_argument(
        "--threads",
        type=positive,
        default=1,
        help="torch threads for training (1 is fastest for these small networks)",
    )
    p.add_argument(
        "--workers",
        type=positive,
        default=None,
        help="processes that train the skills' networks, one skill each at a time "
        "(default: one per core; the weights are the same for any number)",
    )


def run(args: argparse.Namespace) -> int:
    check_skills_dir(args.out, "--out", args.overwrite, [args.demos])
    if args.min_segment_fraction > 1.0:
        raise UserError(f"--min-segment-fraction must be <= 1, got {args.min_segment_fraction}")
    if args.near_goal_scale == 0.0:
        raise UserError("--near-goal-scale must be > 0 or 'off', got 0")
    baseline_flags = {
        "--baseline-steps": args.baseline_steps,
        "--baseline-seed": args.baseline_seed,
    }
    for flag, value in baseline_flags.items():
        if value is not None and not args.baselines:
            raise UserError(f"{flag} applies to the baselines: add --baselines")
    env = file_env(args.demos, None)
    corrections = correction_config_from(args, env, args.demos)
    threads = capped_to_cores(args.threads, "--threads")
    workers = usable_cores() if args.workers is None else capped_to_cores(args.workers, "--workers")
    config = learning_config_from(args, env)
    try:
        with claimed("--out", args.out), writing(args.out):
            learned = learn_to_directory(
                env,
                args.demos,
                args.out,
                config,
                args.limit,
                threads,
                progress,
                stage_reporter(),
                baselines=_baselines_config(args) if args.baselines else None,
                workers=workers,
                corrections=corrections,
            )
    except (DatasetError, CannotLearnError) as err:
        raise UserError(str(err)) from None
    print_lines(learned)
    return 0


def correction_config_from(
    args: argparse.Namespace, env: Environment, demos: Path | None = None
) -> CorrectionConfig | None:
    """The corrections ``--corrections`` asks for (None: none), checked before any work:
    the worlds against the environment, the expert against what it declares, and that
    the demonstrations ``demos`` record their tasks (None: demonstrations still to be
    collected by ``bpns demos``' code, which records them)."""
    flags = {
        "--correction-rounds": args.correction_rounds,
        "--correction-expert": args.correction_expert,
        "--keep-demonstrator-labels": args.keep_demonstrator_labels or None,
        "--keep-last-round": args.keep_last_round or None,
    }
    if args.corrections is None:
        for flag, value in flags.items():
            if value is not None:
                raise UserError(f"{flag} applies to corrections: add --corrections")
        return None
    expert = args.correction_expert or "oracle"
    if args.keep_demonstrator_labels and expert != "oracle":
        raise UserError("--keep-demonstrator-labels applies to corrections by the oracle")
    worlds = check_correctable(env, args.corrections, "--corrections", expert)
    try:
        if demos is not None:
            task_origins(demos)
    except DatasetError as err:
        raise UserError(f"--corrections: {err}") from None
    return CorrectionConfig(
        worlds,
        rounds=args.correction_rounds or 2,
        expert=expert,
        seed=args.seed,
        relabel=False if args.keep_demonstrator_labels else None,
        keep="last" if args.keep_last_round else "best",
    )


def learning_config_from(args: argparse.Namespace, env: Environment) -> LearningConfig:
    """The learning settings of ``bpns learn``'s arguments: the environment's declared
    settings (``learning_config_for``) where a flag is not given."""
    config = learning_config_for(
        env,
        seed=args.seed,
        min_segment_fraction=args.min_segment_fraction,
        use_subgoals=False if args.no_subgoals else None,
        anchor_parameters=False if args.no_anchor else None,
        share_effect_data=False if args.no_share else None,
        linear_sampler_base=False if args.no_linear_base else None,
        linear_policy_base=False if args.no_linear_base else None,
        refuse_novel_starts=False if args.no_novelty_check else None,
        correlated_subgoal_noise=(
            None if args.subgoal_noise is None else args.subgoal_noise == "correlated"
        ),
        settle_steps=args.settle_steps,
        index_names=True if args.index_names else None,
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
    return config


def _baselines_config(args: argparse.Namespace) -> BaselinesConfig:
    base = (
        BaselinesConfig()
        if args.baseline_steps is None
        else BaselinesConfig.with_max_steps(args.baseline_steps)
    )
    return dataclasses.replace(base, seed=args.baseline_seed)
