"""``bpns experiment``: run a sweep (or resume it) and write its table and figures.

``configure`` sets up the sub-command's arguments and ``run`` executes it; the sweep
itself lives in :mod:`bpns.experiments`.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import threading
from pathlib import Path

from bpns.acting.config import MODES, SLOW_FROM
from bpns.approaches import get_approach
from bpns.cli.common import (
    Terminated,
    UserError,
    check_correctable,
    check_slowable,
    fraction,
    path_arg,
    positive_float,
    steps_or_all,
    whole_at_least,
)
from bpns.cli.paths import check_free_space, check_output_dir
from bpns.data.datasets import min_demo_bytes
from bpns.env import registry
from bpns.env.environment import eval_set_of
from bpns.env.object_counts import ObjectCountError, ObjectCounts
from bpns.env.perturbations import PerturbationError, parse_axis
from bpns.env.registry import EnvironmentDeclarationError, PluginError, environment_names
from bpns.experiments.aggregate import markdown_table
from bpns.experiments.approach_info import approach_names
from bpns.experiments.backends import BackendError, PoolBackend, RayBackend, check_reachable
from bpns.experiments.cells import DEMOS, skipped_approaches
from bpns.experiments.presets import PRESETS, SweepConfig, SweepConfigError
from bpns.experiments.store import CellStore, CellStoreError
from bpns.experiments.sweep import load_finished, run_sweep, sweep_cells, write_sweep_file

HELP = "sweep environments x demo counts x seeds x approaches; mean ± std table and figures"


def _whole(text: str, least: int) -> int:
    return whole_at_least(text, least, "a number")


def _count(text: str) -> int:
    return _whole(text, 1)


def _seed(text: str) -> int:
    return _whole(text, 0)


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    presets = ", ".join(
        f"{p.name} ({len(p.envs)} envs x demos {list(p.demo_counts)} x {len(p.seeds)} seeds, "
        f"{p.eval_tasks} eval tasks, {p.timeout:g} s)"
        for p in PRESETS.values()
    )
    parser.add_argument(
        "--preset", choices=list(PRESETS), default="small", help=f"what to sweep: {presets}"
    )
    parser.add_argument(
        "--out", type=path_arg, help="sweep directory (default: outputs/experiments/<preset>)"
    )
    parser.add_argument("--env", nargs="+", help="environments (overrides the preset)")
    parser.add_argument("--demos", nargs="+", type=_count, help="demo counts (overrides)")
    parser.add_argument("--seeds", nargs="+", type=_seed, help="seeds, e.g. 0 1 2 (overrides)")
    parser.add_argument(
        "--approach",
        nargs="+",
        help=f"approaches (overrides the preset); known: {', '.join(approach_names())}",
    )
    parser.add_argument("-n", "--tasks", type=_count, help="eval tasks per seed (overrides)")
    parser.add_argument("--timeout", type=_seconds, help="planning seconds per task (overrides)")
    parser.add_argument(
        "--perturb-axis",
        metavar="NAME=V1,V2,...",
        help="evaluate every eval cell under each level of one perturbation (as `bpns eval "
        "--perturb`), e.g. friction_scale=1,0.7,0.5; the report draws success vs level",
    )
    parser.add_argument(
        "--objects-axis",
        metavar="KIND=N1,N2,...",
        help="evaluate every eval cell with each count of one kind of object (as `bpns eval "
        "--objects`), e.g. button=3,4,5,6; the report draws success and time vs count",
    )
    parser.add_argument(
        "--worlds",
        nargs="+",
        metavar="WORLD",
        help="evaluate every eval cell in each world: nominal, a preset (moderate, hard) or "
        "a quoted 'NAME=SPREAD ...' (as `bpns eval --perturb`); the report pairs each with "
        "the nominal world on the same tasks, with Wilson intervals",
    )
    parser.add_argument(
        "--execution",
        nargs="+",
        choices=MODES,
        help="closed-loop and/or open-loop (default with --worlds: closed-loop)",
    )
    parser.add_argument(
        "--model",
        default="nominal",
        help="what planning simulates with --worlds: nominal (default), world, or a quoted "
        "'NAME=VALUE ...' belief (as `bpns eval --model`)",
    )
    parser.add_argument(
        "--demote-refuted",
        type=positive_float,
        metavar="COST",
        help="plan every eval cell with `bpns eval --demote-refuted COST` (default: the "
        "environments' own setting, off for the shipped domains)",
    )
    parser.add_argument(
        "--world-speed",
        type=fraction,
        metavar="FRACTION",
        help="closed-loop eval cells run with `bpns eval --world-speed FRACTION` (in (0, 1]; "
        "default: full speed)",
    )
    parser.add_argument(
        "--slow-from",
        choices=SLOW_FROM,
        help="with --world-speed: from the task's start (default) or the first deviation",
    )
    parser.add_argument(
        "--predict-latency",
        action="store_true",
        help="closed-loop eval cells run with `bpns eval --predict-latency` (skills see their "
        "observation advanced by the commands in flight; default: off)",
    )
    parser.add_argument(
        "--check-ahead",
        type=steps_or_all,
        metavar="N|all",
        help="closed-loop eval cells run with `bpns eval --check-ahead N` (at a deviated "
        "boundary simulate N steps of the plan's rest again; default: all of them)",
    )
    parser.add_argument(
        "--watch-releases",
        action="store_true",
        help="closed-loop eval cells run with `bpns eval --watch-releases` (a grip lost "
        "before the skill's effects appear ends it; default: off)",
    )
    parser.add_argument(
        "--corrections",
        nargs="+",
        metavar="PRESET|NAME=VALUE",
        help="skills cells learn as `bpns learn --corrections ...` does: policies retrained "
        "on the oracle's corrections in these worlds (DAgger; default: none)",
    )
    parser.add_argument(
        "--correction-rounds",
        type=_count,
        help="with --corrections: rounds of replaying and retraining (default 2)",
    )
    parser.add_argument(
        "--workers",
        type=_count,
        default=1,
        help="cells run at once (pool backend, or a local Ray instance's CPUs); default 1",
    )
    parser.add_argument("--backend", choices=("pool", "ray"), default="pool")
    parser.add_argument(
        "--ray-address",
        help="address of a running Ray cluster ('auto' on one of its nodes, or "
        "ray://HEAD:10001); without it --backend ray starts a local instance",
    )
    parser.add_argument(
        "--report-only",
        action="store_true",
        help="only rebuild the table and figures from the cells finished so far",
    )
    parser.add_argument(
        "--dry-run", action="store_true", help="list the cells and which are finished; run none"
    )


def sweep_config(args: argparse.Namespace) -> SweepConfig:
    axis = None
    if args.perturb_axis:
        try:
            axis = parse_axis(args.perturb_axis)
        except PerturbationError as err:
            raise UserError(f"--perturb-axis: {err}") from None
    objects_axis = _objects_axis(args.objects_axis) if args.objects_axis else None
    try:
        config = PRESETS[args.preset].with_overrides(
            envs=args.env,
            demo_counts=args.demos,
            seeds=args.seeds,
            approaches=args.approach,
            eval_tasks=args.tasks,
            timeout=args.timeout,
            perturb_axis=axis,
            objects_axis=objects_axis,
            worlds=args.worlds,
            executions=args.execution,
            model=args.model,
            demote_refuted=args.demote_refuted,
            world_speed=args.world_speed,
            slow_from=args.slow_from,
            predict_latency=args.predict_latency,
            check_ahead=args.check_ahead,
            watch_releases=args.watch_releases,
            corrections=None if args.corrections is None else " ".join(args.corrections),
            correction_rounds=args.correction_rounds,
        )
    except SweepConfigError as err:
        raise UserError(str(err)) from None
    unknown = [e for e in config.envs if e not in environment_names()]
    if unknown:
        raise UserError(
            f"unknown environment(s) {unknown}; known: {', '.join(environment_names())}"
        )
    unknown = [a for a in config.approaches if a not in approach_names()]
    if unknown:
        raise UserError(f"unknown approach(es) {unknown}; known: {', '.join(approach_names())}")
    return config


#: seconds a preset waits for one environment plugin to load before it skips it
PLUGIN_LOAD_SECONDS = 30.0


def _within(seconds: float, fn, *args):
    """``fn(*args)`` run in a daemon thread; :class:`TimeoutError` if it has not returned
    within ``seconds`` (the thread is left to finish or to die with the process: an
    import cannot be interrupted). Its exception, if any, is raised here."""
    box: dict[str, object] = {}

    def call() -> None:
        try:
            box["value"] = fn(*args)
        except BaseException as err:  # noqa: BLE001  re-raised in the caller
            box["error"] = err

    worker = threading.Thread(target=call, daemon=True, name="plugin-load")
    worker.start()
    worker.join(seconds)
    if worker.is_alive():
        raise TimeoutError(f"{fn.__name__}{args} did not return within {seconds:g} s")
    if "error" in box:
        raise box["error"]  # type: ignore[misc]
    return box["value"]


def loadable(config: SweepConfig, args: argparse.Namespace):
    """``config`` without the plugins (environments, approaches) that fail to load, and
    its environments built: a preset (which takes every installed plugin) skips each
    broken one with one warning line; one named on the command line is an error."""

    def skip(err: PluginError | EnvironmentDeclarationError, named: bool) -> None:
        if named:
            raise UserError(str(err)) from None
        print(f"bpns: warning: {err}; the sweep skips it", file=sys.stderr, flush=True)

    envs = {}
    for name in config.envs:
        try:
            if args.env is not None:  # named: wait for it, however long it takes
                envs[name] = registry.make_environment(name)
            else:
                envs[name] = _within(PLUGIN_LOAD_SECONDS, registry.make_environment, name)
        except (PluginError, EnvironmentDeclarationError) as err:
            skip(err, args.env is not None)
        except TimeoutError:
            print(
                f"bpns: warning: environment plugin {name!r} did not load within "
                f"{PLUGIN_LOAD_SECONDS:g} s; the sweep skips it (name it with --env to "
                "wait for it)",
                file=sys.stderr,
                flush=True,
            )
    approaches = []
    for name in config.approaches:
        try:
            get_approach(name)
            approaches.append(name)
        except PluginError as err:
            skip(err, args.approach is not None)
    if not envs or not approaches:
        raise UserError(
            f"preset {config.name}: no {'environment' if not envs else 'approach'} loads"
        )
    return config.with_overrides(envs=tuple(envs), approaches=tuple(approaches)), envs


def _objects_axis(text: str) -> tuple[str, tuple[int, ...]]:
    """``KIND=N1,N2,...`` as (kind, counts); a UserError naming what is wrong."""
    kind, sep, values = text.partition("=")
    try:
        counts = tuple(int(v) for v in values.split(","))
    except ValueError:
        counts = ()
    if not sep or not kind.strip() or not counts:
        raise UserError(f"--objects-axis: expected KIND=N1,N2,..., got {text!r}")
    return kind.strip(), counts


def check_objects_axis(config: SweepConfig, envs: dict) -> None:
    """Every count of the object axis is one every swept environment can draw (its
    kinds and limits), before any cell runs."""
    for env in envs.values():
        for text in config.object_levels():
            if text is None:
                continue
            try:
                eval_set_of(env, objects=ObjectCounts.parse(text))
            except ObjectCountError as err:
                raise UserError(f"--objects-axis: {err}") from None


def command_line(config: SweepConfig, out: Path, args: argparse.Namespace) -> str:
    """The full command that reproduces ``config`` whatever the preset's defaults become."""
    argv = ["bpns", "experiment", "--preset", config.name, "--out", str(out)]
    argv += ["--env", *config.envs, "--demos", *map(str, config.demo_counts)]
    argv += ["--seeds", *map(str, config.seeds), "--approach", *config.approaches]
    argv += ["--tasks", str(config.eval_tasks), "--timeout", f"{config.timeout:g}"]
    if config.perturb_axis is not None:
        name, levels = config.perturb_axis
        argv += ["--perturb-axis", f"{name}={','.join(format(v, 'g') for v in levels)}"]
    if config.objects_axis is not None:
        kind, counts = config.objects_axis
        argv += ["--objects-axis", f"{kind}={','.join(map(str, counts))}"]
    if config.worlds:
        argv += ["--worlds", *config.worlds]
    if config.executions:
        argv += ["--execution", *config.executions]
    if config.model != "nominal":
        argv += ["--model", config.model]
    if config.demote_refuted is not None:
        argv += ["--demote-refuted", f"{config.demote_refuted:g}"]
    if config.world_speed is not None:
        argv += ["--world-speed", f"{config.world_speed:g}"]
    if config.slow_from is not None:
        argv += ["--slow-from", config.slow_from]
    if config.predict_latency:
        argv += ["--predict-latency"]
    if config.check_ahead is not None:
        argv += ["--check-ahead", str(config.check_ahead)]
    if config.watch_releases:
        argv += ["--watch-releases"]
    if config.corrections is not None:
        argv += ["--corrections", *config.corrections.split()]
    if config.correction_rounds is not None:
        argv += ["--correction-rounds", str(config.correction_rounds)]
    argv += ["--workers", str(args.workers)]
    if args.backend != "pool":
        argv += ["--backend", args.backend]
    if args.ray_address:
        argv += ["--ray-address", args.ray_address]
    return shlex.join(argv)


def run(args: argparse.Namespace) -> int:
    from bpns.experiments.report import write_report  # heavy: loads matplotlib (~1 s)

    if args.ray_address and args.backend != "ray":
        raise UserError("--ray-address needs --backend ray")
    if args.ray_address and not (args.report_only or args.dry_run):
        try:
            check_reachable(args.ray_address)
        except BackendError as err:
            raise UserError(str(err)) from None
    config, envs = loadable(sweep_config(args), args)
    check_objects_axis(config, envs)
    for env in envs.values():
        check_slowable(env, 1.0 if config.world_speed is None else config.world_speed)
        if config.corrections is not None:
            check_correctable(env, config.corrections.split(), "--corrections")
    out: Path = args.out or Path("outputs") / "experiments" / config.name
    if args.report_only or args.dry_run:
        if out.exists() and not out.is_dir():
            raise UserError(f"--out {out}: exists and is not a directory")
        if args.report_only and not (out / "cells").is_dir():
            raise UserError(
                f"--report-only: {out} holds no sweep (no cells/ in it); run the sweep first"
            )
    else:
        check_output_dir(out, "--out")
    cells = sweep_cells(config, envs)
    store = CellStore(out)
    command = command_line(config, out, args)
    for skipped in skipped_approaches(config, envs):
        print(f"note: {skipped} left out: the environment declares no hand-written skills")
    try:
        finished = load_finished(cells, store)
    except CellStoreError as err:
        raise UserError(str(err)) from None
    kinds = {k: sum(c.kind == k for c in cells) for k in dict.fromkeys(c.kind for c in cells)}
    print(
        f"{config.name}: {len(cells)} cells ("
        + ", ".join(f"{n} {k}" for k, n in kinds.items())
        + f"), {len(finished)} already finished in {out}/",
        flush=True,
    )
    if args.dry_run:
        for cell in cells:
            print(f"  {'done' if cell.key in finished else 'todo'}  {cell.key}")
        return 0
    if not args.report_only:
        _check_demos_fit(cells, finished, envs, out)
    del envs  # the workers build their own; the scheduler needs them no more
    code = 0
    if not args.report_only:
        try:
            backend = (
                RayBackend(args.ray_address, None if args.ray_address else args.workers)
                if args.backend == "ray"
                else PoolBackend(args.workers)
            )
        except BackendError as err:
            raise UserError(str(err)) from None
        try:
            summary = run_sweep(cells, store, backend)
        except CellStoreError as err:
            raise UserError(str(err)) from None
        except Terminated:  # a batch scheduler's stop: finished cells are stored
            raise Terminated("run the same command again to resume") from None
        write_sweep_file(out / "sweep.json", config, command, summary)
        print(_summary_line(summary), flush=True)
        for key, error in summary.failed.items():
            print(f"failed: {key}\n{error}", file=sys.stderr)
        code = 0 if summary.complete else 1
    rows, written = write_report(out, cells, store, config, command)
    if rows:
        print(markdown_table(rows), end="")
    print("wrote " + ", ".join(str(p) for p in written))
    return code


def _check_demos_fit(cells, finished, envs, out: Path) -> None:
    """Refuse a sweep whose demonstrations still to collect cannot fit on ``out``'s disk
    (a lower bound per demonstration; see ``bpns.data.datasets.min_demo_bytes``)."""
    todo = [c for c in cells if c.kind == DEMOS and c.key not in finished]
    needed = sum(
        (c.count or 0) * min_demo_bytes(envs[c.env], envs[c.env].task(0, c.seed, True))
        for c in todo
    )
    count = sum(c.count or 0 for c in todo)
    check_free_space(out, needed, "--out", f"{count} demonstrations")


def _summary_line(summary) -> str:
    text = (
        f"{len(summary.computed)} cells computed, {len(summary.reused)} reused in "
        f"{summary.seconds:.0f} s"
    )
    if summary.failed or summary.blocked:
        text += f"; {len(summary.failed)} failed, {len(summary.blocked)} not run because of them"
    return text
