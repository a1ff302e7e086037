r"""An execution monitor for plans refined in a model and executed in a world.

The abstract plan says which atoms the rest of the plan relies on: regressing the goal
through the operators from the last one back,

.. math::

    N_n = G, \qquad N_i = (N_{i+1} \setminus \mathrm{add}_i) \cup \mathrm{pre}_i ,

``N_i`` must hold before step i for steps i..n-1 to reach the goal (the STRIPS
necessary atoms). After step i the world's abstract state must contain ``N_{i+1}``;
while step i runs, the contact-related atoms of ``N_{i+1}`` and of step i's own
preconditions that were already true, that step i does not delete and that the model's
own rollout kept true throughout (so a transient touch the model also made does not
alarm) must go on holding.

Unlike the operators' predicted abstract states (which refinement of simulated plans
matches by construction, so a monitor comparing with them never fires), the necessary
atoms ignore side effects the rest of the plan does not care about.

Optionally (``ExecutionConfig.watch_releases``) a step's contact preconditions that it
deletes itself are watched too, until its add effects hold: a grip the model's rollout
kept until the door opened (and only then let go) that the world loses earlier is a
divergence, not the step's end.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence

from bpns.structs import GroundAtom, GroundOperator, Predicate, State


def necessary_atoms(
    operators: Sequence[GroundOperator], goal: frozenset[GroundAtom]
) -> tuple[frozenset[GroundAtom], ...]:
    """``N_0 .. N_n`` of the module docstring (``len(operators) + 1`` sets)."""
    out = [goal]
    for op in reversed(operators):
        out.append((out[-1] - op.add_effects) | op.preconditions)
    return tuple(reversed(out))


def kept_atoms(
    op: GroundOperator,
    start: frozenset[GroundAtom],
    needed_after: frozenset[GroundAtom],
    contact_predicates: Collection[Predicate],
    model_states: Sequence[State] = (),
) -> tuple[GroundAtom, ...]:
    """The atoms a running step must not lose (see the module docstring), sorted."""
    needed = needed_after | op.preconditions  # the running step needs its own too
    candidates = [
        a
        for a in (start & needed) - op.delete_effects - op.add_effects
        if a.predicate in contact_predicates
    ]
    held = [a for a in candidates if all(a.holds(s) for s in model_states)]
    return tuple(sorted(held, key=str))


def released_atoms(
    op: GroundOperator,
    start: frozenset[GroundAtom],
    contact_predicates: Collection[Predicate],
    model_states: Sequence[State],
) -> tuple[GroundAtom, ...]:
    """The contact preconditions ``op`` deletes (true at the step's start) that the model's
    rollout of the step kept true in every state before the first one where all of its
    add effects hold: in the world they may go only once those hold too, sorted; none
    when the model's rollout never reached the add effects."""
    candidates = [
        a for a in start & op.preconditions & op.delete_effects if a.predicate in contact_predicates
    ]
    if not candidates:
        return ()
    before: list[State] = []
    for s in model_states:
        if all(a.holds(s) for a in op.add_effects):
            held = [a for a in candidates if all(a.holds(b) for b in before)]
            return tuple(sorted(held, key=str))
        before.append(s)
    return ()


def repair_point(
    necessary: Sequence[frozenset[GroundAtom]], atoms: frozenset[GroundAtom]
) -> int | None:
    """The last step j of the plan from which its rest still applies in ``atoms``
    (``necessary[j] <= atoms``, the fewest steps left), or None."""
    for j in range(len(necessary) - 1, -1, -1):
        if necessary[j] <= atoms:
            return j
    return None


def atoms_text(atoms: Iterable[GroundAtom]) -> str:
    """``Holding(block0), HandEmpty(robot)``: atoms for a caption, sorted."""
    return ", ".join(sorted(str(a) for a in atoms))
