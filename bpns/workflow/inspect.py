"""Recordings and datasets a user asks for: ``bpns view``, ``bpns eval --rerun`` and
``bpns export``. The optional extras they need are imported here, only when asked for,
and a missing one is one error naming its pip command (:mod:`bpns.inspect.extras`)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from bpns.atomic import Staging
from bpns.data.datasets import DatasetError, count_demonstrations
from bpns.env.environment import Environment
from bpns.evaluation.evaluate import EvalReport
from bpns.evaluation.reporting import longest_solved
from bpns.evaluation.rollout_files import RolloutsFile, is_rollouts_file
from bpns.inspect.episodes import Episode, episode_of_outcome, read_episode
from bpns.inspect.extras import require

RERUN_TASKS = ("failed", "all")  # what `bpns eval --rerun` records (failed: + the video's)


def _recording() -> ModuleType:
    require("rerun", "a Rerun recording")
    from bpns.inspect import recording  # imports rerun-sdk, an optional extra

    return recording


@dataclass(frozen=True)
class Recorded:
    path: Path
    title: str
    steps: int
    outcome: str
    approach: str = ""
    task: int | None = None  # an eval task's index (None: a demonstration)

    def line(self) -> str:
        return f"wrote {self.path} ({self.title}, {self.outcome}, {self.steps} steps)"


def record_file(
    path: str | os.PathLike,
    env: Environment,
    out: Path,
    task: int | None = None,
    demo: int | None = None,
    cameras: Sequence[str] = (),
    size: tuple[int, int] = (320, 240),
) -> Recorded:
    """A Rerun recording of one episode of a demonstrations or rollouts file."""
    recording = _recording()
    episode = read_episode(path, env, task, demo)
    options = recording.RecordingOptions(tuple(cameras), *size)
    steps = recording.write_recording(episode, out, options)
    task_index = episode.index if episode.is_rollout else None
    return Recorded(out, episode.title, steps, episode.outcome, episode.approach, task_index)


def recording_name(approach: str, task: int) -> str:
    return f"{approach}_task{task}.rrd"


def chosen_outcomes(report: EvalReport, which: str) -> list:
    """The tasks ``bpns eval --rerun`` records: every one (``all``), or the failed ones
    and the solved one ``--video`` shows by default (``failed``)."""
    if which == "all":
        return list(report.outcomes)
    shown = longest_solved(report)
    return [o for o in report.outcomes if not o.solved or o is shown]


def record_evaluation(
    env: Environment,
    reports: Sequence[EvalReport],
    directory: Path,
    which: str = "failed",
    progress: Callable[[str], None] | None = None,
    staging: Staging | None = None,
) -> list[Recorded]:
    """One recording per chosen task and approach in ``directory``; with ``staging``,
    written to its staging directory and put in place when it commits (the
    :class:`Recorded` name the final paths)."""
    recording = _recording()
    out = []
    for report in reports:
        for outcome in chosen_outcomes(report, which):
            episode: Episode = episode_of_outcome(env, report, outcome)
            path = directory / recording_name(report.approach, outcome.index)
            target = path if staging is None else staging.path(path)
            steps = recording.write_recording(episode, target)
            out.append(
                Recorded(
                    path, episode.title, steps, episode.outcome, report.approach, outcome.index
                )
            )
            if progress is not None:
                progress(out[-1].line())
    return out


def _lerobot() -> ModuleType:
    require("pyarrow", "a LeRobot export")
    require("pandas", "a LeRobot export")
    from bpns.inspect import lerobot  # imports pyarrow and pandas, an optional extra

    return lerobot


def file_episodes(path: str | os.PathLike, env: Environment) -> list[Episode]:
    """Every episode of a demonstrations or rollouts file, in the file's order."""
    if is_rollouts_file(path):
        return [read_episode(path, env, task=r.task) for r in RolloutsFile.read(path).rows]
    return [read_episode(path, env, demo=i) for i in range(count_demonstrations(path))]


def export_file(
    path: str | os.PathLike,
    env: Environment,
    out: Path,
    cameras: Sequence[str] = (),
    size: tuple[int, int] = (320, 240),
):
    """``path``'s episodes as a LeRobot v3 dataset in the directory ``out``."""
    lerobot = _lerobot()
    episodes = file_episodes(path, env)
    if not episodes or all(len(e.demo.actions) == 0 for e in episodes):
        raise DatasetError(f"{path}: holds no episode with an action to export")
    episodes = [e for e in episodes if len(e.demo.actions)]
    options = lerobot.ExportOptions(lerobot.default_fps(episodes[0]), tuple(cameras), *size)
    return lerobot.export_lerobot(episodes, out, options)
