"""The whole learning pipeline on ToyCover: operators, statistics, reproducibility and
skills good enough to solve held-out tasks by sampling and rolling out."""

import dataclasses

import numpy as np
import pytest
import torch

from bpns.env.abstraction import abstract
from bpns.learning.pipeline import derive_seed, learn_from_segments, learn_skills
from bpns.learning.samplers import CurrentStateSampler, LearnedSampler
from tests import toy_learning as toy


@pytest.fixture(autouse=True)
def _one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def skills():
    return toy.learned_toy_skills()


def test_learns_pick_and_place_operators(skills):
    text = {op.name: str(op) for op in skills.operators}
    assert text["Holding"] == (
        "Holding(?block0:block, ?robot0:robot)\n"
        "    pre: HandEmpty(?robot0)\n"
        "    add: Holding(?robot0, ?block0)\n"
        "    del: HandEmpty(?robot0)"
    )
    assert text["Covers_HandEmpty"] == (
        "Covers_HandEmpty(?block0:block, ?robot0:robot, ?target0:target)\n"
        "    pre: Holding(?robot0, ?block0)\n"
        "    add: Covers(?block0, ?target0), HandEmpty(?robot0)\n"
        "    del: Holding(?robot0, ?block0)"
    )
    assert all(isinstance(s.sampler, LearnedSampler) for s in skills.skills)


def test_records_counts_and_stage_timings(skills):
    stats = skills.stats
    assert stats.num_demos == 30
    assert stats.num_segments == 120 and stats.num_groups == 2
    assert stats.num_dropped_groups == 0 and stats.num_dropped_segments == 0
    assert [(s.name, s.num_segments) for s in stats.skills] == [
        ("Holding", 60),
        ("Covers_HandEmpty", 60),
    ]
    assert stats.skills[0].num_sampler_negatives == 60  # the other block, per pick
    assert [name for name, _ in stats.stage_seconds] == [
        "segment",
        "partition",
        "operators",
        "policies",
        "samplers",
    ]
    assert all(t >= 0.0 for _, t in stats.stage_seconds)
    assert "120 segments" in str(stats)


def _solve(skills, task, rng, tries=10):
    pick, place = skills.skill("Holding"), skills.skill("Covers_HandEmpty")
    state = task.init
    for b, t in zip(toy.blocks(2), toy.targets(2), strict=True):
        for skill, objs in ((pick, (b, toy.ROBOT_OBJ)), (place, (b, toy.ROBOT_OBJ, t))):
            for _ in range(tries):
                after = toy.run_skill(skill, state, objs, skill.sampler(state, objs, rng))
                if after is not None:
                    state = after
                    break
            else:
                return False
    return task.goal_holds(abstract(state, toy.PREDICATES))


def test_learned_skills_solve_held_out_tasks(skills):
    rng = np.random.default_rng(42)
    solved = [_solve(skills, toy.sample_task(rng), rng) for _ in range(20)]
    assert sum(solved) >= 19


def test_same_inputs_and_seed_give_identical_weights():
    demos = toy.demos(4, seed=1)
    config = toy.fast_config(seed=7, steps=30)
    a = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    b = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    c = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, toy.fast_config(8, 30))
    for sa, sb, sc in zip(a.skills, b.skills, c.skills, strict=True):
        assert sa.policy.params.identical(sb.policy.params)
        assert sa.sampler.generator_params.identical(sb.sampler.generator_params)
        assert sa.sampler.classifier_params.identical(sb.sampler.classifier_params)
        assert not sa.policy.params.identical(sc.policy.params)


def test_networks_trained_in_worker_processes_are_the_same_bit_for_bit():
    demos = toy.demos(4, seed=1)
    config = toy.fast_config(seed=7, steps=30)
    one = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    two = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config, workers=2)
    assert [s.name for s in one.skills] == [s.name for s in two.skills]
    for a, b in zip(one.skills, two.skills, strict=True):
        assert a.policy.params.identical(b.policy.params)
        assert a.sampler.generator_params.identical(b.sampler.generator_params)
        assert a.sampler.classifier_params.identical(b.sampler.classifier_params)
    stages = dict(two.stats.stage_seconds)
    assert stages["policies"] > 0 and stages["samplers"] > 0


def test_seeds_differ_per_skill_and_network():
    seeds = {derive_seed(0, k, role) for k in range(5) for role in range(2)}
    assert len(seeds) == 10
    assert derive_seed(3, 1, 0) == derive_seed(3, 1, 0)


def test_no_subgoal_variant_learns_state_only_policies_and_no_samplers():
    demos = toy.demos(4, seed=1)
    config = toy.fast_config(steps=30, use_subgoals=False)
    result = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    for skill in result.skills:
        assert isinstance(skill.sampler, CurrentStateSampler)
        assert not skill.policy.use_subgoals
        assert skill.policy.params.input_dim == len(skill.policy.dims.state_dims)
    assert all(s.num_sampler_negatives == 0 for s in result.stats.skills)


def test_no_subgoal_skills_learned_from_recorded_segments_equal_learning_them_afresh():
    demos = toy.demos(4, seed=1)
    config = toy.fast_config(seed=7, steps=30)
    bpns = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    assert [len(s) for s in bpns.segments] == [4] * 4  # pick, place, pick, place
    nosub = dataclasses.replace(config, use_subgoals=False)
    afresh = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, nosub)
    reused = learn_from_segments(demos, bpns.segments, toy.PREDICATES, nosub, segment_seconds=1.5)
    assert [s.operator for s in reused.skills] == [s.operator for s in afresh.skills]
    for a, b in zip(reused.skills, afresh.skills, strict=True):
        assert a.policy.params.identical(b.policy.params)
        assert isinstance(a.sampler, CurrentStateSampler)
    assert reused.stats.skills == afresh.stats.skills
    assert dict(reused.stats.stage_seconds)["segment"] == 1.5
    with pytest.raises(ValueError, match="segments of 3 demonstrations given for 4"):
        learn_from_segments(demos, bpns.segments[:3], toy.PREDICATES, nosub)


def test_rare_skills_are_filtered_in_the_pipeline():
    demos = toy.demos(4, seed=1)
    # 16 segments, 8 per skill: a 60% threshold keeps neither, 50% keeps both.
    config = toy.fast_config(steps=10, min_segment_fraction=0.6)
    with pytest.raises(ValueError, match="no segment"):
        learn_skills([], toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    result = learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    assert result.skills == () and result.stats.num_dropped_segments == 16
    config = toy.fast_config(steps=10, min_segment_fraction=0.5)
    assert len(learn_skills(demos, toy.PREDICATES, toy.CONTACT_PREDICATES, config).skills) == 2
