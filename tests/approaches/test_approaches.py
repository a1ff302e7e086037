"""The Approach interface: a metacontroller and a per-step policy on the toy stick
button world, the shared skill execution, the registry and the failure-reason enum."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bpns.approaches import Solution, UnknownApproachError, approach_names, get_approach
from bpns.approaches.base import ApproachEntry
from bpns.approaches.metacontroller import Metacontroller, SkillChoice
from bpns.approaches.policy import ClosedLoopPolicy
from bpns.env.abstraction import abstract
from bpns.evaluation.evaluate import plan_reaches_goal, solve_task
from bpns.execution.executor import (
    Executed,
    RolloutConfig,
    SkillExecutor,
    completion_test,
    expected_after,
)
from bpns.execution.failures import FailureReason
from bpns.planning.config import PlanningConfig
from tests import toy_planning as toy

ENV = toy.ToyStickButton()
FAR = 8.0  # beyond the robot's reach: the button needs the stick


class ScriptedMetacontroller(Metacontroller):
    """Executes a fixed list of (operator, object names), one per ``choose`` call."""

    def __init__(self, steps, skills=None, config=None):
        super().__init__(ENV, config or PlanningConfig())
        self.steps = steps
        self.by_op = {s.operator: s for s in (skills or toy.skills(pick_good=0.5))}

    def choose(self, task, state, atoms, history, rng):
        if len(history) >= len(self.steps):
            return None
        operator, names = self.steps[len(history)]
        objects = {o.name: o for o in task.objects}
        return SkillChoice(self.by_op[operator], tuple(objects[n] for n in names))


STICK_PLAN = [
    (toy.PICK_STICK, ("robot", "stick")),
    (toy.PRESS_WITH_STICK, ("robot", "stick", "button0")),
]


def test_a_metacontroller_executes_one_chosen_skill_after_another_to_the_goal():
    task = toy.make_task([FAR])
    result = ScriptedMetacontroller(STICK_PLAN).solve(task, np.random.default_rng(0), 10.0)
    assert result.success and result.reason is None
    assert result.skeleton == ("PickStick(robot, stick)", "PressWithStick(robot, stick, button0)")
    assert result.samples == 2 and result.sim_steps == len(result.actions) > 0
    assert plan_reaches_goal(ENV, task, result.actions)


def test_a_metacontroller_fails_with_the_failing_executions_reason():
    task = toy.make_task([FAR])
    out_of_reach = [(toy.PRESS_DIRECT, ("robot", "button0"))]
    result = ScriptedMetacontroller(out_of_reach).solve(task, np.random.default_rng(0), 10.0)
    assert not result.success and len(result.actions) == 0
    assert result.reason in (FailureReason.STUCK, FailureReason.SKILL_HORIZON)
    nothing_left = ScriptedMetacontroller(STICK_PLAN[:1])
    result = nothing_left.solve(task, np.random.default_rng(0), 10.0)
    assert result.reason is FailureReason.NO_SKILL and result.sim_steps > 0


class GoTo(ClosedLoopPolicy):
    """Walks to ``x`` and stops: a policy that solves near buttons, never far ones."""

    def __init__(self, x, output=None):
        super().__init__(ENV)
        self.x, self.output = x, output

    def act(self, task, state):
        if self.output is not None:
            return self.output
        robot = next(o for o in task.objects if o.name == "robot")
        return np.array([toy._toward(state.get(robot, "x"), self.x), 0.0])


def test_a_per_step_policy_in_a_slowed_world_moves_the_commanded_fraction():
    from bpns.acting.config import ExecutionConfig
    from tests.acting.test_closed_loop import SlowableArm

    near, rng = toy.make_task([3.0], horizon=100), np.random.default_rng(0)
    full = GoTo(3.0).solve_in_world(near, ENV, SlowableArm(), rng, 10.0, ExecutionConfig())
    slow = GoTo(3.0).solve_in_world(
        near, ENV, SlowableArm(), rng, 10.0, ExecutionConfig(world_speed=0.5)
    )
    assert full.success and slow.success and len(slow.actions) > len(full.actions)
    assert np.abs(slow.actions[:, 0]).max() <= 0.5 * np.abs(full.actions[:, 0]).max() + 1e-12
    assert plan_reaches_goal(SlowableArm(), near, slow.actions)
    # slowed from the first deviation: a policy has no model's prediction to leave
    lazy = ExecutionConfig(world_speed=0.5, slow_from="deviation")
    same = GoTo(3.0).solve_in_world(near, ENV, SlowableArm(), rng, 10.0, lazy)
    assert np.array_equal(same.actions, full.actions)


def test_a_per_step_policy_acts_until_the_goal_holds_or_the_horizon_ends():
    near = toy.make_task([3.0], horizon=100)
    result = GoTo(3.0).solve(near, np.random.default_rng(0), 10.0)
    assert result.success and result.skeleton == () and result.nodes_created == 0
    assert plan_reaches_goal(ENV, near, result.actions)
    far = toy.make_task([FAR], horizon=30)
    result = GoTo(FAR).solve(far, np.random.default_rng(0), 10.0)
    assert not result.success and result.reason is FailureReason.TASK_HORIZON
    assert result.sim_steps == 30


@pytest.mark.parametrize(
    "output, reason",
    [
        (np.array([np.nan, 0.0]), FailureReason.POLICY_NONFINITE),
        (np.zeros(3), FailureReason.POLICY_ERROR),
        ("left", FailureReason.POLICY_ERROR),
    ],
)
def test_a_per_step_policys_bad_output_fails_the_attempt_not_the_caller(output, reason):
    result = GoTo(0.0, output).solve(toy.make_task([3.0]), np.random.default_rng(0), 10.0)
    assert not result.success and result.reason is reason


def test_the_shared_executor_runs_one_ground_skill_until_its_predicted_atoms_hold():
    task = toy.make_task([FAR])
    by_name = {o.name: o for o in task.objects}
    pick = next(s for s in toy.skills() if s.operator == toy.PICK_STICK)
    op = pick.operator.ground([by_name["robot"], by_name["stick"]])
    atoms = abstract(task.init, ENV.predicates)
    test = completion_test(op, expected_after(op, atoms))
    assert op.add_effects <= frozenset(test.must_hold)
    assert op.delete_effects <= frozenset(test.must_not_hold)
    executor = SkillExecutor(ENV, task, RolloutConfig.of(PlanningConfig()))
    subgoal = np.array([3.0, 0.0, 1.0, 4.0, 0.0, 0.0])  # robot x at the grip point
    out = executor.execute(pick, op.objects, subgoal, task.init, test)
    assert isinstance(out, Executed) and executor.sim_steps == len(out.actions)
    assert op.add_effects <= abstract(out.states[-1], ENV.predicates)
    # with the task's horizon already spent, nothing is simulated
    spent = executor.execute(pick, op.objects, subgoal, task.init, test, task.horizon)
    assert spent is FailureReason.TASK_HORIZON


def test_every_registered_approach_is_an_entry_that_solves_through_the_same_interface():
    assert {"bpns", "oracle", "samples1", "abstract1"} <= set(approach_names())
    for name in approach_names():
        entry = get_approach(name)
        assert isinstance(entry, ApproachEntry) and entry.name == name
    with pytest.raises(UnknownApproachError, match="unknown approach 'nope'"):
        get_approach("nope")

    def build(env, config, skills_dir):
        return ScriptedMetacontroller(STICK_PLAN, config=config)

    from bpns.approaches.base import SkillSource

    entry = ApproachEntry("scripted", "Scripted", "a fixed skill list", SkillSource.NONE, build)
    task = toy.make_task([FAR])
    approach = entry.make(ENV, PlanningConfig())
    outcome = solve_task(approach, task, 0, ENV, 10.0, np.random.default_rng(0))
    assert outcome.solved and outcome.validated and len(outcome.skeleton) == 2
    assert isinstance(approach.solve(task, np.random.default_rng(0), 10.0), Solution)


def test_failure_reasons_are_one_enum_that_reads_as_the_old_strings():
    assert FailureReason.CONTACT_CHANGED == "unexpected_contact_change"
    assert str(FailureReason.TIMEOUT) == "timeout" and f"{FailureReason.STUCK}" == "stuck"
    assert json.dumps({FailureReason.NOGOOD: 2}) == '{"nogood": 2}'
    assert {FailureReason.STUCK: 1} == {"stuck": 1}
    from bpns.planning import FailureReason as PlanningFailureReason

    assert PlanningFailureReason is FailureReason
