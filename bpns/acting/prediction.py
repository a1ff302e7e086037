"""Policies that see where the world will be when their command lands.

A command that takes effect ``d`` control steps after it is sent (latency) is computed
from a state ``d`` steps stale: a cloned policy's law, a gain on the distance to its
subgoal, then overshoots and rings (docs/WORLDS.md, "Why the skills were fragile"). The
agent knows the commands it sent; advancing what it observes by the ones the world has
not applied yet, in its model (a Smith predictor), gives the state its next command
will meet.

The agent does not know the world's latency. :class:`InFlightPredictor` identifies it
from the task's first control steps: after each step it asks the model which command,
sent ``d`` = 0, 1, ... steps earlier, best explains the step the world just took (a
one-step prediction from the world's previous state), and takes the ``d`` with the
smallest summed error. Until then it predicts nothing, as with ``d`` = 0.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.env.environment import Environment, adopt_state
from bpns.structs import State


class InFlightPredictor:
    """``predict(state, seen, sent, current)``: ``seen`` (what the policy observes of the
    world's ``state``) advanced in ``model`` by the commands still in flight, the
    observation's noise kept. ``sent`` and ``current`` are the task's commands so far
    (earlier executions', then the current one's), the last of them the one that led to
    ``state``. ``latency``: the robot's, if known; None: identified from the first
    ``learn_steps`` steps among 0..``max_latency``."""

    def __init__(
        self,
        model: Environment,
        latency: int | None = None,
        max_latency: int = 3,
        learn_steps: int = 20,
    ) -> None:
        if latency is not None and not 0 <= latency <= max_latency:
            raise ValueError(f"latency must be in [0, {max_latency}], got {latency}")
        if max_latency < 0 or learn_steps < 1:
            raise ValueError("max_latency must be >= 0 and learn_steps >= 1")
        self.model = model
        self.known = latency
        self.learn_steps = learn_steps
        self.errors = np.zeros(max_latency + 1)
        self.samples = 0
        self.zero = np.zeros(np.asarray(model.action_low).size)
        self._previous: tuple[State, int] | None = None

    @property
    def identified(self) -> bool:
        """Whether the latency was identified (not known beforehand)."""
        return self.known is None and self.samples >= self.learn_steps

    @property
    def latency(self) -> int:
        """The latency predicted with: the known one, else the identified one (0 while
        still identifying)."""
        if self.known is not None:
            return self.known
        return int(np.argmin(self.errors)) if self.samples >= self.learn_steps else 0

    def __call__(
        self,
        state: State,
        seen: State,
        sent: Sequence[np.ndarray],
        current: Sequence[np.ndarray],
    ) -> State:
        count = len(sent) + len(current)

        def command(j: int) -> np.ndarray:  # the task's j-th command; zeros before the first
            if j < 0:
                return self.zero
            return sent[j] if j < len(sent) else current[j - len(sent)]

        if self.known is None and self.samples < self.learn_steps:
            previous = self._previous
            if previous is not None and previous[1] == count - 1:
                self._learn(
                    previous[0], state, [command(count - 1 - d) for d in range(len(self.errors))]
                )
            self._previous = (state, count)
        d = min(self.latency, count)
        if d == 0:
            return seen
        ahead = adopt_state(self.model, state)
        for j in range(count - d, count):
            ahead = self.model.simulate(ahead, command(j))
        return State(
            {o: ahead.data[o] + (seen.data[o] - state.data[o]) for o in seen.data}, ahead.sim
        )

    def _learn(self, before: State, after: State, candidates: Sequence[np.ndarray]) -> None:
        """Add each candidate command's one-step prediction error from ``before``."""
        start = adopt_state(self.model, before)
        truth = np.concatenate([after.data[o] for o in after.data])
        for d, action in enumerate(candidates):
            predicted = self.model.simulate(start, action)
            guess = np.concatenate([predicted.data[o] for o in after.data])
            self.errors[d] += float(np.sum((guess - truth) ** 2))
        self.samples += 1
