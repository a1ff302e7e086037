"""Render states and write frames to mp4 (H.264 via imageio-ffmpeg) or PNG, atomically."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterable, Sequence
from pathlib import Path

import imageio.v2 as imageio
import imageio_ffmpeg
import numpy as np

from bpns.atomic import atomic_path
from bpns.environment import Environment
from bpns.structs import State


class VideoError(RuntimeError):
    """Rendering or encoding failed (no OpenGL backend, no ffmpeg, a bad camera, a full
    disk ...)."""


def write_mp4(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: int = 30) -> int:
    """Encode ``frames`` to ``path``; returns how many. The file appears only once ffmpeg
    finished it and it reads back whole: ffmpeg itself exits quietly on a write error
    (a full disk) and would leave a truncated mp4 behind."""
    n = 0
    try:
        with atomic_path(path, ".mp4") as tmp:
            writer = imageio.get_writer(
                tmp,
                format="FFMPEG",
                fps=fps,
                codec="libx264",
                quality=7,
                macro_block_size=8,
                ffmpeg_log_level="fatal",  # its errors are ours to report (one line)
            )
            try:
                for frame in frames:
                    writer.append_data(frame)
                    n += 1
            finally:
                writer.close()
            if n == 0:
                raise ValueError("no frames to write")
            _check_complete(tmp, n, Path(path))
    except OSError as err:  # e.g. the pipe to an ffmpeg that died of a full disk
        raise VideoError(f"cannot write {path}: {_reason(err, Path(path))}") from None
    return n


def _reason(err: OSError, path: Path) -> str:
    if err.errno is not None and err.strerror:
        return err.strerror
    return _space_note(path) or str(err).strip().splitlines()[0]


def _space_note(path: Path) -> str:
    try:
        free = shutil.disk_usage(path.parent).free
    except OSError:
        return ""
    return f"no space left on the device ({free} bytes free)" if free < 1 << 20 else ""


def _check_complete(tmp: Path, n: int, path: Path) -> None:
    try:
        readable, _ = imageio_ffmpeg.count_frames_and_secs(str(tmp))
    except (RuntimeError, OSError):
        readable = 0
    if readable != n:
        why = _space_note(path) or "ffmpeg did not finish it"
        raise VideoError(f"cannot write {path}: {readable} of {n} frames readable: {why}")


def write_png(path: str | os.PathLike, frame: np.ndarray) -> None:
    try:
        with atomic_path(path, ".png") as tmp:
            imageio.imwrite(tmp, frame, format="PNG")
    except OSError as err:
        raise VideoError(f"cannot write {path}: {_reason(err, Path(path))}") from None


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
