"""Delete-relaxation heuristics (unit operator costs) as plain callables ``h(state)``.

A heuristic is built once per :class:`GroundProblem` and called on abstract states
(bitmask ``int``s, or any collection of :class:`GroundAtom`s, which are encoded first).
Values are cached per state because tree search re-reaches the same abstract states
along many paths. Dead ends (goal unreachable even under the relaxation) give ``inf``.

All four share one relaxed-task encoding: an artificial atom TRUE (always holds) is the
precondition of operators without preconditions, and an artificial goal operator
(cost 0, pre = goal) achieves an artificial atom GOAL, so "reach the goal" is "reach
one atom". Implementations follow Bonet & Geffner (hAdd/hMax), Hoffmann & Nebel (hFF,
best-supporter extraction) and Helmert & Domshlak 2009 (LM-cut).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Collection

from bpns.planning.strips import GroundProblem, iter_bits
from bpns.structs import GroundAtom

INF = math.inf
StateLike = int | Collection[GroundAtom]
Heuristic = Callable[[StateLike], float]


class _RelaxedTask:
    """Index structures of the delete relaxation shared by all heuristics."""

    def __init__(self, problem: GroundProblem) -> None:
        n = problem.n_atoms
        self.true_atom = n
        self.goal_atom = n + 1
        self.n_atoms = n + 2
        pres: list[tuple[int, ...]] = []
        adds: list[tuple[int, ...]] = []
        for p, a in zip(problem.pre_idx, problem.add_idx, strict=True):
            pres.append(p or (self.true_atom,))
            adds.append(tuple(x for x in a if x not in p))  # p -> p edges never help
        goal = tuple(iter_bits(problem.goal))
        pres.append(goal or (self.true_atom,))
        adds.append((self.goal_atom,))
        self.pre: tuple[tuple[int, ...], ...] = tuple(pres)
        self.add: tuple[tuple[int, ...], ...] = tuple(adds)
        self.n_ops = len(pres)
        self.goal_op = self.n_ops - 1
        self.base_cost: list[int] = [1] * (self.n_ops - 1) + [0]
        self.n_pre: list[int] = [len(p) for p in pres]
        pre_of: list[list[int]] = [[] for _ in range(self.n_atoms)]
        achievers: list[list[int]] = [[] for _ in range(self.n_atoms)]
        for o in range(self.n_ops):
            for a in pres[o]:
                pre_of[a].append(o)
            for a in adds[o]:
                achievers[a].append(o)
        self.pre_of = pre_of
        self.achievers = achievers

    def sources(self, state: int) -> list[int]:
        return [*iter_bits(state), self.true_atom]

    def propagate(
        self, state: int, cost: list[int], combine_sum: bool
    ) -> tuple[list[float], list[float], list[int]]:
        """Generalised Dijkstra over the relaxed task.

        Returns atom values, operator values (cost of reaching all preconditions, ``inf``
        if unreachable) and, per operator, the precondition popped last: with ``max``
        combination that is an argmax (the LM-cut precondition choice function).
        """
        val = [INF] * self.n_atoms
        op_val = [0.0] * self.n_ops
        op_last = [-1] * self.n_ops
        remaining = self.n_pre[:]
        closed = [False] * self.n_atoms
        heap: list[tuple[float, int]] = []
        for a in self.sources(state):
            val[a] = 0.0
            heap.append((0.0, a))
        heapq.heapify(heap)
        pre_of, add = self.pre_of, self.add
        while heap:
            v, a = heapq.heappop(heap)
            if closed[a]:
                continue
            closed[a] = True
            for o in pre_of[a]:
                if combine_sum:
                    op_val[o] += v
                elif v > op_val[o]:
                    op_val[o] = v
                op_last[o] = a
                remaining[o] -= 1
                if remaining[o] == 0:
                    c = op_val[o] + cost[o]
                    for b in add[o]:
                        if c < val[b]:
                            val[b] = c
                            heapq.heappush(heap, (c, b))
        for o in range(self.n_ops):
            if remaining[o]:
                op_val[o] = INF
        return val, op_val, op_last


class _CachedHeuristic:
    """Shared plumbing: state encoding and a per-state value cache."""

    max_cache = 500_000

    def __init__(self, problem: GroundProblem) -> None:
        self.problem = problem
        self.task = _RelaxedTask(problem)
        self._cache: dict[int, float] = {}

    def __call__(self, state: StateLike) -> float:
        if not isinstance(state, int):
            state = self.problem.encode(state)
        h = self._cache.get(state)
        if h is None:
            if state & self.problem.goal == self.problem.goal:
                h = 0.0
            else:
                h = float(self.compute(state))
            if len(self._cache) >= self.max_cache:
                self._cache.clear()
            self._cache[state] = h
        return h

    def compute(self, state: int) -> float:
        raise NotImplementedError


class HMax(_CachedHeuristic):
    """Cost of the most expensive goal atom (admissible, weak)."""

    def compute(self, state: int) -> float:
        val, _, _ = self.task.propagate(state, self.task.base_cost, combine_sum=False)
        return val[self.task.goal_atom]


class HAdd(_CachedHeuristic):
    """Sum of goal atom costs, each the sum over preconditions (inadmissible, informative)."""

    def compute(self, state: int) -> float:
        val, _, _ = self.task.propagate(state, self.task.base_cost, combine_sum=True)
        return val[self.task.goal_atom]


class HFF(_CachedHeuristic):
    """Size of a relaxed plan extracted backwards through hAdd best supporters."""

    def compute(self, state: int) -> float:
        t = self.task
        val, op_val, _ = t.propagate(state, t.base_cost, combine_sum=True)
        if val[t.goal_atom] == INF:
            return INF
        in_state = set(t.sources(state))
        plan: set[int] = set()
        seen: set[int] = set()
        stack = [t.goal_atom]
        while stack:
            a = stack.pop()
            if a in seen or a in in_state:
                continue
            seen.add(a)
            # best supporter: cheapest achiever, lowest index on ties (deterministic)
            best, best_c = -1, INF
            for o in t.achievers[a]:
                c = op_val[o] + t.base_cost[o]
                if c < best_c:
                    best, best_c = o, c
            if best not in plan:
                plan.add(best)
                stack.extend(t.pre[best])
        return float(sum(t.base_cost[o] for o in plan))


class LMCut(_CachedHeuristic):
    """Landmark-cut heuristic: sum of costs of disjoint action landmarks (admissible).

    Each round computes hMax under the remaining costs, builds the justification graph
    (edge from each operator's hMax-maximal precondition to each of its add effects),
    takes the cut between the atoms reachable from the state and the zero-cost "goal
    zone", adds its minimum cost to h and subtracts it from the cut's operators.
    """

    def compute(self, state: int) -> float:
        t = self.task
        cost = t.base_cost[:]
        val, op_val, pcf = t.propagate(state, cost, combine_sum=False)
        if val[t.goal_atom] == INF:
            return INF
        sources = t.sources(state)
        h = 0
        while val[t.goal_atom] > 0:
            # goal zone: atoms with a zero-cost justification path to GOAL
            zone = [False] * t.n_atoms
            zone[t.goal_atom] = True
            stack = [t.goal_atom]
            while stack:
                e = stack.pop()
                for o in t.achievers[e]:
                    if cost[o] == 0 and op_val[o] != INF:
                        p = pcf[o]
                        if not zone[p]:
                            zone[p] = True
                            stack.append(p)
            # atoms reachable from the state without entering the zone; collect the cut
            seen = [False] * t.n_atoms
            for a in sources:
                seen[a] = True
            stack = list(sources)
            cut: list[int] = []
            in_cut = [False] * t.n_ops
            while stack:
                a = stack.pop()
                for o in t.pre_of[a]:
                    if pcf[o] != a or op_val[o] == INF:
                        continue
                    for e in t.add[o]:
                        if zone[e]:
                            if not in_cut[o]:
                                in_cut[o] = True
                                cut.append(o)
                        elif not seen[e]:
                            seen[e] = True
                            stack.append(e)
            m = min(cost[o] for o in cut)
            h += m
            for o in cut:
                cost[o] -= m
            val, op_val, pcf = t.propagate(state, cost, combine_sum=False)
        return float(h)


_BY_NAME: dict[str, type[_CachedHeuristic]] = {
    "hmax": HMax,
    "hadd": HAdd,
    "hff": HFF,
    "lmcut": LMCut,
}


def make_heuristic(name: str, problem: GroundProblem) -> Heuristic:
    """The named heuristic ("lmcut", "hff", "hadd", "hmax") for ``problem``."""
    try:
        return _BY_NAME[name](problem)
    except KeyError:
        raise ValueError(f"unknown heuristic {name!r}; choose from {sorted(_BY_NAME)}") from None
