"""Demonstrations or rollouts as a LeRobot dataset (format v3.0), the layout today's
policy-learning code reads:

    meta/info.json                       fps, features (dtype, shape, names), totals
    meta/tasks.parquet                   one row per task text (the goal), its index
    meta/episodes/chunk-000/file-000.parquet   per episode: length, frame range, tasks,
                                         where its frames and video samples are
    data/chunk-000/file-000.parquet      one row per frame
    videos/observation.images.<camera>/chunk-000/file-000.mp4   every episode in turn

Frame ``t`` of an episode is state ``t`` and the action taken in it (a file's ``k``
actions give ``k`` frames; the last state, which no action follows, is the end). Its
features: ``action`` (float32), ``observation.state`` (float32: every object's features,
``<object>.<feature>``; objects absent from an episode are zeros and
``observation.objects_present`` says which are there), ``observation.sim_state`` (the
exact flat simulator state, float64, zero-padded to the largest scene's; its length in
``observation.sim_state_size``), ``next.done`` and, for rollouts, ``next.success``.

Written with pyarrow and pandas (the ``[lerobot]`` extra); import this module only
where an export is asked for.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import imageio.v2 as imageio
import imageio_ffmpeg
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from bpns.atomic import replace_directory
from bpns.execution.video import VideoError
from bpns.inspect.episodes import Episode

CODEBASE_VERSION = "v3.0"
CHUNK = "chunk-000/file-000"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"


@dataclass(frozen=True)
class ExportOptions:
    fps: int
    cameras: tuple[str, ...] = ()
    width: int = 320
    height: int = 240
    robot_type: str = "franka_panda"


@dataclass(frozen=True)
class Exported:
    directory: Path
    episodes: int
    frames: int
    cameras: tuple[str, ...]


def goal_text(episode: Episode) -> str:
    """The task's text: its goal atoms, e.g. ``Covers(block0, target0) and ...``."""
    atoms = sorted(
        f"{a.predicate.name}({', '.join(o.name for o in a.objects)})"
        for a in episode.demo.task.goal
    )
    return " and ".join(atoms)


def export_lerobot(episodes: Sequence[Episode], out: Path, options: ExportOptions) -> Exported:
    """Write ``episodes`` to the dataset directory ``out`` (built aside, then put in
    place whole: an existing ``out`` is replaced only once the new one is complete)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    build = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        frames = _write(episodes, build, options)
        replace_directory(build, out)
    finally:
        shutil.rmtree(build, ignore_errors=True)  # gone once in place; left by a failure
    return Exported(out, len(episodes), frames, options.cameras)


def _layout(episodes: Sequence[Episode]) -> tuple[list, int]:
    """(every object over the episodes, by name; the largest flat simulator state)."""
    objects: dict[str, object] = {}
    for e in episodes:
        for o in e.demo.states[0].objects:
            objects.setdefault(o.name, o)
    sim = max(len(e.demo.states[0].sim.flat) for e in episodes)
    return [objects[n] for n in sorted(objects)], sim


def _write(episodes: Sequence[Episode], root: Path, options: ExportOptions) -> int:
    objects, sim_size = _layout(episodes)
    tasks = list(dict.fromkeys(goal_text(e) for e in episodes))
    rollouts = any(e.is_rollout for e in episodes)
    tables, rows, start, seconds = [], [], 0, 0.0
    for k, episode in enumerate(episodes):
        table = _frames(episode, k, start, objects, sim_size, tasks, options.fps, rollouts)
        n = table.num_rows
        row = {
            "episode_index": k,
            "tasks": [goal_text(episode)],
            "length": n,
            "data/chunk_index": 0,
            "data/file_index": 0,
            "dataset_from_index": start,
            "dataset_to_index": start + n,
            "meta/episodes/chunk_index": 0,
            "meta/episodes/file_index": 0,
        }
        for camera in options.cameras:
            key = f"videos/observation.images.{camera}"
            row |= {f"{key}/chunk_index": 0, f"{key}/file_index": 0}
            row |= {
                f"{key}/from_timestamp": seconds,
                f"{key}/to_timestamp": seconds + n / options.fps,
            }
        tables.append(table)
        rows.append(row)
        start += n
        seconds += n / options.fps
    data = root / DATA_PATH.format(chunk_index=0, file_index=0)
    data.parent.mkdir(parents=True)
    pq.write_table(pa.concat_tables(tables), data, compression="snappy")
    episodes_file = root / "meta" / "episodes" / f"{CHUNK}.parquet"
    episodes_file.parent.mkdir(parents=True)
    pq.write_table(pa.Table.from_pylist(rows), episodes_file)
    pd.DataFrame({"task_index": range(len(tasks))}, index=tasks).to_parquet(
        root / "meta" / "tasks.parquet"
    )
    for camera in options.cameras:
        _write_video(episodes, root, camera, options)
    info = _info(episodes, objects, sim_size, start, len(tasks), rollouts, options)
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=2) + "\n")
    return start


def _frames(
    episode: Episode,
    k: int,
    start: int,
    objects: list,
    sim_size: int,
    tasks: list[str],
    fps: int,
    rollouts: bool,
) -> pa.Table:
    demo = episode.demo
    n = len(demo.actions)
    states = demo.states[:n]
    present = {o.name for o in demo.states[0].objects}
    state = np.zeros((n, sum(o.type.dim for o in objects)), dtype=np.float32)
    at = 0
    for o in objects:
        if o.name in present:
            state[:, at : at + o.type.dim] = [s.data[o] for s in states]
        at += o.type.dim
    sim = np.zeros((n, sim_size), dtype=np.float64)
    for t, s in enumerate(states):
        sim[t, : len(s.sim.flat)] = s.sim.flat
    done = np.arange(n) == n - 1
    columns = {
        "action": _vectors(np.asarray(demo.actions, dtype=np.float32)),
        "observation.state": _vectors(state),
        "observation.objects_present": _vectors(
            np.tile([o.name in present for o in objects], (n, 1))
        ),
        "observation.sim_state": _vectors(sim),
        "observation.sim_state_size": pa.array(np.full(n, len(states[0].sim.flat), np.int64)),
        "next.done": pa.array(done),
        "timestamp": pa.array(np.arange(n, dtype=np.float32) / fps),
        "frame_index": pa.array(np.arange(n, dtype=np.int64)),
        "episode_index": pa.array(np.full(n, k, dtype=np.int64)),
        "index": pa.array(np.arange(start, start + n, dtype=np.int64)),
        "task_index": pa.array(np.full(n, tasks.index(goal_text(episode)), dtype=np.int64)),
    }
    if rollouts:
        columns["next.success"] = pa.array(done & bool(episode.solved))
    return pa.table(columns)


def _vectors(matrix: np.ndarray) -> pa.FixedSizeListArray:
    values = pa.array(matrix.reshape(-1))
    return pa.FixedSizeListArray.from_arrays(values, matrix.shape[1])


def _write_video(
    episodes: Sequence[Episode], root: Path, camera: str, options: ExportOptions
) -> None:
    """One H.264 stream of every episode in turn, without B-frames and with a key frame
    at each episode's start, so a reader can cut any episode out without transcoding."""
    key = f"observation.images.{camera}"
    path = root / VIDEO_PATH.format(video_key=key, chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True)
    starts, total = [], 0
    for e in episodes:
        starts.append(total / options.fps)
        total += len(e.demo.actions)
    keyframes = ",".join(f"{t:.6f}" for t in starts)
    writer = imageio.get_writer(
        path,
        format="FFMPEG",
        fps=options.fps,
        codec="libx264",
        quality=7,
        macro_block_size=8,
        ffmpeg_log_level="fatal",
        output_params=["-bf", "0", "-force_key_frames", keyframes],
    )
    try:
        for e in episodes:
            states = list(e.demo.states[: len(e.demo.actions)])
            for frame in e.env.render(states, camera, options.width, options.height):
                writer.append_data(frame)
    except (ValueError, RuntimeError) as err:  # e.g. a camera the scene does not have
        if isinstance(err, VideoError):
            raise
        raise VideoError(f"camera {camera}: {err}") from None
    finally:
        writer.close()
    readable, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    if readable != total:
        raise VideoError(f"{path}: {readable} of {total} frames readable after encoding")


def _info(
    episodes: Sequence[Episode],
    objects: list,
    sim_size: int,
    frames: int,
    num_tasks: int,
    rollouts: bool,
    options: ExportOptions,
) -> dict:
    env = episodes[0].env
    action_names = [f"a{i}" for i in range(len(env.action_low))]
    state_names = [f"{o.name}.{f}" for o in objects for f in o.type.feature_names]

    def vector(dtype: str, names: list) -> dict:
        return {"dtype": dtype, "shape": [len(names)], "names": names}

    features = {
        "action": vector("float32", action_names),
        "observation.state": vector("float32", state_names),
        "observation.objects_present": vector("bool", [o.name for o in objects]),
        "observation.sim_state": {"dtype": "float64", "shape": [sim_size], "names": None},
        "observation.sim_state_size": {"dtype": "int64", "shape": [1], "names": None},
        "next.done": {"dtype": "bool", "shape": [1], "names": None},
    }
    if rollouts:
        features["next.success"] = {"dtype": "bool", "shape": [1], "names": None}
    for camera in options.cameras:
        features[f"observation.images.{camera}"] = {
            "dtype": "video",
            "shape": [options.height, options.width, 3],
            "names": ["height", "width", "channels"],
            "info": {
                "video.height": options.height,
                "video.width": options.width,
                "video.codec": "h264",
                "video.pix_fmt": "yuv420p",
                "video.is_depth_map": False,
                "video.fps": options.fps,
                "video.channels": 3,
                "has_audio": False,
            },
        }
    for name, dtype in (("timestamp", "float32"), ("frame_index", "int64")):
        features[name] = {"dtype": dtype, "shape": [1], "names": None}
    for name in ("episode_index", "index", "task_index"):
        features[name] = {"dtype": "int64", "shape": [1], "names": None}
    return {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": options.robot_type,
        "total_episodes": len(episodes),
        "total_frames": frames,
        "total_tasks": num_tasks,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": options.fps,
        "splits": {"train": f"0:{len(episodes)}"},
        "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if options.cameras else None,
        "features": features,
        "bpns": {"env": env.name, "source": "rollouts" if rollouts else "demonstrations"},
    }


def default_fps(episode: Episode) -> int:
    """Frames per second: the control rate, from the scene's simulated times (20 when
    the environment shows no scene)."""
    track = episode.env.scene(episode.demo.states[:2])
    if track is None or len(track) < 2 or not track.times[1] > track.times[0]:
        return 20
    return max(1, round(1.0 / float(track.times[1] - track.times[0])))


def episode_files(root: str | os.PathLike) -> list[Path]:
    """Every file of an exported dataset, relative to ``root`` (for messages, tests)."""
    base = Path(root)
    return sorted(p.relative_to(base) for p in base.rglob("*") if p.is_file())
