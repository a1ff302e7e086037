"""``bpns view``: a demonstration or an eval rollout as a Rerun recording (.rrd)."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

from bpns.cli.common import UserError, file_env, nonnegative, path_arg, positive
from bpns.cli.paths import check_output_file, claimed, writing
from bpns.execution.video import default_camera
from bpns.workflow.inspect import record_file

HELP = (
    "write a Rerun recording (.rrd) of a demonstration or an eval rollout: the 3D scene, "
    "every ground atom, the skills and their outcomes (pip install 'bpns[viz]')"
)


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=path_arg, help="demonstration .h5 file, or a rollouts file")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--task", type=nonnegative, help="a rollouts file: the eval task")
    which.add_argument("--demo", type=nonnegative, help="a demonstration file: its index (0)")
    p.add_argument(
        "--out", type=path_arg, help="output .rrd (default: demo_<i>.rrd / task_<i>.rrd)"
    )
    p.add_argument(
        "--images", action="store_true", help="also record camera images (the env's camera)"
    )
    p.add_argument(
        "--camera",
        nargs="+",
        help="record these cameras' images (implies --images); 'all' tiles every camera",
    )
    p.add_argument(
        "--width", type=positive, help="camera image width (with --images; default: 320)"
    )
    p.add_argument(
        "--height", type=positive, help="camera image height (with --images; default: 240)"
    )
    p.add_argument("--env", help="environment (default: the one named in the file)")
    p.add_argument(
        "--open",
        action="store_true",
        help="open the recording in the Rerun viewer when a display is available",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")


def run(args: argparse.Namespace) -> int:
    env = file_env(args.file, args.env)
    if args.out is not None and args.out.suffix != ".rrd":
        raise UserError(f"--out {args.out}: give a .rrd name (a Rerun recording)")
    name = f"task_{args.task}" if args.task is not None else f"demo_{args.demo or 0}"
    out = args.out or Path(f"{name}.rrd")
    check_output_file(out, "--out", args.overwrite, [args.file])
    cameras = list(args.camera or ([default_camera(env)] if args.images else []))
    if not cameras and (args.width is not None or args.height is not None):
        raise UserError(
            "--width and --height size the camera images: pass --images or --camera too"
        )
    size = (args.width or 320, args.height or 240)
    with claimed("--out", out), writing(out, "--out"):
        recorded = record_file(args.file, env, out, args.task, args.demo, cameras, size)
    print(recorded.line())
    if args.open:
        _open(out)
    return 0


def _open(path: Path) -> None:
    """Start the Rerun viewer on ``path`` where there is a display; else say how."""
    viewer = shutil.which("rerun")
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or viewer is None:
        print(f"no display here: open it elsewhere with `rerun {path}`", file=sys.stderr)
        return
    subprocess.Popen([viewer, str(path)], start_new_session=True)  # the viewer outlives us
