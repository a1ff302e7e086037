"""Cost of one control step against raw MuJoCo and raw mink, measured in the same run.

    python scripts/bench_control.py [--steps 2000]

References (same scene, same machine, same run):
  raw_substeps : ``mj_step`` x substeps on the Cover scene (no controller, no Python glue)
  raw_qp       : one ``mink.solve_ik`` call (QP build + daqp solve) at the same configuration
Measured:
  control_step : our IK (controller.apply) + physics substeps + contact refresh
  simulate     : the full transition f(x, u) (state load, control step, feature extraction)
Prints medians in microseconds and ratio = control_step / (raw_qp + raw_substeps).
"""

from __future__ import annotations

import argparse
import json
import time

import mink
import mujoco
import numpy as np

import mj_envs  # noqa: F401
from bpns.env.registry import make_environment as make_env
from mj_envs.world import POSE_SLICE


def median_us(fn, n: int) -> float:
    times = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        fn(i)
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--json", action="store_true", help="print one JSON line only")
    args = parser.parse_args()

    env = make_env("cover")
    task = env.train_tasks(1, seed=0)[0]
    world = task.init.sim.world
    m, d = world.model, world.data
    rng = np.random.default_rng(0)
    actions = rng.uniform(env.action_low, env.action_high, size=(args.steps, 4)) * 0.5

    # raw MuJoCo: substeps of mj_step from the task's initial state
    world.load(task.init.sim.flat)

    def raw_substeps(_: int) -> None:
        for _ in range(world.substeps):
            mujoco.mj_step(m, d)

    raw_sub = median_us(raw_substeps, args.steps)

    # raw mink: the QP our controller solves, at the commanded configuration
    ctrl = world.controller
    world.load(task.init.sim.flat)
    conf, tasks, limits = ctrl.reference_qp(d, POSE_SLICE)

    def raw_qp(_: int) -> None:
        mink.solve_ik(
            conf,
            tasks,
            ctrl.config.control_dt,
            ctrl.config.solver,
            damping=ctrl.config.damping,
            limits=limits,
        )

    raw_q = median_us(raw_qp, args.steps)

    # our control step: IK + substeps + contact refresh
    world.load(task.init.sim.flat)

    def control_step(i: int) -> None:
        a = actions[i]
        ctrl.apply(d, POSE_SLICE, a[:3], None, a[3])
        world.step_physics()

    ours = median_us(control_step, args.steps)

    # the whole transition function
    state = {"s": task.init}

    def simulate(i: int) -> None:
        state["s"] = env.simulate(state["s"], actions[i])

    full = median_us(simulate, args.steps)

    ratio = ours / (raw_q + raw_sub)
    result = {
        "substeps": world.substeps,
        "raw_substeps_us": round(raw_sub, 1),
        "raw_qp_us": round(raw_q, 1),
        "control_step_us": round(ours, 1),
        "simulate_us": round(full, 1),
        "ratio_control_step": round(ratio, 3),
        "ratio_simulate": round(full / (raw_q + raw_sub), 3),
    }
    if args.json:
        print(json.dumps(result))
        return
    print(f"substeps per control step: {world.substeps} (timestep {m.opt.timestep} s)")
    print(f"raw mj_step x substeps : {raw_sub:8.1f} us")
    print(f"raw mink QP (solve_ik) : {raw_q:8.1f} us")
    print(f"our control step       : {ours:8.1f} us   ratio {ratio:.2f} x (target <= 1.5)")
    print(f"full simulate f(x,u)   : {full:8.1f} us   ratio {full / (raw_q + raw_sub):.2f} x")


if __name__ == "__main__":
    main()
