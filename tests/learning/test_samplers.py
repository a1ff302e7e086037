"""Subgoal samplers: Gaussian generator plus a classifier trained on wrong bindings."""

import numpy as np
import pytest
import torch

from bpns.learning.config import LearningConfig, MLPConfig
from bpns.learning.jobs import learn_sampler, sampler_jobs, train_network
from bpns.learning.operators import SkillDataset, learn_operators
from bpns.learning.partition import partition_segments
from bpns.learning.policies import ScopeDims, scope_trajectories
from bpns.learning.samplers import (
    LearnedSampler,
    SamplerFit,
    sampler_training_data,
)
from bpns.learning.segmentation import segment_demonstrations
from bpns.nets.mlp import MLPParams
from bpns.structs import GroundAtom, Predicate, Segment
from tests import toy_learning as toy

B0, B1 = toy.blocks(2)
T0, T1 = toy.targets(2)
R = toy.ROBOT_OBJ


@pytest.fixture(autouse=True)
def _one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def skills():
    return toy.learned_toy_skills()


def test_pick_subgoals_stay_near_the_demonstrated_grasps(skills):
    pick = skills.skill("Holding")
    assert [v.type for v in pick.operator.parameters] == [toy.BLOCK, toy.ROBOT]
    state = toy.make_state(1.0, [3.0, 7.5], [5.0, 9.0])
    rng = np.random.default_rng(0)
    for block in (B0, B1):
        goals = np.array([pick.sampler(state, (block, R), rng) for _ in range(200)])
        # scope: block (x, held), robot (x, holding)
        np.testing.assert_array_equal(goals[:, 0], state.get(block, "x"))  # block does not move
        offsets = goals[:, 2] - state.get(block, "x")
        assert np.mean(np.abs(offsets) < toy.GRASP_TOL) > 0.95
        assert np.abs(goals[:, [1, 3]] - 1.0).max() < 0.2  # held and holding switch on


def test_place_subgoals_put_the_block_on_the_bound_target(skills):
    place = skills.skill("Covers_HandEmpty")
    state = toy.make_state(4.1, [4.0, 7.5], [2.0, 9.0], held=0)
    rng = np.random.default_rng(0)
    for target in (T0, T1):
        goals = np.array([place.sampler(state, (B0, R, target), rng) for _ in range(100)])
        landed = goals[:, 0]  # block x in the subgoal
        assert np.mean(np.abs(landed - state.get(target, "x")) < toy.COVER_TOL) > 0.9


def test_classifier_rejects_subgoals_of_a_wrong_binding(skills):
    sampler = skills.skill("Holding").sampler
    state = toy.make_state(1.0, [3.0, 7.5], [5.0, 9.0])
    grasp_b0 = np.array([3.0, 1.0, 3.05, 1.0])  # block0 held, robot at block0
    assert sampler.accept_probability(state, (B0, R), grasp_b0) > 0.5
    # The same outcome seen through the binding (block1, robot): the robot grasps
    # something 4.45 away from block1, and block1 is not held. A wrong-binding negative.
    wrong = np.array([7.5, 0.0, 3.05, 1.0])
    assert sampler.accept_probability(state, (B1, R), wrong) < 0.5


def test_negatives_come_from_other_bindings_and_other_skills():
    demos = toy.demos(5, seed=0)
    segs = segment_demonstrations(demos, toy.PREDICATES, toy.CONTACT_PREDICATES)
    pick, place = learn_operators(partition_segments(segs))
    scopes = scope_trajectories(pick)
    dims = ScopeDims.from_scopes(scopes)
    _, _, rows = sampler_training_data(pick, scopes, dims, place.segments, None, seed=0)
    labels = rows[:, -1]
    assert labels.sum() == len(pick)
    # Each pick has exactly one other applicable binding (the other block); place
    # segments start holding a block, so Pick's HandEmpty precondition rules them out.
    assert (labels == 0).sum() == len(pick)
    scopes = scope_trajectories(place)
    dims = ScopeDims.from_scopes(scopes)
    _, _, rows = sampler_training_data(place, scopes, dims, pick.segments, None, seed=0)
    assert (rows[:, -1] == 0).sum() == len(place)  # the other target, per segment


def _adjacent_dataset():
    adj = Predicate("Adjacent", (toy.BLOCK, toy.BLOCK), lambda s, o: True)
    s0 = toy.make_state(0.0, [1.0, 2.0], [])
    s1 = toy.make_state(0.0, [1.5, 1.6], [])
    final = frozenset({GroundAtom(adj, (B0, B1)), GroundAtom(adj, (B1, B0))})
    seg = Segment((s0, s1), np.zeros((1, 2)), frozenset(), final)
    (dataset,) = learn_operators(partition_segments([seg]))
    return dataset


def test_bindings_that_explain_the_segment_equally_are_not_negatives():
    dataset = _adjacent_dataset()
    scopes = scope_trajectories(dataset)
    _, _, rows = sampler_training_data(
        dataset, scopes, ScopeDims.from_scopes(scopes), [], None, seed=0
    )
    assert (rows[:, -1] == 0).sum() == 0  # the swapped binding has the same effects


def test_without_negatives_the_sampler_accepts_every_draw():
    config = LearningConfig(generator=MLPConfig(num_steps=200, batch_size=64))
    dataset: SkillDataset = toy.point_dataset(30, seed=0)
    sampler = learn_sampler(dataset, [], config, seed=0)
    assert sampler.classifier_params is None
    state = toy.point_state([0.0, 0.0])
    a = sampler(state, (toy.POINT_OBJ,), np.random.default_rng(5))
    b = sampler(state, (toy.POINT_OBJ,), np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)
    assert sampler.accept_probability(state, (toy.POINT_OBJ,), a) == 1.0


def _reject_all(sampler: LearnedSampler) -> LearnedSampler:
    width = len(sampler.dims.state_dims) + len(sampler.dims.subgoal_dims)
    never = MLPParams(
        weights=(np.zeros((width, 1)),),
        biases=(np.array([-50.0]),),
        input_mean=np.zeros(width),
        input_std=np.ones(width),
        output_mean=np.zeros(1),
        output_std=np.ones(1),
    )
    return LearnedSampler(sampler.dims, sampler.generator_params, never, max_tries=7)


def test_when_every_draw_is_rejected_the_last_draw_is_returned(skills):
    sampler = _reject_all(skills.skill("Holding").sampler)
    state = toy.make_state(1.0, [3.0, 7.5], [5.0, 9.0])
    got = sampler(state, (B0, R), np.random.default_rng(3))
    # Replay the same random stream by hand: 7 draws, keep the 7th.
    x = state.vec((B0, R))
    mean, std = sampler._gen.mean_std(x[sampler.dims.state_dims])
    z = np.random.default_rng(3).standard_normal((7, len(mean)))
    expected = x.copy()
    expected[sampler.dims.subgoal_dims] += mean + std * z[-1]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_sampler_round_trips_through_arrays(skills):
    sampler = skills.skill("Covers_HandEmpty").sampler
    back = LearnedSampler.from_arrays(sampler.to_arrays())
    state = toy.make_state(4.1, [4.0, 7.5], [2.0, 9.0], held=0)
    a = sampler(state, (B0, R, T0), np.random.default_rng(1))
    b = back(state, (B0, R, T0), np.random.default_rng(1))
    np.testing.assert_array_equal(a, b)


def test_a_skill_whose_scope_never_changes_samples_the_current_scope():
    dataset = toy.point_dataset(5, seed=0)
    still = [
        Segment((s.states[0], s.states[0]), s.actions[:1], s.init_atoms, s.final_atoms)
        for s in dataset.segments
    ]
    dataset = SkillDataset(dataset.operator, tuple(still), dataset.bindings)
    sampler = learn_sampler(dataset, [], LearningConfig(), seed=0)
    state = toy.point_state([0.2, 0.3])
    goal = sampler(state, (toy.POINT_OBJ,), np.random.default_rng(0))
    np.testing.assert_array_equal(goal, [0.2, 0.3])


def test_linear_base_recovers_an_affine_subgoal_from_few_examples():
    # the hand goes to the object plus a fixed offset: affine in the start state
    from bpns.nets.linear import LinearBase

    rng = np.random.default_rng(0)
    x = rng.uniform(-0.5, 0.5, size=(24, 4))
    y = np.stack([x[:, 2] - x[:, 0] + 0.03, x[:, 3] - x[:, 1]], axis=1)
    base = LinearBase.fit_if_it_helps(x, y)
    assert base is not None
    unseen = rng.uniform(-0.4, 0.4, size=(50, 4))  # inside the fitted range
    truth = np.stack([unseen[:, 2] - unseen[:, 0] + 0.03, unseen[:, 3] - unseen[:, 1]], axis=1)
    np.testing.assert_allclose(base(unseen), truth, atol=2e-3)
    # inputs are clipped into the training box (+10 %), as every network's are
    far = np.full((1, 4), 5.0)
    np.testing.assert_array_equal(base(far), base(np.minimum(far, base.high)))
    back = LinearBase.from_arrays(base.to_arrays("linear/"), "linear/")
    np.testing.assert_array_equal(back(unseen), base(unseen))


def test_linear_base_is_left_out_where_it_does_not_predict_held_out_segments():
    from bpns.nets.linear import LinearBase

    rng = np.random.default_rng(2)
    x = rng.uniform(-1, 1, size=(12, 9))  # few segments, many inputs, targets unrelated
    assert LinearBase.fit_if_it_helps(x, rng.normal(size=(12, 2))) is None
    assert LinearBase.fit_if_it_helps(x[:3], x[:3, :2]) is None  # too few to judge


def _trained_sampler(gen_x, gen_y, cls_data, dims, net, seed, **fit_args):
    """The sampler the pipeline's jobs train from these data (bpns.learning.jobs)."""
    fit = SamplerFit.of(gen_x, gen_y, cls_data, dims, net, **fit_args)
    config = LearningConfig(generator=net, classifier=net)
    generator_job, classifier_job = sampler_jobs(fit, config, seed, threads=1)
    classifier = None if classifier_job is None else train_network(classifier_job).network
    return fit.assemble(train_network(generator_job).network, classifier)


def test_generator_with_linear_base_is_saved_loaded_and_its_mean_is_base_plus_network():
    rng = np.random.default_rng(1)
    gen_x = rng.uniform(-1, 1, size=(40, 2))
    gen_y = gen_x @ np.array([[1.0], [-2.0]]) + 0.5
    dims = ScopeDims(2, np.array([0, 1]), np.array([0]))
    cls_data = np.concatenate((gen_x, gen_y, np.ones((40, 1))), axis=1)
    net = MLPConfig(num_steps=300, batch_size=32)
    sampler = _trained_sampler(gen_x, gen_y, cls_data, dims, net, 0, linear_base=True)
    assert sampler.base is not None
    mean, _ = sampler.mean_std(np.array([0.3, 0.2]))
    network_mean, _ = sampler._gen.mean_std(np.array([0.3, 0.2]))
    np.testing.assert_allclose(mean, network_mean + sampler.base(np.array([0.3, 0.2])))
    assert abs(mean[0] - (0.3 - 0.4 + 0.5)) < 0.05
    back = LearnedSampler.from_arrays(sampler.to_arrays())
    assert back.base is not None
    np.testing.assert_array_equal(back.mean_std(np.array([0.3, 0.2]))[0], mean)
    plain = _trained_sampler(gen_x, gen_y, cls_data, dims, net, 0, linear_base=False)
    assert plain.base is None and "linear/w0" not in plain.to_arrays()


def test_sampler_jobs_train_the_generator_on_its_seed_and_the_classifier_on_the_next():
    """Learning trains a sampler's generator and classifier as two jobs, possibly in two
    processes, and assembles them: bit for bit the networks trained here from the fit
    with the sampler's seed and that seed + 1."""
    from bpns.nets.mlp import train_classifier, train_gaussian

    rng = np.random.default_rng(2)
    gen_x = rng.uniform(-1, 1, size=(40, 2))
    gen_y = gen_x @ np.array([[1.0], [-2.0]]) + 0.5
    dims = ScopeDims(2, np.array([0, 1]), np.array([0]))
    labels = (np.arange(40) % 3 != 0).astype(float)  # a third of the rows are negatives
    cls_data = np.concatenate((gen_x, gen_y, labels[:, None]), axis=1)
    net = MLPConfig(num_steps=200, batch_size=32)
    fit_args = {"max_tries": 7, "linear_base": True, "novelty_floor": 0.01}
    whole = _trained_sampler(gen_x, gen_y, cls_data, dims, net, 5, **fit_args)
    fit = SamplerFit.of(gen_x, gen_y, cls_data, dims, net, **fit_args)
    assert fit is not None and fit.classifier_labels is not None
    generator = train_gaussian(fit.gen_x, fit.gen_target, net, 5)
    classifier = train_classifier(fit.classifier_x, fit.classifier_labels, net, 6)
    parts = fit.assemble(generator, classifier)
    a, b = whole.to_arrays(), parts.to_arrays()
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    only_positives = np.concatenate((gen_x, gen_y, np.ones((40, 1))), axis=1)
    assert SamplerFit.of(gen_x, gen_y, only_positives, dims, net).classifier_labels is None
    assert (
        sampler_jobs(
            SamplerFit.of(gen_x, gen_y, only_positives, dims, net), LearningConfig(), 0, 1
        )[1]
        is None
    )  # no negatives: no classifier job
    assert SamplerFit.of(gen_x, gen_y[:, :0], cls_data, dims, net) is None  # nothing to sample


def _moving_together(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, ScopeDims]:
    """A held block and the hand holding it: both move by one random amount (plus a
    millimetre of their own), whatever the start."""
    rng = np.random.default_rng(seed)
    gen_x = rng.uniform(-1, 1, size=(n, 2))
    shift = rng.normal(0.0, 0.05, size=n)
    gen_y = np.stack([shift, shift], axis=1) + rng.normal(0.0, 0.001, size=(n, 2))
    dims = ScopeDims(2, np.array([0, 1]), np.array([0, 1]))
    cls_data = np.concatenate((gen_x, gen_y, np.ones((n, 1))), axis=1)
    return gen_x, gen_y, cls_data, dims


def test_correlated_noise_keeps_dims_that_moved_together_together():
    gen_x, gen_y, cls_data, dims = _moving_together(200, seed=0)
    net = MLPConfig(num_steps=400, batch_size=64)
    joint = _trained_sampler(gen_x, gen_y, cls_data, dims, net, 0, correlated=True)
    apart = _trained_sampler(gen_x, gen_y, cls_data, dims, net, 0)
    assert joint.correlation is not None and apart.correlation is None
    state = toy.point_state([0.1, -0.2])
    obj = (toy.POINT_OBJ,)

    def spread(sampler: LearnedSampler) -> tuple[float, float]:
        rng = np.random.default_rng(7)
        goals = np.array([sampler(state, obj, rng) for _ in range(400)])
        return float(np.std(goals[:, 0] - goals[:, 1])), float(np.std(goals[:, 0]))

    joint_gap, joint_marginal = spread(joint)
    apart_gap, apart_marginal = spread(apart)
    assert joint_gap < 0.35 * apart_gap  # the two dims disagree far less
    assert abs(joint_marginal - apart_marginal) < 0.2 * apart_marginal  # same marginals


def test_noise_correlation_is_saved_loaded_and_draws_the_same_subgoals():
    gen_x, gen_y, cls_data, dims = _moving_together(60, seed=1)
    net = MLPConfig(num_steps=200, batch_size=32)
    sampler = _trained_sampler(gen_x, gen_y, cls_data, dims, net, 0, correlated=True)
    arrays = sampler.to_arrays()
    assert arrays["noise/chol"].shape == (2, 2)
    back = LearnedSampler.from_arrays(arrays)
    state = toy.point_state([0.3, 0.3])
    a = sampler(state, (toy.POINT_OBJ,), np.random.default_rng(4))
    b = back(state, (toy.POINT_OBJ,), np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    arrays["noise/chol"] = np.eye(3)  # edited by hand: one dim more than the sampler draws
    with pytest.raises(ValueError, match=r"noise/chol has shape \(3, 3\).*expected \(2, 2\)"):
        LearnedSampler.from_arrays(arrays)


def test_noise_correlation_leaves_dims_that_moved_apart_nearly_independent():
    from bpns.learning.samplers import NoiseCorrelation

    rng = np.random.default_rng(2)
    gen_x = rng.uniform(-1, 1, size=(300, 2))
    gen_y = rng.normal(0.0, 0.05, size=(300, 2))  # two dims, each its own noise
    dims = ScopeDims(2, np.array([0, 1]), np.array([0, 1]))
    cls_data = np.concatenate((gen_x, gen_y, np.ones((300, 1))), axis=1)
    net = MLPConfig(num_steps=300, batch_size=64)
    fit = SamplerFit.of(gen_x, gen_y, cls_data, dims, net, correlated=True)
    generator_job, _ = sampler_jobs(fit, LearningConfig(generator=net), 0, threads=1)
    corr = NoiseCorrelation.of(gen_x, gen_y, train_network(generator_job).network)
    assert corr is not None
    c = corr.chol @ corr.chol.T
    np.testing.assert_allclose(np.diag(c), 1.0, atol=1e-12)  # marginals unchanged
    assert abs(c[0, 1]) < 0.15
