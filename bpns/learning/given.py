"""Given skills: policies and samplers an environment supplies (e.g. motion planners).

Paper Q3 (Doors): where a motion planner exists, BPNS uses it instead of learning to
move. An environment declares its given skills in ``Capabilities(given_skills=...)``
(optional). Each is a :class:`~bpns.structs.GivenSkill`: a name, a *signature* operator
over the skill's own parameters, and a policy and sampler over those parameters.
Operators are still learned from the demonstrations for every segment group. A learned
operator *is produced by* a given skill when some injective, type-preserving mapping of
the signature's parameters onto the operator's parameters sends the signature's add
effects exactly onto the operator's add effects and its delete effects and preconditions
into the operator's. The learned skill of such an operator keeps the given policy and
sampler (called with the objects reordered by that mapping) and no network is trained
for it. The demonstrator makes this hold by running the given skills' own policies for
those segments.

Saved skills record a given skill by name and mapping (``artifacts``); loading needs
the environment's given skills again.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bpns.structs import (
    GivenSkill,
    LiftedAtom,
    Object,
    State,
    STRIPSOperator,
    Variable,
)

if TYPE_CHECKING:
    from bpns.env.environment import Environment


@dataclass(frozen=True)
class BoundPolicy:
    """A given policy called with a learned operator's objects, reordered."""

    given: GivenSkill
    binding: tuple[int, ...]  # signature parameter i -> operator parameter binding[i]

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        return self.given.policy(state, [objects[i] for i in self.binding], subgoal)


@dataclass(frozen=True)
class BoundSampler:
    """A given sampler called with a learned operator's objects, reordered."""

    given: GivenSkill
    binding: tuple[int, ...]

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        return self.given.sampler(state, [objects[i] for i in self.binding], rng)


def _substitute(atoms: Iterable[LiftedAtom], sub: dict[Variable, Variable]) -> frozenset:
    return frozenset(LiftedAtom(a.predicate, tuple(sub[v] for v in a.variables)) for a in atoms)


def binding_for(signature: STRIPSOperator, operator: STRIPSOperator) -> tuple[int, ...] | None:
    """The first mapping (in parameter order) under which ``operator`` is produced by the
    skill with ``signature``, as operator parameter indices; None if there is none."""
    params = list(operator.parameters)
    for choice in itertools.permutations(range(len(params)), len(signature.parameters)):
        if any(params[j].type != v.type for v, j in zip(signature.parameters, choice, strict=True)):
            continue
        sub = {v: params[j] for v, j in zip(signature.parameters, choice, strict=True)}
        if (
            _substitute(signature.add_effects, sub) == operator.add_effects
            and _substitute(signature.delete_effects, sub) <= operator.delete_effects
            and _substitute(signature.preconditions, sub) <= operator.preconditions
        ):
            return tuple(choice)
    return None


def match_given(
    operator: STRIPSOperator, given: Sequence[GivenSkill]
) -> tuple[GivenSkill, tuple[int, ...]] | None:
    """The first given skill that produces ``operator``, with its binding."""
    for g in given:
        binding = binding_for(g.signature, operator)
        if binding is not None:
            return g, binding
    return None


def given_skills_of(env: Environment) -> tuple[GivenSkill, ...]:
    """The environment's given skills (``capabilities.given_skills``), else none."""
    make = env.capabilities.given_skills
    return () if make is None else tuple(make())
