"""Doors' control step against raw MuJoCo and raw mink, and against Cover, in one run.

    python scripts/bench_control_doors.py [--steps 1000] [--grid 3]
    python scripts/bench_control_doors.py --section docs/results/doors_control.md

``--section`` measures 2x2, 3x3 and 5x5 plans and writes a docs/RESULTS.md section
(rebuild the file with ``python scripts/make_results.py --assemble-only``).

As ``bench_control.py`` (same references), on a Doors scene (a ``grid x grid`` floor
plan): the control step here is the base command + the arm's IK + substeps + contact
refresh. Also prints raw substeps of the Cover scene, so the cost of Doors' many wall,
door and obstacle geoms shows as a ratio measured in the same run.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

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
    parser.add_argument("--section", type=Path, help="write a RESULTS.md section here")
    args = parser.parse_args()
    if args.section is not None:
        write_section(args.section, args.steps)
        return
    result = measure(args.grid, args.steps)
    if args.json:
        print(json.dumps(result))
        return
    print(f"Doors {args.grid}x{args.grid}: {result['ngeom']} geoms, {result['nv']} dofs")
    for key, value in result.items():
        print(f"  {key}: {value}")


def write_section(path: Path, steps: int) -> None:
    rows = [measure(grid, steps) for grid in (2, 3, 5)]
    lines = [
        "### Doors: one control step vs. raw MuJoCo and raw mink",
        "",
        f"Produced by `python scripts/bench_control_doors.py --section {path} --steps {steps}` "
        f"on {platform.node()}: {platform.machine()}, Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d')}. Medians over {steps} steps of one task per plan size; "
        "the control step is the base command + the arm's IK + the physics substeps + the "
        "contact refresh; references measured in the same run.",
        "",
        "| plan | geoms | raw substeps vs Cover's | control step (µs) | "
        "control step / (raw QP + raw substeps) | full simulate / (raw QP + raw substeps) |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['grid']}x{r['grid']} | {r['ngeom']} | {r['ratio_substeps_vs_cover']:.2f} | "
            f"{r['control_step_us']:.0f} | {r['ratio_control_step']:.2f} | "
            f"{r['ratio_simulate']:.2f} |"
        )
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)
    print(f"wrote {path}")


def measure(grid: int, steps: int) -> dict:
    """Medians (µs) and ratios of one Doors plan of ``grid`` x ``grid`` rooms."""

    env = DoorsEnv(grid_sizes=(grid,))
    task = env.train_tasks(1, seed=0)[0]
    world = task.init.sim.world
    d = world.data
    rng = np.random.default_rng(0)
    actions = rng.uniform(env.action_low, env.action_high, size=(steps, 8)) * 0.3

    cover = CoverEnv().train_tasks(1, seed=0)[0].init.sim
    cover_sub = raw_substeps_us(cover.world, cover.flat, steps)
    raw_sub = raw_substeps_us(world, task.init.sim.flat, steps)

    ctrl = world.controller
    world.load(task.init.sim.flat)
    conf, tasks, limits = ctrl.reference_qp(d, POSE_SLICE)
    cfg = ctrl.config

    def raw_qp(_: int) -> None:
        mink.solve_ik(conf, tasks, cfg.control_dt, cfg.solver, damping=cfg.damping, limits=limits)

    raw_q = median_us(raw_qp, steps)

    world.load(task.init.sim.flat)
    base_ids = env._ids(world)["base"]

    def control_step(i: int) -> None:
        a = actions[i]
        command_base(base_ids, d, a[0:3], env.base_config)
        ctrl.apply(d, POSE_SLICE, a[3:6], np.array([0.0, 0.0, a[6]]), a[7])
        world.step_physics()

    ours = median_us(control_step, steps)
    state = {"s": task.init}

    def simulate(i: int) -> None:
        state["s"] = env.simulate(state["s"], actions[i])

    full = median_us(simulate, steps)
    ref = raw_q + raw_sub
    m = world.model
    result = {
        "grid": grid,
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
    return result


if __name__ == "__main__":
    main()
