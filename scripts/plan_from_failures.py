"""Could anything have recovered? Plan from where each failed rollout ended.

    python scripts/plan_from_failures.py ROLLOUTS.h5 [--skills SKILLS] [--approach bpns oracle]
        [--timeout 30] [--seed 0]

For every failed row of an eval's rollouts file (``bpns eval --out DIR``:
``DIR/rollouts_<approach>.h5``), the world's last state is carried into the nominal
model (as the closed loop carries it when it replans) and each ``--approach`` plans from
there to the task's goal, once, within ``--timeout`` seconds and the task's whole horizon
(not what the rollout left of it: the question is whether any plan starts there). A
state no approach plans from, the oracle's included, is a dead end of the world (a
dropped stick off its holder, a toppled pot); one only the oracle plans from is a limit
of the learned skills; one the learned skills plan from too is the closed loop's to
mend. Nothing is written; one line per failed row goes to stdout.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bpns.approaches.registry import get_approach
from bpns.cli.common import file_env
from bpns.env.abstraction import abstract
from bpns.env.environment import adopt_state, eval_environment
from bpns.evaluation.rollout_files import RolloutsFile
from bpns.planning.config import PlanningConfig
from bpns.structs import Task


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    parser.add_argument("rollouts", type=Path)
    parser.add_argument("--skills", type=Path, help="skills directory (learned approaches)")
    parser.add_argument("--approach", nargs="+", default=["oracle"])
    parser.add_argument("--timeout", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=0, help="seed of subgoal sampling")
    args = parser.parse_args()
    f = RolloutsFile.read(args.rollouts)
    nominal = file_env(args.rollouts, None)  # the environment the file names
    model = eval_environment(nominal, f.eval_set)
    config = PlanningConfig(timeout=args.timeout)
    approaches = {
        name: get_approach(name).make(model, config, args.skills) for name in args.approach
    }
    failed = [r for r in f.rows if not r.solved]
    print(f"{args.rollouts}: {len(failed)} of {len(f.rows)} rows failed")
    solved = dict.fromkeys(approaches, 0)
    for row in failed:
        demo = f.demonstration(nominal, row)  # its stored states, in the row's own world
        last, demo_task = demo.states[-1], demo.task
        init = adopt_state(model, last)
        task = Task(init, demo_task.goal, demo_task.horizon)
        atoms = ", ".join(sorted(str(a) for a in abstract(init, model.predicates)))
        outcomes = []
        for name, approach in approaches.items():
            result = approach.solve(task, np.random.default_rng(args.seed), args.timeout)
            solved[name] += bool(result.success)
            outcomes.append(f"{name}: {'plan' if result.success else result.reason}")
        print(f"  task {row.task} ({row.reason}) from {{{atoms}}}: {'; '.join(outcomes)}")
    counts = ", ".join(f"{n} {k}/{len(failed)}" for n, k in solved.items())
    print(f"planned from the failures' last states: {counts}")


if __name__ == "__main__":
    main()
