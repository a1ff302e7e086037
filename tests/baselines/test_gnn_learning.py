"""GNN Meta and GNN BC: they learn what they should on ToyCover, numpy inference matches
torch, more objects than in training work, and model files round-trip or fail clearly."""

from __future__ import annotations

import functools
import json
import zipfile

import numpy as np
import pytest

from bpns.baselines.files import (
    load_bc_policy,
    load_metacontroller,
    save_bc_policy,
    save_metacontroller,
)
from bpns.baselines.gnn import GNNConfig, torch_reference
from bpns.baselines.gnn_bc import BCExample, train_bc_policy
from bpns.baselines.gnn_meta import (
    GNNMetacontroller,
    MetaExample,
    metacontroller_examples,
    train_metacontroller,
)
from bpns.baselines.graphs import GraphVocabulary, batch_graphs, encode_graph
from bpns.baselines.learn import (
    BaselinesConfig,
    LearnedBaselines,
    learn_baselines,
    save_baselines,
)
from bpns.env.abstraction import abstract
from bpns.learning.artifacts.skills_dir import ArtifactError
from bpns.learning.config import LearningConfig
from bpns.learning.pipeline import LearnedSkills, learn_skills
from bpns.learning.segmentation import segment_demonstration
from tests import toy_gnn
from tests import toy_learning as toy

VOCAB = GraphVocabulary.build(toy.TYPES, toy.PREDICATES)


def _examples(n: int, seed: int, num_blocks: int = 2) -> list[MetaExample]:
    demos = toy_gnn.demos(n, seed, num_blocks)
    out, skipped = metacontroller_examples(demos, toy_gnn.segments_of(demos), toy_gnn.operators())
    assert skipped == 0
    return out


@functools.cache
def _meta() -> GNNMetacontroller:
    meta, stats = train_metacontroller(
        VOCAB, toy_gnn.operators(), _examples(60, seed=1), GNNConfig(epochs=250, seed=0)
    )
    assert stats.steps == 250 and stats.num_used == 120
    return meta


def _accuracy(meta: GNNMetacontroller, examples: list[MetaExample]) -> float:
    ops = meta.operators
    right = 0
    for ex in examples:
        g = meta.choose(ex.state, ex.atoms, ex.goal)
        right += g is not None and g.operator == ops[ex.op_index] and g.objects == ex.objects
    return right / len(examples)


def test_segments_are_labelled_with_the_learned_ground_operators() -> None:
    pick, place = toy_gnn.operators()
    (first, second) = _examples(1, seed=5)
    (goal,) = first.goal
    block, target = goal.objects
    assert (first.op_index, first.objects) == (0, (block, toy.ROBOT_OBJ))
    assert (second.op_index, second.objects) == (1, (block, toy.ROBOT_OBJ, target))
    assert [v.type for v in pick.parameters] == [toy.BLOCK, toy.ROBOT]


def test_metacontroller_picks_the_next_ground_operator_on_held_out_states() -> None:
    held_out = _examples(100, seed=2)
    assert _accuracy(_meta(), held_out) >= 0.95


def test_metacontroller_runs_on_more_objects_than_in_training() -> None:
    # trained with 2 blocks and 2 targets, asked about 3 of each
    held_out = _examples(50, seed=3, num_blocks=3)
    assert _accuracy(_meta(), held_out) >= 0.9


def test_metacontroller_returns_none_when_nothing_is_applicable() -> None:
    ex = _examples(1, 0)[0]
    assert _meta().choose(ex.state, frozenset(), ex.goal) is None  # no HandEmpty, no Holding


def test_numpy_inference_equals_the_torch_forward_pass() -> None:
    meta = _meta()
    states = [ex for ex in _examples(3, seed=4, num_blocks=3)]
    batch = batch_graphs([encode_graph(VOCAB, e.state, e.atoms, e.goal) for e in states])
    nodes, glob = meta._net(batch)
    ref_nodes, ref_glob = torch_reference(meta.params, VOCAB, batch)
    np.testing.assert_allclose(nodes, ref_nodes, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(glob, ref_glob, rtol=1e-10, atol=1e-10)


def test_batched_graphs_give_the_same_outputs_as_single_graphs() -> None:
    meta = _meta()
    exs = _examples(2, seed=6, num_blocks=3)
    graphs = [encode_graph(VOCAB, e.state, e.atoms, e.goal) for e in exs]
    _, together = meta._net(batch_graphs(graphs))
    for k, g in enumerate(graphs):
        np.testing.assert_allclose(meta._net(batch_graphs([g]))[1][0], together[k], atol=1e-12)


def _bc_examples(n_demos: int, seed: int) -> list[BCExample]:
    out = []
    for demo in toy_gnn.demos(n_demos, seed):
        for state in demo.states:
            atoms = abstract(state, toy.PREDICATES)
            out.append(
                BCExample(
                    state, atoms, demo.task.goal, toy_gnn.toward_goal_block(state, demo.task.goal)
                )
            )
    return out


@functools.cache
def _bc():
    return train_bc_policy(
        VOCAB, _bc_examples(40, seed=7), GNNConfig(epochs=1000, max_steps=1500, seed=0)
    )


def test_bc_policy_imitates_a_goal_conditioned_toy_policy() -> None:
    policy, stats = _bc()
    held_out = _bc_examples(20, seed=8)
    pred = np.stack([policy(e.state, e.atoms, e.goal) for e in held_out])
    target = np.stack([e.action for e in held_out])
    # the baseline of predicting the mean action leaves an error of one std
    rel = np.sqrt(((pred - target) ** 2).mean(axis=0)) / target.std(axis=0)
    assert rel.max() < 0.15, rel
    assert policy.action_dim == 2 and stats.num_used == len(_bc_examples(40, seed=7))


def test_models_round_trip_through_npz_files(tmp_path) -> None:
    meta = _meta()
    save_metacontroller(meta, tmp_path / "gnn_meta.npz", {"note": "toy"})
    loaded = load_metacontroller(
        tmp_path / "gnn_meta.npz", toy_gnn.operators(), toy.PREDICATES, toy.TYPES
    )
    ex = _examples(1, seed=9, num_blocks=3)[0]
    np.testing.assert_array_equal(
        loaded.scores(ex.state, ex.atoms, ex.goal)[1], meta.scores(ex.state, ex.atoms, ex.goal)[1]
    )
    policy, _ = _bc()
    save_bc_policy(policy, tmp_path / "gnn_bc.npz")
    again = load_bc_policy(tmp_path / "gnn_bc.npz", toy.PREDICATES, toy.TYPES)
    np.testing.assert_array_equal(
        again(ex.state, ex.atoms, ex.goal), policy(ex.state, ex.atoms, ex.goal)
    )


def _rewrite(path, change) -> None:
    with np.load(path, allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    change(arrays)
    with open(path, "wb") as out:
        np.savez(out, **arrays)


def _set(key, value):
    return lambda a: a.__setitem__(key, value)


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: p.write_bytes(p.read_bytes()[:300]), "damaged"),
        (lambda p: p.write_bytes(b"not a zip file"), "damaged"),
        (lambda p: _rewrite(p, lambda a: a.pop("core_node/w1")), "damaged"),
        (lambda p: _rewrite(p, lambda a: a.pop("meta.json")), "damaged"),
        (lambda p: _rewrite(p, _set("core_node/w1", np.zeros((3, 3)))), "core_node"),
        (lambda p: _rewrite(p, _set("dec_global/b2", np.array([np.nan, 0.0]))), "non-finite"),
        (lambda p: _rewrite(p, _set("raw_std", np.zeros((3, 2)))), "positive"),
        (lambda p: _rewrite(p, _set("meta.json", np.array("{"))), "damaged"),
    ],
)
def test_damaged_model_files_are_one_clear_error(tmp_path, damage, message) -> None:
    path = tmp_path / "gnn_meta.npz"
    save_metacontroller(_meta(), path)
    damage(path)
    with pytest.raises(ArtifactError, match=message):
        load_metacontroller(path, toy_gnn.operators(), toy.PREDICATES, toy.TYPES)


def test_models_refuse_the_wrong_kind_environment_or_operators(tmp_path) -> None:
    save_metacontroller(_meta(), tmp_path / "m.npz")
    with pytest.raises(ArtifactError, match="gnn-bc"):
        load_bc_policy(tmp_path / "m.npz", toy.PREDICATES, toy.TYPES)
    with pytest.raises(ArtifactError, match="Holding"):
        load_metacontroller(
            tmp_path / "m.npz", toy_gnn.operators(), toy.PREDICATES - {toy.HOLDING}, toy.TYPES
        )
    with pytest.raises(ArtifactError, match="Covers_HandEmpty"):
        load_metacontroller(tmp_path / "m.npz", toy_gnn.operators()[:1], toy.PREDICATES, toy.TYPES)
    with pytest.raises(ArtifactError, match="no such"):
        load_metacontroller(tmp_path / "x.npz", toy_gnn.operators(), toy.PREDICATES, toy.TYPES)
    header = json.loads(str(np.load(tmp_path / "m.npz")["meta.json"]))
    assert header["kind"] == "gnn-meta" and zipfile.is_zipfile(tmp_path / "m.npz")


def test_learn_baselines_reuses_demos_and_operators_and_saves_into_a_skills_dir(tmp_path) -> None:
    demos = toy_gnn.demos(10, seed=11)
    skills = LearnedSkills(
        tuple(toy_gnn.oracle_skills()),
        toy.PREDICATES,
        LearningConfig(),
        segments=toy_gnn.segments_of(demos),
    )
    config = BaselinesConfig(
        meta=GNNConfig(max_steps=5),
        bc=GNNConfig(max_steps=5, max_examples=50, seed=3),
        nosubgoal=False,
    )
    learned = learn_baselines(demos, toy.PREDICATES, toy.TYPES, skills, config)
    assert learned.meta_stats.num_examples == 20 and learned.meta_skipped_segments == 0
    assert learned.bc_stats.num_used == 50
    assert learned.bc_stats.num_examples == sum(len(d.actions) for d in demos)
    written = save_baselines(learned, tmp_path)
    assert sorted(p.name for p in written) == ["gnn_bc.npz", "gnn_meta.npz"]
    load_metacontroller(tmp_path / "gnn_meta.npz", skills.operators, toy.PREDICATES, toy.TYPES)
    load_bc_policy(tmp_path / "gnn_bc.npz", toy.PREDICATES, toy.TYPES)


def _toy_baselines(learning_seed: int, seed: int | None) -> LearnedBaselines:
    demos = toy_gnn.demos(6, seed=11)
    skills = LearnedSkills(
        tuple(toy_gnn.oracle_skills()),
        toy.PREDICATES,
        LearningConfig(seed=learning_seed),
        segments=toy_gnn.segments_of(demos),
    )
    config = BaselinesConfig(
        meta=GNNConfig(max_steps=3),
        bc=GNNConfig(max_steps=3, max_examples=30),
        nosubgoal=False,
        seed=seed,
    )
    return learn_baselines(demos, toy.PREDICATES, toy.TYPES, skills, config)


def _saved_arrays(learned: LearnedBaselines, directory) -> dict[str, np.ndarray]:
    directory.mkdir()
    arrays = {}
    for path in save_baselines(learned, directory):
        with np.load(path) as data:
            arrays.update({f"{path.name}/{k}": data[k] for k in data.files if k != "meta.json"})
    return arrays


def test_gnns_take_the_learning_seed_unless_a_seed_is_given(tmp_path) -> None:
    by_learning_seed = _toy_baselines(learning_seed=4, seed=None)
    assert by_learning_seed.config.meta.seed == by_learning_seed.config.bc.seed == 4
    given = _toy_baselines(learning_seed=4, seed=9)
    assert given.config.meta.seed == given.config.bc.seed == 9

    first = _saved_arrays(by_learning_seed, tmp_path / "a")
    again = _saved_arrays(_toy_baselines(learning_seed=4, seed=None), tmp_path / "b")
    other = _saved_arrays(_toy_baselines(learning_seed=5, seed=None), tmp_path / "c")
    assert first.keys() == again.keys() == other.keys()
    assert all(np.array_equal(first[k], again[k]) for k in first)  # same seed, same weights
    assert not all(np.array_equal(first[k], other[k]) for k in first)  # another draw


def _decisions(examples: list[MetaExample]) -> list[tuple]:
    return [(ex.state, ex.atoms, ex.goal, ex.op_index, ex.objects) for ex in examples]


def test_learned_segments_label_the_same_decisions_as_a_fresh_segmentation() -> None:
    demos = toy_gnn.demos(8, seed=21)
    learned = learn_skills(
        demos, toy.PREDICATES, toy.CONTACT_PREDICATES, toy.fast_config(steps=2, settle_steps=2)
    )
    fresh = tuple(
        tuple(segment_demonstration(d, toy.PREDICATES, toy.CONTACT_PREDICATES, settle_steps=2))
        for d in demos
    )
    assert [len(s) for s in learned.segments] == [len(s) for s in fresh] == [2] * 8
    reused, reused_skipped = metacontroller_examples(demos, learned.segments, learned.operators)
    again, again_skipped = metacontroller_examples(demos, fresh, learned.operators)
    assert len(reused) == 16 and reused_skipped == again_skipped == 0
    for a, b in zip(_decisions(reused), _decisions(again), strict=True):
        state_a, *rest_a = a
        state_b, *rest_b = b
        assert state_a.allclose(state_b) and rest_a == rest_b


@pytest.mark.parametrize(
    "config",
    [
        BaselinesConfig(meta=GNNConfig(max_steps=1), bc=None, nosubgoal=False),
        BaselinesConfig(meta=None, bc=None, nosubgoal=True),
    ],
)
def test_baselines_refuse_skills_that_carry_no_segments_of_their_demos(config) -> None:
    demos = toy_gnn.demos(2, seed=11)
    skills = LearnedSkills(tuple(toy_gnn.oracle_skills()), toy.PREDICATES, LearningConfig())
    with pytest.raises(ValueError, match="segments of 0 demonstrations, and 2 were given"):
        learn_baselines(demos, toy.PREDICATES, toy.TYPES, skills, config)
    bc_only = BaselinesConfig(meta=None, bc=GNNConfig(max_steps=1), nosubgoal=False)
    learned = learn_baselines(demos, toy.PREDICATES, toy.TYPES, skills, bc_only)
    assert learned.bc_policy is not None and learned.metacontroller is None
