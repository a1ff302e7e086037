"""Model and world in real physics: what the planner is told, and exact replay of
worlds drawn per task."""

from __future__ import annotations

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.env.environment import adopt_state, perturbed
from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.env.worlds import WORLD_MODEL, ModelSpec, Spread, WorldDistribution
from bpns.evaluation import evaluate as evaluation
from bpns.evaluation.evaluate import EvalSpec, evaluate
from bpns.evaluation.rollout_files import RolloutsFile, replay_rollouts, save_rollouts
from bpns.planning.config import PlanningConfig

WORLDS = WorldDistribution(
    {
        "mass_scale": Spread(low=0.5, high=2.0),
        "friction_scale": Spread(low=0.7, high=1.4),
        "latency": Spread(choices=(0, 1)),
        "action_noise": Spread(value=0.02),
    },
    seed=3,
)


def _spec(model: ModelSpec, **kw) -> EvalSpec:
    planning = PlanningConfig(timeout=60.0)
    return EvalSpec("cover", "oracle", planning, perturbation=WORLDS, model=model, **kw)


def test_the_model_never_sees_the_worlds_physics_unless_asked(monkeypatch):
    seen: list[Perturbation] = []
    build = evaluation.approach_for

    def spy(spec, env):
        seen.append(env.perturbation)
        return build(spec, env)

    monkeypatch.setattr(evaluation, "approach_for", spy)
    report = evaluate(_spec(ModelSpec()), 2)
    assert seen == [NOMINAL]  # one nominal model serves every task
    worlds = [o.world for o in report.outcomes]
    assert worlds == [WORLDS.draw(0), WORLDS.draw(1)] and worlds[0] != worlds[1]
    seen.clear()
    belief = Perturbation(mass_scale=1.5)
    evaluate(_spec(ModelSpec(belief=belief)), 2)
    assert seen == [belief]
    seen.clear()
    evaluate(_spec(WORLD_MODEL), 2)  # the paper's closed world: the model is the world
    assert seen == worlds


def test_rollouts_of_worlds_drawn_per_task_replay_exactly(tmp_path, cover_env):
    report = evaluate(_spec(ModelSpec(), execution=ExecutionConfig()), 3)
    path = tmp_path / "rollouts_oracle.h5"
    save_rollouts(path, cover_env, report)
    f = RolloutsFile.read(path)
    assert [r.physics for r in f.rows] == [o.world for o in report.outcomes]
    assert f.worlds == WORLDS and f.execution == "closed-loop"
    assert [r.replans for r in f.rows] == [o.replans for o in report.outcomes]
    replay = replay_rollouts(cover_env, path)
    assert replay.ok and all(r.exact for _, r in replay.rows)
    assert replay.rows and all(r.max_state_diff == 0.0 for _, r in replay.rows)


def test_a_state_of_a_latent_world_is_handed_to_the_model_as_it_is(cover_env):
    world = perturbed(cover_env, Perturbation(latency=2, mass_scale=2.0))
    state = world.task(0, 0, False).init
    for _ in range(4):
        state = world.simulate(state, np.array([0.01, 0.0, 0.0, 1.0]))
    seen = adopt_state(cover_env, state)
    assert seen.sim.flat.shape != state.sim.flat.shape  # the model keeps no latency queue
    for obj, value in state.data.items():
        np.testing.assert_array_equal(seen.data[obj], value)
    # back into the world: the queue holds zeros where the model kept nothing
    back = adopt_state(world, seen)
    assert back.sim.flat.shape == state.sim.flat.shape
    # under the world's own physics a state is itself
    assert adopt_state(world, state) is state
