"""``bpns export``: demonstrations or eval rollouts as a LeRobot (v3) dataset."""

from __future__ import annotations

import argparse

from bpns.cli.common import UserError, file_env, path_arg, positive
from bpns.cli.paths import check_output_dir, claimed, writing
from bpns.execution.video import default_camera
from bpns.workflow.inspect import export_file

HELP = (
    "export demonstrations or eval rollouts as a LeRobot v3 dataset (parquet frames, an "
    "mp4 per camera, meta/; pip install 'bpns[lerobot]')"
)
FORMATS = ("lerobot",)


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=path_arg, help="demonstration .h5 file, or a rollouts file")
    p.add_argument("--format", choices=FORMATS, default="lerobot", help="dataset format")
    p.add_argument("--out", type=path_arg, required=True, help="output dataset directory")
    p.add_argument(
        "--camera",
        nargs="+",
        help="cameras to render a video of (default: the environment's camera)",
    )
    p.add_argument("--no-videos", action="store_true", help="frames only, no camera videos")
    p.add_argument("--width", type=positive, default=320)
    p.add_argument("--height", type=positive, default=240)
    p.add_argument("--env", help="environment (default: the one named in the file)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing dataset")


def run(args: argparse.Namespace) -> int:
    env = file_env(args.file, args.env)
    out = args.out
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a directory")
    if out.exists() and any(out.iterdir()):
        if not (out / "meta" / "info.json").is_file():
            raise UserError(f"--out {out}: exists and is not a dataset; refusing to replace it")
        if not args.overwrite:
            raise UserError(f"--out {out}: exists; pass --overwrite to replace it")
    if out.exists() and args.file.resolve().is_relative_to(out.resolve()):
        raise UserError(f"--out {out}: holds this command's input; refusing to replace it")
    check_output_dir(out, "--out")
    if args.no_videos and args.camera:
        raise UserError("--no-videos and --camera: choose one")
    cameras = [] if args.no_videos else list(args.camera or [default_camera(env)])
    with claimed("--out", out), writing(out, "--out"):
        exported = export_file(args.file, env, out, cameras, (args.width, args.height))
    videos = f", videos of {', '.join(exported.cameras)}" if exported.cameras else ""
    print(
        f"wrote {out} (LeRobot v3: {exported.episodes} episodes, {exported.frames} frames{videos})"
    )
    return 0
