"""How often an environment's scripted demonstrator solves train or eval tasks.

    python scripts/demonstrator_success.py --env doors -n 100 --seed 11 [--train]

``bpns demos`` collects train tasks only; this also runs the demonstrator on the eval
stream (same code path: ``bpns.data.demos.run_demonstrator``) and prints the success count and
the demonstrations' lengths.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bpns.data.demos import run_demonstrator
from bpns.env.registry import make_environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", required=True)
    parser.add_argument("-n", "--num", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--train", action="store_true", help="train tasks instead of eval")
    args = parser.parse_args()
    env = make_environment(args.env)
    tasks = (
        env.train_tasks(args.num, args.seed) if args.train else env.eval_tasks(args.num, args.seed)
    )
    t0 = time.perf_counter()
    lengths = []
    for i, task in enumerate(tasks):
        demo = run_demonstrator(env, task, [args.seed, i])
        if demo is not None:
            lengths.append(len(demo.actions))
    kind = "train" if args.train else "eval"
    print(
        f"{args.env}: demonstrator solved {len(lengths)}/{len(tasks)} {kind} tasks "
        f"(seed {args.seed}); steps median {np.median(lengths):.0f}, max {max(lengths)}; "
        f"{time.perf_counter() - t0:.0f} s"
    )


if __name__ == "__main__":
    main()
