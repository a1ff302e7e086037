"""Measure what docs/RESULTS.md reports and rewrite it. Anyone can rerun:

    python scripts/make_results.py [--tasks 200] [--replay 50] [--workers 2]
                                   [--demos 1000] [--learn 100 1000] [--eval-tasks 50]

Sections: the scripted Cover oracle's success in physics on train and eval tasks; exact
replay of saved demonstrations (max |state diff|); the control-step benchmark
(scripts/bench_control.py, ratios against raw MuJoCo and raw mink in the same run);
BPNS learned from the first N of ``--demos`` demonstrations for each N in ``--learn``,
with its ablations and the oracle skills, on the same eval tasks, through the CLI
(`bpns demos/learn/eval`), and the planning benchmark (scripts/bench_planning.py).
Intermediate files go to ``--work`` (default outputs/results); ``--reuse`` keeps
demonstrations already there.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def oracle_rate(env_name: str, n: int, seed: int, train: bool, workers: int) -> tuple[int, float]:
    from bpns.demos import collect_demonstrations

    t0 = time.perf_counter()
    ok = sum(d is not None for _, d in collect_demonstrations(env_name, n, seed, workers, train))
    return ok, time.perf_counter() - t0


def replay_check(env_name: str, n: int, seed: int, workers: int) -> dict:
    from bpns.datasets import load_demonstrations, save_demonstrations
    from bpns.demos import collect_demonstrations, replay
    from bpns.registry import make_environment

    env = make_environment(env_name)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "demos.h5"
        demos = [d for _, d in collect_demonstrations(env_name, n, seed, workers) if d]
        save_demonstrations(path, env, demos)
        loaded = load_demonstrations(path, env)
        reports = [replay(env, d, i) for i, d in enumerate(loaded)]
    return {
        "demos": len(reports),
        "steps": sum(r.steps for r in reports),
        "max_state_diff": max(r.max_state_diff for r in reports),
        "max_feature_diff": max(r.max_feature_diff for r in reports),
        "goal_reached": sum(r.goal_reached for r in reports),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tasks", type=int, default=200)
    parser.add_argument("--replay", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "RESULTS.md")
    parser.add_argument("--demos", type=int, default=1000)
    parser.add_argument("--learn", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--eval-tasks", type=int, default=50)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--work", type=Path, default=ROOT / "outputs" / "results")
    parser.add_argument("--reuse", action="store_true", help="reuse --work/demos.h5")
    args = parser.parse_args()

    import mj_envs  # noqa: F401

    rows = []
    for train in (True, False):
        ok, dt = oracle_rate("cover", args.tasks, args.seed, train, args.workers)
        rows.append((("train" if train else "eval"), ok, args.tasks, dt))
        print(f"oracle cover {rows[-1][0]}: {ok}/{args.tasks} in {dt:.0f} s", flush=True)
    rep = replay_check("cover", args.replay, args.seed + 1, args.workers)
    print(f"replay: {rep}", flush=True)
    bench = json.loads(
        subprocess.run(
            [sys.executable, str(ROOT / "scripts" / "bench_control.py"), "--json"],
            check=True,
            capture_output=True,
            text=True,
        )
        .stdout.strip()
        .splitlines()[-1]
    )
    print(f"bench: {bench}", flush=True)

    learning = learning_results(args)

    cmd = " ".join(
        [
            "python scripts/make_results.py",
            f"--tasks {args.tasks}",
            f"--replay {args.replay}",
            f"--workers {args.workers}",
            f"--demos {args.demos}",
            f"--learn {' '.join(map(str, args.learn))}",
            f"--eval-tasks {args.eval_tasks}",
        ]
    )
    lines = [
        "# Measured results",
        "",
        f"Produced by `{cmd}` (also `make results`) on {platform.node() or 'this machine'}: "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d')}. Every number below was measured by that command; "
        "rerun it to check.",
        "",
        "## Cover: scripted oracle demonstrator in physics",
        "",
        "| tasks | solved | rate | wall time |",
        "|---|---|---|---|",
        *[
            f"| {name} (seed {args.seed}) | {ok}/{n} | {100 * ok / n:.1f} % | {dt:.0f} s "
            f"({args.workers} workers) |"
            for name, ok, n, dt in rows
        ],
        "",
        "## Exact replay of saved demonstrations",
        "",
        f"{rep['demos']} Cover demonstrations ({rep['steps']} control steps) written to HDF5, "
        "loaded back and re-simulated from their first state:",
        "",
        f"- max |flat simulator state difference| = {rep['max_state_diff']:g}",
        f"- max |feature difference| = {rep['max_feature_diff']:g}",
        f"- goal reached on replay: {rep['goal_reached']}/{rep['demos']}",
        "",
        "## One control step vs. raw MuJoCo and raw mink (`scripts/bench_control.py`)",
        "",
        f"Median over 2000 steps; {bench['substeps']} physics substeps per 0.05 s control step.",
        "",
        "| measurement | median (µs) |",
        "|---|---|",
        f"| raw `mj_step` × {bench['substeps']} | {bench['raw_substeps_us']} |",
        f"| raw mink QP (`solve_ik`, daqp) | {bench['raw_qp_us']} |",
        f"| our control step (IK + substeps + contact refresh) | {bench['control_step_us']} |",
        f"| full transition `simulate(x, u)` (state load + step + features) | "
        f"{bench['simulate_us']} |",
        "",
        f"Ratio control step / (raw QP + raw substeps) = **{bench['ratio_control_step']}** "
        f"(target ≤ 1.5); full transition ratio = {bench['ratio_simulate']}.",
        "",
        *learning,
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text("\n".join(lines))
    tmp.replace(args.out)
    print(f"wrote {args.out}")


def bpns(*argv: str) -> str:
    """Run one `bpns` command as a user would; its output, or exit on failure."""
    proc = subprocess.run([sys.executable, "-m", "bpns.cli", *argv], capture_output=True, text=True)
    print(f"$ bpns {' '.join(argv)}\n{proc.stdout}", flush=True)
    if proc.returncode not in (0, 1):
        sys.exit(f"bpns {argv[0]} failed: {proc.stderr.strip()}")
    return proc.stdout


def learning_results(args) -> list[str]:
    from bpns.evaluation import TABLE_HEADER

    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    demos = work / "demos.h5"
    common = ["--seed", str(args.seed), "--workers", str(args.workers)]
    if not (args.reuse and demos.exists()):
        bpns("demos", "--env", "cover", "-n", str(args.demos), "--out", str(demos), *common)
    eval_args = ["-n", str(args.eval_tasks), "--timeout", f"{args.timeout:g}", *common]
    rows, commands, learn_lines = [], [], []
    for i, n in enumerate(args.learn):
        skills = work / f"skills_{n}"
        learn = ["learn", str(demos), "--limit", str(n), "--out", str(skills), "--overwrite"]
        learned = bpns(*learn, "--seed", str(args.seed)).strip().splitlines()
        learn_lines.append(f"- {n} demos: {learned[0].split(' -> ')[0]}")
        approaches = ["bpns", "samples1", "abstract1"] + (["oracle"] if i == 0 else [])
        ev = ["eval", "--skills", str(skills), "--approach", *approaches, "--out"]
        bpns(*ev, str(work / f"eval_{n}"), *eval_args)
        commands += [f"bpns {' '.join(learn)}", f"bpns {' '.join(ev)} {work}/eval_{n} ..."]
        reports = json.loads((work / f"eval_{n}" / "results.json").read_text())
        table = (work / f"eval_{n}" / "results.md").read_text().strip().splitlines()[2:]
        rows += table
        for r in reports:
            print(f"{r['label']} {n}: {r['summary']}", flush=True)
    bench = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts" / "bench_planning.py"),
            "--skills",
            str(work / f"skills_{args.learn[-1]}"),
            "-n",
            str(args.eval_tasks),
            "--timeout",
            f"{args.timeout:g}",
        ],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    print(bench, flush=True)
    rel = lambda p: str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p)  # noqa: E731
    return [
        "## Cover: BPNS learned from demonstrations, solving held-out tasks",
        "",
        f"Demonstrations: `bpns demos --env cover -n {args.demos} --seed {args.seed}` "
        f"(tasks the scripted demonstrator failed are left out). Skills learned from the "
        f"first N of them with `bpns learn --limit N`; each approach then planned the same "
        f"{args.eval_tasks} seeded eval tasks (`bpns eval -n {args.eval_tasks} --seed "
        f"{args.seed} --timeout {args.timeout:g} --workers {args.workers}`). Times are wall "
        "clock per task over solved tasks, measured inside the worker that planned it "
        f"({args.workers} tasks at a time on this machine); nodes created are means over "
        "all tasks; every solved plan was re-simulated and reached its goal.",
        "",
        TABLE_HEADER,
        *rows,
        "",
        "Learning time is the pipeline itself (segment, partition, operators, networks, one "
        "torch thread); reading the HDF5 file comes on top, as `bpns learn` reports:",
        "",
        *learn_lines,
        "",
        "Commands (intermediate files in " + f"`{rel(work)}`):",
        "",
        *[f"    {c.replace(str(ROOT) + '/', '')}" for c in commands],
        "",
        "## Planning time: BPNS vs oracle skills (`scripts/bench_planning.py`)",
        "",
        "Both approaches plan the same eval tasks one at a time, in one run:",
        "",
        *[f"    {line}" for line in bench.splitlines()],
        "",
    ]


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
