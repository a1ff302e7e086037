"""Where the hand closed on an object: its height above the object's centre at the grasp.

    python scripts/grasp_height.py FILE.h5 [--object stick] [--robot robot] [--limit 50]

``FILE.h5`` is a demonstrations file (``bpns demos``) or an eval's rollouts file (``bpns
eval --out DIR``: ``DIR/rollouts_<approach>.h5``, each row's stored states loaded into
its own world). For each, the first state whose ``--object`` reads ``grasped`` > 0.5 gives the
hand's z minus the object's z; the median and 10th-90th percentiles are printed, and for
a rollouts file one line per row with its outcome and world. A cloned pick that closes
while already rising holds the object higher than its demonstrator did (Stick Button:
docs/WORLDS.md, "Where the failures come from").
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bpns.cli.common import file_env
from bpns.data.datasets import load_demonstrations
from bpns.evaluation.rollout_files import RolloutsFile, is_rollouts_file
from bpns.structs import Demonstration


def grasp_height(demo: Demonstration, robot: str, obj: str) -> float | None:
    """Hand z minus object z at the first step the object is grasped (None: never)."""
    objects = {o.name: o for o in demo.states[0].data}
    r, o = objects[robot], objects[obj]
    for state in demo.states:
        if state.get(o, "grasped") > 0.5:
            return float(state.get(r, "z") - state.get(o, "z"))
    return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("file", type=Path)
    parser.add_argument("--object", default="stick")
    parser.add_argument("--robot", default="robot")
    parser.add_argument("--limit", type=int, default=50, help="the first N rows or demos")
    args = parser.parse_args()
    env = file_env(args.file, None)
    heights = []
    if is_rollouts_file(args.file):
        f = RolloutsFile.read(args.file)
        for row in f.rows[: args.limit]:
            h = grasp_height(f.demonstration(env, row), args.robot, args.object)
            if h is not None:
                heights.append(h)
                print(
                    f"  task {row.task:3d} {'solved' if row.solved else 'FAILED'} "
                    f"{1000 * h:6.1f} mm  ({row.physics.label()})"
                )
    else:
        for demo in load_demonstrations(args.file, env, list(range(args.limit))):
            h = grasp_height(demo, args.robot, args.object)
            if h is not None:
                heights.append(h)
    mm = 1000 * np.array(heights)
    if not len(mm):
        print(f"{args.file}: {args.object} never grasped")
        return
    print(
        f"{args.file}: {len(mm)} grasps of {args.object}; hand above its centre at the grasp: "
        f"median {np.median(mm):.1f} mm [10th-90th percentile {np.percentile(mm, 10):.1f}, "
        f"{np.percentile(mm, 90):.1f}]"
    )


if __name__ == "__main__":
    main()
