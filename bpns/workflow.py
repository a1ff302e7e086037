"""The pipeline's steps as library functions: collect demonstrations into a file, learn
skills into a directory (checking that demonstrations replay exactly is a data check:
:func:`bpns.data.demos.check_replay`).

The ``bpns`` commands and ``bpns run`` (which chains them) call these; each returns a
small record whose ``lines()`` are what the command prints, so one step reports the
same way whichever command ran it.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bpns.data.demos import Progress, no_progress
from bpns.env.environment import Environment

if TYPE_CHECKING:
    from bpns.approaches.base import ApproachEntry
    from bpns.learning.baselines import BaselinesConfig
    from bpns.learning.config import LearningConfig
    from bpns.learning.pipeline import LearnedSkills


class CannotLearnError(ValueError):
    """The demonstrations hold nothing to learn skills from (e.g. no segments)."""


# -- demonstrations -----------------------------------------------------------------------
@dataclass(frozen=True)
class DemosWritten:
    path: Path
    env_name: str
    num_written: int
    failed: tuple[int, ...]  # task indices the demonstrator failed on
    seconds: float
    why: tuple[str, ...] = ()  # for each failed task: why (DemoAttempt.explain)
    noise: float = 0.0  # DART noise scale the demonstrations were collected with

    def lines(self) -> list[str]:
        noisy = f" (DART noise {self.noise:g})" if self.noise else ""
        out = [
            f"wrote {self.num_written} demonstrations of {self.env_name}{noisy} to {self.path} "
            f"in {self.seconds:.1f} s"
            + (f"; the demonstrator failed on tasks {list(self.failed)}" if self.failed else "")
        ]
        for index, why in zip(self.failed, self.why, strict=False):
            out.append(f"  task {index}: {why}")
        return out


def collect_demos(
    env: Environment,
    num: int,
    seed: int,
    out: Path,
    workers: int = 1,
    progress: Progress = no_progress,
    debug: bool = False,
    noise: float | None = None,
) -> DemosWritten:
    """Run the scripted demonstrator on train tasks 0..num-1 and save the successes; say
    why each failure failed (with ``debug``: its traceback and last abstract states).
    ``noise``: DART noise scale (:class:`bpns.data.demo_attempts.ActionNoise`); None: the
    environment's declared one. Raises :class:`bpns.atomic.NotEnoughSpaceError`, before
    collecting any, when ``num`` demonstrations cannot fit on ``out``'s disk."""
    from bpns.atomic import require_free_space
    from bpns.data.datasets import min_demo_bytes, save_demonstrations
    from bpns.data.demo_attempts import demo_noise_of
    from bpns.data.demos import collect_attempts

    # a lower bound per demonstration: more than the disk holds is certain not to fit
    needed = num * min_demo_bytes(env, env.task(0, seed, True))
    require_free_space(out, needed, f"{num} demonstrations")

    failed: list[int] = []
    why: list[str] = []
    t0 = time.perf_counter()
    noise = demo_noise_of(env) if noise is None else noise

    def successful():
        for index, attempt in progress(
            collect_attempts(env.name, num, seed, workers, noise=noise),
            num,
            f"demos {env.name}",
            "task",
        ):
            if attempt.demo is None:
                failed.append(index)
                why.append(attempt.explain(debug))
            else:
                yield attempt.demo

    n = save_demonstrations(out, env, successful())
    return DemosWritten(
        out, env.name, n, tuple(failed), time.perf_counter() - t0, tuple(why), noise
    )


# -- learning -----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class LearnedRun:
    learned: LearnedSkills
    env_name: str
    num_demos: int
    load_seconds: float
    out: Path
    baseline_seconds: tuple[tuple[str, float], ...] | None = None  # per baseline learned

    def lines(self) -> list[str]:
        stats = self.learned.stats
        assert stats is not None
        out = [
            f"learned {len(self.learned.skills)} skills from {self.num_demos} demonstrations "
            f"of {self.env_name} in {stats.total_seconds:.1f} s (+{self.load_seconds:.1f} s "
            f"loading) -> {self.out}",
            f"  {stats}",
        ]
        if self.baseline_seconds is not None:
            out.append(
                "  baselines: "
                + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in self.baseline_seconds)
            )
        return out


def baselines_needed(approaches: Iterable[ApproachEntry]) -> tuple[str, ...]:
    """The baselines (``bpns.learning.baselines.STAGES``) that ``approaches`` plan with,
    to learn beside the skills: an approach's ``learned_stages`` name them; one that
    needs baselines but names none of them (a plugin) gets them all."""
    from bpns.learning.baselines import STAGES

    needed: set[str] = set()
    for entry in approaches:
        if entry.needs_baselines:
            named = set(entry.learned_stages or ()) & set(STAGES)
            needed |= named or set(STAGES)
    return tuple(s for s in STAGES if s in needed)


def learn_to_directory(
    env: Environment,
    demos_path: Path,
    out: Path,
    config: LearningConfig,
    limit: int | None = None,
    threads: int = 1,
    progress: Progress = no_progress,
    report: Callable[[str], None] | None = None,
    baselines: BaselinesConfig | None = None,
    workers: int = 1,
) -> LearnedRun:
    """Learn skills from the first ``limit`` (default: all) demonstrations of
    ``demos_path`` and save them to ``out`` (replacing it); with ``baselines`` also the
    paper's baselines from the same demonstrations, saved beside them
    (:mod:`bpns.learning.baselines`); ``workers`` processes train the skills' networks.
    Raises ``bpns.data.datasets.DatasetError`` for a bad
    file and :class:`CannotLearnError` when the demos cannot be learned from."""
    from bpns.data.datasets import count_demonstrations, iter_demonstrations
    from bpns.learning import learn_skills, save_skills
    from bpns.learning.given import given_skills_of

    total = count_demonstrations(demos_path)
    n = min(total, limit or total)
    t0 = time.perf_counter()
    loading = iter_demonstrations(demos_path, env, range(n), features_only=True)
    demos = list(progress(loading, n, "load", "demo"))
    load_seconds = time.perf_counter() - t0
    import torch

    torch.set_num_threads(threads)
    try:
        learned = learn_skills(
            demos,
            env.predicates,
            env.contact_predicates,
            config,
            report,
            given_skills_of(env),
            workers=workers,
        )
    except ValueError as err:
        raise CannotLearnError(f"cannot learn from {demos_path}: {err}") from None
    save_skills(learned, out, overwrite=True, env_name=env.name)
    baseline_seconds = None
    if baselines is not None:
        from bpns.learning.baselines import learn_baselines_into

        # after the skills: saving them replaces `out`
        baseline_seconds = learn_baselines_into(out, env, demos, learned, baselines, report)
    # the segments hold every demonstration's states: not kept through what comes next
    learned = dataclasses.replace(learned, segments=())
    return LearnedRun(learned, env.name, n, load_seconds, out, baseline_seconds)
