"""``bpns replay``: re-simulate demonstrations and report any divergence."""

from __future__ import annotations

import argparse

from bpns.cli.common import UserError, file_env, path_arg, positive, print_lines, progress
from bpns.data.datasets import DatasetError
from bpns.data.demos import check_replay
from bpns.evaluation.rollout_files import is_rollouts_file, replay_rollouts

HELP = "re-simulate demonstrations (or an eval's rollouts) and report any divergence"


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=path_arg, help="demonstration .h5 file, or a rollouts file")
    p.add_argument("--env", help="environment (default: the one named in the file)")
    p.add_argument("--limit", type=positive, help="replay only the first N demos")


def run(args: argparse.Namespace) -> int:
    env = file_env(args.file, args.env)
    try:
        if is_rollouts_file(args.file):  # under the physics they ran under
            checked = replay_rollouts(env, args.file, args.limit)
        else:
            checked = check_replay(env, args.file, args.limit, progress)
    except DatasetError as err:
        raise UserError(str(err)) from None
    print_lines(checked)
    return 0 if checked.ok else 1
