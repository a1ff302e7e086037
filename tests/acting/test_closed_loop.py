"""Closed-loop execution: plans made in a model meet a world that differs from it.

The toy world below is the toy Stick Button with one difference the model cannot know:
the first time the robot carries the stick past x = 2.5 the stick slips out of its grip.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bpns.acting.config import ExecutionConfig, ExecutionConfigError
from bpns.acting.monitor import kept_atoms, necessary_atoms, repair_point
from bpns.acting.replanning import ClosedLoopPlanner, ClosedLoopStats, world_run
from bpns.acting.world import BACK_OFF
from bpns.approaches.bilevel import BilevelPlanning
from bpns.evaluation.evaluate import plan_reaches_goal, solve_task
from bpns.execution.executor import ExecutionTimeout, NotSlowableError, RolloutConfig
from bpns.execution.failures import FailureReason
from bpns.planning.config import PlanningConfig
from bpns.structs import GroundAtom, State
from tests import toy_planning as toy

CONFIG = PlanningConfig(timeout=20.0, n_samples=5)


class SlipOnce(toy.ToyStickButton):
    """The held stick slips out of the grip the first time it is carried past x = 2.5."""

    def __init__(self) -> None:
        self.slipped = False

    def simulate(self, state: State, action: np.ndarray) -> State:
        out = super().simulate(state, action)
        robot = next(o for o in out.objects if o.type == toy.ROBOT)
        stick = next(o for o in out.objects if o.type == toy.STICK)
        if not self.slipped and out.get(robot, "holding") > 0.5 and out.get(robot, "x") > 2.5:
            self.slipped = True
            data = {o: v.copy() for o, v in out.data.items()}
            data[robot][1] = 0.0
            data[stick][2] = 0.0
            return State(data)
        return out


class SoftArm(toy.ToyStickButton):
    """The arm covers 60 % of the distance the model predicts per command."""

    def simulate(self, state: State, action: np.ndarray) -> State:
        return super().simulate(state, np.array([0.6 * action[0], action[1]]))


class Overshoot(toy.ToyStickButton):
    """The arm covers 130 % of the distance the model predicts per command."""

    def simulate(self, state: State, action: np.ndarray) -> State:
        return super().simulate(state, np.array([1.3 * action[0], action[1]]))


def _far_button_task():
    return toy.make_task([7.0])


def test_the_monitor_fires_when_the_stick_slips_and_the_replan_solves_the_task():
    model, world = toy.ToyStickButton(), SlipOnce()
    planner = BilevelPlanning(model, toy.skills(pick_good=0.5), CONFIG)
    task = _far_button_task()
    solution = planner.solve_in_world(
        task, model, world, np.random.default_rng(0), 20.0, ExecutionConfig()
    )
    assert solution.success and world.slipped
    assert solution.replans == 1
    kinds = [e.kind for e in solution.rollout.events]
    assert kinds[0] == "atom_lost" and "replanned" in kinds
    lost = solution.rollout.events[0].text
    assert "Holding(robot, stick)" in lost and lost.startswith("replan 1:")
    # the skills executed in the world: pick, the press that lost the stick, pick, press
    names = [s.operator for s in solution.rollout.steps]
    assert names == ["PickStick", "PressWithStick", "PickStick", "PressWithStick"]
    assert solution.rollout.steps[1].outcome == str(FailureReason.ATOM_LOST)
    # the actions are the world's: replayed in a fresh slippery world they reach the goal
    assert plan_reaches_goal(SlipOnce(), task, solution.actions)


def _with_press_horizon(horizon: int) -> list:
    return [
        dataclasses.replace(s, horizon=horizon) if s.operator is toy.PRESS_DIRECT else s
        for s in toy.skills()
    ]


def test_a_skill_still_moving_in_a_softer_world_gets_more_than_its_own_horizon():
    # the press needs 6 steps in the model and its horizon is 7; the softer world needs 12
    model, world, task = toy.ToyStickButton(), SoftArm(), toy.make_task([3.0])
    planner = BilevelPlanning(model, _with_press_horizon(7), CONFIG)

    def solve(execution: ExecutionConfig):
        return planner.solve_in_world(task, model, world, np.random.default_rng(0), 20.0, execution)

    strict = solve(ExecutionConfig(horizon_scale=1.0))
    assert strict.success and strict.replans >= 1
    assert "skill_horizon" in strict.rollout.events[0].text
    assert strict.rollout.steps[0].outcome == str(FailureReason.SKILL_HORIZON)
    patient = solve(ExecutionConfig())  # horizon_scale 2: the press may take 14 steps
    assert patient.success and patient.replans == 0
    assert len(patient.rollout.steps) == 1 and 7 < len(patient.actions) <= 14
    assert plan_reaches_goal(SoftArm(), task, patient.actions)


def test_a_world_that_deviates_a_little_keeps_the_plans_subgoals_after_checking_them():
    # every skill ends past where the model put it: each boundary deviates, but the rest
    # of the plan, simulated again in the model from there, still reaches the goal
    model, world, task = toy.ToyStickButton(), Overshoot(), toy.make_task([3.0, 6.0])
    planner = BilevelPlanning(model, toy.skills(), CONFIG)
    solution = planner.solve_in_world(
        task, model, world, np.random.default_rng(0), 20.0, ExecutionConfig()
    )
    assert solution.success and solution.replans == 0
    texts = [e.text for e in solution.rollout.events]
    assert texts and all(t.startswith("kept the subgoals of the last") for t in texts)
    assert plan_reaches_goal(Overshoot(), task, solution.actions)


def test_checking_one_step_ahead_simulates_less_and_still_solves_the_task():
    # each boundary deviates; checking the whole rest simulates it again every time,
    # checking one step leaves the later ones to their own boundaries
    model, task = toy.ToyStickButton(), toy.make_task([2.0, 3.0, 4.0])
    planner = BilevelPlanning(model, toy.skills(), CONFIG)

    def solve(execution: ExecutionConfig):
        return planner.solve_in_world(
            task, model, Overshoot(), np.random.default_rng(0), 20.0, execution
        )

    whole, one = solve(ExecutionConfig()), solve(ExecutionConfig(check_ahead=1))
    assert whole.success and one.success and one.replans == 0
    assert len(one.rollout.steps) == len(whole.rollout.steps) == 3
    assert one.sim_steps < whole.sim_steps
    assert plan_reaches_goal(Overshoot(), task, one.actions)


def test_the_worlds_simulation_time_is_told_apart_from_the_agents():
    model, task = toy.ToyStickButton(), toy.make_task([3.0, 6.0])
    planner = BilevelPlanning(model, toy.skills(), CONFIG)
    rng = np.random.default_rng(0)
    outcome = solve_task(planner, task, 0, model, 20.0, rng, world=Overshoot())
    assert outcome.solved and 0.0 < outcome.world_seconds < outcome.seconds
    assert outcome.agent_seconds == outcome.seconds - outcome.world_seconds
    assert outcome.to_json()["world_seconds"] == outcome.world_seconds
    # the same split in CPU seconds
    assert 0.0 < outcome.world_cpu_seconds <= outcome.cpu_seconds
    assert outcome.agent_cpu_seconds == outcome.cpu_seconds - outcome.world_cpu_seconds
    # planning alone, in the model: nothing is the world's
    planned = solve_task(planner, task, 0, model, 20.0, rng)
    assert planned.solved and planned.world_seconds == 0.0


def test_a_rest_of_the_plan_checked_after_the_deadline_is_the_tasks_timeout():
    # the deadline passed at a boundary: refining the rest is the task's timeout, not a
    # planning config with a timeout of 0 (which the config refuses)
    model, task = toy.ToyStickButton(), toy.make_task([3.0])
    planner = ClosedLoopPlanner(toy.skills(), model, CONFIG, ExecutionConfig())
    world = world_run(Overshoot(), task, CONFIG, deadline=0.0)
    robot, button = (task.init.objects_of_type(t)[0] for t in (toy.ROBOT, toy.BUTTON))
    ops = [toy.PRESS_DIRECT.ground((robot, button))]
    with pytest.raises(ExecutionTimeout):
        planner._refine_rest(world, ops, np.random.default_rng(0), 0.0, ClosedLoopStats())


def test_open_loop_replays_the_models_plan_and_misses_the_goal_in_the_world():
    model, world = toy.ToyStickButton(), SlipOnce()
    planner = BilevelPlanning(model, toy.skills(pick_good=0.5), CONFIG)
    solution = planner.solve_in_world(
        _far_button_task(),
        model,
        world,
        np.random.default_rng(0),
        20.0,
        ExecutionConfig(closed_loop=False),
    )
    assert not solution.success and solution.reason is FailureReason.GOAL_NOT_REACHED
    assert solution.replans == 0 and len(solution.rollout.actions) > 0


def test_without_a_monitor_the_lost_stick_is_noticed_only_when_the_press_fails():
    model, world = toy.ToyStickButton(), SlipOnce()
    planner = BilevelPlanning(model, toy.skills(pick_good=0.5), CONFIG)
    solution = planner.solve_in_world(
        _far_button_task(),
        model,
        world,
        np.random.default_rng(0),
        20.0,
        ExecutionConfig(watch_atoms=False),
    )
    assert solution.success and solution.replans == 1
    assert solution.rollout.events[0].kind == "skill_failed"


def test_a_replan_budget_of_zero_fails_at_the_first_divergence():
    model, world = toy.ToyStickButton(), SlipOnce()
    planner = BilevelPlanning(model, toy.skills(pick_good=0.5), CONFIG)
    solution = planner.solve_in_world(
        _far_button_task(),
        model,
        world,
        np.random.default_rng(0),
        20.0,
        ExecutionConfig(max_replans=0),
    )
    assert not solution.success and solution.reason is FailureReason.REPLAN_BUDGET


def test_in_a_world_that_is_the_model_closed_loop_is_the_plan_itself():
    env = toy.ToyStickButton()
    planner = BilevelPlanning(env, toy.skills(pick_good=0.5), CONFIG)
    task = _far_button_task()
    planned = planner.solve(task, np.random.default_rng(0), 20.0)
    acted = planner.solve_in_world(
        task, env, env, np.random.default_rng(0), 20.0, ExecutionConfig()
    )
    assert acted.success and acted.replans == 0 and not acted.rollout.events
    np.testing.assert_array_equal(acted.actions, planned.actions)


def test_necessary_atoms_regress_the_goal_through_the_plan():
    robot, stick, (button,) = toy.objects(1)
    pick = toy.PICK_STICK.ground((robot, stick))
    press = toy.PRESS_WITH_STICK.ground((robot, stick, button))
    goal = frozenset({GroundAtom(toy.PRESSED, (button,))})
    needed = necessary_atoms([pick, press], goal)
    holding = GroundAtom(toy.HOLDING, (robot, stick))
    empty = GroundAtom(toy.HAND_EMPTY, (robot,))
    assert needed == (frozenset({empty}), frozenset({holding}), goal)
    # with the stick in hand the plan's second step is where to resume
    assert repair_point(needed, frozenset({holding})) == 1
    assert repair_point(needed, frozenset()) is None
    # while pressing, the grip (a precondition it does not delete) must hold
    assert kept_atoms(press, frozenset({holding}), goal, {toy.HOLDING}) == (holding,)
    assert kept_atoms(pick, frozenset({empty}), needed[1], {toy.HAND_EMPTY}) == ()


@pytest.mark.parametrize(
    "fields",
    [
        {"max_replans": -1},
        {"max_replans": 1.5},
        {"rerefine_atol": 0.0},
        {"check_ahead": 0},
        {"check_ahead": 1.5},
        {"check_ahead": True},
        {"horizon_scale": 0.5},
        {"horizon_scale": float("inf")},
        {"world_speed": 0.0},
        {"world_speed": 1.5},
        {"world_speed": float("nan")},
        {"slow_from": "never"},
    ],
)
def test_bad_execution_settings_are_refused(fields):
    with pytest.raises(ExecutionConfigError):
        ExecutionConfig(**fields)


class SlowableArm(toy.ToyStickButton):
    """The toy arm declaring its motion dim (dx): a world-side speed may slow it."""

    capabilities = dataclasses.replace(toy.ToyStickButton.capabilities, motion_dims=(0,))


def test_a_slowed_world_moves_the_commanded_fraction_and_leaves_the_fingers_as_commanded():
    model, world, task = toy.ToyStickButton(), SlowableArm(), _far_button_task()
    planner = BilevelPlanning(model, toy.skills(), CONFIG)
    full = planner.solve_in_world(
        task, model, world, np.random.default_rng(0), 20.0, ExecutionConfig()
    )
    slow = planner.solve_in_world(
        task, model, world, np.random.default_rng(0), 20.0, ExecutionConfig(world_speed=0.5)
    )
    assert full.success and slow.success
    fast_dx = np.abs(np.asarray(full.actions)[:, 0]).max()
    slow_acts = np.asarray(slow.actions)
    # the same plan from the model, executed at half the commanded motion: no step moves
    # more than half the fastest full-speed step, and it takes more steps to get there
    assert np.abs(slow_acts[:, 0]).max() <= 0.5 * fast_dx + 1e-12
    assert len(slow.actions) > len(full.actions)
    assert set(np.unique(slow_acts[:, 1])) <= {-1.0, 0.0, 1.0}  # grip commands unscaled
    # the recorded actions are the applied ones: replaying them in the world reaches the goal
    assert plan_reaches_goal(SlowableArm(), task, slow.actions)


class SlowableOvershoot(Overshoot):
    capabilities = SlowableArm.capabilities


def test_slowing_from_the_first_deviation_leaves_a_world_like_the_model_at_full_speed():
    task = _far_button_task()
    model = toy.ToyStickButton()
    planner = BilevelPlanning(model, toy.skills(), CONFIG)
    lazy = ExecutionConfig(world_speed=0.5, slow_from="deviation")

    def solve(world, execution):
        return planner.solve_in_world(task, model, world, np.random.default_rng(0), 20.0, execution)

    # a world that behaves as the model: never slowed, the very actions of full speed
    same = solve(SlowableArm(), lazy)
    full = solve(SlowableArm(), ExecutionConfig())
    assert same.success and np.array_equal(np.asarray(same.actions), np.asarray(full.actions))
    assert not [e for e in same.rollout.events if e.kind == "slowed"]
    # a world that overshoots: the first boundary deviates, every later skill is slowed
    drift = solve(SlowableOvershoot(), lazy)
    slowed = [e for e in drift.rollout.events if e.kind == "slowed"]
    assert drift.success and len(slowed) == 1
    assert "skills slowed to 0.5 of their speed" in slowed[0].text
    after = np.asarray(drift.actions)[slowed[0].at :, 0]
    assert np.abs(after).max() <= 0.5 + 1e-12  # the toy's largest step is 1
    assert plan_reaches_goal(SlowableOvershoot(), task, drift.actions)


def test_a_slowed_skill_gets_the_steps_its_speed_costs_in_the_world():
    limits = ExecutionConfig(world_speed=0.5).world_limits(RolloutConfig(max_skill_horizon=200))
    assert (limits.speed, limits.horizon_scale, limits.max_skill_horizon) == (0.5, 4.0, 400)
    full = ExecutionConfig().world_limits(RolloutConfig(max_skill_horizon=200))
    assert (full.speed, full.horizon_scale, full.max_skill_horizon) == (1.0, 2.0, 200)


def test_slowing_a_world_that_declares_no_motion_dims_is_one_clear_error():
    model, task = toy.ToyStickButton(), _far_button_task()
    planner = BilevelPlanning(model, toy.skills(), CONFIG)
    with pytest.raises(NotSlowableError, match="declares no motion_dims"):
        planner.solve_in_world(
            task, model, model, np.random.default_rng(0), 20.0, ExecutionConfig(world_speed=0.5)
        )


def test_a_videos_caption_names_why_it_replanned_not_only_that_it_did():
    from bpns.execution.rollouts import Event, event_captions

    events = [
        Event(3, "atom_lost", "replan 1: Holding(robot, stick) stopped holding"),
        Event(3, "replanned", "replan 1: the plan's last 2 steps refined again"),
        Event(9, "rerefined", "refined the last 1 steps again"),
    ]
    out = event_captions(["step"] * 12, events, hold=40)
    assert out[0] == "step" and out[4].endswith("Holding(robot, stick) stopped holding")
    assert out[11].endswith("refined the last 1 steps again")
    # slowing says why it happened: shown rather than the re-refinement of the same step
    slowed = [
        Event(2, "slowed", "the world left the model's prediction: skills slowed to 0.8"),
        Event(2, "rerefined", "kept the subgoals of the last 3 steps"),
    ]
    assert event_captions(["step"] * 4, slowed, hold=40)[3].endswith("skills slowed to 0.8")


class GoodGripOnce(toy.PickSampler):
    """The first grip is good; every later one grips too far back to reach the button."""

    def __call__(self, state, objs, rng):
        self.bad_first = 0 if self.calls == 0 else 10**9
        self.good = 0.5
        return super().__call__(state, objs, rng)


def test_a_replan_that_finds_no_plan_says_from_which_abstract_state():
    # the stick slips; every grip the replan can draw is too far back: no plan from there,
    # and the event names the world's atoms a user must explain (what the skills lacked)
    model, world = toy.ToyStickButton(), SlipOnce()
    skills = [
        dataclasses.replace(s, sampler=GoodGripOnce()) if s.operator is toy.PICK_STICK else s
        for s in toy.skills()
    ]
    planner = BilevelPlanning(model, skills, CONFIG)
    solution = planner.solve_in_world(
        _far_button_task(), model, world, np.random.default_rng(0), 20.0, ExecutionConfig()
    )
    assert not solution.success and world.slipped
    failed = [e for e in solution.rollout.events if e.kind == "replan_failed"]
    assert len(failed) == 1
    assert failed[0].text.startswith("replan 1 found no plan: ")
    assert "from {HandEmpty(robot)" in failed[0].text and failed[0].text.endswith("}")


class Dimmer(toy.ToyLights):
    """A push raises light i's level by 0.6 (at most to 1): one push turns it on."""

    def simulate(self, state: State, action: np.ndarray) -> State:
        data = {}
        for o, v in state.data.items():
            v = v.copy()
            if action[int(v[1])] > 0.5:
                v[0] = min(1.0, v[0] + 0.6)
            data[o] = v
        return State(data)


class StallsHalfway(Dimmer):
    """The world's first push stops at level 0.5, neither on nor off, and the switch
    sticks for the next ``stuck`` pushes: the skill ends stuck midway."""

    def __init__(self, n: int, stuck: int) -> None:
        super().__init__(n)
        self.pushes, self.stuck = 0, stuck

    def simulate(self, state: State, action: np.ndarray) -> State:
        if float(np.max(action)) <= 0.5:
            return super().simulate(state, action)
        self.pushes += 1
        if self.pushes > 1 + self.stuck:
            return super().simulate(state, action)
        data = {o: v.copy() for o, v in state.data.items()}
        if self.pushes == 1:
            for v in data.values():
                if action[int(v[1])] > 0.5:
                    v[0] = 0.5
        return State(data)


def test_a_skill_stopped_midway_is_finished_when_no_operator_leads_on_from_there():
    # TurnOn stalls halfway in the world: the light is neither Off nor On, a state no
    # operator starts from; the replan lets TurnOn finish (it lacks only Off, which it
    # deletes anyway), the model confirms it does, and the world's light comes on
    config = dataclasses.replace(CONFIG, stuck_steps=3)
    (light,) = toy.lights(1)
    task = toy.lights_task(1, frozenset({GroundAtom(toy.ON, (light,))}))
    model = Dimmer(1)
    planner = BilevelPlanning(model, toy.light_skills(), config)

    def solve(execution: ExecutionConfig):
        world = StallsHalfway(1, stuck=3)
        return planner.solve_in_world(task, model, world, np.random.default_rng(0), 20.0, execution)

    strict = solve(ExecutionConfig(resume_stopped=False))
    assert not strict.success and strict.reason is FailureReason.NO_ABSTRACT_PLAN
    solution = solve(ExecutionConfig())
    assert solution.success and solution.replans == 1
    texts = [e.text for e in solution.rollout.events]
    assert texts[0] == "replan 1: TurnOn(light00) failed in the world: stuck"
    assert (
        texts[1] == "replan 1: a new plan of 1 steps that first finishes TurnOn(light00), "
        "stopped midway"
    )
    assert [s.operator for s in solution.rollout.steps] == ["TurnOn", "TurnOn"]
    assert plan_reaches_goal(StallsHalfway(1, stuck=3), task, solution.actions)


def test_the_eval_command_turns_resuming_off_with_no_resume():
    from bpns.cli import build_parser
    from bpns.cli.eval import world_settings

    parser = build_parser()
    _, _, default = world_settings(parser.parse_args(["eval", "--env", "cover"]))
    _, _, off = world_settings(parser.parse_args(["eval", "--env", "cover", "--no-resume"]))
    assert default.resume_stopped and not off.resume_stopped


def toy_back_off(env, seen: State, start: State) -> np.ndarray | None:
    """Back along the line to where the robot began, the grip kept (0: no grip command)."""
    robot = next(o for o in start.objects if o.type == toy.ROBOT)
    x, home = seen.get(robot, "x"), start.get(robot, "x")
    return None if abs(x - home) <= toy.TOL else np.array([toy._toward(x, home), 0.0])


class SlipOnceBacksOff(SlipOnce):
    capabilities = dataclasses.replace(SlipOnce.capabilities, back_off=toy_back_off)


class PickFromHomeOnly(toy.PickSampler):
    """A pick learned from demonstrations that all began at home: from anywhere else its
    grip points lie off the track, so no pick refines there."""

    def __call__(self, state, objs, rng):
        g = super().__call__(state, objs, rng)
        if state.get(objs[0], "x") > 0.5:
            g[0] = -100.0
        return g


def test_a_replan_with_no_plan_from_where_the_skill_failed_backs_off_and_plans_again():
    # the stick slips at x = 2.5; the pick only refines from home, so no plan starts where
    # the robot stands; backing off to the start lets the replan pick the stick again
    model = toy.ToyStickButton()
    skills = [
        dataclasses.replace(s, sampler=PickFromHomeOnly(good=0.5))
        if s.operator is toy.PICK_STICK
        else s
        for s in toy.skills()
    ]
    planner = BilevelPlanning(model, skills, CONFIG)
    task = _far_button_task()

    def solve(execution: ExecutionConfig):
        world = SlipOnceBacksOff()
        return planner.solve_in_world(task, model, world, np.random.default_rng(0), 20.0, execution)

    strict = solve(ExecutionConfig(back_off=False))
    assert not strict.success and strict.reason is FailureReason.REFINEMENT_FAILED
    solution = solve(ExecutionConfig())
    assert solution.success and solution.replans == 1
    kinds = [e.kind for e in solution.rollout.events]
    assert kinds == ["atom_lost", "backed_off", "replanned"]
    backed = solution.rollout.events[1].text
    assert backed.startswith("replan 1 found no plan (refinement_failed) from {HandEmpty(robot)")
    names = [(s.operator, s.outcome) for s in solution.rollout.steps]
    assert names[2] == (BACK_OFF, "reached") and names[3][0] == "PickStick"
    assert plan_reaches_goal(SlipOnceBacksOff(), task, solution.actions)


class CountsPicksAway(PickFromHomeOnly):
    """Counts the grips drawn for the robot away from home (where none refines)."""

    away = 0

    def __call__(self, state, objs, rng):
        if state.get(objs[0], "x") > 0.5:
            self.away += 1
        return super().__call__(state, objs, rng)


def test_a_repair_does_not_refine_again_the_rest_it_just_failed_to_refine():
    # the stick slips; the rest of the plan (pick, press) is refined from there in vain
    # (n_samples grips); the new plan then passes over that same abstract plan instead of
    # drawing n_samples more grips for it, and the failure is still a failed refinement
    model = toy.ToyStickButton()
    sampler = CountsPicksAway(good=0.5)
    skills = [
        dataclasses.replace(s, sampler=sampler) if s.operator is toy.PICK_STICK else s
        for s in toy.skills()
    ]
    solution = BilevelPlanning(model, skills, CONFIG).solve_in_world(
        _far_button_task(),
        model,
        SlipOnce(),
        np.random.default_rng(0),
        20.0,
        ExecutionConfig(back_off=False),
    )
    assert not solution.success and solution.reason is FailureReason.REFINEMENT_FAILED
    assert sampler.away == CONFIG.n_samples


def test_an_environment_without_a_back_off_fails_as_before():
    model, world = toy.ToyStickButton(), SlipOnce()
    skills = [
        dataclasses.replace(s, sampler=PickFromHomeOnly(good=0.5))
        if s.operator is toy.PICK_STICK
        else s
        for s in toy.skills()
    ]
    solution = BilevelPlanning(model, skills, CONFIG).solve_in_world(
        _far_button_task(), model, world, np.random.default_rng(0), 20.0, ExecutionConfig()
    )
    assert not solution.success and solution.reason is FailureReason.REFINEMENT_FAILED
    assert "backed_off" not in [e.kind for e in solution.rollout.events]


def test_the_eval_command_turns_backing_off_off_with_no_back_off():
    from bpns.cli import build_parser
    from bpns.cli.eval import world_settings

    parser = build_parser()
    _, _, default = world_settings(parser.parse_args(["eval", "--env", "cover"]))
    _, _, off = world_settings(parser.parse_args(["eval", "--env", "cover", "--no-back-off"]))
    assert default.back_off and not off.back_off
