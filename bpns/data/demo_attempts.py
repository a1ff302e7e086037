"""One run of a scripted demonstrator, with the reason when it fails.

``bpns.data.demos.run_demonstrator`` keeps its contract (a Demonstration or None) by
delegating here; callers that must say *why* a task was not demonstrated (``bpns demos``,
``bpns check-env``) use :func:`attempt_demonstration`, whose :class:`DemoAttempt` carries
the exception (type, message, traceback) and the last abstract states the run went
through: enough to tell a demonstrator bug from a physics failure without a debugger.
"""

from __future__ import annotations

import traceback as tb
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bpns.env.abstraction import abstract
from bpns.env.environment import Environment
from bpns.structs import Demonstration, State, Task

TRACE_LENGTH = 5  # abstract states kept for a failure's atom trace


@dataclass(frozen=True)
class AtomChange:
    """The abstract state from ``step`` on (until the next change)."""

    step: int
    atoms: tuple[str, ...]


@dataclass(frozen=True)
class DemoAttempt:
    """A demonstrator's run on one task: the demo, or why there is none."""

    demo: Demonstration | None
    steps: int  # actions taken
    error: str | None = None  # "ExceptionType: message" or "goal not reached ..."
    traceback: str | None = None  # the formatted traceback when the demonstrator raised
    trace: tuple[AtomChange, ...] = ()  # the last abstract states before the failure

    @property
    def solved(self) -> bool:
        return self.demo is not None

    def explain(self, debug: bool = False) -> str:
        """One line (the error); with ``debug`` also the traceback and the atom trace."""
        if self.solved:
            return f"solved in {self.steps} steps"
        lines = [f"{self.error} (after {self.steps} steps)"]
        if debug:
            if self.traceback:
                lines.append(self.traceback.rstrip())
            for change in self.trace:
                lines.append(f"  from step {change.step}: {', '.join(change.atoms) or '(none)'}")
        return "\n".join(lines)


class ActionNoise:
    """DART-style noise injection (Laskey et al., 2017): the executed action is the
    demonstrator's plus zero-mean Gaussian noise of ``scale`` times each dimension's half
    range, clipped into the bounds; the demonstrator's command is the label.

    Behaviour cloning learns only the states the demonstrator visits. Stick Button's
    cloned stick press overshot the demonstrator's travel height by two centimetres,
    where no demonstration said "go down": inputs clipped into the training box kept
    saying "still rising" and the arm rose to its limit and stayed. With noise the
    demonstrator corrects from wherever the perturbed action took it, and those
    corrections are in the data. The scale must stay below the demonstrator's own
    tolerances: 0.15 (3 mm per step) kept the hand jittering around its 3 mm "arrived:
    close the fingers" test, the labels there became a mix of "open" and "close", and
    the cloned grasp stopped at the stick with open fingers; 0.05 (1 mm) did not.
    Noise proportional to the command instead is smallest exactly where the overshoot
    begins (the arm slows into its travel height) and left that press failing. The
    noise stream is spawned from the demonstration's seed, so the demonstrator's own
    draws (grasp points, orders) are the same with and without noise.
    """

    def __init__(self, scale: float, low: np.ndarray, high: np.ndarray, seed: int | list[int]):
        if not 0.0 <= scale < np.inf:
            raise ValueError(f"action noise scale must be finite and >= 0, got {scale}")
        self.low, self.high = np.asarray(low, np.float64), np.asarray(high, np.float64)
        self.std = scale * (self.high - self.low) / 2.0
        self.rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])

    def __call__(self, action: np.ndarray) -> np.ndarray:
        noisy = action + self.std * self.rng.standard_normal(action.shape)
        return np.minimum(np.maximum(noisy, self.low), self.high)


def demo_noise_of(env: Environment) -> float:
    """The DART noise scale ``env`` declares for its demonstrations (0.0: none)."""
    return env.capabilities.demo_noise


def attempt_demonstration(
    env: Environment,
    task: Task,
    seed: int | list[int],
    trace_length: int = TRACE_LENGTH,
    noise: float = 0.0,
) -> DemoAttempt:
    """Roll the env's demonstrator out from ``task.init`` and report the outcome.

    ``noise`` > 0 executes perturbed actions (:class:`ActionNoise`) and records the
    demonstrator's commands as the demo's ``expert_actions``; 0 is a plain rollout."""
    states: list[State] = [task.init]
    actions: list[np.ndarray] = []
    commanded: list[np.ndarray] = []
    error = trace_text = None
    try:
        perturb = ActionNoise(noise, env.action_low, env.action_high, seed) if noise else None
        policy: Callable[[State], np.ndarray] = env.demonstrator(task, np.random.default_rng(seed))
        state = task.init
        for _ in range(task.horizon):
            if task.goal_holds(abstract(state, env.goal_predicates)):
                break
            action = env.check_action(policy(state))
            commanded.append(action)
            if perturb is not None:
                action = perturb(action)
            state = env.simulate(state, action)
            states.append(state)
            actions.append(action)
    except Exception as err:  # a failed demonstration is reported, not fatal  # noqa: BLE001
        error = f"{type(err).__name__}: {err}"
        trace_text = tb.format_exc()
    if error is None and task.goal_holds(abstract(states[-1], env.goal_predicates)):
        shape = (len(actions), len(env.action_low))
        act = np.asarray(actions, dtype=np.float64).reshape(shape)
        expert = None if perturb is None else np.asarray(commanded, np.float64).reshape(shape)
        demo = Demonstration(task=task, states=tuple(states), actions=act, expert_actions=expert)
        return DemoAttempt(demo, len(actions))
    if error is None:
        missing = task.goal - frozenset(abstract(states[-1], env.goal_predicates))
        error = f"goal not reached within the horizon ({task.horizon}); missing {_names(missing)}"
    trace = _atom_trace(env, states, trace_length)
    return DemoAttempt(None, len(actions), error, trace_text, trace)


def _names(atoms) -> str:
    return ", ".join(sorted(map(str, atoms)))


def _atom_trace(env: Environment, states: list[State], keep: int) -> tuple[AtomChange, ...]:
    """The last ``keep`` distinct abstract states of the run, oldest first."""
    changes: list[AtomChange] = []
    previous: tuple[str, ...] | None = None
    for step, state in enumerate(states):
        try:
            atoms = tuple(sorted(map(str, abstract(state, env.predicates))))
        except Exception as err:  # noqa: BLE001  (a broken predicate must not hide the failure)
            atoms = (f"<predicates raised {type(err).__name__}: {err}>",)
        if atoms != previous:
            changes.append(AtomChange(step, atoms))
            previous = atoms
    return tuple(changes[-keep:])
