"""``bpns render``: render a demonstration to mp4 (and PNG)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bpns.cli.common import UserError, file_env, nonnegative, path_arg, positive
from bpns.cli.paths import check_output_file

HELP = "render a demonstration to mp4 (and PNG)"


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=path_arg, help="demonstration .h5 file")
    p.add_argument("--demo", type=nonnegative, default=0, help="index of the demo to render")
    p.add_argument("--out", type=path_arg, help="output .mp4 (default: demo_<i>.mp4)")
    p.add_argument("--png", type=path_arg, help="also write a PNG snapshot of the last frame")
    p.add_argument("--camera", default="overview")
    p.add_argument("--width", type=positive, default=640)
    p.add_argument("--height", type=positive, default=480)
    p.add_argument("--env", help="environment (default: the one named in the file)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out/--png")


def run(args: argparse.Namespace) -> int:
    from bpns.datasets import DatasetError, load_demonstrations
    from bpns.video import VideoError, render_video

    out = args.out or Path(f"demo_{args.demo}.mp4")
    check_output_file(out, "--out", args.overwrite, [args.file])
    if args.png is not None:
        if args.png == out:
            raise UserError(f"--png {args.png}: the same file as --out")
        check_output_file(args.png, "--png", args.overwrite, [args.file])
    env = file_env(args.file, args.env)
    try:
        (demo,) = load_demonstrations(args.file, env, [args.demo])
    except DatasetError as err:
        raise UserError(str(err)) from None
    try:
        n = render_video(
            env, list(demo.states), out, args.camera, args.width, args.height, args.png
        )
    except VideoError as err:
        raise UserError(str(err)) from None
    print(f"wrote {out} ({n} frames at 30 fps)" + (f" and {args.png}" if args.png else ""))
    return 0
