"""Graph encoding of (state, abstract state, goal) for the GNN baselines."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.baselines.graphs import GraphVocabulary, VocabularyError, batch_graphs, encode_graph
from bpns.env.abstraction import abstract
from bpns.structs import GroundAtom, Object, Predicate, State, Type
from tests import toy_learning as toy

FLAG = Predicate("Tidy", (), lambda s, o: True)


def _vocab() -> GraphVocabulary:
    return GraphVocabulary.build(toy.TYPES, toy.PREDICATES | {FLAG})


def test_vocabulary_orders_types_and_predicates_by_arity() -> None:
    v = _vocab()
    assert [t.name for t in v.types] == ["block", "robot", "target"]
    assert [p.name for p in v.nullary] == ["Tidy"]
    assert [p.name for p in v.unary] == ["HandEmpty"]
    assert [p.name for p in v.binary] == ["Covers", "Holding"]
    assert v.feature_width == 2  # block and robot have 2 features, target 1
    assert (v.node_dim, v.edge_dim, v.global_dim) == (3 + 2 + 2, 8, 2)


def test_vocabulary_refuses_predicates_of_arity_above_two() -> None:
    wide = Predicate("Between", (toy.BLOCK, toy.BLOCK, toy.TARGET), lambda s, o: False)
    with pytest.raises(VocabularyError, match="Between"):
        GraphVocabulary.build(toy.TYPES, {wide})


def test_nodes_edges_and_globals_follow_the_reference_layout() -> None:
    v = _vocab()
    state = toy.make_state(1.0, [1.0, 5.0], [7.0, 3.0], held=0)
    atoms = abstract(state, toy.PREDICATES) | {GroundAtom(FLAG, ())}
    b0, b1 = toy.blocks(2)
    t0, t1 = toy.targets(2)
    goal = frozenset(
        {GroundAtom(toy.COVERS, (b1, t1)), GroundAtom(toy.HAND_EMPTY, (toy.ROBOT_OBJ,))}
    )
    g = encode_graph(v, state, atoms, goal)
    assert g.objects == (b0, b1, toy.ROBOT_OBJ, t0, t1)
    # type one-hot | HandEmpty | goal HandEmpty | raw features (padded to 2)
    np.testing.assert_array_equal(g.nodes[0], [1, 0, 0, 0, 0, 1.0, 1.0])
    np.testing.assert_array_equal(g.nodes[2], [0, 1, 0, 0, 1, 1.0, 1.0])  # goal: hand empty
    np.testing.assert_array_equal(g.nodes[4], [0, 0, 1, 0, 0, 3.0, 0.0])  # target: padded
    # edges: Holding(robot, block0) in the state, Covers(block1, target1) in the goal;
    # each pair appears in both directions, nothing else
    pairs = set(zip(g.senders.tolist(), g.receivers.tolist(), strict=True))
    assert pairs == {(2, 0), (0, 2), (1, 4), (4, 1)}
    row = {
        p: g.edges[k]
        for k, p in enumerate(zip(g.senders.tolist(), g.receivers.tolist(), strict=True))
    }
    # per binary predicate [Covers, Holding]: atom | reverse | goal atom | goal reverse
    np.testing.assert_array_equal(row[(2, 0)], [0, 1, 0, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(row[(0, 2)], [0, 0, 0, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(row[(1, 4)], [0, 0, 0, 0, 1, 0, 0, 0])
    np.testing.assert_array_equal(row[(4, 1)], [0, 0, 0, 0, 0, 0, 1, 0])
    np.testing.assert_array_equal(g.globals, [1.0, 0.0])  # Tidy now, not in the goal


def test_graphs_of_any_object_count_share_one_layout_and_batch() -> None:
    v = _vocab()
    small = toy.make_state(0.0, [1.0], [2.0])
    big = toy.make_state(0.0, [1.0, 3.0, 5.0, 7.0], [2.0, 4.0, 6.0, 8.0])
    graphs = [encode_graph(v, s, abstract(s, toy.PREDICATES), frozenset()) for s in (small, big)]
    assert graphs[0].nodes.shape == (3, v.node_dim) and graphs[1].nodes.shape == (9, v.node_dim)
    batch = batch_graphs(graphs)
    assert batch.num_graphs == 2 and len(batch.nodes) == 12
    np.testing.assert_array_equal(batch.node_graph, [0] * 3 + [1] * 9)


def test_unknown_types_are_a_clear_error() -> None:
    other = Type("ghost", ("x",))
    state = State({Object("g", other): np.zeros(1)})
    with pytest.raises(VocabularyError, match="ghost"):
        encode_graph(_vocab(), state, frozenset(), frozenset())
