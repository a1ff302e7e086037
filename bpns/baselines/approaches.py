"""The paper's baselines as approaches: BPNS No Subgoal, GNN Meta (with and without
subgoals) and GNN BC (paper appendix "Approach Details"; models in
:mod:`bpns.baselines.learn`).

All four are learned once from the same demonstrations as BPNS and saved in its skills
directory (``bpns learn --baselines``): ``nosubgoal/`` (skills whose policies see no
subgoal), ``gnn_meta.npz`` and ``gnn_bc.npz``.

- **No Subgoal**: bilevel planning with the No-Subgoal skills, one rollout per step
  (a policy without subgoal input is deterministic: a second sample would repeat it).
- **GNN Meta**: a :class:`~bpns.approaches.metacontroller.Metacontroller` whose choice
  is the GNN's; each chosen skill is tried with up to 100 subgoals from its sampler
  until the operator's predicted abstract state holds.
- **GNN Meta No Subgoal**: the same metacontroller over the No-Subgoal skills (one
  rollout per choice).
- **GNN BC**: a :class:`~bpns.approaches.policy.ClosedLoopPolicy` querying the GNN for
  an action at every control step; no look-ahead in the simulator.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bpns.approaches.base import Approach, ApproachEntry, SkillSource
from bpns.approaches.bilevel import BilevelPlanning
from bpns.approaches.metacontroller import Metacontroller, SkillChoice
from bpns.approaches.policy import ClosedLoopPolicy
from bpns.baselines.files import BC_FILE, META_FILE, load_bc_policy, load_metacontroller
from bpns.baselines.gnn_bc import GNNPolicy
from bpns.baselines.gnn_meta import GNNMetacontroller
from bpns.baselines.learn import NOSUBGOAL_DIR
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment
from bpns.learning.artifacts.skills_dir import ArtifactError, load_skills
from bpns.learning.given import given_skills_of
from bpns.learning.pipeline import STAGES
from bpns.learning.samplers import CurrentStateSampler
from bpns.planning.config import PlanningConfig
from bpns.structs import GroundAtom, Skill, State, Task

META_SAMPLES = 100  # paper: up to 100 subgoal samples per chosen skill


def _require(path: Path, what: str) -> Path:
    if not path.exists():
        raise ArtifactError(
            f"{path.parent}: no {what} ({path.name}); learn it with "
            f"`bpns learn DEMOS --out {path.parent} --baselines --overwrite`"
        )
    return path


def _skills(env: Environment, directory: Path) -> list[Skill]:
    return list(load_skills(directory, env.predicates, env.types, given_skills_of(env)).skills)


class GNNMeta(Metacontroller):
    """The GNN picks the next ground skill; its subgoals come from the skill's sampler."""

    def __init__(
        self,
        env: Environment,
        config: PlanningConfig,
        skills: Sequence[Skill],
        model: GNNMetacontroller,
    ) -> None:
        super().__init__(env, config, max_samples=META_SAMPLES)
        self.by_name = {s.name: s for s in skills}
        self.model = model

    def samples_for(self, choice: SkillChoice) -> int:
        # a skill without subgoals rolls out the same way every time
        return 1 if isinstance(choice.skill.sampler, CurrentStateSampler) else self.max_samples

    def choose(
        self,
        task: Task,
        state: State,
        atoms: frozenset[GroundAtom],
        history: Sequence[SkillChoice],
        rng: np.random.Generator,
    ) -> SkillChoice | None:
        ground = self.model.choose(state, atoms, task.goal)
        if ground is None:
            return None
        return SkillChoice(self.by_name[ground.name], ground.objects)


class GNNBehaviourCloning(ClosedLoopPolicy):
    """Acts every control step with the goal-conditioned GNN policy."""

    def __init__(self, env: Environment, policy: GNNPolicy) -> None:
        super().__init__(env)
        self.policy = policy

    def act(self, task: Task, state: State) -> np.ndarray:
        return self.policy(state, abstract(state, self.env.predicates), task.goal)


def _nosubgoal(env: Environment, config: PlanningConfig, skills_dir: Path | None) -> Approach:
    assert skills_dir is not None
    return BilevelPlanning(
        env, _skills(env, _require(skills_dir / NOSUBGOAL_DIR, "No-Subgoal skills")), config
    )


def _meta_over(env: Environment, config: PlanningConfig, skills_dir: Path, skills: list[Skill]):
    model = load_metacontroller(
        _require(skills_dir / META_FILE, "GNN metacontroller"),
        [s.operator for s in skills],
        env.predicates,
        env.types,
    )
    return GNNMeta(env, config, skills, model)


def _gnn_meta(env: Environment, config: PlanningConfig, skills_dir: Path | None) -> Approach:
    assert skills_dir is not None
    return _meta_over(env, config, skills_dir, _skills(env, skills_dir))


def _gnn_meta_nosubgoal(
    env: Environment, config: PlanningConfig, skills_dir: Path | None
) -> Approach:
    assert skills_dir is not None
    nosub = _skills(env, _require(skills_dir / NOSUBGOAL_DIR, "No-Subgoal skills"))
    return _meta_over(env, config, skills_dir, nosub)


def _gnn_bc(env: Environment, config: PlanningConfig, skills_dir: Path | None) -> Approach:
    assert skills_dir is not None
    policy = load_bc_policy(
        _require(skills_dir / BC_FILE, "GNN BC policy"), env.predicates, env.types
    )
    return GNNBehaviourCloning(env, policy)


def _one_sample(config: PlanningConfig) -> PlanningConfig:
    return dataclasses.replace(config, n_samples=1)


NOSUBGOAL = ApproachEntry(
    "nosubgoal",
    "BPNS No Subgoal",
    "bilevel planning with skills whose policies see no subgoal (one rollout per step)",
    SkillSource.LEARNED,
    _nosubgoal,
    _one_sample,
    needs_baselines=True,
    learned_stages=("nosubgoal",),  # a whole pipeline of its own
)
GNN_META = ApproachEntry(
    "gnn-meta",
    "GNN Meta",
    "a GNN picks the next ground skill (no AI planning); up to 100 subgoals per skill",
    SkillSource.LEARNED,
    _gnn_meta,
    needs_baselines=True,
    learned_stages=(*STAGES, "gnn_meta"),  # it runs the BPNS skills
)
GNN_META_NOSUBGOAL = ApproachEntry(
    "gnn-meta-nosubgoal",
    "GNN Meta No Subgoal",
    "GNN Meta over the No-Subgoal skills",
    SkillSource.LEARNED,
    _gnn_meta_nosubgoal,
    needs_baselines=True,
    learned_stages=("nosubgoal", "gnn_meta"),
)
GNN_BC = ApproachEntry(
    "gnn-bc",
    "GNN BC",
    "a goal-conditioned GNN policy acting every control step (model-free)",
    SkillSource.LEARNED,
    _gnn_bc,
    needs_baselines=True,
    learned_stages=("gnn_bc",),
)
