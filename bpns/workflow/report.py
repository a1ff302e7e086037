"""What an evaluation leaves for the user: the table, the results files and a video of a
task (the end of ``bpns eval`` and ``bpns run``). Returns a record whose ``lines()`` are
what a command prints; writing nothing to the terminal itself."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bpns.atomic import staged
from bpns.env.environment import Environment
from bpns.errors import BpnsError
from bpns.evaluation.by_world import world_tables
from bpns.evaluation.evaluate import EvalReport, conditions_line, markdown_table
from bpns.evaluation.reporting import SolvedVideo, render_longest_solved, write_results
from bpns.execution.video import VideoError
from bpns.pools import WorkerDiedError
from bpns.workflow.report_page import DEFAULT_PAGE, PageRequest, PageWritten, write_eval_page


class TaskNotEvaluatedError(BpnsError, ValueError):
    """A video of a task that was not among the evaluated ones was asked for."""


@dataclass(frozen=True, eq=False)
class EvaluationReported:
    table: str
    out: Path | None
    video: SolvedVideo | None
    no_video_of: str | None  # the approach whose video was asked for but solved nothing
    page: PageWritten | None = None  # out/report.html

    def lines(self) -> list[str]:
        out = self.table.rstrip("\n").splitlines()
        if self.out is not None:
            out.append(
                f"wrote {self.out / 'results.json'}, {self.out / 'results.md'} "
                "and rollouts_<approach>.h5"
            )
        if self.page is not None:
            out.append(self.page.line())
        if self.video is not None:
            out.extend(self.video.lines())
        return out


def report_evaluation(
    env: Environment,
    reports: Sequence[EvalReport],
    out: Path | None = None,
    video: Path | None = None,
    seed: int = 0,
    train: bool = False,
    task: int | None = None,
    camera: str | None = None,
    page: PageRequest = DEFAULT_PAGE,
) -> EvaluationReported:
    """Write the results files to ``out`` and render a task to ``video`` (each when
    given): ``task`` of the first approach, solved or failed, else the longest solved
    plan of the first approach that solved anything; ``out/report.html`` with the videos
    ``page`` asks for (:mod:`bpns.workflow.report_page`). Raises ``VideoError`` when rendering
    ``video`` fails (after the results are in place, when ``out`` is given: an evaluation
    that took hours is not lost to its video) and :class:`TaskNotEvaluatedError` for a
    task not evaluated."""
    table = conditions_line(reports) + "\n\n" + markdown_table(reports)
    by_world = world_tables(reports)
    if by_world:
        table += "\n" + by_world
    # every file is written under a staging directory and put in place at the end, so
    # that a command stopped while rendering leaves the earlier outputs as they were
    with staged(out) as staging:
        if out is not None:
            write_results(staging.path(out), reports, table, env)
        rendered = None
        no_video_of = None
        video_failed: Exception | None = None
        if video is not None:
            solving = next((r for r in reports if r.num_solved), reports[0])
            if task is not None:
                solving = reports[0]
            try:
                rendered = render_longest_solved(
                    env, solving, staging.path(video), seed, train, task, camera
                )
            except (VideoError, WorkerDiedError) as err:
                if out is None:
                    raise
                video_failed = err  # raised once the results are in place: they stand
            except ValueError as err:
                raise TaskNotEvaluatedError(str(err)) from None
            if rendered is not None:
                rendered = dataclasses.replace(rendered, video=video, png=video.with_suffix(".png"))
            elif video_failed is None:
                no_video_of = solving.label
        written = None
        if out is not None:
            if rendered is not None:  # the page shows it, not a second rendering of it
                key = (solving.approach, rendered.outcome.index)
                page = dataclasses.replace(page, rendered={key: (rendered.video, rendered.png)})
            written = write_eval_page(env, reports, out, table, seed, train, page, staging.path)
    if video_failed is not None:
        raise VideoError(f"{video_failed} (the results were written to {out})")
    return EvaluationReported(table, out, rendered, no_video_of, written)
