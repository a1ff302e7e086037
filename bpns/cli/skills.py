"""``bpns skills show``: print learned operators readably (or as PDDL)."""

from __future__ import annotations

import argparse

from bpns.cli.common import learned_in, path_arg
from bpns.learning import describe
from bpns.learning.artifacts.pddl import domain_pddl
from bpns.workflow.learn import corrections_note

HELP = "inspect learned skills (`bpns skills show DIR`)"


def configure(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="skills_command", required=True, metavar="ACTION")
    show = sub.add_parser("show", help="print the learned operators, readably")
    show.add_argument("directory", type=path_arg, help="skills directory (from `bpns learn`)")
    show.add_argument("--env", help="environment (default: the one recorded in the skills)")
    show.add_argument("--pddl", action="store_true", help="print the PDDL domain instead")


def run(args: argparse.Namespace) -> int:
    env, learned = learned_in(args.directory, args.env)
    if args.pddl:
        print(domain_pddl(env.name, learned.types, learned.predicates, learned.operators), end="")
    else:
        print(describe(learned))
        note = corrections_note(args.directory)
        if note is not None:
            print(note)
    return 0
