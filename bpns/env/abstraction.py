"""State abstraction: the set of ground atoms true in a state (paper §2)."""

from __future__ import annotations

import itertools
from collections.abc import Collection, Iterator, Sequence

from bpns.structs import GroundAtom, Object, Predicate, State, Type


def object_tuples(objects: Sequence[Object], types: Sequence[Type]) -> Iterator[tuple[Object, ...]]:
    """All tuples of distinct objects whose types match ``types`` position by position."""
    by_type = {t: [o for o in objects if o.type == t] for t in set(types)}
    for combo in itertools.product(*(by_type[t] for t in types)):
        if len(set(combo)) == len(combo):
            yield combo


def ground_atoms(
    objects: Sequence[Object], predicates: Collection[Predicate]
) -> tuple[GroundAtom, ...]:
    """Every ground atom of ``predicates`` over ``objects``, true or not: built once for
    the many states of one task (a demonstration), which all hold the same objects."""
    return tuple(
        GroundAtom(p, combo)
        for p in sorted(predicates)
        for combo in object_tuples(objects, p.types)
    )


def true_atoms(state: State, atoms: Sequence[GroundAtom]) -> frozenset[GroundAtom]:
    """The atoms of ``atoms`` (from :func:`ground_atoms`) whose classifier holds in ``state``."""
    return frozenset(a for a in atoms if a.predicate.classifier(state, a.objects))


def abstract(state: State, predicates: Collection[Predicate]) -> frozenset[GroundAtom]:
    """alpha(x): every ground atom over ``state``'s objects whose classifier holds."""
    return true_atoms(state, ground_atoms(state.objects, predicates))
