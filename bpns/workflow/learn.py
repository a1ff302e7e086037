"""Learn skills (and the baselines the approaches need) from a demonstrations file into
a skills directory (``bpns learn``, ``bpns run``)."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from bpns.baselines.learn import STAGES, learn_baselines, save_baselines
from bpns.data.datasets import count_demonstrations, iter_demonstrations, task_origins
from bpns.data.demos import Progress, no_progress
from bpns.env.environment import Environment
from bpns.errors import BpnsError
from bpns.learning import learn_skills, save_skills
from bpns.learning.corrections import (
    CorrectionConfig,
    DemoOrigin,
    RoundReport,
    improve_with_corrections,
)
from bpns.learning.given import given_skills_of

if TYPE_CHECKING:
    from bpns.approaches.base import ApproachEntry
    from bpns.baselines.learn import BaselinesConfig
    from bpns.learning.config import LearningConfig
    from bpns.learning.pipeline import LearnedSkills


#: what the policies were corrected with, beside the skills (``bpns learn --corrections``)
CORRECTIONS_RECORD = "corrections.json"


def corrections_note(directory: Path) -> str | None:
    """One line on the corrections the policies in ``directory`` were retrained on
    (``CORRECTIONS_RECORD``), None when they were not; a record that cannot be read
    says so instead of failing (it describes the skills, it does not define them)."""
    path = Path(directory) / CORRECTIONS_RECORD
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
        rounds = [r for r in record["per_round"] if r.get("retrained", True)]
        total = sum(int(n) for n in rounds[-1]["corrections"].values()) if rounds else 0
        kept = [i for i, r in enumerate(record["per_round"]) if r.get("kept")]
        which = ""
        if kept:
            which = f"; kept round {kept[0]}'s policies" if kept[0] else "; kept the plain ones"
        return (
            f"policies retrained on {total} corrections by the {record['expert']} in "
            f"{record['worlds']} worlds over {len(rounds)} round(s){which} ({CORRECTIONS_RECORD})"
        )
    except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError) as err:
        return f"{path}: unreadable record of corrections ({type(err).__name__})"


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
    corrections: tuple[RoundReport, ...] = ()  # per round, when corrections were asked for

    def lines(self) -> list[str]:
        stats = self.learned.stats
        assert stats is not None
        out = [
            f"learned {len(self.learned.skills)} skills from {self.num_demos} demonstrations "
            f"of {self.env_name} in {stats.total_seconds:.1f} s (+{self.load_seconds:.1f} s "
            f"loading) -> {self.out}",
            f"  {stats}",
        ]
        out.extend(f"  {r.line(k)}" for k, r in enumerate(self.corrections, 1))
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
    corrections: CorrectionConfig | None = None,
) -> LearnedRun:
    """Learn skills from the first ``limit`` (default: all) demonstrations of
    ``demos_path`` and save them to ``out`` (replacing it); with ``baselines`` also the
    paper's baselines from the same demonstrations, saved beside them
    (:mod:`bpns.baselines.learn`); ``workers`` processes train the skills' networks.
    With ``corrections`` the policies are then retrained on the expert's corrections in
    those worlds (:mod:`bpns.learning.corrections`; the file must record its tasks'
    origins), recorded in ``out/corrections.json``. Raises
    ``bpns.data.datasets.DatasetError`` for a bad file and :class:`CannotLearnError`
    when the demos cannot be learned from."""
    total = count_demonstrations(demos_path)
    n = min(total, limit or total)
    origins = None
    if corrections is not None:  # checked before anything is learned
        origins = [DemoOrigin(seed, index) for seed, index in task_origins(demos_path)[:n]]
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
    rounds: tuple[RoundReport, ...] = ()
    if corrections is not None and origins is not None:

        def demo_states(i: int):  # with simulator state, for an oracle that reads the scene
            (demo,) = iter_demonstrations(demos_path, env, [i])
            return demo.states

        learned, rounds = improve_with_corrections(
            env, learned, origins, corrections, workers, report, demo_states
        )
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
    baseline_seconds = None
    if learned_baselines is not None:
        baseline_seconds = learned_baselines.stage_seconds

    def beside(directory: Path) -> None:  # into the new directory before it replaces `out`
        if learned_baselines is not None:
            save_baselines(learned_baselines, directory, env.name)
        if corrections is not None:
            record = {**corrections.to_json(), "per_round": [r.to_json() for r in rounds]}
            (directory / CORRECTIONS_RECORD).write_text(json.dumps(record, indent=2) + "\n")

    save_skills(learned, out, overwrite=True, env_name=env.name, beside=beside)
    # the segments hold every demonstration's states: not kept through what comes next
    learned = dataclasses.replace(learned, segments=())
    return LearnedRun(learned, env.name, n, load_seconds, out, baseline_seconds, rounds)
