"""What an approach executed on one task: the actions and, per skill, what it was for.

A :class:`Rollout` is the answer to "what did the robot do, and why did it fail":
the executed actions from the task's initial state (replayable in the environment) and
one :class:`PlanStep` per skill execution: the ground operator, its subgoal, the index
of its first action and its outcome (``reached`` or the failure reason). For a solved
task it is the plan; for a failed one, what the approach reports as the attempt that got
furthest (bilevel planning: the deepest refined prefix plus the failed sample after it).
Evaluation writes them to a rollouts file (:mod:`bpns.evaluation.rollout_files`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bpns.structs import GroundOperator

REACHED = "reached"


@dataclass(frozen=True)
class PlanStep:
    """One skill execution: ``actions[start:next step's start]`` of the rollout."""

    operator: str
    objects: tuple[str, ...]
    subgoal: tuple[float, ...] | None  # None: the skill drew none (or it failed to)
    start: int
    outcome: str  # REACHED, or why the execution failed

    @property
    def label(self) -> str:
        return f"{self.operator}({', '.join(self.objects)})"

    def to_json(self) -> dict:
        return {
            "operator": self.operator,
            "objects": list(self.objects),
            "subgoal": None if self.subgoal is None else list(self.subgoal),
            "start": self.start,
            "outcome": self.outcome,
        }

    @classmethod
    def from_json(cls, d: dict) -> PlanStep:
        subgoal = d["subgoal"]
        return cls(
            str(d["operator"]),
            tuple(str(o) for o in d["objects"]),
            None if subgoal is None else tuple(float(x) for x in subgoal),
            int(d["start"]),
            str(d["outcome"]),
        )


@dataclass(frozen=True)
class Event:
    """Something an execution monitor saw or did, before action ``at`` of a rollout:
    ``kind`` is ``diverged``, ``skill_failed``, ``atom_lost``, ``replanned``,
    ``rerefined``, ``replan_failed``, ``backed_off``, ``slowed`` or ``latency``; ``text``
    says it for people ("replan 1: expected Holding(block0) did not hold")."""

    at: int
    kind: str
    text: str

    def to_json(self) -> dict:
        return {"at": self.at, "kind": self.kind, "text": self.text}

    @classmethod
    def from_json(cls, d: dict) -> Event:
        return cls(int(d["at"]), str(d["kind"]), str(d["text"]))


@dataclass(frozen=True, eq=False)
class Rollout:
    """Executed ``actions`` (k x action_dim), the skill executions they consist of and
    what an execution monitor saw on the way (closed-loop execution only)."""

    actions: np.ndarray
    steps: tuple[PlanStep, ...] = ()
    events: tuple[Event, ...] = ()

    @property
    def progress(self) -> tuple[int, int]:
        """How far it got: skills reached, then actions (larger is further)."""
        return sum(s.outcome == REACHED for s in self.steps), len(self.actions)


# a ground operator's execution, or a named motion that is no skill (e.g. a back-off)
Executed = tuple["GroundOperator | str", "np.ndarray | None", Sequence[np.ndarray], str]


def rollout_of(
    executions: Sequence[Executed], action_dim: int, events: Sequence[Event] = ()
) -> Rollout:
    """A rollout from (ground operator or motion name, subgoal, actions, outcome) per
    execution."""
    steps, actions = [], []
    for op, subgoal, acts, outcome in executions:
        sub = None if subgoal is None else tuple(float(x) for x in np.ravel(subgoal))
        if isinstance(op, str):
            name, objects = op, ()
        else:
            name, objects = op.operator.name, tuple(o.name for o in op.objects)
        steps.append(PlanStep(name, objects, sub, len(actions), outcome))
        actions.extend(acts)
    flat = np.array(actions, dtype=np.float64).reshape(len(actions), action_dim)
    return Rollout(flat, tuple(steps), tuple(events))


def further(a: Rollout | None, b: Rollout | None) -> Rollout | None:
    """The one of ``a`` and ``b`` that got further (``a`` on ties)."""
    if a is None:
        return b
    if b is None:
        return a
    return b if b.progress > a.progress else a


def step_captions(steps: Sequence[PlanStep], num_states: int) -> list[str]:
    """Per state of a rollout, the skill being executed and its objects (state i follows
    action i - 1; the initial state shows the first skill)."""
    if not steps:
        return [""] * num_states
    out, k = [], 0
    for i in range(num_states):
        action = max(0, i - 1)
        while k + 1 < len(steps) and steps[k + 1].start <= action:
            k += 1
        out.append(f"{k + 1}/{len(steps)} {steps[k].label}")
    return out


def event_captions(captions: Sequence[str], events: Sequence[Event], hold: int = 40) -> list[str]:
    """``captions`` with each monitor event's text added below, from the state where it
    happened for ``hold`` states (2 s at 20 Hz), so a video shows why it replanned.

    Of the latest step's events the cause is shown (``replan 1: expected ... did not
    hold``), not what the planner did about it, which follows at the same step."""
    out = list(captions)
    for i in range(len(out)):
        current = [e for e in events if e.at <= max(0, i - 1) < e.at + hold]
        if current:
            latest = [e for e in current if e.at == current[-1].at]
            causes = [e for e in latest if e.kind not in _RESPONSES]
            out[i] = f"{out[i]}\n{(causes or latest)[-1].text}"
    return out


# what the planner did, not why ("slowed" says why: the world left the model's prediction)
_RESPONSES = frozenset({"replanned", "rerefined"})


def outcome_caption(
    solved: bool, reason: str, steps: Sequence[PlanStep], num_actions: int, physics: str = ""
) -> str:
    """The last frame's caption: solved, or the task's failure and the step it ended in."""
    where = f" [{physics}]" if physics and physics != "nominal" else ""
    if solved:
        return f"SOLVED in {num_actions} steps, {len(steps)} skills{where}"
    failed = next((s for s in reversed(steps) if s.outcome != REACHED), None)
    text = f"FAILED: {reason}{where}"
    if failed is not None:
        text += f"\nlast try: {failed.label} -> {failed.outcome} after {num_actions} steps"
    return text
