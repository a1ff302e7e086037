"""Grounding of lifted operators into a compact STRIPS problem for fast search.

Atoms are interned to bit positions, so an abstract state is a Python ``int`` bitmask:
subset tests, successor computation and hashing are single integer operations, which
keeps the search loop cheap. Operators are only grounded where a relaxed (delete-free)
forward exploration from the initial atoms can reach all their preconditions; nothing
unreachable is ever created.
"""

from __future__ import annotations

import time
from collections.abc import Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass, field

from bpns.errors import BpnsError
from bpns.structs import GroundAtom, GroundOperator, LiftedAtom, Object, STRIPSOperator, Variable


class SearchTimeout(BpnsError):
    """Raised by grounding and search when their wall-clock deadline has passed."""


def check_deadline(deadline: float | None) -> None:
    if deadline is not None and time.monotonic() >= deadline:
        raise SearchTimeout


def iter_bits(mask: int) -> Iterator[int]:
    """Indices of the set bits of ``mask``, lowest first."""
    while mask:
        low = mask & -mask
        yield low.bit_length() - 1
        mask ^= low


@dataclass(frozen=True, eq=False)
class GroundProblem:
    """A ground STRIPS problem over interned atoms; states are ``int`` bitmasks.

    ``pre``/``add``/``delete`` hold one mask per operator, ``pre_idx``/``add_idx`` the same
    as index tuples (what the relaxation heuristics iterate over). Atoms unknown to the
    problem (never reachable, in no goal) are dropped by :meth:`encode`: no operator
    mentions them, so they cannot matter to search.
    """

    atoms: tuple[GroundAtom, ...]
    operators: tuple[GroundOperator, ...]
    pre: tuple[int, ...]
    add: tuple[int, ...]
    delete: tuple[int, ...]
    init: int
    goal: int
    index: dict[GroundAtom, int] = field(repr=False)
    pre_idx: tuple[tuple[int, ...], ...] = field(repr=False)
    add_idx: tuple[tuple[int, ...], ...] = field(repr=False)

    @staticmethod
    def from_ground_operators(
        operators: Iterable[GroundOperator],
        init_atoms: Collection[GroundAtom],
        goal: Collection[GroundAtom],
    ) -> GroundProblem:
        """Build from already-ground operators (kept in the given order, duplicates dropped)."""
        ops = tuple(dict.fromkeys(operators))
        atoms: set[GroundAtom] = set(init_atoms) | set(goal)
        for op in ops:
            atoms |= op.preconditions | op.add_effects | op.delete_effects
        ordered = tuple(sorted(atoms))
        index = {a: i for i, a in enumerate(ordered)}

        def mask(xs: Iterable[GroundAtom]) -> int:
            m = 0
            for a in xs:
                m |= 1 << index[a]
            return m

        return GroundProblem(
            atoms=ordered,
            operators=ops,
            pre=tuple(mask(op.preconditions) for op in ops),
            add=tuple(mask(op.add_effects) for op in ops),
            delete=tuple(mask(op.delete_effects - op.add_effects) for op in ops),
            init=mask(init_atoms),
            goal=mask(goal),
            index=index,
            pre_idx=tuple(tuple(sorted(index[a] for a in op.preconditions)) for op in ops),
            add_idx=tuple(tuple(sorted(index[a] for a in op.add_effects)) for op in ops),
        )

    @property
    def n_atoms(self) -> int:
        return len(self.atoms)

    def encode(self, atoms: Iterable[GroundAtom]) -> int:
        m = 0
        index = self.index
        for a in atoms:
            i = index.get(a)
            if i is not None:
                m |= 1 << i
        return m

    def decode(self, mask: int) -> frozenset[GroundAtom]:
        return frozenset(self.atoms[i] for i in iter_bits(mask))

    def is_goal(self, state: int) -> bool:
        return state & self.goal == self.goal

    def applicable(self, state: int) -> Iterator[int]:
        """Indices of the operators applicable in ``state``, in operator order."""
        for i, p in enumerate(self.pre):
            if state & p == p:
                yield i

    def successors(self, state: int) -> Iterator[tuple[int, int]]:
        """(operator index, successor state) for every applicable operator."""
        pre, add, delete = self.pre, self.add, self.delete
        for i, p in enumerate(pre):
            if state & p == p:
                yield i, (state & ~delete[i]) | add[i]


def ground(
    operators: Sequence[STRIPSOperator],
    objects: Sequence[Object],
    init_atoms: Collection[GroundAtom],
    goal: Collection[GroundAtom],
    deadline: float | None = None,
) -> GroundProblem:
    """Ground ``operators`` over typed, pairwise-distinct ``objects``, keeping only those
    whose preconditions are reachable in the delete relaxation from ``init_atoms``.

    Ground operators are ordered by (operator ``sort_name``, position in ``operators``,
    object names) so search tie-breaking is deterministic. Raises :class:`SearchTimeout` past
    ``deadline``.
    """
    check_deadline(deadline)
    by_type: dict = {}
    for o in sorted(objects):
        by_type.setdefault(o.type, []).append(o)
    reached: set[GroundAtom] = set(init_atoms)
    reached_by_pred: dict = {}
    index: dict = {}  # (predicate, position, object) -> indices into reached_by_pred's list
    for a in sorted(reached):
        _reach(a, reached_by_pred, index)

    found: dict[tuple[int, tuple[Object, ...]], GroundOperator] = {}
    # semi-naive: after the first pass a binding is new only if one of its preconditions
    # was reached since the previous pass began (index >= that pass' length of its list);
    # every other binding was already enumerated then
    since: dict | None = None
    changed = True
    while changed:
        changed = False
        marks = {pred: len(objs) for pred, objs in reached_by_pred.items()}
        for k, op in enumerate(operators):
            new_ops = []
            for objs in _bindings(op, reached_by_pred, by_type, deadline, since, index):
                if (k, objs) not in found:
                    new_ops.append((k, objs))
            for k_objs in new_ops:
                gop = op.ground(k_objs[1])
                found[k_objs] = gop
                for a in sorted(gop.add_effects - reached):
                    reached.add(a)
                    _reach(a, reached_by_pred, index)
                    changed = True
        since = marks
    ordered = sorted(
        found.items(),
        key=lambda kv: (kv[1].operator.sort_name, kv[0][0], tuple(o.name for o in kv[0][1])),
    )
    return GroundProblem.from_ground_operators((g for _, g in ordered), init_atoms, goal)


def _reach(atom: GroundAtom, reached_by_pred: dict, index: dict) -> None:
    """Append ``atom`` to its predicate's list of reached atoms and index it by each of
    its (position, object) pairs."""
    atoms = reached_by_pred.setdefault(atom.predicate, [])
    for position, obj in enumerate(atom.objects):
        index.setdefault((atom.predicate, position, obj), []).append(len(atoms))
    atoms.append(atom.objects)


def _bindings(
    op: STRIPSOperator,
    reached_by_pred: dict,
    by_type: dict,
    deadline: float | None,
    since: dict | None = None,
    index: dict | None = None,
) -> Iterator[tuple[Object, ...]]:
    """Injective, typed parameter tuples for which every precondition is already reached.

    Preconditions are matched one at a time against reached atoms (a join), so the cost
    follows the number of reached atoms, not |objects|^arity; parameters that occur in no
    precondition range over all remaining objects of their type. With ``since`` (a
    length per predicate's list of reached atoms) only tuples with at least one
    precondition at or past that length are yielded, each once: the first such
    precondition d matches new atoms only, those before it old atoms only. With
    ``index`` (see :func:`_reach`) a precondition with a bound parameter is matched
    only against the atoms that have its object there, not every atom of its predicate.
    """
    # Most constraining first: high arity binds more variables per match.
    pres: list[LiftedAtom] = sorted(op.preconditions, key=lambda a: (-len(a.variables), str(a)))
    params = op.parameters
    binding: dict[Variable, Object] = {}
    used: set[Object] = set()

    def free_params(j: int) -> Iterator[tuple[Object, ...]]:
        while j < len(params) and params[j] in binding:
            j += 1
        if j == len(params):
            yield tuple(binding[v] for v in params)
            return
        var = params[j]
        for obj in by_type.get(var.type, ()):
            if obj in used:
                continue
            binding[var] = obj
            used.add(obj)
            yield from free_params(j + 1)
            del binding[var]
            used.discard(obj)

    def match(i: int, delta: int) -> Iterator[tuple[Object, ...]]:
        if i == len(pres):
            yield from free_params(0)
            return
        check_deadline(deadline)
        atom = pres[i]
        candidates = reached_by_pred.get(atom.predicate, ())
        # the list may grow later; index what exists now
        indices = range(len(candidates))
        if since is not None and delta >= 0:
            mark = since.get(atom.predicate, 0)
            indices = range(min(mark, len(candidates))) if i < delta else indices
            indices = range(mark, len(candidates)) if i == delta else indices
        if index is not None:
            keys = [
                (atom.predicate, position, binding[var])
                for position, var in enumerate(atom.variables)
                if var in binding
            ]
            if keys:
                shortest = min((index.get(key, ()) for key in keys), key=len)
                indices = [n for n in shortest if indices.start <= n < indices.stop]
        for n in indices:
            objs = candidates[n]
            bound: list[Variable] = []
            ok = True
            for var, obj in zip(atom.variables, objs, strict=True):
                cur = binding.get(var)
                if cur is None:
                    if obj in used:
                        ok = False
                        break
                    binding[var] = obj
                    used.add(obj)
                    bound.append(var)
                elif cur != obj:
                    ok = False
                    break
            if ok:
                yield from match(i + 1, delta)
            for var in bound:
                used.discard(binding.pop(var))

    if since is None:
        yield from match(0, -1)
        return
    for d, atom in enumerate(pres):  # the first precondition matched to a new atom
        if len(reached_by_pred.get(atom.predicate, ())) > since.get(atom.predicate, 0):
            yield from match(0, d)
