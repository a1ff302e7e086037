"""``bpns render``: render a demonstration, or an evaluation's rollout, to mp4 (and PNG)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bpns.cli.common import UserError, file_env, nonnegative, path_arg, positive
from bpns.cli.paths import check_output_file, claimed
from bpns.data.datasets import DatasetError, load_demonstrations
from bpns.evaluation.rollout_files import RolloutsFile, is_rollouts_file
from bpns.execution.video import VideoError, default_camera, render_rollout, render_video

HELP = "render a demonstration or an eval rollout (rollouts_<approach>.h5) to mp4 (and PNG)"


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=path_arg, help="demonstration .h5 file, or a rollouts file")
    p.add_argument("--demo", type=nonnegative, default=0, help="index of the demo to render")
    p.add_argument(
        "--task",
        type=nonnegative,
        help="a rollouts file: the eval task whose rollout to render (solved or failed)",
    )
    p.add_argument(
        "--out", type=path_arg, help="output .mp4 (default: demo_<i>.mp4 / task_<i>.mp4)"
    )
    p.add_argument("--png", type=path_arg, help="also write a PNG snapshot of the last frame")
    p.add_argument(
        "--camera",
        help="a camera of the scene (overview, front, top; Doors: follow, closeup, ...) or "
        "'all' (every camera tiled in one frame); default: the environment's",
    )
    p.add_argument("--width", type=positive, default=640)
    p.add_argument("--height", type=positive, default=480)
    p.add_argument("--env", help="environment (default: the one named in the file)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out/--png")


def run(args: argparse.Namespace) -> int:
    env = file_env(args.file, args.env)
    try:
        rollouts = RolloutsFile.read(args.file) if is_rollouts_file(args.file) else None
    except DatasetError as err:
        raise UserError(str(err)) from None
    if rollouts is None and args.task is not None:
        raise UserError(f"{args.file}: --task needs a rollouts file (`bpns eval --out`)")
    if rollouts is not None and args.task is None:
        raise UserError(f"{args.file}: a rollouts file: say which task with --task I")
    name = f"task_{args.task}" if rollouts is not None else f"demo_{args.demo}"
    out = args.out or Path(f"{name}.mp4")
    check_output_file(out, "--out", args.overwrite, [args.file])
    if args.png is not None:
        if args.png == out:
            raise UserError(f"--png {args.png}: the same file as --out")
        check_output_file(args.png, "--png", args.overwrite, [args.file])
        if args.png.suffix != ".png":
            raise UserError(f"--png {args.png}: give a .png name")
    if out.suffix != ".mp4":
        raise UserError(f"--out {out}: give an .mp4 name (the video is H.264 in MP4)")
    with claimed("--out", out, args.png):
        try:
            if rollouts is not None:
                row = rollouts.row(args.task)
                demo = rollouts.demonstration(env, row)
                world = rollouts.environment(env, row)
                n = render_rollout(
                    world,
                    demo.states,
                    row.steps,
                    row.solved,
                    row.reason,
                    out,
                    args.camera,
                    args.width,
                    args.height,
                    args.png,
                    row.physics.label(),
                    row.events,
                )
            else:
                (demo,) = load_demonstrations(args.file, env, [args.demo])
                camera = args.camera or default_camera(env)
                n = render_video(
                    env, list(demo.states), out, camera, args.width, args.height, args.png
                )
        except (DatasetError, VideoError) as err:
            raise UserError(str(err)) from None
    print(f"wrote {out} ({n} frames at 30 fps)" + (f" and {args.png}" if args.png else ""))
    return 0
