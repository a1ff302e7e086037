"""Watching a grip a step lets go of only at its end (``ExecutionConfig.watch_releases``):
the toy stick carried to x = 3 and put down there, in a world where it slips out of the
grip on the way (the hand stays closed on nothing, as a Doors handle slips out of the
fingers before the door opened)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.acting.monitor import released_atoms
from bpns.acting.world import WorldRun
from bpns.env.abstraction import abstract
from bpns.execution.executor import (
    Executed,
    RolloutConfig,
    SkillExecutor,
    completion_test,
    expected_after,
)
from bpns.execution.failures import FailureReason
from bpns.planning.config import PlanningConfig
from bpns.structs import Object, Skill, State, Task
from tests import toy_planning as toy

CONTACTS = frozenset({toy.HOLDING, toy.HAND_EMPTY})


def carry_then_place(state: State, objs: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    """Carry the stick to the subgoal's x, then open the hand."""
    x = state.get(objs[0], "x")
    if x < subgoal[0] - 1e-9:
        return np.array([1.0, 0.0])
    return np.array([0.0, -1.0])


class SlipsOnTheWay(toy.ToyStickButton):
    """Past x = 2 a carried stick slips out of the grip; the hand stays closed."""

    def simulate(self, state: State, action: np.ndarray) -> State:
        out = super().simulate(state, action)
        robot = next(o for o in out.objects if o.type == toy.ROBOT)
        stick = next(o for o in out.objects if o.type == toy.STICK)
        if out.get(robot, "holding") > 0.5 and out.get(robot, "x") > 2.0:
            data = {o: v.copy() for o, v in out.data.items()}
            data[stick][2] = 0.0  # no longer held, though the hand is closed
            return State(data)
        return out


def _holding_task() -> tuple[Task, Object, Object]:
    """The toy task with the stick already gripped at the robot (x = 1)."""
    robot, stick, buttons = toy.objects(1)
    data = {
        robot: np.array([1.0, 1.0]),
        stick: np.array([0.0, 4.0, 1.0, 1.0]),
        buttons[0]: np.array([7.0, 0.0]),
    }
    task = toy.make_task([7.0])
    return Task(State(data), task.goal, task.horizon), robot, stick


def _place_in_the_model(task: Task, robot: Object, stick: Object):
    model = toy.ToyStickButton()
    skill = Skill(toy.PLACE_STICK, carry_then_place, toy.place_sampler)
    op = toy.PLACE_STICK.ground((robot, stick))
    atoms = abstract(task.init, model.predicates)
    test = completion_test(op, expected_after(op, atoms))
    subgoal = np.array([3.0, 1.0])
    config = RolloutConfig.of(PlanningConfig(timeout=5.0))
    done = SkillExecutor(model, task, config).execute(skill, op.objects, subgoal, task.init, test)
    assert isinstance(done, Executed)
    return skill, op, atoms, test, subgoal, (task.init, *done.states), config


def test_the_grip_a_step_lets_go_of_at_its_end_is_watched_until_its_effects_hold():
    task, robot, stick = _holding_task()
    _, op, atoms, _, _, states, _ = _place_in_the_model(task, robot, stick)
    # the model kept Holding until the stick was put down (HandEmpty): watch it till then
    assert [str(a) for a in released_atoms(op, atoms, CONTACTS, states)] == [
        "Holding(robot, stick)"
    ]
    # not a contact predicate, or lost in the model before the effects: not watched
    assert released_atoms(op, atoms, frozenset({toy.HAND_EMPTY}), states) == ()
    early = (states[0], *(_dropped(s, stick) for s in states[1:]))
    assert released_atoms(op, atoms, CONTACTS, early) == ()


def _dropped(state: State, stick: Object) -> State:
    data = {o: v.copy() for o, v in state.data.items()}
    data[stick][2] = 0.0
    return State(data)


def test_a_grip_lost_before_the_place_ends_the_step_at_once_when_watching_releases():
    task, robot, stick = _holding_task()
    skill, op, atoms, test, subgoal, states, config = _place_in_the_model(task, robot, stick)
    released = released_atoms(op, atoms, CONTACTS, states)
    watching = WorldRun(SlipsOnTheWay(), task, config, None)
    reason = watching.execute(skill, op, subgoal, test, (), released)
    assert reason is FailureReason.ATOM_LOST
    assert watching.state.get(robot, "x") <= 2.5  # ended where it slipped, not at x = 3
    # without watching it the step carries nothing on to x = 3, opens the hand and
    # counts as done
    blind = WorldRun(SlipsOnTheWay(), task, config, None)
    assert blind.execute(skill, op, subgoal, test) is None
    assert blind.state.get(robot, "x") >= 3.0
    # in a world where the stick stays in the grip the watched step ends as planned
    steady = WorldRun(toy.ToyStickButton(), task, config, None)
    assert steady.execute(skill, op, subgoal, test, (), released) is None


def test_watching_releases_is_off_by_default():
    assert ExecutionConfig().watch_releases is False
