"""DART-style noise injection in demonstrations: replay stays exact, labels are the
demonstrator's clean commands, and no noise is exactly the plain demonstration."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demo_attempts import ActionNoise, attempt_demonstration
from bpns.data.demos import replay
from bpns.learning.segmentation import segment_demonstration
from bpns.structs import Demonstration


@pytest.fixture(scope="module")
def noisy_cover_demo(cover_env):
    task = cover_env.task(0, 7, True)
    attempt = attempt_demonstration(cover_env, task, [7, 0], noise=0.1)
    assert attempt.solved, attempt.explain(debug=True)
    return attempt.demo


def test_zero_noise_is_the_plain_demonstration(cover_env, cover_demos):
    again = attempt_demonstration(cover_env, cover_env.task(0, 7, True), [7, 0], noise=0.0).demo
    assert again.expert_actions is None
    assert np.array_equal(again.actions, cover_demos[0].actions)
    assert np.array_equal(again.labels, again.actions)


def test_noisy_demo_executes_perturbed_actions_and_labels_the_clean_commands(
    cover_env, cover_demos, noisy_cover_demo
):
    demo = noisy_cover_demo
    assert demo.expert_actions is not None and demo.expert_actions.shape == demo.actions.shape
    assert np.array_equal(demo.labels, demo.expert_actions)
    moved = np.abs(demo.actions - demo.expert_actions).max(axis=1)
    assert (moved > 0).mean() > 0.9  # almost every step was perturbed ...
    low, high = cover_env.action_low, cover_env.action_high
    assert (demo.actions >= low).all() and (demo.actions <= high).all()  # ... within bounds
    # the demonstrator corrected from where the noise took it: another path than the plain one
    plain = cover_demos[0]
    n = min(len(plain.states), len(demo.states))
    assert any(not plain.states[i].allclose(demo.states[i]) for i in range(n))


def test_noisy_demo_replays_exactly_after_a_round_trip(tmp_path, cover_env, noisy_cover_demo):
    path = tmp_path / "noisy.h5"
    save_demonstrations(path, cover_env, [noisy_cover_demo])
    for features_only in (False, True):
        (back,) = load_demonstrations(path, cover_env, features_only=features_only)
        assert np.array_equal(back.actions, noisy_cover_demo.actions)
        assert np.array_equal(back.expert_actions, noisy_cover_demo.expert_actions)
    (back,) = load_demonstrations(path, cover_env)
    report = replay(cover_env, back)
    assert report.max_state_diff == 0.0 and report.goal_reached


def test_noise_is_seeded_by_the_demonstration_seed(cover_env):
    task = cover_env.task(1, 7, True)
    a = attempt_demonstration(cover_env, task, [7, 1], noise=0.1).demo
    b = attempt_demonstration(cover_env, task, [7, 1], noise=0.1).demo
    c = attempt_demonstration(cover_env, task, [8, 1], noise=0.1).demo
    assert np.array_equal(a.actions, b.actions)
    assert c is None or not np.array_equal(a.actions[:5], c.actions[:5])


def test_segments_imitate_the_expert_commands(cover_env, noisy_cover_demo):
    demo = noisy_cover_demo
    segments = segment_demonstration(
        demo, cover_env.predicates, cover_env.contact_predicates, cover_env.contact_settle_steps
    )
    assert segments
    labels = np.concatenate([s.actions for s in segments])
    rows = {tuple(r) for r in demo.expert_actions}
    assert all(tuple(r) in rows for r in labels)


def test_action_noise_scales_with_each_dimensions_range_and_refuses_bad_scales():
    low, high = np.array([-0.02, -1.0]), np.array([0.02, 1.0])
    noise = ActionNoise(0.1, low, high, seed=3)
    draws = np.array([noise(np.zeros(2)) for _ in range(4000)])
    assert np.std(draws[:, 0]) == pytest.approx(0.002, rel=0.1)
    assert np.std(draws[:, 1]) == pytest.approx(0.1, rel=0.1)
    assert np.mean(draws, axis=0) == pytest.approx([0.0, 0.0], abs=0.01)
    at_bound = np.array([noise(np.array([0.02, -1.0])) for _ in range(100)])
    assert (at_bound <= high).all() and (at_bound >= low).all()  # clipped into the bounds
    for bad in (-0.1, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="noise scale"):
            ActionNoise(bad, low, high, seed=0)


def test_expert_actions_must_match_the_executed_actions_shape(cover_demos):
    demo = cover_demos[0]
    with pytest.raises(ValueError, match="expert_actions"):
        Demonstration(demo.task, demo.states, demo.actions, demo.actions[:-1])
