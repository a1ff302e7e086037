"""Doors' control step against raw MuJoCo and raw mink, and against Cover, in one run.

    python scripts/bench_control_doors.py [--steps 1000] [--grid 3]

As ``bench_control.py`` (same references), on a Doors scene (a ``grid x grid`` floor
plan): the control step here is the base command + the arm's IK + substeps + contact
refresh. Also prints raw substeps of the Cover scene, so the cost of Doors' many wall,
door and obstacle geoms shows as a ratio measured in the same run.
"""

from __future__ import annotations

import argparse
import json
import time

import mink
import mujoco
import numpy as np

from mj_envs.domains.cover.env import CoverEnv
from mj_envs.domains.doors.env import DoorsEnv
from mj_envs.robots.mobile_panda import command_base
from mj_envs.world import POSE_SLICE


def median_us(fn, n: int) -> float:
    times = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        fn(i)
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)


def raw_substeps_us(world, flat, n: int) -> float:
    world.load(flat)
    m, d = world.model, world.data

    def step(_: int) -> None:
        for _ in range(world.substeps):
            mujoco.mj_step(m, d)

    return median_us(step, n)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--grid", type=int, default=3, help="rooms per side of the plan")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    env = DoorsEnv(grid_sizes=(args.grid,))
    task = env.train_tasks(1, seed=0)[0]
    world = task.init.sim.world
    d = world.data
    rng = np.random.default_rng(0)
    actions = rng.uniform(env.action_low, env.action_high, size=(args.steps, 8)) * 0.3

    cover = CoverEnv().train_tasks(1, seed=0)[0].init.sim
    cover_sub = raw_substeps_us(cover.world, cover.flat, args.steps)
    raw_sub = raw_substeps_us(world, task.init.sim.flat, args.steps)

    ctrl = world.controller
    world.load(task.init.sim.flat)
    conf, tasks, limits = ctrl.reference_qp(d, POSE_SLICE)
    cfg = ctrl.config

    def raw_qp(_: int) -> None:
        mink.solve_ik(conf, tasks, cfg.control_dt, cfg.solver, damping=cfg.damping, limits=limits)

    raw_q = median_us(raw_qp, args.steps)

    world.load(task.init.sim.flat)
    base_ids = env._ids(world)["base"]

    def control_step(i: int) -> None:
        a = actions[i]
        command_base(base_ids, d, a[0:3], env.base_config)
        ctrl.apply(d, POSE_SLICE, a[3:6], np.array([0.0, 0.0, a[6]]), a[7])
        world.step_physics()

    ours = median_us(control_step, args.steps)
    state = {"s": task.init}

    def simulate(i: int) -> None:
        state["s"] = env.simulate(state["s"], actions[i])

    full = median_us(simulate, args.steps)
    ref = raw_q + raw_sub
    m = world.model
    result = {
        "grid": args.grid,
        "ngeom": int(m.ngeom),
        "nv": int(m.nv),
        "cover_raw_substeps_us": round(cover_sub, 1),
        "raw_substeps_us": round(raw_sub, 1),
        "raw_qp_us": round(raw_q, 1),
        "control_step_us": round(ours, 1),
        "simulate_us": round(full, 1),
        "ratio_control_step": round(ours / ref, 3),
        "ratio_simulate": round(full / ref, 3),
        "ratio_substeps_vs_cover": round(raw_sub / cover_sub, 3),
    }
    if args.json:
        print(json.dumps(result))
        return
    print(f"Doors {args.grid}x{args.grid}: {m.ngeom} geoms, {m.nv} dofs, {world.substeps} substeps")
    print(f"raw mj_step x substeps, Cover : {cover_sub:8.1f} us")
    print(f"raw mj_step x substeps, Doors : {raw_sub:8.1f} us   {raw_sub / cover_sub:.2f} x Cover")
    print(f"raw mink QP (solve_ik)        : {raw_q:8.1f} us")
    print(f"our control step              : {ours:8.1f} us   ratio {ours / ref:.2f} x")
    print(f"full simulate f(x,u)          : {full:8.1f} us   ratio {full / ref:.2f} x")


if __name__ == "__main__":
    main()
