"""BPNS vs oracle skills on the same eval tasks: planning time ratio, measured in one run.

    python scripts/bench_planning.py --skills outputs/cover/skills [-n 50] [--workers 1]
    python scripts/bench_planning.py --env cover --demos 100     # collect + learn first

Both approaches plan the same seeded eval tasks with the same planner settings; the
oracle (hand-written operators, samplers and policies) is the reference measured in the
same run, so the printed ratios do not depend on the machine's speed. ``--workers 1``
(the default) keeps the two from competing for cores.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path


def learn_from_fresh_demos(env_name: str, n: int, seed: int, workers: int, out: Path) -> Path:
    from bpns.cli import main as cli

    demos, skills = out / "demos.h5", out / "skills"
    common = ["--seed", str(seed)]
    if cli(
        [
            "demos",
            "--env",
            env_name,
            "-n",
            str(n),
            "--out",
            str(demos),
            "--workers",
            str(workers),
            *common,
        ]
    ):
        sys.exit("collecting demonstrations failed")
    if cli(["learn", str(demos), "--out", str(skills), *common]):
        sys.exit("learning failed")
    return skills


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--skills", type=Path, help="learned skills directory")
    parser.add_argument("--env", default="cover", help="environment (with --demos)")
    parser.add_argument("--demos", type=int, default=100, help="demos to learn from (no --skills)")
    parser.add_argument("-n", "--tasks", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0, help="eval task stream seed")
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args()

    from bpns.evaluation.evaluate import EvalSpec, evaluate, markdown_table
    from bpns.learning.artifacts.learned import load_learned
    from bpns.planning.config import planning_config_for

    with tempfile.TemporaryDirectory() as tmp:
        skills_dir = args.skills or learn_from_fresh_demos(
            args.env, args.demos, args.seed, 2, Path(tmp)
        )
        env, learned = load_learned(skills_dir)
        planning = planning_config_for(env, timeout=args.timeout)
        reports = []
        for approach in ("oracle", "bpns"):
            spec = EvalSpec(env.name, approach, planning, str(skills_dir), task_seed=args.seed)
            t0 = time.perf_counter()
            stats = learned.stats if approach == "bpns" else None
            reports.append(
                evaluate(
                    spec,
                    args.tasks,
                    args.workers,
                    num_demos=stats.num_demos if stats else None,
                    learning_seconds=stats.total_seconds if stats else None,
                )
            )
            print(f"{approach}: {time.perf_counter() - t0:.0f} s wall", file=sys.stderr)
    oracle, bpns = reports
    print(
        f"{env.name}: {args.tasks} eval tasks (seed {args.seed}), timeout {args.timeout:g} s, "
        f"{args.workers} worker(s)\n"
    )
    print(markdown_table(reports))

    def ratio(a: float, b: float) -> str:
        return f"{a / b:.1f}x" if math.isfinite(a) and math.isfinite(b) and b > 0 else "n/a"

    print(
        f"BPNS / oracle planning time: median {ratio(bpns.median_seconds, oracle.median_seconds)}"
        f", mean {ratio(bpns.mean_seconds, oracle.mean_seconds)} (over each one's solved tasks)"
    )
    both = [
        (b.seconds, o.seconds)
        for b, o in zip(bpns.outcomes, oracle.outcomes, strict=True)
        if b.solved and o.solved
    ]
    if both:
        total_b, total_o = sum(b for b, _ in both), sum(o for _, o in both)
        print(f"on the {len(both)} tasks both solved: total time ratio {ratio(total_b, total_o)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
