"""Seeing where the world will be when a command lands: the in-flight predictor
identifies the world's latency from the task's first steps and advances what a policy
observes by the commands not applied yet."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.acting.prediction import InFlightPredictor
from bpns.structs import State
from tests import toy_planning as toy


def _delayed_run(latency: int, steps: int, seed: int = 0):
    """The toy robot on its line, each command taking effect ``latency`` steps late
    (zeros before the first): the states the world shows and the commands sent."""
    model = toy.ToyStickButton()
    task = toy.make_task([7.0])
    robot = next(o for o in task.init.objects if o.type == toy.ROBOT)
    data = {o: v.copy() for o, v in task.init.data.items()}
    data[robot][0] = 2.5
    states = [State(data)]
    rng = np.random.default_rng(seed)
    sent = [np.array([rng.uniform(-0.3, 0.3), 0.0]) for _ in range(steps)]
    for k in range(steps):
        applied = sent[k - latency] if k >= latency else np.zeros(2)
        states.append(model.simulate(states[-1], applied))
    return model, robot, states, sent


@pytest.mark.parametrize("latency", [0, 1, 2, 3])
def test_the_predictor_identifies_the_worlds_latency_from_the_first_steps(latency):
    model, robot, states, sent = _delayed_run(latency, 30)
    predictor = InFlightPredictor(model, learn_steps=20)
    for k in range(25):  # the policy at state k has sent commands 0..k-1
        predictor(states[k], states[k], sent[:k], [])
    assert predictor.samples == 20 and predictor.latency == latency


def test_a_policy_sees_the_state_its_command_will_meet_with_the_observations_noise():
    model, robot, states, sent = _delayed_run(2, 12)
    predictor = InFlightPredictor(model, latency=2)
    k = 10
    noise = {o: np.full_like(v, 0.01) for o, v in states[k].data.items()}
    seen = State({o: v + noise[o] for o, v in states[k].data.items()})
    ahead = predictor(states[k], seen, sent[:8], sent[8:k])  # split across two skills
    # commands k-2 and k-1 are still in flight: state k + 2 is what command k will meet
    assert ahead.get(robot, "x") == pytest.approx(states[k + 2].get(robot, "x") + 0.01)
    # a known latency of 0, or no command sent yet, leaves the observation as it is
    assert InFlightPredictor(model, latency=0)(states[k], seen, sent[:k], []) is seen
    assert predictor(states[0], seen, [], []) is seen


def test_a_break_in_the_commands_it_saw_is_not_learnt_from():
    # a motion the predictor did not see (a back-off) leaves a gap in the commands: the
    # transition across it is skipped, not misread
    model, robot, states, sent = _delayed_run(1, 30)
    predictor = InFlightPredictor(model, learn_steps=5)
    predictor(states[3], states[3], sent[:3], [])
    predictor(states[10], states[10], sent[:10], [])
    assert predictor.samples == 0
    predictor(states[11], states[11], sent[:11], [])
    assert predictor.samples == 1


class DelayedToy(toy.ToyStickButton):
    """The toy whose commands take effect one step late (the command in flight is kept
    by the environment: a world that only ever moves forward, as a closed loop's does)."""

    def simulate(self, state: State, action: np.ndarray) -> State:
        pending = getattr(self, "pending", np.zeros(2))
        self.pending = np.asarray(action, dtype=np.float64)
        return super().simulate(state, pending)


def test_the_closed_loop_predicts_only_when_asked_and_records_the_latency_it_found():
    from bpns.acting.config import ExecutionConfig
    from bpns.approaches.bilevel import BilevelPlanning
    from bpns.planning.config import PlanningConfig

    model = toy.ToyStickButton()
    task = toy.make_task([3.0, 4.5])
    planner = BilevelPlanning(model, toy.skills(pick_good=0.5), PlanningConfig(timeout=20.0))

    def solve(execution: ExecutionConfig):
        return planner.solve_in_world(
            task, model, DelayedToy(), np.random.default_rng(0), 20.0, execution
        )

    solution = solve(ExecutionConfig(predict_latency=True, latency_learn_steps=4))
    assert solution.success and len(solution.actions) > 4
    (told,) = [e for e in solution.rollout.events if e.kind == "latency"]
    assert told.text == "identified a latency of 1 control steps from the first 4 steps"
    assert "latency" not in [e.kind for e in solve(ExecutionConfig()).rollout.events]


def test_the_eval_command_predicts_only_with_predict_latency_and_checks_its_settings():
    from bpns.acting.config import ExecutionConfig, ExecutionConfigError
    from bpns.cli import build_parser
    from bpns.cli.eval import world_settings

    parser = build_parser()
    _, _, default = world_settings(parser.parse_args(["eval", "--env", "cover"]))
    _, _, on = world_settings(parser.parse_args(["eval", "--env", "cover", "--predict-latency"]))
    assert not default.predict_latency and on.predict_latency
    with pytest.raises(ExecutionConfigError, match="latency_learn_steps"):
        ExecutionConfig(latency_learn_steps=0)
    with pytest.raises(ValueError, match="latency"):
        InFlightPredictor(toy.ToyStickButton(), latency=5)
