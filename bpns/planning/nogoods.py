r"""Refuted refinement steps, remembered across samples and skeletons of one ``plan`` call.

Plain chronological backtracking (paper Alg. 1) is exponential in the depth of an
unrefinable step: if step :math:`j` can never succeed, every one of the
:math:`N_{samples}^{j}` sample combinations of the steps before it is tried, although
most of them lead to practically the same state. In physical domains a refinement
attempt costs a rollout, so this dominates planning time (Stick Button: pressing an
out-of-reach button by hand at step 3 of a skeleton costs about a thousand rollouts).

A *nogood* records that, from a low-level state :math:`x`, something failed after
``n_samples`` samples:

* a **step nogood** ``(o_i, \text{test}_i, x)``: the ground skill :math:`o_i` never reached
  its expected abstract state from :math:`x` (no sample succeeded). It holds whatever
  the skeleton around it, so it also prunes other skeletons that contain the step.
* a **suffix nogood** ``((o_i, \text{test}_i), \ldots, (o_{n-1}, \text{test}_{n-1}), x)``:
  step :math:`i` succeeded but no continuation refined the rest of the skeleton.

A fresh arrival at a step from a state :math:`x'` that matches a recorded :math:`x` (every
feature within ``atol``, in the features' own units) is refuted at once, without
simulation. The effect is automatic backjumping: once a later step is refuted, resampling
an earlier step that leaves the world as it was is skipped, and backtracking moves on to
the step whose samples actually change the state (e.g. the grasp that decides a reach).
This is a heuristic: ``n_samples`` failures from a state are taken as evidence that
samples from a nearby state fail too. ``PlanningConfig.nogood_atol=None`` switches it off
(the paper's plain backtracking).

The module also holds the plan call's two other memories: :class:`PrefixCache` (refined
prefixes, reused by later skeletons) and :class:`SetAsidePrefixes` (prefixes whose last
step failed from several arrivals, see ``PlanningConfig.set_aside_after``).
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from bpns.structs import GroundAtom, GroundOperator, STRIPSOperator

StepKey = tuple[GroundOperator, frozenset[GroundAtom], frozenset[GroundAtom]]
Achiever = tuple[STRIPSOperator, frozenset[GroundAtom]]


class NogoodMemo:
    """Low-level states from which a step, or a skeleton suffix, was refuted."""

    def __init__(self, atol: float) -> None:
        if not atol >= 0.0:
            raise ValueError(f"nogood atol must be >= 0, got {atol}")
        self.atol = atol
        self._states: dict[Hashable, list[np.ndarray]] = {}
        self.hits = 0

    @staticmethod
    def step_key(op: GroundOperator, must_hold, must_not_hold) -> StepKey:
        return (op, frozenset(must_hold), frozenset(must_not_hold))

    def add(self, key: Hashable, features: np.ndarray) -> None:
        self._states.setdefault(key, []).append(features)

    def refuted(self, key: Hashable, features: np.ndarray) -> bool:
        for x in self._states.get(key, ()):
            if (
                x.shape == features.shape
                and float(np.max(np.abs(x - features), initial=0.0)) <= self.atol
            ):
                self.hits += 1
                return True
        return False

    def __len__(self) -> int:
        return sum(len(v) for v in self._states.values())


class PrefixCache:
    """The first successful refinement of every skeleton prefix, keyed by its steps.

    Skeletons generated one after another share long prefixes (they differ in their last
    steps), and the abstract states a prefix must produce are part of the key, so a new
    skeleton can start from the deepest prefix already refined instead of simulating it
    again. Backtracking into a reused step draws fresh samples as usual.
    """

    def __init__(self) -> None:
        self._prefixes: dict[tuple[Hashable, ...], list] = {}
        self.steps_reused = 0

    def longest(self, keys: list[Hashable]) -> list:
        """The cached segments of the longest refined prefix of ``keys`` (maybe empty)."""
        for k in range(len(keys), 0, -1):
            found = self._prefixes.get(tuple(keys[:k]))
            if found is not None:
                self.steps_reused += k
                return found
        return []

    def add(self, keys: list[Hashable], segments: list) -> None:
        self._prefixes.setdefault(tuple(keys), list(segments))


class SetAsidePrefixes:
    """Skeleton prefixes set aside: their last step failed every sample from
    ``PlanningConfig.set_aside_after`` different arrivals.

    A step's success depends only on the steps before it, so another skeleton that
    starts with the same steps (the same expected abstract states included) would fail
    there the same way: it is set aside at once, without simulation. Skeletons that
    differ only after such a step are common (the same plan with its last steps in
    another order), and each would otherwise pay for its own arrivals.
    """

    def __init__(self) -> None:
        self._prefixes: set[tuple[Hashable, ...]] = set()
        self.hits = 0

    def add(self, keys: list[Hashable]) -> None:
        self._prefixes.add(tuple(keys))

    def covering(self, keys: list[Hashable]) -> int | None:
        """The index of the last step of the shortest set-aside prefix of ``keys``."""
        for k in range(1, len(keys) + 1):
            if tuple(keys[:k]) in self._prefixes:
                self.hits += 1
                return k - 1
        return None


class RefutedAchievers:
    """Ways of achieving atoms that refinement keeps refuting, demoted in the abstract
    search (``PlanningConfig.demote_refuted``).

    An *achiever* is a lifted operator with the atoms a ground step of it adds: the
    skill, and what it was chosen to achieve, whatever the other arguments (Stick
    Button's press from one button or another). Once a step has failed every sample from
    an arrival and no step of the same achiever has succeeded in this ``plan`` call, every
    ground operator of it costs ``cost`` more, so skeletons that achieve those atoms
    another way come first. In Stick Button a button out of the hand's reach is refuted
    at the first skeleton; without this the search yields every order of the other
    presses (7 buttons: 720) before a skeleton that presses it with the stick. Demotion
    only reorders skeletons, it drops none; an achiever that later succeeds is restored.
    """

    def __init__(self, cost: float) -> None:
        if not 0.0 < cost < float("inf"):
            raise ValueError(f"demotion cost must be finite and > 0, got {cost}")
        self.cost = cost
        self._refuted: set[Achiever] = set()
        self._achieved: set[Achiever] = set()
        self.demoted: frozenset[Achiever] = frozenset()

    def observe(
        self,
        operators: tuple[GroundOperator, ...],
        successes: tuple[int, ...],
        refutations: tuple[int, ...],
    ) -> bool:
        """Record one refinement's steps; True if the demoted set changed."""
        for op, ok, refuted in zip(operators, successes, refutations, strict=False):
            if ok:
                self._achieved.add(_achiever(op))
            elif refuted:
                self._refuted.add(_achiever(op))
        demoted = frozenset(self._refuted - self._achieved)
        changed = demoted != self.demoted
        self.demoted = demoted
        return changed

    def extra_cost(self, operators: tuple[GroundOperator, ...]) -> list[float]:
        """Per ground operator: ``cost`` if its achiever is demoted, else 0."""
        return [self.cost if _achiever(op) in self.demoted else 0.0 for op in operators]


def _achiever(op: GroundOperator) -> Achiever:
    return (op.operator, op.add_effects)
