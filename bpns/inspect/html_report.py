"""``report.html``: an evaluation a browser opens offline, from the folder it sits in.

One self-contained page (inline CSS and a few lines of inline JavaScript, no fonts,
scripts or styles fetched from anywhere): the results table, then per approach every
task with its outcome, failure reason, plan (the skills executed and how each ended),
its video where one was rendered, and links to the rollouts file, the Rerun recording
and the results files, all relative to the page.
"""

from __future__ import annotations

import html
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from bpns.atomic import atomic_path
from bpns.evaluation.by_world import SPLIT_CAPTION, report_columns, world_split
from bpns.evaluation.evaluate import EvalReport, TaskOutcome, conditions_line
from bpns.evaluation.rollout_files import rollouts_name
from bpns.execution.rollouts import REACHED
from bpns.inspect.explain import explanation_lines

PAGE = "report.html"

_CSS = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 2em; color: #222; background: #fafafa; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 2em; }
table { border-collapse: collapse; background: #fff; margin: 0.5em 0; }
th, td { border: 1px solid #ccc; padding: 4px 8px; text-align: left; vertical-align: top; }
th { background: #eee; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.solved { color: #176b2c; font-weight: 600; } .failed { color: #a11; font-weight: 600; }
.step-failed { color: #a11; } video { width: 320px; display: block; }
details { margin-top: 0.3em; } pre { margin: 0.2em 0; white-space: pre-wrap; }
.note { color: #666; } .toolbar { margin: 0.5em 0; }
"""

_JS = """
function showOnlyFailed(on) {
  document.querySelectorAll('tr.task.solved-row').forEach(function (row) {
    row.style.display = on ? 'none' : '';
  });
}
"""


@dataclass(frozen=True)
class PageMedia:
    """What the page can show of each (approach, task): paths relative to its folder."""

    videos: Mapping[tuple[str, int], str] = field(default_factory=dict)
    posters: Mapping[tuple[str, int], str] = field(default_factory=dict)
    recordings: Mapping[tuple[str, int], str] = field(default_factory=dict)
    notes: Sequence[str] = ()  # e.g. videos left out for the time budget


def relative_link(target: Path, page_dir: Path) -> str:
    """``target`` as a link from a page in ``page_dir`` (forward slashes, URL-quoted)."""
    rel = os.path.relpath(Path(target).resolve(), Path(page_dir).resolve())
    return "/".join(quote(part) for part in Path(rel).parts)


def write_page(out: Path, reports: Sequence[EvalReport], table: str, media: PageMedia) -> Path:
    """Write ``out/report.html`` atomically; returns its path."""
    path = out / PAGE
    body = [
        "<h1>" + _esc(_title(reports)) + "</h1>",
        f"<p>{_esc(conditions_line(reports))}</p>",
        _summary_table(reports),
        _world_split(reports),
        '<p class="toolbar"><label><input type="checkbox" id="only-failed" '
        'onchange="showOnlyFailed(this.checked)"> show failed tasks only</label></p>',
        '<p>Files: <a href="results.json">results.json</a> · '
        '<a href="results.md">results.md</a></p>',
    ]
    body += [f'<p class="note">{_esc(n)}</p>' for n in media.notes]
    for report in reports:
        body.append(_approach_section(report, media))
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{_esc(_title(reports))}</title><style>{_CSS}</style>"
        f"<script>{_JS}</script></head><body>\n" + "\n".join(body) + "\n</body></html>\n"
    )
    with atomic_path(path) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return path


def _esc(text: object) -> str:
    return html.escape(str(text), quote=True)


def _title(reports: Sequence[EvalReport]) -> str:
    first = reports[0]
    kind = "train" if first.train_tasks else "eval"
    return f"bpns evaluation: {first.env}, {first.num_tasks} {kind} tasks (seed {first.task_seed})"


def _num(x: float | None, fmt: str) -> str:
    return "–" if x is None or not math.isfinite(x) else format(x, fmt)


def _world_split(reports: Sequence[EvalReport]) -> str:
    """The results split by the world each task met (nothing for nominal tasks)."""
    split = world_split(report_columns(reports))
    if split is None:
        return ""
    head = "".join(f"<th>{_esc(h)}</th>" for h in split.headings)
    rows = [f"<tr><th>World parameter</th><th>Range</th>{head}</tr>"]
    for parameter, label, cells in split.rows:
        tds = "".join(f'<td class="num">{_esc(c)}</td>' for c in cells)
        rows.append(f"<tr><td>{_esc(parameter)}</td><td>{_esc(label)}</td>{tds}</tr>")
    return f'<p>{_esc(SPLIT_CAPTION)}:</p><table class="world-split">' + "".join(rows) + "</table>"


def _summary_table(reports: Sequence[EvalReport]) -> str:
    rows = [
        "<tr><th>Approach</th><th>Demos</th><th>Solved</th><th>Median time (s)</th>"
        "<th>Mean time (s)</th><th>Median agent time (s)</th><th>Median agent CPU (s)</th>"
        "<th>Nodes created</th>"
        "<th>Sim steps / plan step</th>"
        "<th>Failures</th></tr>"
    ]
    for r in reports:
        failures = ", ".join(f"{k} {v}" for k, v in sorted(r.failures.items())) or "–"
        rows.append(
            f'<tr class="approach"><td><a href="#{_esc(r.approach)}">{_esc(r.label)}</a></td>'
            f'<td class="num">{_esc(r.num_demos if r.num_demos is not None else "–")}</td>'
            f'<td class="num">{r.num_solved}/{r.num_tasks} ({r.solved_percent:.1f}%)</td>'
            f'<td class="num">{_num(r.median_seconds, ".2f")}</td>'
            f'<td class="num">{_num(r.mean_seconds, ".2f")}</td>'
            f'<td class="num">{_num(r.median_agent_seconds, ".2f")}</td>'
            f'<td class="num">{_num(r.median_agent_cpu_seconds, ".2f")}</td>'
            f'<td class="num">{r.mean_nodes:.1f}</td>'
            f'<td class="num">{_num(r.median_sim_steps_per_step, ".1f")}</td>'
            f"<td>{_esc(failures)}</td></tr>"
        )
    return '<table id="results">' + "".join(rows) + "</table>"


def _approach_section(report: EvalReport, media: PageMedia) -> str:
    rollouts = rollouts_name(report.approach)
    head = (
        f'<h2 id="{_esc(report.approach)}">{_esc(report.label)}: '
        f"{report.num_solved}/{report.num_tasks} solved</h2>"
        f'<p>Rollouts of every task: <a href="{_esc(rollouts)}">{_esc(rollouts)}</a> '
        f"(<code>bpns replay</code>, <code>bpns render --task I</code>, "
        f"<code>bpns view --task I</code>)</p>"
    )
    rows = [
        "<tr><th>Task</th><th>Outcome</th><th>Plan</th><th>Time (s)</th><th>Samples</th>"
        "<th>Video</th><th>Recording</th></tr>"
    ]
    rows += [_task_row(report, o, media) for o in report.outcomes]
    return (
        head
        + f'<table class="tasks" data-approach="{_esc(report.approach)}">'
        + "".join(rows)
        + "</table>"
    )


def _task_row(report: EvalReport, o: TaskOutcome, media: PageMedia) -> str:
    key = (report.approach, o.index)
    outcome = (
        '<span class="solved">solved</span>'
        if o.solved
        else f'<span class="failed">failed</span>: {_esc(o.reason)}'
    )
    if not o.solved:
        lines = "\n".join(explanation_lines(o.explanation))
        outcome += (
            f"<details><summary>what the planner tried</summary><pre>{_esc(lines)}</pre></details>"
        )
    events = o.rollout.events if o.rollout is not None else ()
    if events:
        text = "\n".join(f"before action {e.at}: {e.kind}: {e.text}" for e in events)
        outcome += (
            f"<details><summary>execution monitor: {len(events)} events, {o.replans} "
            f"replans</summary><pre>{_esc(text)}</pre></details>"
        )
    video = '<span class="note">not rendered</span>'
    if key in media.videos:
        poster = f' poster="{media.posters[key]}"' if key in media.posters else ""
        video = (
            f'<video controls muted preload="metadata" src="{media.videos[key]}"{poster}></video>'
            f'<a href="{media.videos[key]}">mp4</a>'
        )
    recording = f'<a href="{media.recordings[key]}">.rrd</a>' if key in media.recordings else "–"
    css = "task solved-row" if o.solved else "task failed-row"
    return (
        f'<tr class="{css}" id="{_esc(report.approach)}-task{o.index}">'
        f'<td class="num">{o.index}</td><td>{outcome}</td><td>{_plan(o)}</td>'
        f'<td class="num">{o.seconds:.2f}</td><td class="num">{o.samples}</td>'
        f"<td>{video}</td><td>{recording}</td></tr>"
    )


def _plan(o: TaskOutcome) -> str:
    steps = o.rollout.steps if o.rollout is not None else ()
    if not steps:
        return (
            _esc(", ".join(o.skeleton))
            if o.skeleton
            else '<span class="note">(nothing executed)</span>'
        )
    items = []
    for s in steps:
        css = "" if s.outcome == REACHED else ' class="step-failed"'
        suffix = "" if s.outcome == REACHED else f" → {s.outcome}"
        items.append(f"<li{css}>{_esc(s.label + suffix)}</li>")
    return "<ol>" + "".join(items) + "</ol>"
