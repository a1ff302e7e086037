"""What a baseline's solving loop returns for one task."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

# Why a baseline failed (besides the skill rollout's own reasons).
NO_APPLICABLE_SKILL = "no_applicable_skill"
SUBGOALS_EXHAUSTED = "subgoals_exhausted"
MAX_SKILLS = "max_skills"
TASK_HORIZON = "task_horizon"
TIMEOUT = "timeout"
POLICY_NONFINITE = "policy_nonfinite"


@dataclass(frozen=True, eq=False)
class BaselineResult:
    """``actions`` (k x action_dim) take the task's initial state to its last state;
    on failure they are the actions executed before giving up. ``reason`` is None on
    success; ``stats`` holds counts and seconds (skills, samples, sim_steps, ...)."""

    success: bool
    actions: np.ndarray
    reason: str | None
    stats: Mapping[str, float] = field(default_factory=dict)
