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
    SET_ASIDE = "set_aside"  # one abstract plan: a step failed from too many arrivals
    NO_SKILL = "no_skill"  # a metacontroller found no ground skill to execute
    WORKER_DIED = "worker_died"  # the process solving it died, twice (evaluation)
    # executing in a world that differs from the planner's model
    GOAL_NOT_REACHED = "goal_not_reached"  # a plan replayed open loop missed the goal
    REPLAN_BUDGET = "replan_budget"  # closed loop: the world diverged more often than allowed
    ATOM_LOST = "atom_lost"  # closed loop: an atom the rest of the plan needs stopped holding
    # one execution of a skill (or of a policy acting every step)
    SAMPLER_ERROR = "sampler_error"  # the subgoal sampler raised
    SAMPLER_NONFINITE = "sampler_nonfinite"  # ... or returned NaN/inf
    NO_SUBGOAL = "no_subgoal"  # the sampler refused: no subgoal worth simulating
    POLICY_ERROR = "policy_error"  # the policy raised or returned the wrong shape
    POLICY_NONFINITE = "policy_nonfinite"  # ... or returned NaN/inf
    SKILL_HORIZON = "skill_horizon"  # the skill's expected atoms never held in time
    STUCK = "stuck"  # the world stopped changing
    DEAD_END = "dead_end"  # the environment declares the state a dead end
    CONTACT_CHANGED = "unexpected_contact_change"  # a contact atom changed unexpectedly
    TASK_HORIZON = "task_horizon"  # the task's step budget would be exceeded
    NOGOOD = "nogood"  # refinement refuted a step from memory (no sample drawn)

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


MEANING: dict[FailureReason, str] = {
    FailureReason.TIMEOUT: "the wall-clock budget ran out",
    FailureReason.NO_ABSTRACT_PLAN: "the abstract search found no plan at all",
    FailureReason.REFINEMENT_FAILED: "every abstract plan tried failed to refine",
    FailureReason.EXHAUSTED: "every sample of the plan's first step failed",
    FailureReason.SET_ASIDE: "one step failed every sample from several different arrivals: "
    "the plan was set aside for the other abstract plans (refined again after them)",
    FailureReason.NO_SKILL: "no ground skill was left to execute",
    FailureReason.WORKER_DIED: "the worker process solving the task died, also when it ran "
    "again alone (killed, most often by the kernel's out-of-memory killer, or crashed in "
    "native code)",
    FailureReason.GOAL_NOT_REACHED: "the plan found in the model, replayed open loop in the "
    "world, did not reach the goal",
    FailureReason.REPLAN_BUDGET: "the world diverged from the plan more often than the "
    "replan budget allows",
    FailureReason.ATOM_LOST: "an atom the rest of the plan relies on stopped holding while "
    "the skill ran (e.g. the held object slipped)",
    FailureReason.SAMPLER_ERROR: "the subgoal sampler raised",
    FailureReason.SAMPLER_NONFINITE: "the subgoal sampler returned NaN/inf",
    FailureReason.NO_SUBGOAL: "the sampler had no subgoal worth simulating (out of reach or "
    "of the demonstrations' support)",
    FailureReason.POLICY_ERROR: "the policy raised or returned the wrong shape",
    FailureReason.POLICY_NONFINITE: "the policy returned NaN/inf",
    FailureReason.SKILL_HORIZON: "the step's atoms did not hold within the skill's horizon",
    FailureReason.STUCK: "the world stopped changing before the step's atoms held",
    FailureReason.DEAD_END: "the rollout reached a state from which no goal can be reached "
    "(the environment's dead_end, e.g. spilled coffee)",
    FailureReason.CONTACT_CHANGED: "a contact atom the step should not touch changed",
    FailureReason.TASK_HORIZON: "the task's step budget would be exceeded",
    FailureReason.NOGOOD: "refuted from memory: the same state already failed here",
}

# Reasons a sample fails before its policy executes a single step (a rollouts file shows
# no actions of such a sample).
NOT_EXECUTED: frozenset[FailureReason] = frozenset(
    {
        FailureReason.SAMPLER_ERROR,
        FailureReason.SAMPLER_NONFINITE,
        FailureReason.NO_SUBGOAL,
        FailureReason.NOGOOD,
        FailureReason.EXHAUSTED,
        FailureReason.SET_ASIDE,
    }
)
