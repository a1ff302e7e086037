"""Why an attempt failed: one enum for every approach, planner and skill execution.

Members are ``str`` valued and print as their value, so results JSON, statistics keys
and messages read ``"timeout"``, ``"stuck"`` ..., and compare equal to those strings.
"""

from __future__ import annotations

import enum


class FailureReason(str, enum.Enum):
    # a whole attempt at a task
    TIMEOUT = "timeout"  # the wall-clock budget ran out
    NO_ABSTRACT_PLAN = "no_abstract_plan"  # the abstract search found no plan at all
    REFINEMENT_FAILED = "refinement_failed"  # every abstract plan tried failed to refine
    EXHAUSTED = "exhausted"  # one abstract plan: every sample of its first step failed
    NO_SKILL = "no_skill"  # a metacontroller found no ground skill to execute
    # one execution of a skill (or of a policy acting every step)
    SAMPLER_ERROR = "sampler_error"  # the subgoal sampler raised
    SAMPLER_NONFINITE = "sampler_nonfinite"  # ... or returned NaN/inf
    POLICY_ERROR = "policy_error"  # the policy raised or returned the wrong shape
    POLICY_NONFINITE = "policy_nonfinite"  # ... or returned NaN/inf
    SKILL_HORIZON = "skill_horizon"  # the skill's expected atoms never held in time
    STUCK = "stuck"  # the world stopped changing
    CONTACT_CHANGED = "unexpected_contact_change"  # a contact atom changed unexpectedly
    TASK_HORIZON = "task_horizon"  # the task's step budget would be exceeded
    NOGOOD = "nogood"  # refinement refuted a step from memory (no sample drawn)

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)
