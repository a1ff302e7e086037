"""Render states and write frames to mp4 (H.264 via imageio-ffmpeg) or PNG, atomically."""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence

import imageio.v2 as imageio
import numpy as np

from bpns.atomic import atomic_path
from bpns.environment import Environment
from bpns.structs import State


def write_mp4(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: int = 30) -> int:
    n = 0
    with atomic_path(path, ".mp4") as tmp:
        writer = imageio.get_writer(
            tmp,
            format="FFMPEG",
            fps=fps,
            codec="libx264",
            quality=7,
            macro_block_size=8,
            ffmpeg_log_level="error",
        )
        try:
            for frame in frames:
                writer.append_data(frame)
                n += 1
        finally:
            writer.close()
        if n == 0:
            raise ValueError("no frames to write")
    return n


def write_png(path: str | os.PathLike, frame: np.ndarray) -> None:
    with atomic_path(path, ".png") as tmp:
        imageio.imwrite(tmp, frame, format="PNG")


class VideoError(RuntimeError):
    """Rendering or encoding failed (no OpenGL backend, no ffmpeg, a bad camera ...)."""


def render_video(
    env: Environment,
    states: Sequence[State],
    out: str | os.PathLike,
    camera: str = "overview",
    width: int = 640,
    height: int = 480,
    png: str | os.PathLike | None = None,
    control_hz: float = 20.0,
    fps: int = 30,
) -> int:
    """Render ``states`` to a real-time mp4 (frames resampled from the control rate) and
    optionally a PNG of the last frame; returns the number of frames written."""
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
        raise VideoError(str(err)) from None
    return n
