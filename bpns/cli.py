"""The ``bpns`` command line: demos, replay, render, learn, eval, run, skills.

Every command reports bad input (missing/corrupt files, unknown environments, bad
arguments) as one ``bpns: error: ...`` line and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from bpns import check_env_cli, commands, commands_learning
from bpns.cli_common import UserError

# name -> (help, configure the argument parser, run)
COMMANDS: dict[str, tuple[str, Callable, Callable]] = {
    "demos": (
        "collect demonstrations with the scripted oracle",
        commands.demos_args,
        commands.cmd_demos,
    ),
    "replay": (
        "re-simulate demonstrations and report any divergence",
        commands.replay_args,
        commands.cmd_replay,
    ),
    "render": (
        "render a demonstration to mp4 (and PNG)",
        commands.render_args,
        commands.cmd_render,
    ),
    "learn": (
        "learn neuro-symbolic skills from demonstrations",
        commands_learning.learn_args,
        commands_learning.cmd_learn,
    ),
    "skills": (
        "inspect learned skills (`bpns skills show DIR`)",
        commands_learning.skills_args,
        commands_learning.cmd_skills,
    ),
    "eval": (
        "solve held-out tasks by bilevel planning; results JSON + markdown table",
        commands_learning.eval_args,
        commands_learning.cmd_eval,
    ),
    "run": (
        "the whole pipeline: demos -> learn -> eval -> table -> video",
        commands_learning.run_args,
        commands_learning.cmd_run,
    ),
    "check-env": (
        "check an environment's contract, one line per violation",
        check_env_cli.configure,
        check_env_cli.run,
    ),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bpns",
        description="Bilevel planning with learned neuro-symbolic skills on a MuJoCo Panda.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (help_, configure, _) in COMMANDS.items():
        configure(sub.add_parser(name, help=help_, description=help_))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _, _, run = COMMANDS[args.command]
    try:
        return int(run(args) or 0)
    except UserError as err:
        print(f"bpns: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("bpns: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

__all__ = ["COMMANDS", "main", "build_parser", "Path"]
