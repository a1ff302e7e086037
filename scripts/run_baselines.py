"""Learn the GNN baselines from a demo file + BPNS skills directory, then run GNN Meta,
GNN Meta No Subgoal and GNN BC on eval tasks; prints learning time, peak memory, solved
counts, times, failure reasons and GNN BC's per-call inference cost (numpy vs torch).

    python scripts/run_baselines.py --env cover --demos /tmp/gnn/cover.h5 \
        --skills /tmp/gnn/skills -n 10 --timeout 60

Models are written into the skills directory (gnn_meta.npz, gnn_bc.npz, nosubgoal/) and
read back from there before solving, so the artifact path is exercised too. With
``--reuse`` existing models are loaded instead of learned. ``--train-dist`` also runs
GNN Meta on tasks drawn from the training distribution (the paper's object-count
analysis; a different seed from the demos').
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time
from collections import Counter
from pathlib import Path

import numpy as np


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", required=True)
    parser.add_argument("--demos", type=Path, required=True)
    parser.add_argument("--skills", type=Path, required=True, help="BPNS skills directory")
    parser.add_argument("-n", "--tasks", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0, help="eval task stream seed")
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--reuse", action="store_true", help="load models, do not learn")
    parser.add_argument("--meta-max-steps", type=int, default=None)
    parser.add_argument("--bc-max-steps", type=int, default=None)
    parser.add_argument("--bc-max-examples", type=int, default=None)
    parser.add_argument("--train-dist", action="store_true")
    parser.add_argument(
        "--bc",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="learn and run GNN BC (default: yes)",
    )
    parser.add_argument(
        "--nosubgoal",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="learn No-Subgoal skills too (default: yes)",
    )
    parser.add_argument("--skip", nargs="*", default=(), help="approaches not to run")
    args = parser.parse_args()

    import dataclasses

    from bpns.abstraction import abstract
    from bpns.baselines import solve_with_metacontroller, solve_with_policy
    from bpns.datasets import load_demonstrations
    from bpns.evaluation import plan_reaches_goal
    from bpns.learning.artifacts import load_skills
    from bpns.learning.baselines import (
        NOSUBGOAL_DIR,
        BaselinesConfig,
        learn_baselines,
        save_baselines,
    )
    from bpns.learning.gnn import torch_forward, torch_module
    from bpns.learning.gnn_artifacts import (
        BC_FILE,
        META_FILE,
        load_bc_policy,
        load_metacontroller,
        saved_info,
    )
    from bpns.learning.graphs import batch_graphs, encode_graph
    from bpns.registry import make_environment

    env = make_environment(args.env)
    skills = load_skills(args.skills, env.predicates, env.types)
    if not args.reuse:
        t0 = time.perf_counter()
        demos = load_demonstrations(args.demos, env)
        load_s = time.perf_counter() - t0
        config = BaselinesConfig()
        if args.meta_max_steps is not None:
            config = dataclasses.replace(
                config, meta=dataclasses.replace(config.meta, max_steps=args.meta_max_steps)
            )
        bc = config.bc
        if args.bc_max_steps is not None:
            bc = dataclasses.replace(bc, max_steps=args.bc_max_steps)
        if args.bc_max_examples is not None:
            bc = dataclasses.replace(bc, max_examples=args.bc_max_examples)
        config = dataclasses.replace(config, bc=bc if args.bc else None, nosubgoal=args.nosubgoal)
        print(f"{len(demos)} demos loaded in {load_s:.1f} s; peak RSS {_peak_mb():.0f} MB")
        t0 = time.perf_counter()
        learned = learn_baselines(
            demos, env.predicates, env.types, env.contact_predicates, skills, config, print
        )
        total = time.perf_counter() - t0
        save_baselines(learned, args.skills, env.name)
        print(f"learning: {total:.1f} s in all; per stage {dict(learned.stage_seconds)}")
        print(
            f"  GNN Meta: {learned.meta_stats}; unlabelled segments {learned.meta_skipped_segments}"
        )
        print(f"  GNN BC:   {learned.bc_stats}")
        print(f"  peak RSS of this process so far: {_peak_mb():.0f} MB")
    else:
        for name, kind in ((META_FILE, "gnn-meta"), (BC_FILE, "gnn-bc")):
            if (args.skills / name).is_file():
                print(name, saved_info(args.skills / name, kind).get("stats"))

    meta = load_metacontroller(args.skills / META_FILE, skills.operators, env.predicates, env.types)
    bc_policy = (
        load_bc_policy(args.skills / BC_FILE, env.predicates, env.types) if args.bc else None
    )
    nosub_dir = args.skills / NOSUBGOAL_DIR
    nosub = load_skills(nosub_dir, env.predicates, env.types) if nosub_dir.is_dir() else None

    # per-call inference cost (GNN BC's, every control step): numpy vs the same forward in torch
    if bc_policy is None:
        args.skip = [*args.skip, "gnn-bc"]
    task0 = env.task(0, args.seed, False)
    atoms0 = abstract(task0.init, env.predicates)
    graph = encode_graph(meta.vocab, task0.init, atoms0, task0.goal)
    batch = batch_graphs([graph])

    def timed(fn, n=200):
        times = []
        for _ in range(n):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return statistics.median(times)

    timed_model = bc_policy if bc_policy is not None else meta
    label = "GNN BC" if bc_policy is not None else "GNN Meta"
    t_np = timed(
        lambda: timed_model._net(
            batch_graphs([encode_graph(meta.vocab, task0.init, atoms0, task0.goal)])
        )
    )
    t_net = timed(lambda: timed_model._net(batch))
    net = torch_module(timed_model.params, timed_model.vocab)
    t_torch = timed(lambda: torch_forward(net, timed_model.params, timed_model.vocab, batch))
    t_abs = timed(lambda: abstract(task0.init, env.predicates), 50)
    print(
        f"{label} one call ({len(graph.objects)} nodes, {len(graph.edges)} edges): "
        f"numpy incl. encoding {t_np * 1e6:.0f} us, network only {t_net * 1e6:.0f} us; "
        f"torch float64 forward (module built once, no autograd) {t_torch * 1e6:.0f} us "
        f"= {t_torch / t_net:.1f}x the numpy network; abstraction {t_abs * 1e6:.0f} us"
    )

    runs = []
    if "gnn-meta" not in args.skip:
        runs.append(
            (
                "GNN Meta",
                lambda env, task, rng, dl: solve_with_metacontroller(
                    env, task, rng, dl, meta, skills.skills, env.predicates
                ),
                False,
            )
        )
    if nosub is not None and "gnn-meta-nosubgoal" not in args.skip:
        runs.append(
            (
                "GNN Meta No Subgoal",
                lambda env, task, rng, dl: solve_with_metacontroller(
                    env, task, rng, dl, meta, nosub.skills, env.predicates
                ),
                False,
            )
        )
    if "gnn-bc" not in args.skip:
        runs.append(
            (
                "GNN BC",
                lambda env, task, rng, dl: solve_with_policy(
                    env, task, rng, dl, bc_policy, env.predicates
                ),
                False,
            )
        )
    if args.train_dist and "gnn-meta" not in args.skip:
        runs.append((runs[0][0] + " (train distribution)", runs[0][1], True))

    print("\n| approach | solved | median s (solved) | failures |\n|---|---|---|---|")
    for label, solve, train_dist in runs:
        solved, times, reasons = 0, [], Counter()
        for i in range(args.tasks):
            task = env.task(i, args.seed + 1 if train_dist else args.seed, train_dist)
            rng = np.random.default_rng([args.seed, i])
            t0 = time.perf_counter()
            out = solve(env, task, rng, time.monotonic() + args.timeout)
            seconds = time.perf_counter() - t0
            ok = out.success and plan_reaches_goal(env, task, out.actions)
            if ok:
                solved += 1
                times.append(seconds)
            else:
                reasons[out.reason or "replay_failed"] += 1
        med = f"{statistics.median(times):.1f}" if times else "-"
        print(f"| {label} | {solved}/{args.tasks} | {med} | {dict(reasons)} |", flush=True)
    print(f"\npeak RSS {_peak_mb():.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
