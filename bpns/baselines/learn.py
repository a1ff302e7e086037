"""Learn the paper's baselines from the same demonstrations as BPNS, once.

- GNN Meta / GNN Meta No Subgoal: one metacontroller, labelled with the operators BPNS
  learned (``skills``); the No-Subgoal variant runs it with No-Subgoal skills, whose
  operators are the same (operator learning does not depend on subgoals).
- BPNS No Subgoal: skills learned with ``use_subgoals=False`` from the BPNS skills'
  segments (same segmentation, operators and policy networks, policies without subgoal
  input, no samplers).
- GNN BC: a GNN policy trained on (subsampled) demonstrated steps.

:func:`save_baselines` writes them into a skills directory: ``gnn_meta.npz``,
``gnn_bc.npz`` and ``nosubgoal/`` (a nested skills directory written by
:func:`~bpns.learning.artifacts.skills_dir.save_skills`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bpns.baselines.files import (
    BC_FILE,
    KIND_BC,
    KIND_META,
    META_FILE,
    save_bc_policy,
    save_metacontroller,
    saved_info,
)
from bpns.baselines.gnn import GNNConfig, GNNTrainingStats
from bpns.baselines.gnn_bc import GNNPolicy, bc_examples, train_bc_policy
from bpns.baselines.gnn_meta import GNNMetacontroller, metacontroller_examples, train_metacontroller
from bpns.baselines.graphs import GraphVocabulary
from bpns.learning.artifacts.skills_dir import save_skills
from bpns.learning.given import GivenSkill
from bpns.learning.pipeline import LearnedSkills, learn_from_segments
from bpns.structs import Demonstration, Predicate, Type

NOSUBGOAL_DIR = "nosubgoal"
#: the baselines' stage names (keys of ``LearnedBaselines.stage_seconds``, and the names
#: approaches list in ``ApproachEntry.learned_stages``)
STAGES = ("gnn_meta", "gnn_bc", "nosubgoal")


@dataclass(frozen=True)
class BaselinesConfig:
    """Which baselines to learn and how.

    Defaults keep each GNN within a few minutes per domain at 1000 demonstrations on
    one core: the metacontroller trains the paper's 1000 epochs up to 20000 gradient
    steps; BC trains on at most 20000 demonstrated steps (seeded subsample; every step
    of 1000 demonstrations would be ~10^5-10^6 graphs) for at most 20000 steps.
    """

    meta: GNNConfig | None = field(default_factory=GNNConfig)
    bc: GNNConfig | None = field(
        default_factory=lambda: GNNConfig(max_examples=20000, max_steps=20000)
    )
    nosubgoal: bool = True
    #: seed of both GNNs (initial weights, batches, BC's subsample), replacing theirs;
    #: None: the BPNS skills' learning seed, so one ``bpns learn --seed`` seeds all
    #: network training and a different seed is a different draw for every approach
    seed: int | None = None

    def seeded(self, seed: int) -> BaselinesConfig:
        """These settings with both GNNs' configs carrying ``seed``."""
        return dataclasses.replace(
            self,
            meta=None if self.meta is None else dataclasses.replace(self.meta, seed=seed),
            bc=None if self.bc is None else dataclasses.replace(self.bc, seed=seed),
            seed=seed,
        )

    def only(self, stages: Collection[str]) -> BaselinesConfig:
        """These settings learning only the baselines named in ``stages`` (see STAGES)."""
        return dataclasses.replace(
            self,
            meta=self.meta if "gnn_meta" in stages else None,
            bc=self.bc if "gnn_bc" in stages else None,
            nosubgoal=self.nosubgoal and "nosubgoal" in stages,
        )

    @staticmethod
    def with_max_steps(steps: int) -> BaselinesConfig:
        """The defaults with at most ``steps`` gradient steps per GNN (quick runs, tests)."""
        base = BaselinesConfig()
        assert base.meta is not None and base.bc is not None
        return BaselinesConfig(
            meta=dataclasses.replace(base.meta, max_steps=steps),
            bc=dataclasses.replace(base.bc, max_steps=steps),
        )


@dataclass(frozen=True, eq=False)
class LearnedBaselines:
    metacontroller: GNNMetacontroller | None
    meta_stats: GNNTrainingStats | None
    meta_skipped_segments: int
    bc_policy: GNNPolicy | None
    bc_stats: GNNTrainingStats | None
    nosubgoal_skills: LearnedSkills | None
    stage_seconds: tuple[tuple[str, float], ...]
    config: BaselinesConfig = field(default_factory=BaselinesConfig)


def learn_baselines(
    demos: Sequence[Demonstration],
    predicates: Collection[Predicate],
    types: Collection[Type],
    skills: LearnedSkills,
    config: BaselinesConfig | None = None,
    report: Callable[[str], None] | None = None,
    given: Sequence[GivenSkill] = (),
) -> LearnedBaselines:
    """Learn the baselines ``config`` asks for. ``predicates`` and ``types`` are the
    environment's declared ones (they fix the graph vocabulary); ``skills`` are the
    BPNS skills learned from the same ``demos``: the segments they were learned from
    (``skills.segments``) are what the metacontroller's data labels with their operators
    and what the No-Subgoal skills learn from, with their learning config's settings;
    unless ``config.seed`` is set, that config's seed seeds the GNNs."""
    config = BaselinesConfig() if config is None else config
    config = config.seeded(skills.config.seed if config.seed is None else config.seed)
    say = report or (lambda message: None)
    if (config.meta is not None or config.nosubgoal) and len(skills.segments) != len(demos):
        raise ValueError(
            f"the skills carry the segments of {len(skills.segments)} demonstrations, and "
            f"{len(demos)} were given: GNN Meta and No Subgoal learn from the segments the "
            "skills were learned from (learn_skills records them; skills loaded from disk "
            "carry none)"
        )
    vocab = GraphVocabulary.build(types, predicates)
    seconds: dict[str, float] = {}
    meta = meta_stats = None
    skipped = 0
    if config.meta is not None:
        say("GNN Meta: labelling segments with the learned operators")
        t0 = time.perf_counter()
        examples, skipped = metacontroller_examples(demos, skills.segments, skills.operators)
        say(f"GNN Meta: training on {len(examples)} decisions")
        meta, meta_stats = train_metacontroller(vocab, skills.operators, examples, config.meta)
        seconds["gnn_meta"] = time.perf_counter() - t0
    bc = bc_stats = None
    if config.bc is not None:
        t0 = time.perf_counter()
        steps, _ = bc_examples(demos, predicates, config.bc.max_examples, config.bc.seed)
        say(f"GNN BC: training on {len(steps)} demonstrated steps")
        bc, bc_stats = train_bc_policy(
            vocab, steps, dataclasses.replace(config.bc, max_examples=None)
        )
        # the subsample was drawn before abstraction; record the full count
        bc_stats = dataclasses.replace(bc_stats, num_examples=sum(len(d.actions) for d in demos))
        seconds["gnn_bc"] = time.perf_counter() - t0
    nosub = None
    if config.nosubgoal:
        say("No Subgoal: learning skills without subgoals")
        t0 = time.perf_counter()
        # the BPNS skills' segmentation (a No-Subgoal skill differs only in its policy),
        # its time counted as this pipeline's own segment stage
        stages = dict(skills.stats.stage_seconds) if skills.stats is not None else {}
        nosub = learn_from_segments(
            demos,
            skills.segments,
            predicates,
            dataclasses.replace(skills.config, use_subgoals=False),
            report,
            given,
            segment_seconds=stages.get("segment", 0.0),
        )
        seconds["nosubgoal"] = time.perf_counter() - t0
    return LearnedBaselines(
        meta, meta_stats, skipped, bc, bc_stats, nosub, tuple(seconds.items()), config
    )


def save_baselines(
    baselines: LearnedBaselines, skills_dir: str | os.PathLike, env_name: str | None = None
) -> list[Path]:
    """Write what was learned into ``skills_dir`` (which must exist); returns the paths.

    Note: :func:`save_skills` replaces a skills directory wholesale, so re-saving the
    BPNS skills afterwards drops these files; save the baselines after the skills.
    """
    directory = Path(skills_dir)
    if not directory.is_dir():
        raise FileNotFoundError(f"{directory}: no such skills directory")
    written = []
    if baselines.metacontroller is not None:
        info = {
            "config": _config_json(baselines.config.meta),
            "stats": _stats_json(baselines.meta_stats),
            "skipped_segments": baselines.meta_skipped_segments,
        }
        written.append(save_metacontroller(baselines.metacontroller, directory / META_FILE, info))
    if baselines.bc_policy is not None:
        info = {
            "config": _config_json(baselines.config.bc),
            "stats": _stats_json(baselines.bc_stats),
        }
        written.append(save_bc_policy(baselines.bc_policy, directory / BC_FILE, info))
    if baselines.nosubgoal_skills is not None:
        written.append(
            save_skills(
                baselines.nosubgoal_skills,
                directory / NOSUBGOAL_DIR,
                overwrite=True,
                env_name=env_name,
            )
        )
    return written


def _stats_json(stats: GNNTrainingStats | None) -> dict | None:
    return None if stats is None else dataclasses.asdict(stats)


def _config_json(config: GNNConfig | None) -> dict | None:
    return None if config is None else dataclasses.asdict(config)


def saved_baseline_seconds(directory: str | os.PathLike) -> dict[str, float]:
    """The training seconds recorded with each baseline saved in a skills ``directory``
    (GNN training alone; labelling the segments is not included), by stage name as in
    ``learn_baselines``; baselines absent or without a record are left out."""
    d = Path(directory)
    seconds: dict[str, float] = {}
    for stage, file, kind in (("gnn_meta", META_FILE, KIND_META), ("gnn_bc", BC_FILE, KIND_BC)):
        if (d / file).is_file():
            stats = saved_info(d / file, kind).get("stats") or {}
            if isinstance(stats.get("seconds"), (int, float)):
                seconds[stage] = float(stats["seconds"])
    index = d / NOSUBGOAL_DIR / "skills.json"
    if index.is_file():
        try:
            stages = json.loads(index.read_text())["stats"]["stage_seconds"]
            seconds["nosubgoal"] = float(sum(t for _, t in stages))
        except (OSError, ValueError, KeyError, TypeError):
            pass
    return seconds
