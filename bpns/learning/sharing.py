"""Skills that reach the same effects from different situations learn from each other.

Segmentation splits one motion into several operators whenever what it leaves behind
differs. In Stick Button, pressing a button with the held stick is two operators: from
above no button (deleting ``AboveNoButton()``) and from above the button just pressed
(deleting ``StickAboveButton(?stick, ?other)``). The paper trains each operator's policy
and sampler on its own segments only, and the second variant gets a fifth of the data:
at 250 demonstrations 29 segments against 157, and its learned policy reached the
button from held-out demo states in 9 of 45 sampled rollouts (``scripts/
skill_diagnostics.py``), while the motion it must make, bringing the stick's tip onto
a button and pressing, is the one the first variant has 157 examples of.

So a skill also learns from every *donor* segment: a segment of an operator that ends
in a ground instance of all of this operator's add effects and reached at least one of
them itself. Formally, an injective, type-preserving mapping of this operator's
add-effect variables into the donor's parameters under which every add effect of this
operator is an atom the donor guarantees at its end (its add effects, or preconditions
it does not delete) and at least one is a donor add effect. Such a segment demonstrably
went where this skill must go. (Stick Button's grasp of the stick right after a press by
hand, which adds ``AboveNoButton()`` and ``Grasped``, learns from the plain grasps, which
keep ``AboveNoButton()`` and add ``Grasped``: at 250 demos its sampler's hand-y error
fell from 10 mm to ... on held-out segments.) The shared networks (policy and
subgoal generator) see the *effect scope*: the objects of the add effects, in parameter
order, the one part of the scope every donor has. Preconditions, effects, the skill
horizon and the classifier's negatives stay the skill's own. A skill with no donor keeps
its scope and its data exactly as before.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from bpns.learning.operators import SkillDataset
from bpns.structs import LiftedAtom, Object, Segment, STRIPSOperator, Variable


@dataclass(frozen=True, eq=False)
class SharedData:
    """The data a skill's policy and generator learn from.

    ``scope``: operator parameter indices forming the networks' scope. ``objects[i]``:
    the scope's objects in segment ``segments[i]``. The skill's own segments come first.
    ``donors``: the operators that lent segments, with how many."""

    scope: tuple[int, ...]
    segments: tuple[Segment, ...]
    objects: tuple[tuple[Object, ...], ...]
    donors: tuple[tuple[str, int], ...]


def effect_scope(operator: STRIPSOperator) -> tuple[int, ...]:
    """Indices of the parameters that occur in ``operator``'s add effects, in order."""
    used = {v for atom in operator.add_effects for v in atom.variables}
    return tuple(i for i, v in enumerate(operator.parameters) if v in used)


def embed_effects(
    operator: STRIPSOperator, donor: STRIPSOperator
) -> dict[Variable, Variable] | None:
    """A mapping of ``operator``'s add-effect variables to ``donor``'s variables,
    injective and type-preserving, under which each of ``operator``'s add effects holds
    at the end of ``donor`` (is one of its add effects or a precondition it keeps) and at
    least one is an add effect of ``donor``; None if there is none (or ``operator`` adds
    nothing)."""
    if not operator.add_effects:
        return None
    achieved = frozenset(donor.add_effects)
    targets = achieved | (donor.preconditions - donor.delete_effects)
    variables = [operator.parameters[i] for i in effect_scope(operator)]
    candidates = [[d for d in donor.parameters if d.type == v.type] for v in variables]
    atoms = sorted(operator.add_effects, key=str)

    def consistent(mapping: dict[Variable, Variable]) -> bool:
        for atom in atoms:
            if all(v in mapping for v in atom.variables):
                image = LiftedAtom(atom.predicate, tuple(mapping[v] for v in atom.variables))
                if image not in targets:
                    return False
        return True

    def reaches_one(mapping: dict[Variable, Variable]) -> bool:
        return any(
            LiftedAtom(a.predicate, tuple(mapping[v] for v in a.variables)) in achieved
            for a in atoms
        )

    def extend(i: int, mapping: dict[Variable, Variable]) -> dict[Variable, Variable] | None:
        if i == len(variables):
            return dict(mapping) if reaches_one(mapping) else None
        used = set(mapping.values())
        for d in candidates[i]:
            if d in used:
                continue
            mapping[variables[i]] = d
            if consistent(mapping):
                found = extend(i + 1, mapping)
                if found is not None:
                    return found
            del mapping[variables[i]]
        return None

    return extend(0, {})


def shared_data(datasets: Sequence[SkillDataset], k: int) -> SharedData | None:
    """What skill ``k`` learns from when other operators can lend it segments (in
    dataset order), else None: then it learns from its own data and scope as before."""
    own = datasets[k]
    scope = effect_scope(own.operator)
    if not scope:
        return None
    variables = [own.operator.parameters[i] for i in scope]
    segments = list(own.segments)
    objects = [tuple(b[i] for i in scope) for b in own.bindings]
    donors = []
    for j, other in enumerate(datasets):
        if j == k:
            continue
        mapping = embed_effects(own.operator, other.operator)
        if mapping is None:
            continue
        where = [other.operator.parameters.index(mapping[v]) for v in variables]
        segments.extend(other.segments)
        objects.extend(tuple(b[i] for i in where) for b in other.bindings)
        donors.append((other.operator.name, len(other.segments)))
    if not donors:
        return None
    return SharedData(scope, tuple(segments), tuple(objects), tuple(donors))
