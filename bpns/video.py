"""Write rendered frames to mp4 (H.264 via imageio-ffmpeg) or PNG, atomically."""

from __future__ import annotations

import os
from collections.abc import Iterable

import imageio.v2 as imageio
import numpy as np

from bpns.atomic import atomic_path


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
