"""Export operators, predicates and types as PDDL (STRIPS with :typing).

Lets users inspect learned operators with standard tools or hand them to an external
planner. Names that are not PDDL identifiers are made so deterministically (invalid
characters become ``_``; a leading non-letter gets an ``x`` prefix); two names that end up
equal are an error rather than a silent merge.
"""

from __future__ import annotations

import re
from collections.abc import Collection, Iterable

from bpns.env.abstraction import abstract
from bpns.structs import GroundAtom, LiftedAtom, Object, Predicate, STRIPSOperator, Task, Type

_INVALID = re.compile(r"[^A-Za-z0-9_-]")


def pddl_name(name: str) -> str:
    """``name`` as a PDDL identifier (letters, digits, '_' and '-', starting with a letter)."""
    out = _INVALID.sub("_", name)
    if not out or not out[0].isalpha():
        out = "x" + out
    return out


class _Names:
    """Sanitised names per namespace, checked for collisions."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._by_clean: dict[str, str] = {}

    def __call__(self, name: str) -> str:
        clean = pddl_name(name)
        other = self._by_clean.setdefault(clean.lower(), name)  # PDDL is case-insensitive
        if other != name:
            raise ValueError(
                f"{self.kind} names {other!r} and {name!r} both become {clean!r} in PDDL"
            )
        return clean


def _var(name: str) -> str:
    return "?" + pddl_name(name.lstrip("?"))


def domain_pddl(
    name: str,
    types: Iterable[Type],
    predicates: Iterable[Predicate],
    operators: Iterable[STRIPSOperator],
) -> str:
    """A PDDL domain with one typed STRIPS action per operator, deterministic order."""
    types, predicates, operators = tuple(types), tuple(predicates), tuple(operators)
    tnames, pnames, anames = _Names("type"), _Names("predicate"), _Names("operator")
    all_types = sorted(set(types) | {t for p in predicates for t in p.types})
    all_types += sorted({v.type for op in operators for v in op.parameters} - set(all_types))
    type_names = {t: tnames(t.name) for t in all_types}
    declared = [type_names[t] for t in all_types if type_names[t] != "object"]
    preds = sorted(set(predicates) | {a.predicate for op in operators for a in _atoms(op)})
    lines = [
        f"(define (domain {pddl_name(name)})",
        "  (:requirements :strips :typing)",
    ]
    if declared:
        lines.append(f"  (:types {' '.join(declared)} - object)")
    lines.append("  (:predicates")
    for p in preds:
        args = " ".join(f"?x{i} - {type_names[t]}" for i, t in enumerate(p.types))
        lines.append(f"    ({pnames(p.name)}{' ' + args if args else ''})")
    lines.append("  )")
    for op in sorted(operators):
        params = " ".join(f"{_var(v.name)} - {type_names[v.type]}" for v in op.parameters)
        pre = " ".join(_lifted(a, pnames) for a in sorted(op.preconditions))
        effects = [_lifted(a, pnames) for a in sorted(op.add_effects)]
        effects += [f"(not {_lifted(a, pnames)})" for a in sorted(op.delete_effects)]
        lines += [
            f"  (:action {anames(op.name)}",
            f"    :parameters ({params})",
            f"    :precondition (and {pre})" if pre else "    :precondition (and)",
            f"    :effect (and {' '.join(effects)})" if effects else "    :effect (and)",
            "  )",
        ]
    lines.append(")")
    return "\n".join(lines) + "\n"


def problem_pddl(
    name: str,
    domain_name: str,
    objects: Iterable[Object],
    init: Iterable[GroundAtom],
    goal: Iterable[GroundAtom],
) -> str:
    """A PDDL problem over ``objects`` with the given initial and goal atoms."""
    onames, pnames = _Names("object"), _Names("predicate")
    objs = sorted(objects)
    decl = " ".join(f"{onames(o.name)} - {pddl_name(o.type.name)}" for o in objs)
    goal_atoms = " ".join(_ground(a, pnames) for a in sorted(goal))
    return (
        "\n".join(
            [
                f"(define (problem {pddl_name(name)})",
                f"  (:domain {pddl_name(domain_name)})",
                f"  (:objects {decl})",
                f"  (:init {' '.join(_ground(a, pnames) for a in sorted(init))})",
                f"  (:goal (and {goal_atoms}))" if goal_atoms else "  (:goal (and))",
                ")",
            ]
        )
        + "\n"
    )


def task_problem_pddl(
    task: Task, predicates: Collection[Predicate], domain_name: str, name: str = "task"
) -> str:
    """The problem of ``task``: its objects, the abstraction of its initial state, its goal."""
    return problem_pddl(name, domain_name, task.objects, abstract(task.init, predicates), task.goal)


def _atoms(op: STRIPSOperator) -> frozenset[LiftedAtom]:
    return op.preconditions | op.add_effects | op.delete_effects


def _lifted(atom: LiftedAtom, pnames: _Names) -> str:
    return (
        "(" + " ".join([pnames(atom.predicate.name), *(_var(v.name) for v in atom.variables)]) + ")"
    )


def _ground(atom: GroundAtom, pnames: _Names) -> str:
    return (
        "("
        + " ".join([pnames(atom.predicate.name), *(pddl_name(o.name) for o in atom.objects)])
        + ")"
    )
