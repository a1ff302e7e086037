"""Operator induction from lifted skill datasets (paper §4.2, "Operator Learning").

Effects come straight from a group's lifted effects; preconditions are the lifted
initial atoms common to every segment of the group. Rare groups are filtered out.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

from bpns.abstraction import object_tuples
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

    ``bindings[i]`` are the objects of ``segments[i]`` in the operator's parameter order:
    the skill scope used for that segment by policy and sampler learning.
    """

    operator: STRIPSOperator
    segments: tuple[Segment, ...]
    bindings: tuple[tuple[Object, ...], ...]

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


def learn_operators(
    groups: Sequence[SegmentGroup], min_segment_fraction: float = 0.01
) -> list[SkillDataset]:
    """One operator per group holding at least ``min_segment_fraction`` of all segments.

    Operators are named ``Op0, Op1, ...`` by decreasing dataset size (ties: first
    appearance in the demos), so names are stable for a given dataset.
    """
    total = sum(len(g) for g in groups)
    kept = [(i, g) for i, g in enumerate(groups) if len(g) >= min_segment_fraction * total]
    kept.sort(key=lambda ig: (-len(ig[1]), ig[0]))
    datasets = []
    for k, (_, group) in enumerate(kept):
        op = STRIPSOperator(
            name=f"Op{k}",
            parameters=group.parameters,
            preconditions=induce_preconditions(group),
            add_effects=group.add_effects,
            delete_effects=group.delete_effects,
        )
        inverses = (_inverse(sub) for sub in group.substitutions)
        bindings = tuple(tuple(inv[v] for v in group.parameters) for inv in inverses)
        datasets.append(SkillDataset(op, group.segments, bindings))
    return datasets


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
