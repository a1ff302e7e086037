"""Operator induction from lifted skill datasets (paper §4.2, "Operator Learning").

Effects come straight from a group's lifted effects; preconditions are the lifted
initial atoms common to every segment of the group. Rare groups are filtered out.

Beyond the paper, a group's parameters may be extended by *anchored* objects (see
:func:`anchor_parameters`): with parameters = affected objects only, a precondition that
relates an affected object to an unaffected one (the robot holding the stick that
presses a button) is dropped, and the planner proposes pressing with a stick nobody holds.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

from bpns.env.abstraction import object_tuples
from bpns.learning.naming import index_name, readable_names
from bpns.learning.partition import SegmentGroup
from bpns.structs import (
    GroundAtom,
    LiftedAtom,
    Object,
    Predicate,
    Segment,
    STRIPSOperator,
    Variable,
)


@dataclass(frozen=True, eq=False)
class SkillDataset:
    """A learned operator with the segments it was induced from.

    ``bindings[i]`` are the objects of ``segments[i]`` in the operator's parameter order;
    the first ``scope_size`` of them (None: all) are the skill's scope, used by policy
    and sampler learning. Anchored parameters come after the scope: they strengthen the
    operator's preconditions but the skill's networks never see them.
    """

    operator: STRIPSOperator
    segments: tuple[Segment, ...]
    bindings: tuple[tuple[Object, ...], ...]
    scope_size: int | None = None

    def __len__(self) -> int:
        return len(self.segments)


def lift_atoms(
    atoms: Collection[GroundAtom], sub: Mapping[Object, Variable]
) -> frozenset[LiftedAtom]:
    """Lift the atoms whose objects are all in ``sub``; the others are discarded."""
    return frozenset(a.lift(sub) for a in atoms if all(o in sub for o in a.objects))


def induce_preconditions(group: SegmentGroup) -> frozenset[LiftedAtom]:
    """Intersection over the group's segments of their lifted initial atoms."""
    pre: frozenset[LiftedAtom] | None = None
    for seg, sub in zip(group.segments, group.substitutions, strict=True):
        lifted = lift_atoms(seg.init_atoms, sub)
        pre = lifted if pre is None else pre & lifted
    return pre or frozenset()


def anchor_parameters(group: SegmentGroup) -> SegmentGroup:
    """``group`` with a parameter added for every object outside its effects that a
    relation ties to its parameters in the initial state of *every* segment.

    A pattern is a predicate of arity >= 2 with exactly one argument outside the
    segment's parameters and the others equal to given parameters, e.g.
    ``Grasped(?robot, ?stick0)`` for a stick press whose parameters are the button and
    the stick. It anchors a new parameter when it holds in every segment for exactly one
    object; the most common such patterns are taken one at a time (first by predicate
    name, argument position and variables), so a chain (a pot on the plate, the plate a
    parameter) is followed too. Unary atoms of outside objects never anchor: they would
    add a parameter the operator does not relate to anything. The new parameters take
    part in precondition induction; the skill's scope stays the affected objects (see
    ``SkillDataset.scope_size``): Coffee's button press with the pot in its scope had to
    predict the pot's features in its subgoals and planned slower.
    """
    params = list(group.parameters)
    subs = [dict(s) for s in group.substitutions]
    while True:
        found = [
            _outside_relations(seg.init_atoms, sub)
            for seg, sub in zip(group.segments, subs, strict=True)
        ]
        common = set.intersection(*(set(f) for f in found)) if found else set()
        usable = sorted(
            (key for key in common if all(len(f[key]) == 1 for f in found)),
            key=lambda key: (key[0].name, key[1], tuple(str(v) for v in key[2])),
        )
        if not usable:
            break
        predicate, position, _ = usable[0]
        new_type = predicate.types[position]
        var = Variable(f"?{new_type.name}{sum(v.type == new_type for v in params)}", new_type)
        while var in params:  # a name taken by a type with a digit-ending name: extend
            var = Variable(var.name + "_", new_type)
        for sub, f in zip(subs, found, strict=True):
            (obj,) = f[usable[0]]
            sub[obj] = var
        params.append(var)
    if len(params) == len(group.parameters):
        return group
    return SegmentGroup(
        parameters=tuple(params),
        add_effects=group.add_effects,
        delete_effects=group.delete_effects,
        segments=group.segments,
        substitutions=tuple(subs),
    )


def _outside_relations(
    atoms: Collection[GroundAtom], sub: Mapping[Object, Variable]
) -> dict[tuple, set[Object]]:
    """(predicate, outside position, lifted arguments) -> objects at that position, over
    the atoms with exactly one argument outside ``sub`` (arity >= 2)."""
    out: dict[tuple, set[Object]] = defaultdict(set)
    for atom in atoms:
        if len(atom.objects) < 2:
            continue
        outside = [k for k, o in enumerate(atom.objects) if o not in sub]
        if len(outside) != 1:
            continue
        k = outside[0]
        lifted = tuple(None if i == k else sub[o] for i, o in enumerate(atom.objects))
        out[(atom.predicate, k, lifted)].add(atom.objects[k])
    return out


def learn_operators(
    groups: Sequence[SegmentGroup],
    min_segment_fraction: float = 0.01,
    anchor: bool = True,
    index_names: bool = False,
) -> list[SkillDataset]:
    """One operator per group holding at least ``min_segment_fraction`` of all segments.

    Operators are indexed by decreasing dataset size (ties: first appearance in the
    demos), so they are stable for a given dataset, and named after their effects
    (:mod:`bpns.learning.naming`), or ``Op0, Op1, ...`` with ``index_names``; the index
    name is always the ``order_key``. ``anchor`` adds anchored parameters
    (:func:`anchor_parameters`) before preconditions are induced.
    """
    total = sum(len(g) for g in groups)
    kept = [(i, g) for i, g in enumerate(groups) if len(g) >= min_segment_fraction * total]
    kept.sort(key=lambda ig: (-len(ig[1]), ig[0]))
    datasets = []
    for k, (_, group) in enumerate(kept):
        scope_size = None
        if anchor:
            anchored = anchor_parameters(group)
            if anchored is not group:
                scope_size, group = len(group.parameters), anchored
        op = STRIPSOperator(
            name=index_name(k),
            parameters=group.parameters,
            preconditions=induce_preconditions(group),
            add_effects=group.add_effects,
            delete_effects=group.delete_effects,
        )
        inverses = (_inverse(sub) for sub in group.substitutions)
        bindings = tuple(tuple(inv[v] for v in group.parameters) for inv in inverses)
        datasets.append(SkillDataset(op, group.segments, bindings, scope_size))
    if index_names:
        return datasets
    names = readable_names([d.operator for d in datasets])
    return [
        dataclasses.replace(
            d, operator=dataclasses.replace(d.operator, name=name, order_key=d.operator.name)
        )
        for d, name in zip(datasets, names, strict=True)
    ]


def _inverse(sub: Mapping[Object, Variable]) -> dict[Variable, Object]:
    return {v: o for o, v in sub.items()}


def applicable_bindings(
    operator: STRIPSOperator, atoms: Collection[GroundAtom], objects: Sequence[Object]
) -> list[tuple[Object, ...]]:
    """All tuples of distinct objects (parameter order) whose ground preconditions hold
    in ``atoms``, sorted. Matches preconditions against the atoms instead of enumerating
    every typed tuple, which matters with many objects."""
    by_predicate: dict[Predicate, list[GroundAtom]] = defaultdict(list)
    for atom in sorted(atoms):
        by_predicate[atom.predicate].append(atom)
    pres = sorted(operator.preconditions, key=lambda a: (len(by_predicate[a.predicate]), a))
    binding: dict[Variable, Object] = {}
    used: set[Object] = set()
    results: list[tuple[Object, ...]] = []

    def complete() -> None:
        free = [v for v in operator.parameters if v not in binding]
        rest = [o for o in objects if o not in used]
        for combo in object_tuples(rest, [v.type for v in free]):
            full = {**binding, **dict(zip(free, combo, strict=True))}
            results.append(tuple(full[v] for v in operator.parameters))

    def extend(k: int) -> None:
        if k == len(pres):
            complete()
            return
        lifted = pres[k]
        for ground in by_predicate[lifted.predicate]:
            added: list[Variable] = []
            ok = True
            for var, obj in zip(lifted.variables, ground.objects, strict=True):
                current = binding.get(var)
                if current is None:
                    if obj in used:
                        ok = False
                        break
                    binding[var] = obj
                    used.add(obj)
                    added.append(var)
                elif current != obj:
                    ok = False
                    break
            if ok:
                extend(k + 1)
            for var in added:
                used.discard(binding.pop(var))

    extend(0)
    return sorted(results)
