"""Setting a skeleton aside: a step that fails from every arrival stops the skeleton's
backtracking early, and the planner refines it again after the other skeletons."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.planning.bilevel import plan
from bpns.planning.config import PlanningConfig
from bpns.planning.nogoods import NogoodMemo, SetAsidePrefixes
from bpns.planning.refinement import refine
from bpns.structs import Skill
from tests import toy_planning as toy
from tests.planning.test_refinement import ENV, STICK_PLAN, by_op, skeleton


class VaryingBadGrips:
    """Grips ``bad`` times near the stick's far end, each time a little further forward
    (so every arrival at the press is a different state, out of reach of the far button),
    then at ``good`` from the stick's end, whose tip reaches it."""

    def __init__(self, bad: int, good: float = 0.5) -> None:
        self.bad, self.good, self.calls = bad, good, 0

    def __call__(self, state, objs, rng):
        self.calls += 1
        g = state.vec(objs).copy()
        offset = 3.5 - 0.1 * self.calls if self.calls <= self.bad else self.good
        g[0] = state.get(objs[1], "x") + offset
        return g


def _skills(bad: int) -> list[Skill]:
    table = by_op(toy.skills())
    table[toy.PICK_STICK] = Skill(toy.PICK_STICK, toy.pick_policy, VaryingBadGrips(bad))
    return list(table.values())


def _refine(task, steps, skills, config, memo=None):
    sk = skeleton(task, steps)
    table = by_op(skills)
    ops = [table[o.operator] for o in sk.operators]
    return refine(sk, ops, task, ENV, config, np.random.default_rng(0), memo=memo)


def test_a_step_failing_from_every_arrival_sets_its_skeleton_aside():
    task = toy.make_task([8.0])
    config = PlanningConfig(set_aside_after=3)
    res = _refine(task, STICK_PLAN, _skills(bad=20), config, NogoodMemo(config.nogood_atol))
    assert not res.success and res.reason == "set_aside"
    # three different grips, each followed by n_samples failed presses
    assert res.stats.step_successes == (3, 0)
    assert res.stats.samples == 3 * (1 + config.n_samples)
    assert res.stats.backtracks == 2  # the third refutation sets it aside instead


def test_without_setting_aside_every_grip_is_tried():
    task = toy.make_task([8.0])
    config = PlanningConfig(set_aside_after=None)
    res = _refine(task, STICK_PLAN, _skills(bad=20), config, NogoodMemo(config.nogood_atol))
    assert not res.success and res.reason == "exhausted"
    n = config.n_samples
    assert res.stats.step_successes == (n, 0)
    assert res.stats.samples == n * (1 + n)  # every grip, each with n presses


def test_arrivals_that_fail_only_for_lack_of_time_steps_do_not_count():
    task = toy.make_task([8.0], horizon=6)  # too few steps to press after any grip
    res = _refine(task, STICK_PLAN, _skills(bad=0), PlanningConfig(set_aside_after=1))
    assert not res.success and res.reason == "exhausted"


def test_a_set_aside_skeleton_is_refined_again_after_the_others_and_solves_the_task():
    task = toy.make_task([8.0])
    rng = np.random.default_rng(0)
    res = plan(task, _skills(bad=4), ENV, PlanningConfig(set_aside_after=2), rng)
    assert res.success
    reasons = [a.reason for a in res.stats.attempts]
    pick_press = ("PickStick", "PressWithStick")
    tried = [tuple(s.split("(")[0] for s in a.steps) for a in res.stats.attempts]
    # the stick plan was set aside after two bad grips, the generator had nothing better,
    # and its second refinement went on to the good grip
    assert reasons.count("set_aside") == 1 and reasons[-1] is None
    assert tried[reasons.index("set_aside")] == pick_press and tried[-1] == pick_press
    state = task.init
    for action in res.actions:
        state = ENV.simulate(state, action)
    assert all(g.holds(state) for g in task.goal)


def _press_anywhere_on_the_button(state, objs, rng):
    """PressDirect's sampler, aiming anywhere within 5 cm of the button's centre: the
    robot ends the press where it aimed, so each sample leaves a different state."""
    g = toy.press_direct_sampler(state, objs, rng)
    g[0] += rng.uniform(-0.05, 0.05)
    return g


def test_setting_aside_moves_on_to_a_skeleton_that_refines():
    """A far and a near button. The second skeleton presses the near one by hand, then
    the far one by hand, which never works wherever the first press left the robot.
    Setting it aside after two such arrivals moves on to the stick plan sooner than
    trying every first press."""
    task = toy.make_task([8.0, 3.2])
    table = by_op(toy.skills(press_direct_sampler_fn=_press_anywhere_on_the_button))

    def solve(after):
        config = PlanningConfig(set_aside_after=after)
        return plan(task, list(table.values()), ENV, config, np.random.default_rng(0))

    patient, quick = solve(None), solve(2)
    assert patient.success and quick.success
    hand_then_far = quick.stats.attempts[1]
    assert [s.split("(")[0] for s in hand_then_far.steps] == ["PressDirect", "PressDirect"]
    assert hand_then_far.reason == "set_aside" and hand_then_far.step_successes == (2, 0)
    assert patient.stats.attempts[1].reason == "exhausted"
    assert patient.stats.attempts[1].step_successes[0] > 2  # every other first press
    # the set-aside skeleton is not refined again: a later one solved the task first
    assert len(quick.stats.attempts) == len(patient.stats.attempts)
    assert quick.stats.sim_steps < patient.stats.sim_steps / 2


def test_set_aside_after_must_be_positive():
    with pytest.raises(ValueError, match="set_aside_after"):
        PlanningConfig(set_aside_after=0)


def test_a_skeleton_starting_with_a_set_aside_prefix_is_set_aside_without_simulation():
    task = toy.make_task([8.0, 3.2])
    skills = toy.skills(press_direct_sampler_fn=_press_anywhere_on_the_button)
    near, far = (toy.PRESS_DIRECT, ("robot", "button1")), (toy.PRESS_DIRECT, ("robot", "button0"))
    config = PlanningConfig(set_aside_after=2)
    memo, doomed = NogoodMemo(config.nogood_atol), SetAsidePrefixes()
    table = by_op(skills)

    def refine_(steps):
        sk = skeleton(task, steps)
        ops = [table[o.operator] for o in sk.operators]
        rng = np.random.default_rng(0)
        return refine(sk, ops, task, ENV, config, rng, memo=memo, set_aside=doomed)

    first = refine_([near, far])
    longer = refine_([near, far, STICK_PLAN[0]])  # same two steps, then something else
    other = refine_([near, *STICK_PLAN[:1], (toy.PRESS_WITH_STICK, ("robot", "stick", "button0"))])
    assert first.reason == "set_aside" and first.stats.sim_steps > 0
    assert longer.reason == "set_aside" and longer.stats.sim_steps == 0
    assert longer.stats.step_failures[1] == (("set_aside", 1),)
    assert other.success  # a different second step is not affected
    assert doomed.hits == 1
