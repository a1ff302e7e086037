"""``bpns demos``, ``bpns replay`` and ``bpns render``: demonstrations and their videos."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from bpns.cli_common import UserError, env_by_name, file_env, positive, progress
from bpns.datasets import DatasetError


# -- demos ------------------------------------------------------------------------------
def demos_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env", required=True, help="environment name (e.g. cover)")
    p.add_argument("-n", "--num", type=positive, default=10, help="number of train tasks")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, type=Path, help="output .h5 file")
    p.add_argument("--workers", type=positive, default=max(1, (os.cpu_count() or 1)))


def cmd_demos(args: argparse.Namespace) -> int:
    from bpns.datasets import save_demonstrations
    from bpns.demos import collect_demonstrations

    env = env_by_name(args.env)
    failed: list[int] = []
    t0 = time.perf_counter()

    def successful():
        for index, demo in progress(
            collect_demonstrations(env.name, args.num, args.seed, args.workers),
            args.num,
            f"demos {env.name}",
        ):
            if demo is None:
                failed.append(index)
            else:
                yield demo

    n = save_demonstrations(args.out, env, successful())
    dt = time.perf_counter() - t0
    print(
        f"wrote {n} demonstrations of {env.name} to {args.out} in {dt:.1f} s"
        + (f"; the demonstrator failed on tasks {failed}" if failed else "")
    )
    return 0 if n else 1


# -- replay -----------------------------------------------------------------------------
def replay_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="demonstration .h5 file")
    p.add_argument("--env", help="environment (default: the one named in the file)")
    p.add_argument("--limit", type=positive, help="replay only the first N demos")


def cmd_replay(args: argparse.Namespace) -> int:
    from bpns.datasets import count_demonstrations, iter_demonstrations
    from bpns.demos import replay

    env = file_env(args.file, args.env)
    try:
        total = count_demonstrations(args.file)
        n = min(total, args.limit or total)
        reports = [
            replay(env, d, i)
            for i, d in enumerate(
                progress(iter_demonstrations(args.file, env, range(n)), n, "replay")
            )
        ]
    except DatasetError as err:
        raise UserError(str(err)) from None
    bad = [r for r in reports if not r.exact or not r.goal_reached]
    worst = max((r.max_state_diff for r in reports), default=0.0)
    print(
        f"replayed {len(reports)} demonstrations ({sum(r.steps for r in reports)} steps): "
        f"max |state diff| = {worst:.3g}, "
        f"{len(reports) - len(bad)}/{len(reports)} exact and reaching their goal"
    )
    for r in bad:
        print(
            f"  demo_{r.demo}: max state diff {r.max_state_diff:.3g}, feature diff "
            f"{r.max_feature_diff:.3g}, goal {'reached' if r.goal_reached else 'NOT reached'}"
        )
    return 0 if not bad else 1


# -- render -----------------------------------------------------------------------------
def render_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="demonstration .h5 file")
    p.add_argument("--demo", type=int, default=0, help="index of the demo to render")
    p.add_argument("--out", type=Path, help="output .mp4 (default: demo_<i>.mp4)")
    p.add_argument("--png", type=Path, help="also write a PNG snapshot of the last frame")
    p.add_argument("--camera", default="overview")
    p.add_argument("--width", type=positive, default=640)
    p.add_argument("--height", type=positive, default=480)
    p.add_argument("--env", help="environment (default: the one named in the file)")


def cmd_render(args: argparse.Namespace) -> int:
    from bpns.datasets import load_demonstrations

    env = file_env(args.file, args.env)
    try:
        (demo,) = load_demonstrations(args.file, env, [args.demo])
    except DatasetError as err:
        raise UserError(str(err)) from None
    out = args.out or Path(f"demo_{args.demo}.mp4")
    n = render_video(env, list(demo.states), out, args.camera, args.width, args.height, args.png)
    print(f"wrote {out} ({n} frames at 30 fps)" + (f" and {args.png}" if args.png else ""))
    return 0


def render_video(
    env,
    states,
    out: Path,
    camera: str,
    width: int,
    height: int,
    png: Path | None = None,
    control_hz: float = 20.0,
    fps: int = 30,
) -> int:
    """Render ``states`` to a real-time mp4 (frames resampled from the control rate)."""
    from bpns.video import write_mp4, write_png

    n_frames = max(1, int(len(states) * fps / control_hz))
    picked = [states[min(len(states) - 1, int(i * control_hz / fps))] for i in range(n_frames)]
    try:
        frames = env.render(picked, camera, width, height)
        last = None

        def keep_last():
            nonlocal last
            for f in frames:
                last = f
                yield f

        n = write_mp4(out, keep_last(), fps=fps)
        if png is not None and last is not None:
            write_png(png, last)
    except (RuntimeError, ValueError) as err:
        raise UserError(str(err)) from None
    return n
