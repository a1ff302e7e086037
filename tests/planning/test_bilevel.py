import dataclasses
import time

import numpy as np
import pytest

from bpns.env.abstraction import abstract
from bpns.planning import FailureReason, PlanningConfig, plan
from bpns.structs import GroundAtom
from tests import toy_planning as toy

ENV = toy.ToyStickButton()
RNG = np.random.default_rng


def replay_reaches_goal(task, result, env=ENV):
    state = task.init
    for a in result.actions:
        state = env.simulate(state, a)
    return task.goal <= abstract(state, env.predicates)


def names(result):
    return [str(o) for o in result.skeleton.operators]


def test_plan_solves_a_reachable_button_with_the_first_abstract_plan():
    task = toy.make_task([2.5])
    res = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(0))
    assert res.success and res.reason is None
    assert names(res) == ["PressDirect(robot, button0)"]
    assert res.stats.abstract_plans_tried == 1
    assert replay_reaches_goal(task, res)
    assert res.actions.shape == (len(res.states) - 1, 2)


def test_goal_already_satisfied_gives_an_empty_plan():
    task = toy.make_task([2.5], pressed=[True])
    res = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(0))
    assert res.success
    assert res.actions.shape == (0, 2) and res.states == (task.init,)
    assert len(res.skeleton) == 0 and res.stats.abstract_plans_tried == 0


def test_planning_moves_on_to_the_second_abstract_plan_when_the_first_is_not_refinable():
    task = toy.make_task([8.0])  # beyond reach: only the stick works
    res = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(0))
    assert res.success
    assert names(res) == ["PickStick(robot, stick)", "PressWithStick(robot, stick, button0)"]
    assert res.stats.abstract_plans_tried == 2
    assert dict(res.stats.sample_failures)["stuck"] >= 10
    assert replay_reaches_goal(task, res)
    assert [s.name for s in res.skills] == ["PickStick", "PressWithStick"]
    assert len(res.subgoals) == 2 and res.step_starts[0] == 0


def test_plain_backtracking_resamples_steps_that_lead_to_a_refuted_step():
    task = toy.make_task([2.0, 8.0])  # press the near one, then fail on the far one
    off = plan(task, toy.skills(), ENV, PlanningConfig(nogood_atol=None), RNG(0))
    on = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(0))
    assert off.success and on.success
    assert "nogood" not in dict(off.stats.sample_failures)
    assert dict(on.stats.sample_failures)["nogood"] >= 1
    assert on.stats.sim_steps < off.stats.sim_steps


@pytest.mark.parametrize(
    "bad",
    [
        {"press_direct_policy_fn": lambda s, o, g: np.array([np.nan, 0.0])},
        {"press_direct_policy_fn": lambda s, o, g: 1 / 0},
        {"press_direct_sampler_fn": lambda s, o, rng: (_ for _ in ()).throw(RuntimeError("boom"))},
    ],
)
def test_a_broken_skill_fails_its_samples_and_planning_continues(bad):
    task = toy.make_task([2.5])
    res = plan(task, toy.skills(**bad), ENV, PlanningConfig(), RNG(0))
    assert res.success
    assert names(res)[-1] == "PressWithStick(robot, stick, button0)"
    assert replay_reaches_goal(task, res)


def test_abstract_plans_1_ablation_tries_only_the_first_plan():
    task = toy.make_task([8.0])
    res = plan(task, toy.skills(), ENV, PlanningConfig(n_abstract=1), RNG(0))
    assert not res.success and res.reason == FailureReason.REFINEMENT_FAILED
    assert res.stats.abstract_plans_tried == 1
    assert res.stats.samples_drawn == 10
    assert res.actions.shape == (0, 2) and res.states == (task.init,)


def test_samples_1_ablation_draws_one_sample_per_step():
    task = toy.make_task([8.0])
    skills = toy.skills(pick_bad_first=1)
    res = plan(task, skills, ENV, PlanningConfig(n_samples=1), RNG(0))
    # [PressDirect]: 1 sample; [PickStick (bad grip), PressWithStick]: 1 + 1; no other
    # acyclic plans
    assert not res.success and res.reason == "refinement_failed"
    assert res.stats.abstract_plans_tried == 2
    assert res.stats.samples_drawn == 3
    full = plan(task, toy.skills(pick_bad_first=1), ENV, PlanningConfig(), RNG(0))
    assert full.success and full.stats.samples_drawn > 3


def test_a_plan_that_puts_the_stick_down_and_regrasps_it_recovers_from_a_bad_grip():
    """With one abstract loop allowed, Samples=1 still solves it: Pick (bad), Place,
    Pick (good), PressWithStick revisits the hand-empty state once."""
    task = toy.make_task([8.0])
    strict = plan(
        task, toy.skills(pick_bad_first=1, pick_good=0.5), ENV, PlanningConfig(n_samples=1), RNG(0)
    )
    assert not strict.success  # acyclic plans: the bad grip is never undone
    looping = PlanningConfig(n_samples=1, max_state_repeats=1)
    res = plan(task, toy.skills(pick_bad_first=1, pick_good=0.5), ENV, looping, RNG(0))
    assert res.success and replay_reaches_goal(task, res)
    assert [s.name for s in res.skills] == [
        "PickStick",
        "PlaceStick",
        "PickStick",
        "PressWithStick",
    ]


def test_both_ablations_together_draw_a_single_sample():
    task = toy.make_task([8.0])
    res = plan(task, toy.skills(), ENV, PlanningConfig(n_samples=1, n_abstract=1), RNG(0))
    assert res.stats.samples_drawn == 1 and res.stats.abstract_plans_tried == 1


def test_timeout_is_obeyed_during_refinement():
    task = toy.make_task([8.0, 7.5])
    env = toy.SlowEnv(0.02)
    start = time.monotonic()
    res = plan(task, toy.skills(pick_bad_first=1000), env, PlanningConfig(timeout=1.0), RNG(0))
    elapsed = time.monotonic() - start
    assert not res.success and res.reason == "timeout"
    assert elapsed < 1.0 + 1.0  # the contract: the timeout is obeyed within 1 s
    assert res.stats.sim_steps > 0 and res.stats.abstract_plans_tried >= 1


def test_timeout_is_obeyed_during_abstract_search():
    env = toy.ToyLights(16)
    light0 = toy.lights(1)[0]
    goal = frozenset({GroundAtom(toy.ON, (light0,)), GroundAtom(toy.OFF, (light0,))})  # unsolvable
    task = toy.lights_task(16, goal)
    start = time.monotonic()
    res = plan(task, toy.light_skills(), env, PlanningConfig(timeout=0.5, heuristic="hff"), RNG(0))
    elapsed = time.monotonic() - start
    assert not res.success and res.reason == FailureReason.TIMEOUT
    assert elapsed < 0.5 + 1.0  # the contract: the timeout is obeyed within 1 s
    assert res.stats.sim_steps == 0 and res.stats.nodes_created > 0


def test_unreachable_goal_gives_no_abstract_plan():
    task = toy.make_task([2.5])
    pick_and_place = [s for s in toy.skills() if s.name in ("PickStick", "PlaceStick")]
    res = plan(task, pick_and_place, ENV, PlanningConfig(), RNG(0))
    assert not res.success and res.reason == FailureReason.NO_ABSTRACT_PLAN
    assert res.stats.abstract_plans_tried == 0


def test_unsolvable_abstract_problem_terminates_without_timeout():
    light0 = toy.lights(1)[0]
    task = toy.lights_task(
        3, frozenset({GroundAtom(toy.ON, (light0,)), GroundAtom(toy.OFF, (light0,))})
    )
    res = plan(task, toy.light_skills(), toy.ToyLights(3), PlanningConfig(timeout=10.0), RNG(0))
    assert res.reason == FailureReason.NO_ABSTRACT_PLAN
    assert res.stats.total_time < 5.0


@pytest.mark.parametrize("heuristic", ["lmcut", "hff", "hadd", "hmax"])
@pytest.mark.parametrize("search", ["astar", "gbfs"])
def test_every_heuristic_and_strategy_solves_a_two_button_task(heuristic, search):
    task = toy.make_task([2.5, 8.0])
    cfg = PlanningConfig(heuristic=heuristic, search=search, timeout=30.0)
    res = plan(task, toy.skills(), ENV, cfg, RNG(0))
    assert res.success and replay_reaches_goal(task, res)


def test_uniform_cost_search_also_plans():
    task = toy.make_task([8.0])
    res = plan(task, toy.skills(), ENV, PlanningConfig(search="ucs"), RNG(0))
    assert res.success


def test_statistics_are_counted():
    task = toy.make_task([2.5, 8.0])
    res = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(0))
    s = res.stats
    assert res.success
    assert s.nodes_created >= s.nodes_expanded > 0 and s.ground_operators == 6
    assert s.abstract_plans_tried >= 2 and s.samples_drawn >= s.abstract_plans_tried
    assert s.sim_steps >= len(res.actions) > 0
    assert s.search_time > 0 and s.refinement_time > 0
    assert s.total_time >= s.search_time + s.refinement_time


def test_planning_is_deterministic_given_the_seed():
    task = toy.make_task([2.5, 8.0])
    a = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(7))
    b = plan(task, toy.skills(), ENV, PlanningConfig(), RNG(7))
    assert names(a) == names(b) and np.array_equal(a.actions, b.actions)
    assert dataclasses.replace(
        a.stats, search_time=0, refinement_time=0, total_time=0
    ) == dataclasses.replace(b.stats, search_time=0, refinement_time=0, total_time=0)


def test_config_rejects_unknown_names_and_bad_counts():
    with pytest.raises(ValueError):
        PlanningConfig(heuristic="blind")
    with pytest.raises(ValueError):
        PlanningConfig(search="dfs")
    with pytest.raises(ValueError):
        PlanningConfig(n_samples=0)
    with pytest.raises(ValueError):
        PlanningConfig(timeout=0)


def test_two_skills_with_the_same_operator_are_rejected():
    task = toy.make_task([2.5])
    skills = toy.skills()
    with pytest.raises(ValueError):
        plan(task, skills + [skills[0]], ENV, PlanningConfig(), RNG(0))
