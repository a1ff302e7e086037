"""``bpns check-env NAME``: check an environment's contract, one line per violation.

Exit status 0 when the environment keeps the contract, 1 on violations, 2 on bad input
(an unknown environment name). The checks themselves are :mod:`bpns.workflow.contract`;
``--demo`` also runs the demonstrator and the oracle skills on the first tasks
(:mod:`bpns.workflow.demo_check`), a line each, and exits 1 if any of them fails.
"""

from __future__ import annotations

import argparse
import importlib

from bpns.cli.common import UserError, env_by_name, nonnegative, positive, positive_float
from bpns.workflow.contract import ContractConfig, run_checks
from bpns.workflow.demo_check import check_demonstrations

HELP = "check an environment's contract, one line per violation"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", metavar="NAME", help="environment name (an entry-point name)")
    parser.add_argument("--tasks", type=positive, default=3, help="tasks per stream (default 3)")
    parser.add_argument("--demos", type=positive, default=2, help="demos to collect (default 2)")
    parser.add_argument("--seed", type=nonnegative, default=0)
    parser.add_argument("--no-gym", action="store_true", help="skip Gymnasium's check_env")
    parser.add_argument(
        "--demo",
        action="store_true",
        help="also run the demonstrator on the first --tasks train and eval tasks, and the "
        "oracle skills (where declared) through the planner on those eval tasks: a line "
        "each, saying which phase failed and why",
    )
    parser.add_argument(
        "--timeout",
        type=positive_float,
        default=30.0,
        help="with --demo: seconds the planner may take per oracle plan (default 30)",
    )


def run(args: argparse.Namespace) -> int:
    env = env_by_name(args.name)
    # The Gym ids are registered by the environment's own package on import.
    try:
        importlib.import_module(type(env).__module__.partition(".")[0])
    except ImportError as err:  # pragma: no cover  (the env was just loaded from it)
        raise UserError(f"cannot import the package of {args.name!r}: {err}") from None
    config = ContractConfig(
        n_tasks=args.tasks, seed=args.seed, n_demos=args.demos, gym=not args.no_gym
    )
    report = run_checks(env, config)
    for v in report.violations:
        print(f"violation: {v}")
    for note in report.notes:
        print(f"note: {note}")
    n = len(report.violations)
    checks = len(report.checks)
    if n:
        print(f"{args.name}: {n} violation{'s' * (n != 1)} in {checks} checks")
    else:
        print(f"{args.name}: keeps the contract ({checks} checks passed)")
    failed = 0
    if args.demo:
        demos = check_demonstrations(env, args.tasks, args.seed, args.timeout)
        for line in demos.lines():
            print(line)
        failed = demos.failed
    return 1 if n or failed else 0
