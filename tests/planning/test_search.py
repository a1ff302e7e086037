import heapq
import itertools
import math
import time

import numpy as np
import pytest

from bpns.planning.heuristics import HFF, LMCut
from bpns.planning.search import SearchStats, astar, gbfs, skeletons, uniform_cost
from bpns.planning.strips import SearchTimeout, ground
from bpns.structs import GroundAtom
from tests import toy_planning as toy


def lights_problem(n, goal):
    task = toy.lights_task(n, frozenset(goal))
    init = frozenset(GroundAtom(toy.OFF, (o,)) for o in task.objects)
    return ground([toy.TURN_ON, toy.TURN_OFF], task.objects, init, task.goal)


def on(i):
    return GroundAtom(toy.ON, (toy.lights(i + 1)[i],))


def off(i):
    return GroundAtom(toy.OFF, (toy.lights(i + 1)[i],))


def assert_valid(problem, plan, max_repeats=0):
    atoms = plan.atoms[0]
    assert atoms == problem.decode(problem.init)
    for op, expected in zip(plan.operators, plan.atoms[1:], strict=True):
        assert op.applicable(atoms)
        atoms = op.apply(atoms)
        assert atoms == expected
    assert problem.decode(problem.goal) <= atoms
    assert _visits(plan) <= 1 + max_repeats, "an abstract state repeats along the plan"
    assert plan.cost == len(plan.operators)


@pytest.mark.parametrize("seed", range(30))
def test_astar_first_plan_is_optimal(seed):
    p = toy.random_problem(np.random.default_rng(seed))
    plans = list(skeletons(p, LMCut(p), astar, max_skeletons=1, max_length=20))
    h_star = toy.optimal_cost(p, p.init)
    if math.isinf(h_star):
        assert plans == []
    else:
        assert len(plans) == 1
        assert_valid(p, plans[0])
        assert plans[0].cost == h_star


def test_generator_yields_distinct_plans_in_nondecreasing_cost_for_astar():
    p = lights_problem(3, {on(0), on(1)})
    plans = list(skeletons(p, LMCut(p), astar, max_skeletons=8, max_length=10))
    assert len(plans) == 8
    costs = [pl.cost for pl in plans]
    assert costs == sorted(costs)
    assert costs[:2] == [2.0, 2.0]
    assert len({pl.operators for pl in plans}) == 8
    for pl in plans:
        assert_valid(p, pl)


def test_later_plans_may_revisit_states_reached_by_earlier_plans():
    p = lights_problem(3, {on(0), on(1)})
    first, second = itertools.islice(
        skeletons(p, LMCut(p), astar, max_skeletons=2, max_length=10), 2
    )
    assert [str(o) for o in first.operators] != [str(o) for o in second.operators]
    assert first.atoms[-1] == second.atoms[-1]  # both end in the same abstract state


def _visits(plan):
    return max(plan.atoms.count(a) for a in plan.atoms)


def test_plans_revisit_an_abstract_state_at_most_max_repeats_times():
    p = lights_problem(2, {on(1)})  # loops: TurnOn(l0), TurnOff(l0) returns to the start
    strict = list(skeletons(p, LMCut(p), astar, max_skeletons=20, max_length=10))
    assert sorted(len(pl) for pl in strict) == [1, 2]
    assert all(_visits(pl) == 1 for pl in strict)
    once = list(skeletons(p, LMCut(p), astar, max_skeletons=20, max_length=10, max_repeats=1))
    assert {_visits(pl) for pl in once} == {1, 2}
    assert [str(o) for o in once[-1].operators][:2] != [str(o) for o in once[0].operators][:2]
    loop = next(pl for pl in once if _visits(pl) == 2)
    assert len(loop) > 2
    for pl in once:
        assert_valid(p, pl, max_repeats=1)
    assert [pl.cost for pl in once] == sorted(pl.cost for pl in once)  # loops come later


def test_generator_is_lazy_and_counts_nodes():
    p = lights_problem(4, {on(0), on(1), on(2)})
    stats = SearchStats()
    gen = skeletons(p, LMCut(p), astar, max_skeletons=50, max_length=10, stats=stats)
    assert stats.nodes_created == 0
    next(gen)
    after_one = stats.nodes_created
    assert after_one > 0 and stats.nodes_expanded > 0 and stats.skeletons == 1
    for _ in range(10):
        next(gen)
    assert stats.nodes_created > after_one and stats.skeletons == 11


def test_gbfs_finds_a_valid_plan():
    p = lights_problem(5, {on(0), on(2), on(4)})
    plans = list(skeletons(p, HFF(p), gbfs, max_skeletons=1, max_length=20))
    assert len(plans) == 1
    assert_valid(p, plans[0])


def test_uniform_cost_without_heuristic_finds_an_optimal_plan():
    p = lights_problem(3, {on(0), on(1)})
    (pl,) = skeletons(p, None, uniform_cost, max_skeletons=1, max_length=10)
    assert pl.cost == 2.0


def test_unsolvable_problem_with_unreachable_goal_ends_immediately():
    objs = toy.lights(3)
    init = {GroundAtom(toy.OFF, (o,)) for o in objs}
    p_bad = ground([toy.TURN_OFF], objs, init, {on(0)})  # nothing turns a light on
    stats = SearchStats()
    assert (
        list(skeletons(p_bad, LMCut(p_bad), astar, max_skeletons=5, max_length=10, stats=stats))
        == []
    )
    assert stats.nodes_created == 0


def test_relaxed_solvable_but_unsolvable_problem_terminates():
    p = lights_problem(3, {on(0), off(0)})  # contradictory goal; relaxation cannot tell
    stats = SearchStats()
    assert list(skeletons(p, LMCut(p), astar, max_skeletons=4, max_length=50, stats=stats)) == []
    assert 0 < stats.nodes_expanded <= 4 * 2**3


def test_max_length_bounds_plans():
    p = lights_problem(3, {on(0), on(1)})
    assert list(skeletons(p, LMCut(p), astar, max_skeletons=3, max_length=1)) == []
    plans = list(skeletons(p, LMCut(p), astar, max_skeletons=20, max_length=3))
    assert plans and all(len(pl) <= 3 for pl in plans)


def test_search_is_deterministic():
    def run():
        p = lights_problem(4, {on(0), on(3)})
        return [
            [str(o) for o in pl.operators]
            for pl in skeletons(p, LMCut(p), astar, max_skeletons=10, max_length=8)
        ]

    assert run() == run()


def test_search_raises_timeout_past_its_deadline():
    p = lights_problem(16, {on(0), off(0)})  # unsolvable, 2^16 states: long search
    start = time.monotonic()
    with pytest.raises(SearchTimeout):
        for _ in skeletons(p, HFF(p), astar, max_skeletons=8, max_length=100, deadline=start + 0.3):
            pass
    assert time.monotonic() - start < 0.3 + 1.0  # obeyed within 1 s (the contract)


def test_resuming_lets_the_first_step_lack_only_preconditions_it_deletes():
    # a drive to the door stopped midway: it left the room (AtStart gone, as its effects
    # say) but never reached the door; no operator describes that state
    go = toy.op("Go", pre={"AtStart", "Ready"}, add={"AtDoor"}, delete={"AtStart"})
    open_door = toy.op("Open", pre={"AtDoor"}, add={"Open"})
    jump = toy.op("Jump", pre={"Ready", "Key"}, add={"Open"})  # lacks Key: never resumed
    p = toy.problem([go, open_door, jump], init={"Ready"}, goal={"Open"})
    assert list(skeletons(p, LMCut(p), astar, max_skeletons=4, max_length=5)) == []
    plans = list(skeletons(p, LMCut(p), astar, max_skeletons=4, max_length=5, resume=True))
    assert [[o.name for o in pl.operators] for pl in plans] == [["Go", "Open"]]
    assert plans[0].atoms[1] == frozenset({toy.atom("Ready"), toy.atom("AtDoor")})


def test_resuming_relaxes_only_the_first_step():
    # Go lacks AtStart only after Back deleted it: deeper in the plan it stays strict
    back = toy.op("Back", pre={"Ready"}, add={"Moved"}, delete={"AtStart"})
    go = toy.op("Go", pre={"AtStart", "Moved"}, add={"Open"}, delete={"AtStart"})
    p = toy.problem([back, go], init={"Ready", "AtStart"}, goal={"Open"})
    assert list(skeletons(p, None, astar, max_skeletons=4, max_length=5, resume=True)) == []


def _unbounded_skeletons(problem, heuristic, max_skeletons, max_length, extra_cost):
    """The specification: A* over paths, each state popped up to ``max_skeletons`` times
    as soon as the priority order reaches it (no pop is ever put off)."""
    order = itertools.count()
    h0 = heuristic(problem.init)
    frontier = [((h0, h0), next(order), (problem.init,), (), 0.0)]
    pops, plans = {}, []
    while frontier and len(plans) < max_skeletons:
        _, _, states, ops, g = heapq.heappop(frontier)
        state = states[-1]
        pops[state] = pops.get(state, 0) + 1
        if pops[state] > max_skeletons:
            continue
        if state & problem.goal == problem.goal:
            plans.append(tuple(problem.operators[i] for i in ops))
            continue
        if len(ops) >= max_length:
            continue
        for i, pre in enumerate(problem.pre):
            child = (state & ~problem.delete[i]) | problem.add[i]
            if state & pre != pre or child in states or math.isinf(h := heuristic(child)):
                continue
            cost = g + 1.0 + extra_cost[i]
            node = ((cost + h, h), next(order), (*states, child), (*ops, i), cost)
            heapq.heappush(frontier, node)
    return plans


@pytest.mark.parametrize("seed", range(40))
def test_with_extra_costs_pops_put_off_change_no_plan_cost_in_the_order(seed):
    """Extra costs make the search put off repeated pops of a state until another plan is
    found; the costs of the plans, in the order yielded, are those of the unbounded
    search (only plans of equal cost may swap places), each plan valid and new."""
    rng = np.random.default_rng(seed)
    p = toy.random_problem(rng, n_atoms=7, n_ops=12)
    extra = [float(rng.choice([0.0, 0.0, 4.0])) for _ in p.operators]
    got = list(skeletons(p, LMCut(p), astar, max_skeletons=30, max_length=8, extra_cost=extra))
    want = _unbounded_skeletons(p, LMCut(p), 30, 8, extra)
    assert [pl.cost for pl in got] == [_cost(p, ops, extra) for ops in want]
    assert len({pl.operators for pl in got}) == len(got)
    for pl in got:
        atoms = pl.atoms[0]
        for op, expected in zip(pl.operators, pl.atoms[1:], strict=True):
            assert op.applicable(atoms) and op.apply(atoms) == expected
            atoms = expected
        assert p.decode(p.goal) <= atoms


def _cost(problem, operators, extra):
    index = {op: i for i, op in enumerate(problem.operators)}
    return sum(1.0 + extra[index[op]] for op in operators)
