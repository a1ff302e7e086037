"""The ``bpns`` command line: demos, replay, render, learn, eval, run, skills.

Every command reports bad input (missing/corrupt files, unknown environments, bad
arguments) as one ``bpns: error: ...`` line and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from bpns.commands import COMMANDS, UserError


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

__all__ = ["main", "build_parser", "Path"]
