"""Scripted demonstrators as a queue of closed-loop phases, shared by the domains' oracles.

A phase is a function of the current state that returns the next action, or None once it
is done; the demonstrator runs its phases in order and asks the domain's ``plan`` for the
next batch when the queue is empty. Every phase is bounded, so a demonstrator that
cannot make progress says so (:class:`DemonstrationFailed`) instead of idling out the
task's horizon.
"""

from __future__ import annotations

import abc
from collections.abc import Callable

import numpy as np

from bpns.errors import BpnsError
from bpns.structs import State

Phase = Callable[[State], "np.ndarray | None"]


class DemonstrationFailed(BpnsError, RuntimeError):
    """The scripted demonstrator could not carry on (reported, never silent)."""


class PhasedDemonstrator(abc.ABC):
    """A stateful closed-loop oracle policy for one task (call it once per step)."""

    max_phase_steps: int = 150

    def __init__(self) -> None:
        self._phases: list[Phase] = []
        self._phase_steps = 0

    @abc.abstractmethod
    def plan(self, state: State) -> list[Phase]:
        """The next phases from ``state``; an empty list when the task is done."""

    @abc.abstractmethod
    def idle_action(self, state: State) -> np.ndarray:
        """What to do once nothing is left to do (hold still)."""

    def __call__(self, state: State) -> np.ndarray:
        while True:
            if not self._phases:
                self._phases = self.plan(state)
                if not self._phases:
                    return self.idle_action(state)
            action = self._phases[0](state)
            if action is not None:
                self._phase_steps += 1
                if self._phase_steps > self.max_phase_steps:
                    raise DemonstrationFailed("a phase of the demonstration did not finish")
                return action
            self._phases.pop(0)
            self._phase_steps = 0
