"""Nogoods and prefix reuse: less simulation for the same refinement outcome."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.planning.bilevel import plan
from bpns.planning.config import PlanningConfig
from bpns.planning.nogoods import NogoodMemo, PrefixCache
from tests import toy_planning as toy
from tests.planning.test_refinement import ENV, STICK_PLAN, by_op, skeleton

PLAIN = PlanningConfig(nogood_atol=None, reuse_prefixes=False, set_aside_after=None)


def test_memo_refutes_only_states_within_its_tolerance():
    memo = NogoodMemo(atol=0.01)
    memo.add("step", np.array([1.0, 2.0]))
    assert memo.refuted("step", np.array([1.005, 1.995]))
    assert not memo.refuted("step", np.array([1.02, 2.0]))
    assert not memo.refuted("other step", np.array([1.0, 2.0]))
    assert not memo.refuted("step", np.array([1.0, 2.0, 3.0]))  # another object set
    assert memo.hits == 1 and len(memo) == 1


def test_memo_rejects_a_negative_tolerance():
    with pytest.raises(ValueError, match="atol"):
        NogoodMemo(atol=-1.0)
    with pytest.raises(ValueError, match="nogood_atol"):
        PlanningConfig(nogood_atol=-1.0)


def test_prefix_cache_returns_the_longest_refined_prefix():
    cache = PrefixCache()
    cache.add(["a"], ["seg a"])
    cache.add(["a", "b"], ["seg a", "seg b"])
    assert cache.longest(["a", "b", "c"]) == ["seg a", "seg b"]
    assert cache.longest(["a", "x"]) == ["seg a"]
    assert cache.longest(["x"]) == []
    cache.add(["a"], ["another a"])  # the first refinement is kept
    assert cache.longest(["a"]) == ["seg a"]


def _unrefinable_third_step_task():
    """Two near buttons pressed by hand, then a far one by hand: never refinable, and
    the failing step sits behind two steps that always succeed."""
    return toy.make_task([2.0, 3.0, 8.0])


def _hand_plan(task):
    return skeleton(
        task,
        [
            (toy.PRESS_DIRECT, ("robot", "button0")),
            (toy.PRESS_DIRECT, ("robot", "button1")),
            (toy.PRESS_DIRECT, ("robot", "button2")),
        ],
    )


@pytest.mark.parametrize("atol", [1e-3, 0.5])
def test_nogoods_turn_exponential_backtracking_into_linear_work(atol):
    from bpns.planning.refinement import refine

    task = _unrefinable_third_step_task()
    sk = _hand_plan(task)
    skills = [by_op(toy.skills())[o.operator] for o in sk.operators]
    cfg = PlanningConfig(n_samples=4)
    plain = refine(
        sk,
        skills,
        task,
        ENV,
        PlanningConfig(n_samples=4, nogood_atol=None, set_aside_after=None),
        np.random.default_rng(0),
    )
    memo = NogoodMemo(atol)
    fast = refine(sk, skills, task, ENV, cfg, np.random.default_rng(0), memo=memo)
    assert not plain.success and not fast.success
    assert plain.stats.samples >= 4**3  # every combination of the first two steps
    assert fast.stats.samples <= 3 * 4  # each step at most n_samples times
    assert len(memo) >= 1


def test_a_refuted_step_is_refuted_for_later_skeletons_without_simulation():
    from bpns.planning.refinement import refine

    task = toy.make_task([8.0])
    direct = skeleton(task, [(toy.PRESS_DIRECT, ("robot", "button0"))])
    skills = [by_op(toy.skills())[o.operator] for o in direct.operators]
    memo = NogoodMemo(1e-6)
    cfg = PlanningConfig(n_samples=3)
    first = refine(direct, skills, task, ENV, cfg, np.random.default_rng(0), memo=memo)
    again = refine(direct, skills, task, ENV, cfg, np.random.default_rng(1), memo=memo)
    assert not first.success and first.stats.sim_steps > 0
    assert not again.success and again.stats.sim_steps == 0
    assert again.stats.failures("nogood") == 1


def test_a_later_skeleton_starts_after_the_prefix_already_refined():
    from bpns.planning.refinement import refine

    task = toy.make_task([3.0, 8.0])
    near = (toy.PRESS_DIRECT, ("robot", "button0"))
    first = skeleton(task, [near, (toy.PRESS_DIRECT, ("robot", "button1"))])
    second = skeleton(
        task, [near, STICK_PLAN[0], (toy.PRESS_WITH_STICK, ("robot", "stick", "button1"))]
    )
    table = by_op(toy.skills(pick_good=0.5))
    cache = PrefixCache()

    def run(sk, prefixes):
        skills = [table[o.operator] for o in sk.operators]
        rng = np.random.default_rng(0)
        return refine(sk, skills, task, ENV, PlanningConfig(), rng, prefixes=prefixes)

    a, b, alone = run(first, cache), run(second, cache), run(second, None)
    assert not a.success and b.success and alone.success
    assert cache.steps_reused == 1
    assert b.stats.sim_steps < alone.stats.sim_steps
    # the reused prefix is part of the plan: replaying the actions reaches the goal
    state = task.init
    for action in b.actions:
        state = ENV.simulate(state, action)
    assert all(g.holds(state) for g in task.goal)


def test_planning_with_and_without_nogoods_solves_the_same_toy_tasks():
    for xs in ([2.0], [8.0], [2.0, 8.0], [3.0, 8.5, 1.0]):
        task = toy.make_task(xs)
        fast = plan(task, toy.skills(), ENV, PlanningConfig(), np.random.default_rng(0))
        slow = plan(task, toy.skills(), ENV, PLAIN, np.random.default_rng(0))
        assert fast.success == slow.success, xs
        assert fast.stats.sim_steps <= slow.stats.sim_steps, xs
