import dataclasses
import time

import numpy as np
import pytest

from bpns.env.abstraction import abstract
from bpns.planning.config import PlanningConfig
from bpns.planning.refinement import refine
from bpns.planning.search import AbstractPlan
from bpns.structs import LiftedAtom, NoSubgoal, Skill, STRIPSOperator
from tests import toy_planning as toy

ENV = toy.ToyStickButton()


def skeleton(task, steps):
    """AbstractPlan from (operator, object names) pairs, applied to abstract(init)."""
    by_name = {o.name: o for o in task.objects}
    atoms = [abstract(task.init, ENV.predicates)]
    ops = []
    for operator, names in steps:
        g = operator.ground([by_name[n] for n in names])
        assert g.applicable(atoms[-1])
        ops.append(g)
        atoms.append(g.apply(atoms[-1]))
    return AbstractPlan(tuple(ops), tuple(atoms), float(len(ops)))


def by_op(skills):
    return {s.operator: s for s in skills}


DEFAULT = PlanningConfig()


def run(task, steps, skills, config=DEFAULT, seed=0, deadline=None):
    plan = skeleton(task, steps)
    table = by_op(skills)
    return refine(
        plan,
        [table[o.operator] for o in plan.operators],
        task,
        ENV,
        config,
        np.random.default_rng(seed),
        deadline,
    )


STICK_PLAN = [
    (toy.PICK_STICK, ("robot", "stick")),
    (toy.PRESS_WITH_STICK, ("robot", "stick", "button0")),
]


def replay(task, actions):
    state = task.init
    for a in actions:
        state = ENV.simulate(state, a)
    return state


def test_refinement_backtracks_when_the_first_subgoals_are_bad_and_succeeds_later():
    task = toy.make_task([8.0])
    res = run(task, STICK_PLAN, toy.skills(pick_bad_first=2, pick_good=0.5))
    assert res.success and res.reason is None
    # bad grip, 10 stuck presses, backtrack; again; then a good grip and one press
    assert res.stats.backtracks == 2
    assert res.stats.failures("stuck") == 20
    assert res.stats.samples == 1 + 10 + 1 + 10 + 1 + 1
    final = replay(task, res.actions)
    assert np.array_equal(final.vec(final.objects), res.states[-1].vec(res.states[-1].objects))
    assert task.goal <= abstract(final, ENV.predicates)
    assert res.states[0] is task.init and len(res.states) == len(res.actions) + 1
    assert res.step_starts[0] == 0 and 0 < res.step_starts[1] < len(res.actions)
    assert [s.name for s in res.skills] == ["PickStick", "PressWithStick"]
    assert res.stats.sim_steps >= len(res.actions)


def test_refinement_fails_after_n_samples_when_no_subgoal_works():
    task = toy.make_task([8.0])
    res = run(
        task, [(toy.PRESS_DIRECT, ("robot", "button0"))], toy.skills(), PlanningConfig(n_samples=3)
    )
    assert not res.success and res.reason == "exhausted"
    assert res.stats.samples == 3 and res.stats.failures("stuck") == 3
    assert res.actions.shape == (0, 2) and res.states == ()


def test_stuck_detection_fails_a_sample_quickly():
    task = toy.make_task([8.0])
    cfg = PlanningConfig(n_samples=1, stuck_steps=4, max_skill_horizon=1000)
    res = run(task, [(toy.PRESS_DIRECT, ("robot", "button0"))], toy.skills(), cfg)
    # 10 steps to the reach limit at x=5, then 4 unchanged steps
    assert res.stats.sim_steps == 10 + 4


def test_a_rollout_ends_at_once_in_a_declared_dead_end():
    """10 steps to the reach limit, where the cliff env declares a dead end: the sample
    fails there instead of waiting out stuck_steps (or the horizon)."""
    task = toy.make_task([8.0])
    cfg = PlanningConfig(n_samples=1, stuck_steps=4, max_skill_horizon=1000)
    plan = skeleton(task, [(toy.PRESS_DIRECT, ("robot", "button0"))])
    skills = [by_op(toy.skills())[o.operator] for o in plan.operators]
    rng = np.random.default_rng(0)
    res = refine(plan, skills, task, toy.CliffEnv(), cfg, rng)
    assert res.stats.failures("dead_end") == 1 and res.stats.sim_steps == 10
    # the paper's rollouts run on: here until the world stands still
    paper = dataclasses.replace(cfg, end_at_dead_end=False)
    res = refine(plan, skills, task, toy.CliffEnv(), paper, rng)
    assert res.stats.failures("dead_end") == 0 and res.stats.failures("stuck") == 1
    assert res.stats.sim_steps == 10 + 4


def test_a_policy_chattering_in_place_counts_as_stuck():
    """Period-2 chatter below stuck_atol (an arm at its reach limit) goes nowhere."""
    task = toy.make_task([4.0])
    flip = {"sign": 1.0}

    def chatter(state, objs, subgoal):
        flip["sign"] *= -1.0
        return np.array([flip["sign"] * 1e-3, 0.0])  # +-0.5 mm a step

    skills = toy.skills(press_direct_policy_fn=chatter)
    cfg = PlanningConfig(n_samples=1, stuck_steps=4, stuck_atol=1e-3, max_skill_horizon=1000)
    res = run(task, [(toy.PRESS_DIRECT, ("robot", "button0"))], skills, cfg)
    assert res.stats.failures("stuck") == 1 and res.stats.sim_steps == 4


def test_a_slow_but_steady_policy_is_not_stuck():
    """0.6 mm a step is below stuck_atol, but it gets somewhere: only the horizon ends it."""
    task = toy.make_task([4.0])

    def creep(state, objs, subgoal):
        return np.array([1.2e-3, 0.0])

    skills = toy.skills(press_direct_policy_fn=creep)
    cfg = PlanningConfig(n_samples=1, stuck_steps=4, stuck_atol=1e-3, max_skill_horizon=30)
    res = run(task, [(toy.PRESS_DIRECT, ("robot", "button0"))], skills, cfg)
    assert res.stats.failures("skill_horizon") == 1 and res.stats.failures("stuck") == 0


def test_skill_horizon_fails_a_sample():
    task = toy.make_task([4.0])
    res = run(
        task,
        [(toy.PRESS_DIRECT, ("robot", "button0"))],
        toy.skills(),
        PlanningConfig(n_samples=2, max_skill_horizon=3),
    )
    assert res.stats.failures("skill_horizon") == 2 and res.stats.sim_steps == 6


def test_task_horizon_is_never_exceeded():
    task = toy.make_task([4.0], horizon=5)  # needs 8 steps
    res = run(
        task, [(toy.PRESS_DIRECT, ("robot", "button0"))], toy.skills(), PlanningConfig(n_samples=2)
    )
    assert not res.success and res.stats.failures("task_horizon") == 2
    assert res.stats.sim_steps == 2 * 5


def _nan_policy(state, objs, subgoal):
    return np.array([np.nan, 0.0])


def _inf_policy(state, objs, subgoal):
    return np.array([np.inf, 0.0])


def _raising_policy(state, objs, subgoal):
    raise RuntimeError("network exploded")


def _raising_sampler(state, objs, rng):
    raise ValueError("bad sampler")


def _nan_sampler(state, objs, rng):
    return np.full(4, np.nan)


def _refusing_sampler(state, objs, rng):
    raise NoSubgoal("never demonstrated from here")


@pytest.mark.parametrize(
    "policy, sampler, reason",
    [
        (_nan_policy, None, "policy_nonfinite"),
        (_inf_policy, None, "policy_nonfinite"),
        (_raising_policy, None, "policy_error"),
        (lambda s, o, g: np.zeros(5), None, "policy_error"),  # wrong action shape
        (None, _raising_sampler, "sampler_error"),
        (None, _nan_sampler, "sampler_nonfinite"),
        (None, _refusing_sampler, "no_subgoal"),  # a sampler's refusal: no simulation
    ],
)
def test_misbehaving_policy_or_sampler_fails_its_sample_without_crashing(policy, sampler, reason):
    task = toy.make_task([2.5])
    skills = toy.skills(press_direct_policy_fn=policy, press_direct_sampler_fn=sampler)
    res = run(task, [(toy.PRESS_DIRECT, ("robot", "button0"))], skills, PlanningConfig(n_samples=4))
    assert not res.success and res.reason == "exhausted"
    assert res.stats.failures(reason) == 4 and res.stats.sim_steps == 0


def test_keyboard_interrupt_in_a_policy_is_not_swallowed():
    def interrupt(state, objs, subgoal):
        raise KeyboardInterrupt

    task = toy.make_task([2.5])
    with pytest.raises(KeyboardInterrupt):
        run(
            task,
            [(toy.PRESS_DIRECT, ("robot", "button0"))],
            toy.skills(press_direct_policy_fn=interrupt),
        )


def test_actions_are_clipped_to_the_action_box():
    def wild(state, objs, subgoal):
        return np.array([100.0 * np.sign(subgoal[0] - state.get(objs[0], "x")), -7.0])

    task = toy.make_task([2.0])
    res = run(
        task, [(toy.PRESS_DIRECT, ("robot", "button0"))], toy.skills(press_direct_policy_fn=wild)
    )
    assert res.success
    assert np.all(res.actions <= 1.0) and np.all(res.actions >= -1.0)
    assert np.array_equal(res.actions[0], [1.0, -1.0])


def test_a_step_is_complete_only_once_its_delete_effects_stop_holding():
    # Same as PressDirect but claims to delete HandEmpty, which pressing never does.
    r, b = toy.PRESS_DIRECT.parameters
    liar = STRIPSOperator(
        "PressAndGrab",
        (r, b),
        toy.PRESS_DIRECT.preconditions,
        toy.PRESS_DIRECT.add_effects,
        frozenset({LiftedAtom(toy.HAND_EMPTY, (r,))}),
    )
    task = toy.make_task([2.0])
    skill = Skill(liar, toy.press_direct_policy, toy.press_direct_sampler)
    res = run(
        task, [(liar, ("robot", "button0"))], [skill], PlanningConfig(n_samples=2, stuck_steps=3)
    )
    assert not res.success and res.stats.failures("stuck") == 2


def test_refinement_obeys_its_deadline():
    task = toy.make_task([8.0])
    start = time.monotonic()
    slow = toy.SlowEnv(0.01)
    plan = skeleton(task, STICK_PLAN)
    table = by_op(toy.skills(pick_bad_first=100))
    res = refine(
        plan,
        [table[o.operator] for o in plan.operators],
        task,
        slow,
        PlanningConfig(),
        np.random.default_rng(0),
        deadline=start + 0.3,
    )
    assert not res.success and res.reason == "timeout"
    assert time.monotonic() - start < 0.3 + 1.0  # obeyed within 1 s (the contract)


def test_skills_must_match_plan_steps():
    task = toy.make_task([8.0])
    plan = skeleton(task, STICK_PLAN)
    with pytest.raises(ValueError):
        refine(plan, toy.skills()[:2], task, ENV, PlanningConfig(), np.random.default_rng(0))


def test_a_skill_horizon_shorter_than_the_planners_ends_its_rollouts_first():
    import dataclasses

    task = toy.make_task([4.0])  # pressing needs 8 steps
    skills = [
        dataclasses.replace(s, horizon=3) if s.operator == toy.PRESS_DIRECT else s
        for s in toy.skills()
    ]
    res = run(
        task,
        [(toy.PRESS_DIRECT, ("robot", "button0"))],
        skills,
        PlanningConfig(n_samples=2, max_skill_horizon=50),
    )
    assert res.stats.failures("skill_horizon") == 2 and res.stats.sim_steps == 6
