"""Readable names for learned operators, derived from what they achieve.

An operator is named after the predicates of its add effects (sorted, joined by
``_``), or ``Not`` + those of its delete effects when it adds nothing: Cover's pick is
``Holding`` and its place ``Covers_HandEmpty``. Operators that would share a name get
a numeric suffix in learned-index order (``Pressed_StickAboveButton_1``, ``..._2``).
Names are valid PDDL identifiers (a letter, then letters, digits, ``_`` or ``-``) and
file names. The paper's ``Op0, Op1, ...`` stay available (``LearningConfig.index_names``)
and remain every learned operator's ``order_key``, so planning orders operators exactly
as it did under index names.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Sequence

from bpns.structs import STRIPSOperator

_INVALID = re.compile(r"[^A-Za-z0-9_-]")


def index_name(k: int) -> str:
    """The paper's name of the ``k``-th learned operator."""
    return f"Op{k}"


def effect_name(op: STRIPSOperator) -> str:
    """``op``'s name before tie-breaks: its add effects' predicates, else ``Not`` + its
    delete effects' predicates, else ``Noop``."""
    if op.add_effects:
        base = "_".join(sorted({a.predicate.name for a in op.add_effects}))
    elif op.delete_effects:
        base = "Not" + "_".join(sorted({a.predicate.name for a in op.delete_effects}))
    else:
        base = "Noop"
    base = _INVALID.sub("_", base)
    return base if base[:1].isalpha() else f"Op_{base}"


def readable_names(operators: Sequence[STRIPSOperator]) -> list[str]:
    """One unique readable name per operator, in the given (learned-index) order."""
    bases = [effect_name(op) for op in operators]
    shared = Counter(bases)
    seen: Counter = Counter()
    names: list[str] = []
    taken = {b for b, n in shared.items() if n == 1}
    for base in bases:
        if shared[base] == 1:
            names.append(base)
            continue
        while True:
            seen[base] += 1
            name = f"{base}_{seen[base]}"
            if name not in taken:
                break
        taken.add(name)
        names.append(name)
    return names
