"""Lazy top-k generation of abstract plans ("skeletons") by best-first tree search.

Bilevel planning needs more than the first plan: when a skeleton cannot be refined the
next one is tried (paper §5, "top-k"). So the search is a *tree* search: a node is a path,
not a state, and several plans may pass through the same abstract state. Cycles along one
path are forbidden and paths are capped in length. To keep unsolvable problems finite and
avoid re-expanding popular states endlessly, each abstract state is expanded at most
``max_skeletons`` times (for A* with a consistent heuristic this is the classic
k-shortest-paths bound: the k best plans never need a state's (k+1)-th best prefix).
With extra operator costs the same bound is applied lazily: while looking for the
(j+1)-th plan a state is popped at most j+1 times, later pops being put off until a plan
is found or nothing else is left (so no plan is lost).

The strategy is only an ordering function ``priority(g, h)``; ties are broken by
insertion order, so results are deterministic.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Container, Iterator, Sequence
from dataclasses import dataclass

from bpns.planning.heuristics import Heuristic
from bpns.planning.strips import GroundProblem, check_deadline
from bpns.structs import GroundAtom, GroundOperator

Priority = Callable[[float, float], tuple[float, ...]]


def astar(g: float, h: float) -> tuple[float, ...]:
    """f = g + h, preferring deeper (lower h) nodes on ties."""
    return (g + h, h)


def gbfs(g: float, h: float) -> tuple[float, ...]:
    """Greedy: h only, shorter paths first on ties."""
    return (h, g)


def uniform_cost(g: float, h: float) -> tuple[float, ...]:
    """Dijkstra order; the heuristic is ignored (pass ``heuristic=None``)."""
    return (g,)


STRATEGIES: dict[str, Priority] = {"astar": astar, "gbfs": gbfs, "ucs": uniform_cost}


@dataclass(frozen=True)
class AbstractPlan:
    """A skeleton: ground operators and the abstract states they are expected to produce.

    ``atoms[0]`` is the initial abstract state and ``atoms[i + 1]`` the expected state
    after ``operators[i]``; refinement checks exactly these.
    """

    operators: tuple[GroundOperator, ...]
    atoms: tuple[frozenset[GroundAtom], ...]
    cost: float

    def __len__(self) -> int:
        return len(self.operators)


@dataclass
class SearchStats:
    """Mutable counters, updated while the generator runs (also across a timeout)."""

    nodes_created: int = 0
    nodes_expanded: int = 0
    skeletons: int = 0
    skipped: int = 0  # plans found but passed over (``skip``)


class _Node:
    __slots__ = ("state", "parent", "op", "g", "depth")

    def __init__(self, state: int, parent: _Node | None, op: int, g: float, depth: int) -> None:
        self.state = state
        self.parent = parent
        self.op = op
        self.g = g
        self.depth = depth

    def visits(self, state: int) -> int:
        """How often ``state`` occurs on the path from the root to this node."""
        n = 0
        node: _Node | None = self
        while node is not None:
            n += node.state == state
            node = node.parent
        return n


def skeletons(
    problem: GroundProblem,
    heuristic: Heuristic | None,
    priority: Priority,
    *,
    max_skeletons: int,
    max_length: int,
    max_repeats: int = 0,
    deadline: float | None = None,
    stats: SearchStats | None = None,
    extra_cost: Sequence[float] | None = None,
    skip: Container[tuple[GroundOperator, ...]] = (),
    resume: bool = False,
) -> Iterator[AbstractPlan]:
    """Yield up to ``max_skeletons`` distinct abstract plans in ``priority`` order.

    Plans have at most ``max_length`` operators, and an abstract state recurs on one plan
    at most ``max_repeats`` times: a loop in the abstraction can be real progress in the
    world (turning a pot by its knob and letting go changes only a continuous feature).
    Operator ``i`` costs ``1 + extra_cost[i]`` (1 without ``extra_cost``); the heuristic
    never sees the extra, so it stays admissible. Plans whose operators are in ``skip``
    (yielded by an earlier search of the same problem) are passed over and not counted.
    ``heuristic=None`` means h = 0 (and no dead-end pruning). With ``resume`` the first
    step may also be an operator whose only unmet preconditions are atoms it deletes
    itself (a skill the world stopped midway: its delete effects happened, its add
    effects not yet), so a plan may let that skill finish; the root is then not pruned
    as a dead end, since such a state is outside what the operators describe. The
    generator raises
    :class:`~bpns.planning.strips.SearchTimeout` once ``deadline`` (a
    ``time.monotonic()`` value) has passed, and simply ends when the space is exhausted.
    """
    stats = stats if stats is not None else SearchStats()
    h_of = heuristic if heuristic is not None else (lambda s: 0.0)
    check_deadline(deadline)
    h0 = h_of(problem.init)
    if max_skeletons < 1 or (h0 == math.inf and not resume):
        return
    counter = itertools.count()
    root = _Node(problem.init, None, -1, 0.0, 0)
    stats.nodes_created += 1
    frontier: list[tuple[tuple[float, ...], int, _Node]] = [
        (priority(0.0, h0 if h0 < math.inf else 0.0), next(counter), root)
    ]
    pops: dict[int, int] = {}
    n_yielded = 0
    # With extra costs (a restart after demotion) the heuristic does not see them, and
    # the orders of many steps reach the same states at an f below the cheapest plan:
    # a tree search pops each of those states up to max_skeletons times. There the
    # bound is applied lazily: the next plan needs no more pops of a state than the
    # plans found so far (yielded or skipped) + 1, and a node popped beyond that waits
    # in ``deferred`` until another plan is found or nothing else is left (put off,
    # never lost). Without extra costs the bound stays max_skeletons: putting nodes
    # off reorders plans of equal priority, and there it saves nothing measurable.
    bound = 1 if extra_cost is not None else max_skeletons
    deferred: list[tuple[tuple[float, ...], int, _Node]] = []

    def admit_deferred() -> None:
        nonlocal bound
        bound += 1
        for entry in deferred:
            heapq.heappush(frontier, entry)
        deferred.clear()

    goal = problem.goal
    pre, add, delete = problem.pre, problem.add, problem.delete
    while frontier or deferred:
        check_deadline(deadline)
        if not frontier:
            admit_deferred()
            continue
        entry = heapq.heappop(frontier)
        node = entry[2]
        state = node.state
        found = _extract(problem, node) if state & goal == goal else None
        if found is not None and found.operators in skip:
            stats.skipped += 1
            admit_deferred()
            continue
        k = pops.get(state, 0) + 1
        if k > max_skeletons:
            continue
        if k > bound:
            deferred.append(entry)
            continue
        pops[state] = k
        if found is not None:
            stats.skeletons += 1
            n_yielded += 1
            yield found
            if n_yielded >= max_skeletons:
                return
            admit_deferred()
            continue
        if node.depth >= max_length:
            continue
        stats.nodes_expanded += 1
        resuming = resume and node.parent is None
        for i, p in enumerate(pre):
            if resuming:
                p &= ~delete[i]
            if state & p != p:
                continue
            g = node.g + 1.0 + (extra_cost[i] if extra_cost is not None else 0.0)
            child = (state & ~delete[i]) | add[i]
            if node.visits(child) > max_repeats:
                continue
            check_deadline(deadline)
            h = h_of(child)
            if h == math.inf:
                continue
            stats.nodes_created += 1
            heapq.heappush(
                frontier, (priority(g, h), next(counter), _Node(child, node, i, g, node.depth + 1))
            )


def _extract(problem: GroundProblem, node: _Node) -> AbstractPlan:
    ops: list[GroundOperator] = []
    states: list[int] = []
    cur: _Node | None = node
    while cur is not None:
        states.append(cur.state)
        if cur.parent is not None:
            ops.append(problem.operators[cur.op])
        cur = cur.parent
    ops.reverse()
    states.reverse()
    return AbstractPlan(tuple(ops), tuple(problem.decode(s) for s in states), node.g)
