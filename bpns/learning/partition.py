"""Partition segments into skill datasets by effects equal up to object renaming (§4.1).

Two segments belong together when an injective, type-preserving mapping of the first's
affected objects onto the second's carries its add effects onto the other's add effects
and its delete effects onto the other's delete effects. Each group is lifted onto
variables made from its representative (first) segment, so lifting happens here too.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from bpns.structs import GroundAtom, LiftedAtom, Object, Predicate, Segment, Variable

_ADD, _DEL = 0, 1


@dataclass(frozen=True, eq=False)
class SegmentGroup:
    """Segments with equivalent effects, each with its object -> variable substitution.

    ``substitutions[i]`` maps exactly the affected objects of ``segments[i]`` onto
    ``parameters``; ``add_effects``/``delete_effects`` are the lifted effects they share.
    """

    parameters: tuple[Variable, ...]
    add_effects: frozenset[LiftedAtom]
    delete_effects: frozenset[LiftedAtom]
    segments: tuple[Segment, ...]
    substitutions: tuple[Mapping[Object, Variable], ...]

    def __len__(self) -> int:
        return len(self.segments)


def effect_mapping(source: Segment, target: Segment) -> dict[Object, Object] | None:
    """An injective, type-preserving map of ``source``'s affected objects onto
    ``target``'s under which their effects coincide, or None. Deterministic."""
    return _unify(_tagged(source), _tagged(target))


def _tagged(segment: Segment) -> list[tuple[int, GroundAtom]]:
    return [(_ADD, a) for a in sorted(segment.add_effects)] + [
        (_DEL, a) for a in sorted(segment.delete_effects)
    ]


def _signature(segment: Segment) -> tuple:
    """Invariant under renaming: cheap filter before backtracking."""
    preds = Counter((tag, a.predicate.name) for tag, a in _tagged(segment))
    types = Counter(o.type.name for o in segment.affected_objects)
    return tuple(sorted(preds.items())), tuple(sorted(types.items()))


def _unify(
    source: list[tuple[int, GroundAtom]], target: list[tuple[int, GroundAtom]]
) -> dict[Object, Object] | None:
    if len(source) != len(target):
        return None
    index: dict[tuple[int, Predicate], list[GroundAtom]] = defaultdict(list)
    for tag, atom in target:
        index[(tag, atom.predicate)].append(atom)
    if Counter((t, a.predicate) for t, a in source) != Counter((t, a.predicate) for t, a in target):
        return None
    # Most constrained atoms first; sort is stable, so ties keep the deterministic order.
    order = sorted(source, key=lambda ta: len(index[(ta[0], ta[1].predicate)]))
    mapping: dict[Object, Object] = {}
    used: set[Object] = set()

    def extend(k: int) -> bool:
        if k == len(order):
            return True
        tag, atom = order[k]
        for candidate in index[(tag, atom.predicate)]:
            added: list[Object] = []
            ok = True
            for obj, img in zip(atom.objects, candidate.objects, strict=True):
                current = mapping.get(obj)
                if current is None:
                    if img in used or img.type != obj.type:
                        ok = False
                        break
                    mapping[obj] = img
                    used.add(img)
                    added.append(obj)
                elif current != img:
                    ok = False
                    break
            if ok and extend(k + 1):
                return True
            for obj in added:
                used.discard(mapping.pop(obj))
        return False

    # Injective mapping + equal multisets per (tag, predicate) => image equals target.
    return dict(mapping) if extend(0) else None


def make_parameters(objects: Iterable[Object]) -> dict[Object, Variable]:
    """Variables ``?<type><k>`` ordered by type name, then object name."""
    sub: dict[Object, Variable] = {}
    counts: Counter[str] = Counter()
    for obj in sorted(objects, key=lambda o: (o.type.name, o.name)):
        sub[obj] = Variable(f"?{obj.type.name}{counts[obj.type.name]}", obj.type)
        counts[obj.type.name] += 1
    return sub


def partition_segments(segments: Iterable[Segment]) -> list[SegmentGroup]:
    """Group segments by equivalent effects; groups in order of first appearance."""
    reps: list[tuple[list[tuple[int, GroundAtom]], dict[Object, Variable]]] = []
    members: list[list[tuple[Segment, dict[Object, Variable]]]] = []
    by_signature: dict[tuple, list[int]] = defaultdict(list)
    for seg in segments:
        tagged = _tagged(seg)
        candidates = by_signature[_signature(seg)]
        for g in candidates:
            rep_tagged, rep_sub = reps[g]
            mapping = _unify(tagged, rep_tagged)
            if mapping is not None:
                members[g].append((seg, {o: rep_sub[m] for o, m in mapping.items()}))
                break
        else:
            sub = make_parameters(seg.affected_objects)
            candidates.append(len(reps))
            reps.append((tagged, sub))
            members.append([(seg, sub)])
    groups = []
    for (_, rep_sub), group in zip(reps, members, strict=True):
        rep = group[0][0]
        groups.append(
            SegmentGroup(
                parameters=tuple(rep_sub.values()),  # make_parameters' order
                add_effects=frozenset(a.lift(rep_sub) for a in rep.add_effects),
                delete_effects=frozenset(a.lift(rep_sub) for a in rep.delete_effects),
                segments=tuple(s for s, _ in group),
                substitutions=tuple(sub for _, sub in group),
            )
        )
    return groups
