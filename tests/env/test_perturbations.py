"""Perturbed physics: each perturbation changes the simulation the way its name says,
stays deterministic, and a perturbed rollout replays bit-exactly from its file."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.env.abstraction import abstract
from bpns.env.environment import Capabilities, observation_of, perturbed
from bpns.env.perturbations import (
    NOMINAL,
    Perturbation,
    PerturbationError,
    parse_axis,
    parse_perturbation,
)
from mj_envs.domains.cover.env import CoverEnv

PUSH = np.array([0.01, 0.0, 0.0, 0.0])  # hand forward 1 cm per step, fingers unchanged


def _objects(state):
    return {o.name: o for o in state.objects}


def _rollout(env, task, actions):
    states = [task.init]
    for a in actions:
        states.append(env.simulate(states[-1], a))
    return states


def _heights(states, name):
    obj = _objects(states[0])[name]
    return np.array([s.data[obj][2] for s in states])


def _hand(state):
    return state.data[_objects(state)["robot"]][:3]


# -- the spec --------------------------------------------------------------------------


def test_perturbation_items_parse_into_a_typed_spec_and_round_trip_through_json():
    p = parse_perturbation(["mass_scale=2", "latency=3", "action_noise=0.1", "seed=4"])
    assert p == Perturbation(mass_scale=2.0, latency=3, action_noise=0.1, seed=4)
    assert Perturbation.from_json(p.to_json()) == p
    assert p.label() == "mass_scale=2,action_noise=0.1,latency=3"
    assert parse_perturbation([]) is NOMINAL or parse_perturbation([]) == NOMINAL
    assert parse_axis("friction_scale=1,0.7,0.5") == ("friction_scale", (1.0, 0.7, 0.5))


@pytest.mark.parametrize(
    "items, message",
    [
        (["frcition_scale=1"], "unknown perturbation 'frcition_scale'"),
        (["mass_scale"], "not NAME=VALUE"),
        (["mass_scale=0"], "mass_scale must be > 0"),
        (["friction_scale=-0.1"], "friction_scale must be >= 0"),
        (["action_noise=nan"], "action_noise must be a finite number"),
        (["latency=1.5"], "latency must be a whole number"),
        (["latency=999"], "latency must be a whole number of control steps in [0, 50]"),
        (["gain_scale=x"], "gain_scale must be a number"),
    ],
)
def test_a_bad_perturbation_is_one_clear_error(items, message):
    with pytest.raises(PerturbationError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_perturbation(items)


def test_a_bad_perturbation_axis_is_one_clear_error():
    for text in ("friction_scale", "seed=1,2", "latency=1,1", "mass_scale=1,-1"):
        with pytest.raises(PerturbationError):
            parse_axis(text)


def test_the_nominal_spec_leaves_the_environment_itself(cover_env):
    assert perturbed(cover_env, NOMINAL) is cover_env


class NominalOnlyCover(CoverEnv):
    """Declares its own capabilities without MuJoCo's perturbed physics."""

    capabilities = Capabilities(oracle_skills=CoverEnv.capabilities.oracle_skills)


def test_an_environment_declaring_no_perturbed_physics_refuses_a_perturbation():
    env = NominalOnlyCover()
    assert perturbed(env, NOMINAL) is env  # nominal physics needs no declaration
    refused = r"'cover' does not support perturbations \(its Capabilities declare no perturbed"
    with pytest.raises(PerturbationError, match=refused):
        perturbed(env, Perturbation(mass_scale=2.0))
    state = env.task(0, 7, True).init
    assert observation_of(env)(state) is state  # no declared observation: the state itself


def test_the_declared_observation_is_called_with_the_environment(cover_env):
    seen = []
    env = NominalOnlyCover()
    object.__setattr__(env, "capabilities", Capabilities(observe=lambda e, s: seen.append(e) or s))
    state = env.task(0, 7, True).init
    assert observation_of(env)(state) is state and seen == [env]


# -- physics ---------------------------------------------------------------------------


def test_model_scales_edit_only_what_they_name(cover_env):
    nominal = cover_env.task(0, 7, True).init.sim.world.model
    p = Perturbation(mass_scale=3.0, friction_scale=0.5, gain_scale=0.25)
    model = perturbed(cover_env, p).task(0, 7, True).init.sim.world.model
    block = nominal.body("block0").id
    hand = nominal.body("panda/hand").id
    assert model.body_mass[block] == pytest.approx(3.0 * nominal.body_mass[block])
    assert model.body_mass[hand] == nominal.body_mass[hand]  # the robot keeps its mass
    np.testing.assert_allclose(model.geom_friction, 0.5 * nominal.geom_friction)
    arm = nominal.actuator("panda/act_joint1").id
    finger = nominal.actuator("panda/act_fingers").id
    assert model.actuator_gainprm[arm, 0] == pytest.approx(0.25 * nominal.actuator_gainprm[arm, 0])
    assert model.actuator_biasprm[arm, 1] == pytest.approx(0.25 * nominal.actuator_biasprm[arm, 1])
    assert model.actuator_gainprm[finger, 0] == nominal.actuator_gainprm[finger, 0]
    # the nominal world is untouched (worlds are cached per scene and physics)
    assert (
        cover_env.task(0, 7, True).init.sim.world.model.body_mass[block] == nominal.body_mass[block]
    )


def test_zero_friction_makes_the_demonstrated_grasp_fail(cover_env, cover_demos):
    demo = cover_demos[0]
    nominal = _heights(demo.states, "block0")
    slippery = perturbed(cover_env, Perturbation(friction_scale=0.0))
    states = _rollout(slippery, slippery.task(0, 7, True), demo.actions)
    assert nominal.max() > nominal[0] + 0.05  # the demo lifts block0
    assert _heights(states, "block0").max() < nominal[0] + 0.01  # it slips out of the pads
    goal = demo.task.goal
    assert not goal <= abstract(states[-1], slippery.goal_predicates)


def test_heavier_blocks_slip_out_of_the_same_grasp(cover_env, cover_demos):
    demo = cover_demos[0]
    lifted = {}
    for scale in (1.0, 20.0):
        env = perturbed(cover_env, Perturbation(mass_scale=scale))
        states = _rollout(env, env.task(0, 7, True), demo.actions)
        lifted[scale] = (
            _heights(states, "block0").max() - states[0].data[_objects(states[0])["block0"]][2]
        )
    assert lifted[1.0] > 0.05 and lifted[20.0] < 0.5 * lifted[1.0]


def test_lower_arm_gains_track_the_commanded_hand_motion_more_slowly(cover_env):
    moved = {}
    for scale in (1.0, 0.2):
        env = perturbed(cover_env, Perturbation(gain_scale=scale))
        states = _rollout(env, env.task(0, 7, True), [PUSH] * 5)
        moved[scale] = _hand(states[-1])[0] - _hand(states[0])[0]
    assert moved[1.0] > 0.02 and moved[0.2] < 0.5 * moved[1.0]


def test_action_noise_is_deterministic_per_seed_and_differs_between_seeds(cover_env):
    def hand_path(p):
        env = perturbed(cover_env, p)
        return np.array([_hand(s) for s in _rollout(env, env.task(0, 7, True), [PUSH] * 6)])

    clean = hand_path(NOMINAL)
    a = hand_path(Perturbation(action_noise=0.3, seed=1))
    b = hand_path(Perturbation(action_noise=0.3, seed=1))
    c = hand_path(Perturbation(action_noise=0.3, seed=2))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c) and not np.array_equal(a, clean)


def test_observation_noise_changes_what_policies_see_but_not_the_physics(cover_env):
    p = Perturbation(obs_noise=0.01, seed=3)
    env = perturbed(cover_env, p)
    task = env.task(0, 7, True)
    noisy_states = _rollout(env, task, [PUSH] * 3)
    clean_states = _rollout(cover_env, cover_env.task(0, 7, True), [PUSH] * 3)
    for noisy, clean in zip(noisy_states, clean_states, strict=True):
        np.testing.assert_array_equal(noisy.sim.flat, clean.sim.flat)  # same simulation
    seen = observation_of(env)(noisy_states[-1])
    again = observation_of(env)(noisy_states[-1])
    robot = _objects(seen)["robot"]
    delta = seen.data[robot] - noisy_states[-1].data[robot]
    assert 0 < np.abs(delta).max() < 0.06
    np.testing.assert_array_equal(seen.data[robot], again.data[robot])
    assert seen.sim is noisy_states[-1].sim
    other_env = perturbed(cover_env, Perturbation(obs_noise=0.01, seed=4))
    other = observation_of(other_env)(noisy_states[-1])
    assert not np.array_equal(other.data[robot], seen.data[robot])


@pytest.mark.parametrize("k", [1, 3])
def test_latency_delays_the_response_by_k_control_steps(cover_env, k):
    env = perturbed(cover_env, Perturbation(latency=k))
    late = _rollout(env, env.task(0, 7, True), [PUSH] * 6)
    hold = np.zeros_like(PUSH)
    prompt = _rollout(cover_env, cover_env.task(0, 7, True), [hold] * k + [PUSH] * (6 - k))
    for t in range(7):  # the same physics as the nominal one acting k steps later
        np.testing.assert_array_equal(_hand(late[t]), _hand(prompt[t]))
    np.testing.assert_allclose(_hand(late[k]), _hand(late[0]), atol=1e-6)  # still holding
    assert _hand(late[k + 1])[0] > _hand(late[0])[0] + 1e-3  # moving once the push arrives


def test_the_latency_queue_is_saved_state_so_a_restored_state_steps_identically(cover_env):
    env = perturbed(cover_env, Perturbation(latency=2, action_noise=0.2, seed=5))
    states = _rollout(env, env.task(0, 7, True), [PUSH, -PUSH, PUSH])
    restored = env.state_from_flat(
        env.load_world(env.save_world(states[2].sim.world)), states[2].sim.flat.copy(), states[2]
    )
    np.testing.assert_array_equal(
        env.simulate(restored, PUSH).sim.flat, env.simulate(states[2], PUSH).sim.flat
    )
