"""What an evaluation leaves behind: one summary line per approach, the results files
(results.json, results.md, plans_<approach>.npz, rollouts_<approach>.h5) and a video of a
task's rollout."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bpns.atomic import atomic_path, remove_stale_temporaries
from bpns.env.environment import Environment, eval_environment, perturbed
from bpns.env.object_counts import EvalSet
from bpns.env.perturbations import Perturbation
from bpns.env.registry import make_environment
from bpns.evaluation.evaluate import EvalReport, TaskOutcome
from bpns.evaluation.rollout_files import demonstration_of, rollouts_name, save_rollouts
from bpns.execution.failures import MEANING
from bpns.execution.rollouts import Rollout
from bpns.execution.video import render_rollout
from bpns.pools import WorkerDiedError, make_pool, result_of


def solved_line(report: EvalReport) -> str:
    """``BPNS: solved 3/4 cover eval tasks (failures: {...})`` ("train tasks" when the
    tasks came from the train distribution, ``bpns eval --train``)."""
    kind = "train" if report.train_tasks else "eval"
    return (
        f"{report.label}: solved {report.num_solved}/{report.num_tasks} "
        f"{report.env} {kind} tasks"
        + ("" if report.eval_set.is_paper else f" (eval set: {report.eval_set.label()})")
        + (f" (failures: {report.failures})" if report.failures else "")
    )


def write_results(
    out: Path, reports: Sequence[EvalReport], table: str, env: Environment | None = None
) -> None:
    """results.json (every report), results.md (``table``) and one plans file per
    approach in ``out`` (created if missing), each written atomically; given ``env``,
    also one rollouts file per approach (:mod:`bpns.evaluation.rollout_files`)."""
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "results.json") as tmp:
        tmp.write_text(json.dumps([r.to_json() for r in reports], indent=2, allow_nan=False) + "\n")
    with atomic_path(out / "results.md") as tmp:
        tmp.write_text(table)
    for r in reports:
        save_plans(out / f"plans_{r.approach}.npz", r)
        if env is not None:
            save_rollouts(out / rollouts_name(r.approach), env, r)


def save_plans(path: str | Path, report: EvalReport) -> None:
    """Actions of every solved task as ``task_<index>`` arrays in one .npz (atomic)."""
    arrays = {f"task_{o.index}": o.actions for o in report.outcomes if o.solved}
    with atomic_path(Path(path)) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)


@dataclass(frozen=True)
class SolvedVideo:
    video: Path
    png: Path
    frames: int
    label: str
    outcome: TaskOutcome

    def lines(self) -> list[str]:
        o = self.outcome
        steps = o.rollout.steps if o.rollout is not None else ()
        if not o.solved:
            return [
                f"wrote {self.video} ({self.frames} frames: {self.label} failing eval task "
                f"{o.index}: {o.reason}) and {self.png}",
                "  furthest attempt: "
                + (", ".join(f"{s.label} {s.outcome}" for s in steps) or "(nothing executed)"),
            ]
        return [
            f"wrote {self.video} ({self.frames} frames: {self.label} solving eval task "
            f"{o.index} in {len(o.actions)} steps) and {self.png}",
            "  plan: " + ", ".join(o.skeleton),
        ]


def explain_lines(report: EvalReport) -> list[str]:
    """Why each failed task failed, readably (``bpns eval --explain``): the abstract plans
    tried and, per step, how many samples succeeded and how many failed and why."""
    lines = []
    seen: set[str] = set()
    for o in report.outcomes:
        if o.solved:
            continue
        e = o.explanation or {}
        seen.update(e.get("failures", {}), [str(o.reason)])
        lines.append(
            f"{report.label}, task {o.index}: {o.reason} after {o.seconds:.1f} s "
            f"({o.samples} samples, {o.sim_steps} simulated steps)"
        )
        if e.get("failures"):
            failures = ", ".join(f"{r} {n}" for r, n in sorted(e["failures"].items()))
            lines.append(f"  failed samples by reason: {failures}")
        if "abstract_plans" in e:
            shown = len(e.get("skeletons", ()))
            more = e["abstract_plans"] - shown
            lines.append(
                f"  {e['abstract_plans']} abstract plans tried"
                + (f" (the first {shown} below)" if more > 0 else "")
                + (": the abstract search found none" if e["abstract_plans"] == 0 else "")
            )
        for k, sk in enumerate(e.get("skeletons", ())):
            lines.append(f"  plan {k + 1} ({sk['reason'] or 'refined'}):")
            steps = sk["steps"]
            active = [i for i, st in enumerate(steps) if st["successes"] or st["failures"]]
            last = active[-1] if active else -1
            for step in steps[: last + 1]:
                failed = ", ".join(f"{r} {n}" for r, n in sorted(step["failures"].items()))
                if not step["successes"] and not failed:
                    lines.append(f"    {step['step']}: refined by an earlier plan (reused)")
                    continue
                lines.append(
                    f"    {step['step']}: {step['successes']} samples reached it"
                    + (f"; failed: {failed}" if failed else "")
                )
            if len(steps) > last + 1:
                lines.append(f"    ({len(steps) - last - 1} later steps not reached)")
        if "executed" in e:
            lines.append(f"  executed: {', '.join(e['executed']) or '(nothing)'}")
            if e.get("failed_step"):
                lines.append(f"  failed at: {e['failed_step']}")
    known = {str(r): text for r, text in MEANING.items()}
    glossary = [f"  {r}: {known[r]}" for r in sorted(seen) if r in known]
    return lines + (["reasons:", *glossary] if glossary else [])


def longest_solved(report: EvalReport) -> TaskOutcome | None:
    """The solved task with the longest abstract plan (the first of ties), or None: the
    longest plan shows the most skills at work."""
    solved = [o for o in report.outcomes if o.solved]
    return max(solved, key=lambda o: len(o.skeleton)) if solved else None


def render_longest_solved(
    env: Environment,
    report: EvalReport,
    video: Path,
    seed: int,
    train: bool,
    task: int | None = None,
    camera: str | None = None,
    deadline: float | None = None,
) -> SolvedVideo | None:
    """Re-simulate :func:`longest_solved` (or the rollout of eval task ``task``, solved
    or failed) from its task's initial state under the report's physics and render it to
    ``video`` with captions and a PNG of its end; None when nothing was solved and no
    task was named. ``camera`` defaults to the environment's; past ``deadline`` (a
    ``time.time()``) rendering stops with ``bpns.execution.video.OutOfTimeError``. Raises
    ``bpns.execution.video.VideoError`` when rendering fails, ValueError for a task not
    evaluated."""
    if task is None:
        outcome = longest_solved(report)
        if outcome is None:
            return None
    else:
        outcome = next((o for o in report.outcomes if o.index == task), None)
        if outcome is None:
            raise ValueError(f"task {task} was not evaluated (tasks 0..{report.num_tasks - 1})")
    png = video.with_suffix(".png")
    # Rendered in a fresh worker: writing the mp4 forks ffmpeg, and a fork of a parent that
    # holds a thousand loaded demonstrations fails with ENOMEM (`bpns run` at 1000 demos).
    with make_pool(1) as pool, _cleared_when_killed(video, png):
        n = result_of(
            pool.submit(
                _render_task,
                env.name,
                outcome.world,
                seed,
                train,
                outcome,
                camera,
                video,
                png,
                report.eval_set,
                deadline,
            ),
            f"the video of task {outcome.index}",
        )
    return SolvedVideo(video, png, n, report.label, outcome)


@contextlib.contextmanager
def _cleared_when_killed(*paths: Path) -> Iterator[None]:
    """A rendering worker killed mid-write leaves its temporaries beside ``paths``
    (a staging directory that would put them in place): remove them."""
    try:
        yield
    except WorkerDiedError:
        for path in paths:
            remove_stale_temporaries(path)
        raise


def _render_task(
    env_name: str,
    physics: Perturbation,
    seed: int,
    train: bool,
    outcome: TaskOutcome,
    camera: str | None,
    video: Path,
    png: Path,
    eval_set: EvalSet,
    deadline: float | None = None,
) -> int:
    """Re-simulate ``outcome``'s rollout from its task of the seeded stream (of
    ``eval_set``) and render it."""
    env = perturbed(eval_environment(make_environment(env_name), eval_set), physics)
    task = env.task(outcome.index, seed, train)
    rollout = outcome.rollout if outcome.rollout is not None else Rollout(outcome.actions)
    demo = demonstration_of(env, task, rollout.actions)
    reason = "" if outcome.solved else str(outcome.reason)
    return render_rollout(
        env,
        demo.states,
        rollout.steps,
        outcome.solved,
        reason,
        video,
        camera,
        png=png,
        physics=physics.label(),
        events=rollout.events,
        deadline=deadline,
    )
