"""Learning neuro-symbolic skills from demonstrations (paper §4).

Stages, each usable alone: :func:`segment_demonstrations` -> :func:`partition_segments`
-> :func:`learn_operators` -> :func:`learn_policy` / :func:`learn_sampler`;
:func:`learn_skills` runs them all (:func:`learn_from_segments` all but the first), the
networks as the jobs of :mod:`bpns.learning.jobs` that the last two train one skill with.
:func:`save_skills` / :func:`load_skills` persist the result.
"""

from bpns.learning.artifacts.skills_dir import ArtifactError, describe, load_skills, save_skills
from bpns.learning.config import LearningConfig, MLPConfig
from bpns.learning.jobs import learn_policy, learn_sampler
from bpns.learning.operators import SkillDataset, applicable_bindings, learn_operators
from bpns.learning.partition import SegmentGroup, partition_segments
from bpns.learning.pipeline import (
    LearnedSkills,
    LearningStats,
    SkillStats,
    learn_from_segments,
    learn_skills,
)
from bpns.learning.policies import LearnedPolicy, ScopeDims
from bpns.learning.samplers import CurrentStateSampler, LearnedSampler
from bpns.learning.segmentation import segment_demonstration, segment_demonstrations

__all__ = [
    "ArtifactError",
    "CurrentStateSampler",
    "LearnedPolicy",
    "LearnedSampler",
    "LearnedSkills",
    "LearningConfig",
    "LearningStats",
    "MLPConfig",
    "ScopeDims",
    "SegmentGroup",
    "SkillDataset",
    "SkillStats",
    "applicable_bindings",
    "describe",
    "learn_from_segments",
    "learn_operators",
    "learn_policy",
    "learn_sampler",
    "learn_skills",
    "load_skills",
    "partition_segments",
    "save_skills",
    "segment_demonstration",
    "segment_demonstrations",
]
