"""Learn skills (and the baselines the approaches need) from a demonstrations file into
a skills directory (``bpns learn``, ``bpns run``)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bpns.baselines.learn import STAGES, learn_baselines, save_baselines
from bpns.data.datasets import count_demonstrations, iter_demonstrations
from bpns.data.demos import Progress, no_progress
from bpns.env.environment import Environment
from bpns.errors import BpnsError
from bpns.learning import learn_skills, save_skills
from bpns.learning.given import given_skills_of

if TYPE_CHECKING:
    from bpns.approaches.base import ApproachEntry
    from bpns.baselines.learn import BaselinesConfig
    from bpns.learning.config import LearningConfig
    from bpns.learning.pipeline import LearnedSkills


class CannotLearnError(BpnsError, ValueError):
    """The demonstrations hold nothing to learn skills from (e.g. no segments)."""


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
    """The baselines (``bpns.baselines.learn.STAGES``) that ``approaches`` plan with,
    to learn beside the skills: an approach's ``learned_stages`` name them; one that
    needs baselines but names none of them (a plugin) gets them all."""
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
    (:mod:`bpns.baselines.learn`); ``workers`` processes train the skills' networks.
    Raises ``bpns.data.datasets.DatasetError`` for a bad
    file and :class:`CannotLearnError` when the demos cannot be learned from."""
    total = count_demonstrations(demos_path)
    n = min(total, limit or total)
    t0 = time.perf_counter()
    loading = iter_demonstrations(demos_path, env, range(n), features_only=True)
    demos = list(progress(loading, n, "load", "demo"))
    load_seconds = time.perf_counter() - t0
    import torch  # deferred: loading and checking the demonstrations needs no torch

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
    learned_baselines = None
    if baselines is not None:  # before saving anything: stopped while they train (the
        # longest stage), the old `out` is left whole, not new skills without baselines
        learned_baselines = learn_baselines(
            demos,
            env.predicates,
            env.types,
            learned,
            baselines,
            report=report,
            given=given_skills_of(env),
        )
    beside = None
    baseline_seconds = None
    if learned_baselines is not None:  # into the new directory before it replaces `out`
        beside = lambda d: save_baselines(learned_baselines, d, env.name)  # noqa: E731
        baseline_seconds = learned_baselines.stage_seconds
    save_skills(learned, out, overwrite=True, env_name=env.name, beside=beside)
    # the segments hold every demonstration's states: not kept through what comes next
    learned = dataclasses.replace(learned, segments=())
    return LearnedRun(learned, env.name, n, load_seconds, out, baseline_seconds)
