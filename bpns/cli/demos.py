"""``bpns demos``: collect demonstrations with the scripted oracle."""

from __future__ import annotations

import argparse

from bpns.cli.common import (
    UserError,
    default_workers,
    env_by_name,
    nonnegative,
    nonnegative_float,
    path_arg,
    positive,
    print_lines,
    progress,
)
from bpns.cli.paths import capped_to_cores, check_output_file, claimed, writing
from bpns.env.environment import perturbed
from bpns.env.perturbations import PerturbationError
from bpns.env.worlds import parse_world
from bpns.workflow import collect_demos

HELP = "collect demonstrations with the scripted oracle"


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", required=True, help="environment name (e.g. cover)")
    p.add_argument("-n", "--num", type=positive, default=10, help="number of train tasks")
    p.add_argument("--seed", type=nonnegative, default=0)
    p.add_argument("--out", required=True, type=path_arg, help="output .h5 file")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    p.add_argument("--workers", type=positive, default=default_workers())
    p.add_argument(
        "--noise",
        type=nonnegative_float,
        help="DART noise injection: execute the demonstrator's action plus Gaussian noise "
        "of NOISE times each action dimension's half range, and record its clean commands "
        "for imitation (default: the environment's; 0: plain demonstrations, as in the paper)",
    )
    p.add_argument(
        "--perturb",
        nargs="+",
        metavar="PRESET|NAME=VALUE",
        default=[],
        help="demonstrate each task in its own perturbed world, drawn per task as "
        "`bpns eval --perturb` draws them, from --seed (a preset: moderate, hard; or "
        "NAME=VALUE items); "
        "stored per demonstration, so replay stays exact (default: nominal physics)",
    )
    p.add_argument(
        "--debug",
        action="store_true",
        help="for each failed demonstration also print its traceback and last abstract states",
    )


def run(args: argparse.Namespace) -> int:
    env = env_by_name(args.env)
    try:
        worlds = parse_world(args.perturb).seeded(args.seed)  # other seeds, other worlds
        perturbed(env, worlds.draw(0))  # an environment without perturbations says so now
    except PerturbationError as err:
        raise UserError(f"--perturb: {err}") from None
    check_output_file(args.out, "--out", args.overwrite)
    workers = capped_to_cores(args.workers, "--workers")
    with claimed("--out", args.out), writing(args.out, "--out"):  # too many demos: refused first
        written = collect_demos(
            env,
            args.num,
            args.seed,
            args.out,
            workers,
            progress,
            debug=args.debug,
            noise=args.noise,
            worlds=worlds,
        )
    print_lines(written)
    return 0 if written.num_written else 1
