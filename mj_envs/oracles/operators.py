"""Writing the oracle skills' STRIPS operators, shared by the domains' skills modules.

A domain lists its hand-written operators as plainly as the paper's appendix does: a name,
the parameters, and the preconditions, add and delete effects as sets of lifted atoms.
:func:`make_operator` turns those sets into the frozensets
:class:`bpns.structs.STRIPSOperator` holds, :func:`atom` builds one lifted atom.
"""

from __future__ import annotations

from collections.abc import Iterable

from bpns.structs import LiftedAtom, Predicate, STRIPSOperator, Variable


def make_operator(
    name: str,
    params: Iterable[Variable],
    pre: Iterable[LiftedAtom],
    add: Iterable[LiftedAtom],
    delete: Iterable[LiftedAtom],
) -> STRIPSOperator:
    """The operator ``name`` over ``params`` (in order) with preconditions ``pre``, add
    effects ``add`` and delete effects ``delete``; any iterables, frozen here so that a
    domain can write them as set literals."""
    return STRIPSOperator(name, tuple(params), frozenset(pre), frozenset(add), frozenset(delete))


def atom(pred: Predicate, *args: Variable) -> LiftedAtom:
    """``pred`` applied to the variables ``args``, e.g. ``atom(HOLDING, robot, block)``."""
    return LiftedAtom(pred, tuple(args))
