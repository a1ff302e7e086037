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


def abstract(state: State, predicates: Collection[Predicate]) -> frozenset[GroundAtom]:
    """alpha(x): every ground atom over ``state``'s objects whose classifier holds."""
    objects = state.objects
    return frozenset(
        GroundAtom(p, combo)
        for p in sorted(predicates)
        for combo in object_tuples(objects, p.types)
        if p.holds(state, combo)
    )
