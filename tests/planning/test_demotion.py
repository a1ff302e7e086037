"""Demoting refuted achievers (``PlanningConfig.demote_refuted``): skeletons that achieve
an atom another way come first, and no skeleton is lost."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.planning.bilevel import plan
from bpns.planning.config import PlanningConfig
from bpns.planning.heuristics import LMCut
from bpns.planning.nogoods import RefutedAchievers
from bpns.planning.search import astar, skeletons
from bpns.structs import GroundAtom
from tests import toy_planning as toy

ENV = toy.ToyStickButton()


def _near_buttons_and_one_far():
    """Four buttons the hand reaches and one it does not (REACH is 5): the 24 orders of
    pressing everything by hand come first in the search, and all fail at the far one."""
    return toy.make_task([1.5, 2.0, 2.5, 3.0, 8.0])


def test_a_far_button_is_pressed_with_the_stick_once_the_hand_is_refuted():
    task = _near_buttons_and_one_far()
    budget = PlanningConfig(n_abstract=20, n_samples=3, timeout=60.0)
    paper = plan(task, toy.skills(), ENV, budget, np.random.default_rng(0))
    demoting = PlanningConfig(n_abstract=20, n_samples=3, timeout=60.0, demote_refuted=4.0)
    result = plan(task, toy.skills(), ENV, demoting, np.random.default_rng(0))
    assert not paper.success and paper.stats.abstract_plans_tried == 20
    assert result.success, result.reason
    assert result.stats.abstract_plans_tried <= 3
    names = [op.name for op in result.skeleton.operators]
    assert names.count("PressDirect") == 4 and "PressWithStick" in names


def test_demotion_reorders_skeletons_but_drops_none():
    """Every skeleton unrefinable: with and without demotion the planner tries the same
    set of skeletons (in another order) before it gives up."""
    task = toy.make_task([8.0, 8.5])  # both far, and every grip refuted below
    skills = toy.skills(pick_good=3.9)  # gripped at the tip: the hand would need x 7.9
    tried = {}
    for cost in (None, 4.0):
        cfg = PlanningConfig(n_abstract=1000, n_samples=2, timeout=60.0, demote_refuted=cost)
        result = plan(task, skills, ENV, cfg, np.random.default_rng(0))
        assert not result.success
        tried[cost] = result.stats.abstract_plans_tried
    assert tried[None] == tried[4.0] > 1


def test_extra_operator_costs_reorder_the_search_and_skipped_plans_are_not_yielded():
    """g is achieved directly (1 step) or through a tool (2 steps)."""
    p = toy.problem(
        [toy.op("direct", add=["g"]), toy.op("tool", add=["t"]), toy.op("use", ["t"], ["g"])],
        init=[],
        goal=["g"],
    )
    plain = list(skeletons(p, LMCut(p), astar, max_skeletons=4, max_length=5))
    names = [[op.name for op in pl.operators] for pl in plain]
    assert names == [["direct"], ["tool", "direct"], ["tool", "use"]]
    extra = [4.0 if op.name == "direct" else 0.0 for op in p.operators]
    costly = list(skeletons(p, LMCut(p), astar, max_skeletons=4, max_length=5, extra_cost=extra))
    assert [[op.name for op in pl.operators] for pl in costly][0] == ["tool", "use"]
    assert {pl.operators for pl in costly} == {pl.operators for pl in plain}  # none dropped
    assert [pl.cost for pl in costly] == [2.0, 5.0, 6.0]
    rest = skeletons(p, LMCut(p), astar, max_skeletons=4, max_length=5, skip={plain[0].operators})
    assert [pl.operators for pl in rest] == [pl.operators for pl in plain[1:]]


def test_an_achiever_that_succeeds_later_is_restored():
    task = toy.make_task([8.0])
    robot, _, (button,) = toy.objects(1)
    direct = toy.PRESS_DIRECT.ground([robot, button])
    achievers = RefutedAchievers(4.0)
    assert achievers.observe((direct,), (0,), (1,))
    assert achievers.extra_cost((direct,)) == [4.0]
    assert achievers.observe((direct,), (1,), (0,))  # succeeded from another arrival
    assert achievers.extra_cost((direct,)) == [0.0]
    assert not achievers.observe((direct,), (0,), (1,))  # known to work: not demoted again
    assert task.goal == frozenset({GroundAtom(toy.PRESSED, (button,))})


@pytest.mark.parametrize("cost", [0.0, -1.0, float("inf"), float("nan")])
def test_a_demotion_cost_must_be_finite_and_positive(cost):
    with pytest.raises(ValueError, match="demot"):
        PlanningConfig(demote_refuted=cost)
    with pytest.raises(ValueError, match="demot"):
        RefutedAchievers(cost)


def test_a_search_restarted_with_extra_costs_does_not_expand_every_order_of_the_presses():
    """Six near buttons and two far: once the hand is refuted at a far button, the
    restarted search must not pop each abstract state once per order of the presses that
    reach it (the heuristic does not see the extra cost, so every order looks cheap)."""
    task = toy.make_task([1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 8.0, 8.5])
    cfg = PlanningConfig(n_abstract=1000, n_samples=3, timeout=60.0, demote_refuted=4.0)
    result = plan(task, toy.skills(), ENV, cfg, np.random.default_rng(0))
    assert result.success, result.reason
    names = [op.name for op in result.skeleton.operators]
    assert names.count("PressDirect") == 6 and names.count("PressWithStick") == 2
    # every pop of a state bounded by max_skeletons alone created 40,898 nodes here
    assert result.stats.nodes_created < 2_000
