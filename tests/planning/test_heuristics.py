import math

import numpy as np
import pytest

from bpns.planning.heuristics import HFF, HAdd, HMax, LMCut, make_heuristic
from tests.toy_planning import (
    atom,
    op,
    optimal_cost,
    problem,
    random_problem,
    reachable_states,
    relaxed_optimal_cost,
)

ALL = (HMax, HAdd, HFF, LMCut)


def values(p, state=None):
    state = p.init if state is None else state
    return {cls.__name__: cls(p)(state) for cls in ALL}


def test_chain_every_heuristic_is_exact():
    ops = [op(f"step{i}", [f"a{i}"], [f"a{i + 1}"]) for i in range(5)]
    p = problem(ops, ["a0"], ["a5"])
    assert values(p) == {"HMax": 5, "HAdd": 5, "HFF": 5, "LMCut": 5}


def test_independent_goals_add_up_except_for_hmax():
    ops = [op(f"get{i}", [], [f"g{i}"]) for i in range(3)]
    p = problem(ops, [], ["g0", "g1", "g2"])
    assert values(p) == {"HMax": 1, "HAdd": 3, "HFF": 3, "LMCut": 3}


def test_shared_achiever_is_counted_once_by_hff_and_lmcut():
    ops = [op("both", [], ["g1", "g2"]), op("one", [], ["g1"]), op("two", [], ["g2"])]
    p = problem(ops, [], ["g1", "g2"])
    assert values(p) == {"HMax": 1, "HAdd": 2, "HFF": 1, "LMCut": 1}


def test_hadd_double_counts_a_shared_precondition_but_hff_does_not():
    ops = [op("make_p", [], ["p"]), op("use1", ["p"], ["g1"]), op("use2", ["p"], ["g2"])]
    p = problem(ops, [], ["g1", "g2"])
    assert values(p) == {"HMax": 2, "HAdd": 4, "HFF": 3, "LMCut": 3}


def test_dead_ends_are_infinite_for_every_heuristic():
    p = problem([op("a", ["x"], ["y"])], ["y"], ["z"])
    assert all(math.isinf(v) for v in values(p).values())
    p2 = problem([op("a", ["x"], ["g"])], [], ["g"])  # achiever never applicable
    assert all(math.isinf(v) for v in values(p2).values())


def test_goal_states_have_value_zero():
    p = problem([op("a", [], ["g"])], ["g"], ["g"])
    assert values(p) == {"HMax": 0, "HAdd": 0, "HFF": 0, "LMCut": 0}


def test_heuristics_accept_atom_sets_as_well_as_encoded_states():
    ops = [op(f"step{i}", [f"a{i}"], [f"a{i + 1}"]) for i in range(3)]
    p = problem(ops, ["a0"], ["a3"])
    h = LMCut(p)
    assert h(frozenset({atom("a1")})) == 2 == h(p.encode({atom("a1")}))


def test_lmcut_prefers_cheaper_disjunctive_landmarks():
    # g needs either (x then y) or z-chain of 3; x and y are both landmarks of the cheap way
    ops = [
        op("x", [], ["x"]),
        op("y", ["x"], ["y"]),
        op("g_from_y", ["y"], ["g"]),
        op("z1", [], ["z1"]),
        op("z2", ["z1"], ["z2"]),
        op("z3", ["z2"], ["z3"]),
        op("g_from_z", ["z3"], ["g"]),
    ]
    p = problem(ops, [], ["g"])
    assert LMCut(p)(p.init) == 3 == optimal_cost(p, p.init)


@pytest.mark.parametrize("seed", range(40))
def test_random_problems_respect_the_known_heuristic_orderings(seed):
    rng = np.random.default_rng(seed)
    p = random_problem(rng)
    hmax, hadd, hff, lmcut = (cls(p) for cls in ALL)
    for s in reachable_states(p):
        h_star = optimal_cost(p, s)
        h_plus = relaxed_optimal_cost(p, s)
        if math.isinf(h_plus):
            assert all(math.isinf(h(s)) for h in (hmax, hadd, hff, lmcut))
            continue
        assert hmax(s) <= lmcut(s) <= h_plus <= h_star
        assert h_plus <= hff(s) <= hadd(s)
        assert hmax(s) <= hadd(s)


def test_make_heuristic_knows_the_four_names_and_rejects_others():
    p = problem([op("a", [], ["g"])], [], ["g"])
    for name in ("lmcut", "hff", "hadd", "hmax"):
        assert make_heuristic(name, p)(p.init) == 1
    with pytest.raises(ValueError):
        make_heuristic("blind", p)
