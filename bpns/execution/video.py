"""Render states and write frames to mp4 (H.264 via imageio-ffmpeg) or PNG, atomically."""

from __future__ import annotations

import functools
import os
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

import imageio.v2 as imageio
import imageio_ffmpeg
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from bpns.atomic import atomic_path, nearly_full
from bpns.env.environment import Environment
from bpns.errors import BpnsError
from bpns.execution.rollouts import (
    Event,
    PlanStep,
    event_captions,
    outcome_caption,
    step_captions,
)
from bpns.structs import State


class VideoError(BpnsError, RuntimeError):
    """Rendering or encoding failed (no OpenGL backend, no ffmpeg, a bad camera, a full
    disk ...)."""


class OutOfTimeError(VideoError):
    """A video's rendering passed its deadline and was dropped (nothing written)."""


def _until(frames: Iterable[np.ndarray], deadline: float | None) -> Iterator[np.ndarray]:
    """``frames``, stopped with :class:`OutOfTimeError` once ``time.time()`` passes
    ``deadline`` (None: never)."""
    for frame in frames:
        if deadline is not None and time.time() > deadline:
            raise OutOfTimeError("the rendering time budget ran out")
        yield frame


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
    free = nearly_full(path)
    return "" if free is None else f"no space left on the device ({free} bytes free)"


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


def default_camera(env: Environment) -> str:
    """The camera an environment's videos use unless told (its capabilities say)."""
    return env.capabilities.default_camera


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
    captions: Sequence[str] | None = None,
    final_caption: str | None = None,
    deadline: float | None = None,
) -> int:
    """Render ``states`` to a real-time mp4 (frames resampled from the control rate) and
    optionally a PNG of the last frame; returns the number of frames written. Past
    ``deadline`` (a ``time.time()``) it stops with :class:`OutOfTimeError`, writing
    nothing.

    ``captions[i]`` is drawn into the frames of ``states[i]``; ``final_caption`` into the
    last state's frame, held for ``HOLD_SECONDS`` at the end (and in the PNG)."""
    n_frames = max(1, int(len(states) * fps / control_hz))
    index = [min(len(states) - 1, int(i * control_hz / fps)) for i in range(n_frames)]
    picked = [states[i] for i in index]
    try:
        frames = _until(env.render(picked, camera, width, height), deadline)
        if captions is not None or final_caption is not None:
            frames = _captioned(frames, index, captions, final_caption, int(HOLD_SECONDS * fps))
        last = None

        def keep_last():
            nonlocal last
            for f in frames:
                last = f
                yield f

        n = write_mp4(out, keep_last(), fps=fps)
        if png is not None and last is not None:
            write_png(png, last)
    except VideoError:
        raise
    except (RuntimeError, ValueError) as err:
        raise VideoError(str(err)) from None
    return n


HOLD_SECONDS = 1.5


def _captioned(
    frames: Iterable[np.ndarray],
    index: Sequence[int],
    captions: Sequence[str] | None,
    final_caption: str | None,
    hold: int,
) -> Iterator[np.ndarray]:
    last = None
    for frame, i in zip(frames, index, strict=True):
        last = frame
        text = captions[i] if captions is not None else ""
        yield draw_caption(frame, text) if text else frame
    if last is not None and final_caption is not None:
        end = draw_caption(last, final_caption)
        for _ in range(max(1, hold)):
            yield end


#: characters of a caption considered at most; more cannot fit in a frame anyway
MAX_CAPTION_CHARS = 4000


def draw_caption(frame: np.ndarray, text: str, at_top: bool = False) -> np.ndarray:
    """``frame`` with ``text`` in white on a dark band along its bottom (or top; lines
    wrap). Pillow's built-in font: nothing to install. The band covers at most half the
    frame: a caption too long for it (a plan of hundreds of steps) ends in "...". The
    wrapping is computed once per caption, not per frame (a video repeats each one)."""
    h, w = frame.shape[:2]
    size = max(10, min(22, w // 40))
    line_h = size + size // 3
    max_lines = max(1, (h // 2) // line_h)
    lines = _wrapped(text, size, w - 2 * size, max_lines)
    font = _font(size)
    top = size // 4 if at_top else h - line_h * len(lines) - size // 2
    band = frame.copy()
    rows = (
        slice(0, top + line_h * len(lines) + size // 4)
        if at_top
        else slice(max(0, top - size // 4), h)
    )
    band[rows] //= 3  # darken behind the text
    img = Image.fromarray(band)
    draw = ImageDraw.Draw(img)
    for k, line in enumerate(lines):
        draw.text((size // 2, top + k * line_h), line, fill=(255, 255, 255), font=font)
    return np.asarray(img)


@functools.lru_cache(maxsize=8)
def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default(size=size)


@functools.lru_cache(maxsize=256)
def _wrapped(text: str, size: int, width: int, max_lines: int) -> tuple[str, ...]:
    """``text`` wrapped at spaces into lines of at most ``width`` pixels (a word wider
    than that is cut), at most ``max_lines`` of them, the last ending in "..." when
    text was left out."""
    font = _font(size)
    draw = ImageDraw.Draw(Image.new("RGB", (1, 1)))

    def fits(line: str) -> bool:
        return draw.textlength(line, font=font) <= width

    lines: list[str] = []
    clipped = len(text) > MAX_CAPTION_CHARS
    for paragraph in text[:MAX_CAPTION_CHARS].split("\n"):
        line = ""
        for word in paragraph.split(" "):
            while word and not fits(word):  # cut a word wider than a line
                cut = max(1, _longest_fitting_prefix(word, fits))
                if line:
                    lines.append(line)
                    line = ""
                lines.append(word[:cut])
                word = word[cut:]
            trial = f"{line} {word}".strip()
            if line and not fits(trial):
                lines.append(line)
                line = word
            else:
                line = trial
            if len(lines) > max_lines:
                break
        lines.append(line)
        if len(lines) > max_lines:
            break
    if len(lines) > max_lines or clipped:
        lines = lines[:max_lines]
        last = lines[-1]
        while last and not fits(last + " ..."):
            last = last[:-1]
        lines[-1] = last + " ..."
    return tuple(lines)


def _longest_fitting_prefix(word: str, fits: Callable[[str], bool]) -> int:
    lo, hi = 0, len(word)  # fits(word[:lo]) holds, fits(word[:hi + 1]) does not
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if fits(word[:mid]):
            lo = mid
        else:
            hi = mid - 1
    return lo


def render_rollout(
    env: Environment,
    states: Sequence[State],
    steps: Sequence[PlanStep],
    solved: bool,
    reason: str,
    out: str | os.PathLike,
    camera: str | None = None,
    width: int = 640,
    height: int = 480,
    png: str | os.PathLike | None = None,
    physics: str = "",
    events: Sequence[Event] = (),
    deadline: float | None = None,
) -> int:
    """A rollout's video: each frame captioned with its skill and objects (and, for a
    while after each, the execution monitor's events: "replan 1: expected Holding(block0)
    did not hold"), the last held with the outcome or the failure reason (``physics``:
    the perturbation, if any)."""
    return render_video(
        env,
        states,
        out,
        camera or default_camera(env),
        width,
        height,
        png,
        captions=event_captions(step_captions(steps, len(states)), events),
        final_caption=outcome_caption(solved, reason, steps, len(states) - 1, physics),
        deadline=deadline,
    )
