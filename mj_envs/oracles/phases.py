"""Scripted demonstrators as a queue of closed-loop phases, shared by the domains' oracles.

A phase is a function of the current state that returns the next action, or None once it
is done; the demonstrator runs its phases in order and asks the domain's ``plan`` for the
next batch when the queue is empty. Every phase is bounded, so a demonstrator that
cannot make progress says so (:class:`DemonstrationFailed`) instead of idling out the
task's horizon.

A phase is usually a closure over the objects it works on, built from the primitives in
:mod:`mj_envs.oracles.motions`, e.g. ``lambda s: None if done(s) else grasp_action(...)``.
Its actions are the environment's (by default ``(dx, dy, dz, grip)``: metres per control
step and a finger command in [-1, 1]).
"""

from __future__ import annotations

import abc
from collections.abc import Callable

import numpy as np

from bpns.errors import BpnsError
from bpns.structs import State

# A phase: State -> the next action, or None once it is done. A finished phase is dropped
# and the next one is asked in the same state, so finishing costs no control step.
Phase = Callable[[State], "np.ndarray | None"]


class DemonstrationFailed(BpnsError, RuntimeError):
    """The scripted demonstrator could not carry on (reported, never silent).

    Raised by :meth:`PhasedDemonstrator.__call__` when one phase returns more than
    ``max_phase_steps`` actions, and by domain phases that see the task cannot be done any
    more (an object dropped or spilled). The demonstration run records the message as the
    attempt's failure (``bpns.data.demo_attempts``); it is a :class:`RuntimeError` and a
    ``BpnsError`` (its ``str()`` is the message as written).
    """


class PhasedDemonstrator(abc.ABC):
    """A stateful closed-loop oracle policy for one task (call it once per step).

    Subclasses implement :meth:`plan` and :meth:`idle_action`, and may set
    ``max_phase_steps`` (default 150 actions, 7.5 s at the default 0.05 s control step)
    to bound how long any one phase may run, and override :meth:`phase_failed` to say
    what a phase that runs longer failed to do. Its state is the queue and the current
    phase's step count: make a new demonstrator for each task (there is no reset).
    """

    max_phase_steps: int = 150

    def __init__(self) -> None:
        self._phases: list[Phase] = []
        self._phase_steps = 0
        self._planned = 0  # phases in the last plan (to say which one failed)

    @abc.abstractmethod
    def plan(self, state: State) -> list[Phase]:
        """The next phases from ``state``; an empty list when the task is done.

        Called whenever the queue is empty, in the state the next action is for, so a
        plan can look at what the previous phases achieved. It should not return only
        phases that are already done in ``state`` (each returning None at once): the call
        would then ask again in the same state, and never return.
        """

    @abc.abstractmethod
    def idle_action(self, state: State) -> np.ndarray:
        """What to do once nothing is left to do (hold still).

        Returned whenever :meth:`plan` returns an empty list; it does not count against
        ``max_phase_steps``.
        """

    def __call__(self, state: State) -> np.ndarray:
        """The action for ``state``: the first unfinished phase's, planning when needed.

        Phases that return None are dropped in order (in this same state) until one
        returns an action; an empty queue is refilled by :meth:`plan`, and an empty plan
        gives :meth:`idle_action`. Raises :meth:`phase_failed`'s
        :class:`DemonstrationFailed` on the ``max_phase_steps + 1``-th action of one phase
        (the counter restarts with each phase), and lets any exception of a phase or of
        :meth:`plan` through.
        """
        while True:
            if not self._phases:
                self._phases = self.plan(state)
                self._planned = len(self._phases)
                if not self._phases:
                    return self.idle_action(state)
            action = self._phases[0](state)
            if action is not None:
                self._phase_steps += 1
                if self._phase_steps > self.max_phase_steps:
                    raise self.phase_failed()
                return action
            self._phases.pop(0)
            self._phase_steps = 0

    def phase_failed(self) -> DemonstrationFailed:
        """The error for a phase that ran past ``max_phase_steps``: by default it names
        the phase (:func:`phase_name`) and its place in the plan; a subclass that knows
        what the phase was for may say that instead (the message is what the
        demonstration run records as the attempt's failure, and what ``bpns demos`` and
        ``bpns check-env --demo`` print)."""
        number = self._planned - len(self._phases) + 1
        return DemonstrationFailed(
            f"phase {phase_name(self._phases[0])!r} ({number} of {self._planned} in the plan) "
            f"did not finish within {self.max_phase_steps} actions"
        )


def phase_name(phase: Phase) -> str:
    """A phase's name for messages: its function's qualified name, with the function that
    built a closure before a colon (``twist_phases: turn``, ``CoverDemonstrator._cover:
    phase``)."""
    name = getattr(phase, "__qualname__", None) or type(phase).__name__
    return name.replace(".<locals>.", ": ")
