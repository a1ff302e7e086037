"""``bpns check-env``: each contract violation is caught on a Cover environment broken in
exactly that one way, and the registered environments keep the contract."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import mj_envs  # noqa: F401  (registers the Gymnasium ids)
from bpns.cli import main
from bpns.env.environment import Capabilities
from bpns.env.registry import environment_names, make_environment
from bpns.structs import Predicate
from bpns.workflow.contract import ContractConfig, check_environment, run_checks
from mj_envs.base import TaskLayout
from mj_envs.domains.cover.env import CoverEnv
from mj_envs.domains.cover.rules import BLOCK, COVERS
from mj_envs.gym_wrapper import BPNSGymEnv
from mj_envs.world import World


def _violations(env, *checks: str, **kw) -> list[str]:
    config = ContractConfig(n_tasks=2, n_demos=1, rollout_steps=4, only=frozenset(checks), **kw)
    return [str(v) for v in run_checks(env, config).violations]


def test_the_intact_cover_passes_the_cheap_checks():
    assert (
        _violations(
            CoverEnv(),
            "name",
            "tasks",
            "declarations",
            "classifiers",
            "pickle",
            "simulate",
            "predicates",
        )
        == []
    )


def test_a_name_other_than_the_entry_point_is_a_violation():
    env = CoverEnv()
    env.name = "covers"
    (v,) = _violations(env, "name")
    assert "'covers' differs from its entry-point name 'cover'" in v


def test_an_unregistered_environment_class_is_a_violation():
    class Unlisted(CoverEnv):
        pass

    (v,) = _violations(Unlisted(), "name")
    assert "is not registered" in v


class Unseeded(CoverEnv):
    def sample_layout(self, rng, train):
        return super().sample_layout(np.random.default_rng(), train)


def test_tasks_that_ignore_their_seed_are_a_violation():
    (v, *_) = _violations(Unseeded(), "tasks")
    assert v.startswith("tasks: train task 0 differs between two samplings")


class SequentialStream(CoverEnv):
    def _tasks(self, n, seed, train):
        rng = np.random.default_rng(seed)  # one stream: task i depends on tasks 0..i-1
        return [self.make_task(self.sample_layout(rng, train)) for _ in range(n)]


def test_a_task_that_depends_on_other_indices_is_a_violation():
    vs = _violations(SequentialStream(), "tasks")
    assert any("must not depend on other indices" in v for v in vs)


def _lambda_covers():
    return Predicate("Covers", COVERS.types, lambda s, o: COVERS.holds(s, o))


class LambdaClassifier(CoverEnv):
    @property
    def predicates(self):
        return (super().predicates - {COVERS}) | {_lambda_covers()}


def test_a_classifier_that_is_not_module_level_is_a_violation():
    (v,) = _violations(LambdaClassifier(), "classifiers")
    assert v.startswith("classifiers: Covers's classifier") and "module-level" in v


class UnpicklableGoal(CoverEnv):
    def sample_layout(self, rng, train):
        layout = super().sample_layout(rng, train)
        lam = _lambda_covers()
        goal = frozenset(dataclasses.replace(a, predicate=lam) for a in layout.goal)
        return dataclasses.replace(layout, goal=goal)


def test_a_task_that_does_not_pickle_is_a_violation():
    (v,) = _violations(UnpicklableGoal(), "pickle")
    assert v.startswith("pickle: task 0 does not pickle")


class NoisyPhysics(CoverEnv):
    def after_step(self, world: World) -> None:
        world.data.qpos[0] += np.random.default_rng().normal(0.0, 1e-9)


def test_a_nondeterministic_simulate_is_a_violation():
    (v, *_) = _violations(NoisyPhysics(), "simulate")
    assert v.startswith("simulate: not deterministic")


class LenientActions(CoverEnv):
    def check_action(self, action):
        return np.nan_to_num(np.resize(np.asarray(action, dtype=np.float64), 4))


def test_accepting_bad_actions_is_a_violation():
    vs = _violations(LenientActions(), "simulate")
    assert vs == [
        "simulate: an action of the wrong shape was accepted; it must raise ValueError",
        "simulate: a NaN action was accepted; it must raise ValueError",
    ]


def _reads_missing_feature(state, objs):
    return state.get(objs[0], "colour") > 0


def _returns_float(state, objs):
    return state.get(objs[0], "x")


class RaisingPredicate(CoverEnv):
    @property
    def predicates(self):
        return super().predicates | {Predicate("Red", (BLOCK,), _reads_missing_feature)}


class FloatPredicate(CoverEnv):
    @property
    def predicates(self):
        return super().predicates | {Predicate("Far", (BLOCK,), _returns_float)}


def test_a_predicate_that_raises_is_a_violation():
    (v,) = _violations(RaisingPredicate(), "predicates")
    assert v.startswith("predicates: Red(block0) raised KeyError")


def test_a_predicate_that_returns_a_non_bool_is_a_violation():
    (v,) = _violations(FloatPredicate(), "predicates")
    assert v == "predicates: Far(block0) returned float, not bool"


class UndeclaredPredicates(CoverEnv):
    @property
    def contact_predicates(self):
        return super().contact_predicates | {Predicate("Touches", (BLOCK,), _returns_float)}

    @property
    def goal_predicates(self):
        return frozenset()


def test_contact_and_goal_predicates_outside_the_declared_ones_are_violations():
    vs = _violations(UndeclaredPredicates(), "declarations")
    assert vs[0] == "declarations: contact_predicates not in predicates: Touches"
    assert vs[1].startswith("declarations: task 0's goal uses Covers, not goal predicates")


class BuggyDemonstrator(CoverEnv):
    def demonstrator(self, task, rng):
        def policy(state):
            return state.robot_position  # an AttributeError: a bug, reported as such

        return policy


def test_a_demonstrator_that_fails_is_a_violation_that_says_why():
    (v,) = _violations(BuggyDemonstrator(), "demonstrator")
    assert v.startswith("demonstrator: train task 0 not solved: AttributeError: ")
    assert "robot_position" in v


class DriftingReload(CoverEnv):
    def load_world(self, text: str) -> World:
        return super().load_world(text.replace('timestep="0.002"', 'timestep="0.0019"'))


def test_demos_that_do_not_replay_exactly_after_saving_are_a_violation():
    (v,) = _violations(DriftingReload(), "replay")
    assert v.startswith("replay: saved demo 0 does not replay exactly")


class _WrongObservation(BPNSGymEnv):
    def __init__(self, **kw):
        super().__init__(**kw)
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float64)


def test_a_gym_id_that_fails_gymnasiums_check_env_is_a_violation():
    id_ = "bpns_test/BrokenCover-v0"
    gym.register(id=id_, entry_point=_WrongObservation, kwargs={"env_name": "cover"})
    try:
        vs = _violations(CoverEnv(), "gym")
    finally:
        del gym.registry[id_]
    assert len(vs) == 1 and vs[0].startswith(f"gym: {id_} fails Gymnasium's check_env")


def test_no_gym_id_is_a_note_not_a_violation():
    env = CoverEnv()
    env.name = "nameless"
    report = run_checks(env, ContractConfig(only=frozenset({"gym"})))
    assert report.violations == [] and "no Gymnasium id" in report.notes[0]


CHEAP = frozenset(
    {"name", "tasks", "declarations", "classifiers", "pickle", "simulate", "predicates", "gym"}
)


@pytest.mark.parametrize("name", environment_names())
def test_registered_environments_keep_the_contract(name):
    """Every check but the (slow) demonstrations; Cover's are checked in full below."""
    assert _violations(make_environment(name), *CHEAP) == []


def test_cover_keeps_the_whole_contract():
    assert check_environment(CoverEnv(), n_tasks=2, n_demos=1, rollout_steps=4) == []


def test_check_env_cli_exit_codes(capsys, monkeypatch):
    assert main(["check-env", "no_such_env"]) == 2
    assert "unknown environment 'no_such_env'" in capsys.readouterr().err
    assert main(["check-env", "cover", "--tasks", "1", "--demos", "1", "--no-gym"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["note: gym: skipped (disabled)", "cover: keeps the contract (10 checks passed)"]

    from bpns.cli import check_env as check_env_cli
    from bpns.workflow.contract import ContractReport, Violation

    broken = ContractReport([Violation("simulate", "a NaN action was accepted")], [], ["simulate"])
    monkeypatch.setattr(check_env_cli, "run_checks", lambda env, config: broken)
    assert main(["check-env", "cover"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "violation: simulate: a NaN action was accepted",
        "cover: 1 violation in 1 checks",
    ]


def test_layout_type_is_public():  # TaskLayout stays importable for task authors
    assert TaskLayout.__name__ == "TaskLayout"


class OldStyle(CoverEnv):
    """Declares its planning defaults the way the contract did before ``Capabilities``."""

    planning_defaults = {"n_abstract": 1000}


def test_optional_declarations_made_the_old_way_are_refused_with_the_fix_named():
    (v,) = _violations(OldStyle(), "declarations")
    assert "declares planning_defaults as attributes" in v
    assert "capabilities = Capabilities(planning_defaults=...)" in v


class OldStylePhysics(CoverEnv):
    """Offers perturbed physics as methods of its own, as ``MujocoEnv`` did before."""

    def perturbed(self, spec):
        return self

    def observe(self, state):
        return state


def test_perturbation_methods_made_the_old_way_are_refused_with_the_fix_named():
    (v,) = _violations(OldStylePhysics(), "declarations")
    assert "declares perturbed, observe as attributes" in v
    assert "capabilities = Capabilities(perturbed=..., observe=...)" in v


class MisspeltDefaults(CoverEnv):
    capabilities = Capabilities(planning_defaults={"n_abstrct": 3})


def test_declared_defaults_that_are_no_config_fields_are_a_violation():
    (v,) = _violations(MisspeltDefaults(), "declarations")
    assert "planning defaults are not valid" in v and "n_abstrct" in v


def test_capabilities_are_read_only_declarations():
    caps = Capabilities(planning_defaults={"n_abstract": 7})
    with pytest.raises(TypeError):
        caps.planning_defaults["n_abstract"] = 8  # type: ignore[index]
    assert not caps.has_oracle_skills and CoverEnv().capabilities.has_oracle_skills


def test_the_registry_refuses_an_environment_declared_the_old_way(monkeypatch):
    from importlib.metadata import EntryPoint

    import bpns.env.registry as registry

    old = EntryPoint("old_style", f"{__name__}:OldStyle", registry.GROUP)
    monkeypatch.setattr(registry, "entry_points", lambda group: [old])
    with pytest.raises(registry.UnknownEnvironmentError, match="Capabilities"):
        registry.make_environment("old_style")
