"""The end of ``bpns eval --out DIR``: ``DIR/report.html`` with the videos it shows.

Videos of the chosen tasks (``failed``: every failed task and the solved one with the
longest plan, per approach; ``all``; ``none``) are rendered into ``DIR/videos/`` one by
one until the time budget is spent; the page says which were left out and how to render
them. A machine that cannot render (no OSMesa) still gets the page, without videos.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bpns.env.environment import Environment
from bpns.evaluation.evaluate import EvalReport
from bpns.evaluation.reporting import render_longest_solved
from bpns.execution.video import OutOfTimeError, VideoError
from bpns.inspect.html_report import PageMedia, relative_link, write_page
from bpns.pools import WorkerDiedError
from bpns.workflow.inspect import Recorded, chosen_outcomes

REPORT_VIDEOS = ("failed", "all", "none")
VIDEO_DIR = "videos"


@dataclass(frozen=True)
class PageRequest:
    """What report.html shows: which tasks' videos, rendered for at most ``budget``
    seconds, and the recordings written (``bpns eval --rerun``)."""

    videos: str = "failed"
    budget: float = 60.0
    camera: str | None = None
    recordings: tuple[Recorded, ...] = ()
    # videos already rendered (bpns eval --video): (approach, task) -> (mp4, png)
    rendered: Mapping[tuple[str, int], tuple[Path, Path]] = field(default_factory=dict)


DEFAULT_PAGE = PageRequest()


@dataclass(frozen=True)
class PageWritten:
    path: Path
    videos: int
    left_out: int

    def line(self) -> str:
        more = f", {self.left_out} left out (time budget)" if self.left_out else ""
        videos = f"{self.videos} video" + ("" if self.videos == 1 else "s")
        return f"wrote {self.path} ({videos}{more}; opens offline in a browser)"


def video_name(approach: str, task: int) -> str:
    return f"{approach}_task{task}.mp4"


def write_eval_page(
    env: Environment,
    reports: Sequence[EvalReport],
    out: Path,
    table: str,
    seed: int,
    train: bool,
    request: PageRequest = DEFAULT_PAGE,
    place: Callable[[Path], Path] = lambda path: path,
) -> PageWritten:
    """Render the chosen videos (within the budget) and write ``out/report.html``, each
    file to ``place(its path)`` (a staging directory: links are made to the path)."""
    videos, posters, notes = {}, {}, []
    wanted = (
        []
        if request.videos == "none"
        else [(r, o) for r in reports for o in chosen_outcomes(r, request.videos)]
    )
    started = time.monotonic()
    done = 0
    for (approach, index), (video, png) in request.rendered.items():
        videos[(approach, index)] = relative_link(video, out)
        posters[(approach, index)] = relative_link(png, out)
    for report, outcome in wanted:
        key = (report.approach, outcome.index)
        if key in videos:
            done += 1
            continue
        if time.monotonic() - started >= request.budget:
            break
        path = out / VIDEO_DIR / video_name(report.approach, outcome.index)
        deadline = time.time() + request.budget - (time.monotonic() - started)
        try:
            render_longest_solved(
                env, report, place(path), seed, train, outcome.index, request.camera, deadline
            )
        except OutOfTimeError:  # a long rollout: stopped at the budget, not after it
            break
        except (VideoError, WorkerDiedError) as err:  # the results stand without videos
            notes.append(f"videos not rendered: {err}")
            break
        videos[key] = relative_link(path, out)
        posters[key] = relative_link(path.with_suffix(".png"), out)
        done += 1
    left_out = len(wanted) - done if not notes else 0
    if left_out:
        notes.append(
            f"{left_out} videos left out after {request.budget:g} s of rendering "
            "(--report-video-budget); `bpns render ROLLOUTS --task I` renders any task"
        )
    recordings = {
        (r.approach, r.task): relative_link(r.path, out)
        for r in request.recordings
        if r.task is not None
    }
    media = PageMedia(videos, posters, recordings, tuple(notes))
    written = write_page(place(out), reports, table, media)
    return PageWritten(out / written.name, done, left_out)
