"""GNN metacontroller (the paper's "GNN Meta" baseline): (state, abstract state, goal)
-> next ground skill.

Training data reuses BPNS learning: each segment skill learning cut the demonstrations
into (its own segmentation, not a second one) is labelled with the learned operator
(and binding) whose ground preconditions hold at its start and whose ground effects are
its effects.
Segments of filtered (rare) operators have no label and are skipped.

Outputs: the operator as a one-hot on the global node; for each argument slot k a
column on the nodes, 1 on the object filling slot k. Choosing: operators in order of
decreasing global score; the first with a binding whose preconditions hold in the
current abstract state wins, with its highest-scoring binding (sum of its objects' slot
scores). None when no operator is applicable.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bpns.baselines.gnn import (
    GNNConfig,
    GNNParams,
    GNNTrainingData,
    GNNTrainingStats,
    NumpyGNN,
    train_gnn,
)
from bpns.baselines.graphs import GraphInput, GraphVocabulary, batch_graphs, encode_graph
from bpns.learning.operators import applicable_bindings
from bpns.structs import (
    Demonstration,
    GroundAtom,
    GroundOperator,
    Object,
    Segment,
    State,
    STRIPSOperator,
)


@dataclass(frozen=True, eq=False)
class MetaExample:
    """One demonstrated decision: at ``state`` (abstract ``atoms``) towards ``goal`` the
    demonstrator executed ``operators[op_index]`` on ``objects``."""

    state: State
    atoms: frozenset[GroundAtom]
    goal: frozenset[GroundAtom]
    op_index: int
    objects: tuple[Object, ...]


def label_segment(
    segment: Segment, operators: Sequence[STRIPSOperator]
) -> tuple[int, tuple[Object, ...]] | None:
    """(operator index, binding) of the first operator that explains ``segment``: its
    ground preconditions hold at the start and its ground effects are the segment's."""
    objects = segment.states[0].objects
    for k, op in enumerate(operators):
        for binding in applicable_bindings(op, segment.init_atoms, objects):
            ground = op.ground(binding)
            if (
                ground.add_effects == segment.add_effects
                and ground.delete_effects == segment.delete_effects
            ):
                return k, binding
    return None


def metacontroller_examples(
    demos: Sequence[Demonstration],
    segments: Sequence[Sequence[Segment]],
    operators: Sequence[STRIPSOperator],
) -> tuple[list[MetaExample], int]:
    """Labelled decisions from ``demos``, cut into ``segments`` (per demo, in order: the
    segmentation the operators were learned from, ``LearnedSkills.segments``), and the
    number of segments left unlabelled."""
    if len(segments) != len(demos):
        raise ValueError(f"segments of {len(segments)} demonstrations given for {len(demos)}")
    examples, skipped = [], 0
    for demo, segs in zip(demos, segments, strict=True):
        for seg in segs:
            label = label_segment(seg, operators)
            if label is None:
                skipped += 1
                continue
            examples.append(MetaExample(seg.states[0], seg.init_atoms, demo.task.goal, *label))
    return examples, skipped


def max_arity(operators: Sequence[STRIPSOperator]) -> int:
    return max((len(op.parameters) for op in operators), default=0)


def meta_training_data(
    vocab: GraphVocabulary, operators: Sequence[STRIPSOperator], examples: Sequence[MetaExample]
) -> GNNTrainingData:
    slots = max(1, max_arity(operators))  # at least one node column, even if unused
    graphs, global_t, node_t = [], [], []
    for ex in examples:
        g = encode_graph(vocab, ex.state, ex.atoms, ex.goal)
        graphs.append(g)
        onehot = np.zeros(len(operators))
        onehot[ex.op_index] = 1.0
        global_t.append(onehot)
        nodes = np.zeros((len(g.objects), slots))
        index = {o: i for i, o in enumerate(g.objects)}
        for slot, obj in enumerate(ex.objects):
            nodes[index[obj], slot] = 1.0
        node_t.append(nodes)
    return GNNTrainingData(tuple(graphs), np.array(global_t), tuple(node_t))


class GNNMetacontroller:
    """A trained metacontroller over fixed operators (numpy inference)."""

    def __init__(
        self, vocab: GraphVocabulary, operators: Sequence[STRIPSOperator], params: GNNParams
    ) -> None:
        self.vocab = vocab
        self.operators = tuple(operators)
        self.params = params
        self._net = NumpyGNN(params, vocab)
        if params.global_out_dim != len(self.operators):
            raise ValueError(
                f"the network scores {params.global_out_dim} operators, {len(self.operators)} given"
            )
        if params.node_out_dim < max_arity(self.operators):
            raise ValueError(
                f"the network scores {params.node_out_dim} argument slots, operators need "
                f"{max_arity(self.operators)}"
            )

    def scores(
        self, state: State, atoms: Collection[GroundAtom], goal: Collection[GroundAtom]
    ) -> tuple[GraphInput, np.ndarray, np.ndarray]:
        """(graph, per-operator scores, per-(node, slot) scores)."""
        g = encode_graph(self.vocab, state, atoms, goal)
        nodes, glob = self._net(batch_graphs([g]))
        return g, glob[0], nodes

    def choose(
        self, state: State, atoms: frozenset[GroundAtom], goal: Collection[GroundAtom]
    ) -> GroundOperator | None:
        g, op_scores, slot_scores = self.scores(state, atoms, goal)
        index = {o: i for i, o in enumerate(g.objects)}
        for k in np.argsort(-op_scores, kind="stable"):
            op = self.operators[int(k)]
            bindings = applicable_bindings(op, atoms, g.objects)
            if not bindings:
                continue
            best = max(
                bindings,
                key=lambda b: sum(slot_scores[index[o], s] for s, o in enumerate(b)),
            )
            return op.ground(best)
        return None

    def to_json(self) -> dict[str, Any]:
        return {
            "vocabulary": self.vocab.to_json(),
            "operators": [
                {"name": op.name, "parameters": [v.type.name for v in op.parameters]}
                for op in self.operators
            ],
        }


def train_metacontroller(
    vocab: GraphVocabulary,
    operators: Sequence[STRIPSOperator],
    examples: Sequence[MetaExample],
    config: GNNConfig,
) -> tuple[GNNMetacontroller, GNNTrainingStats]:
    if not examples:
        raise ValueError("no labelled segments to train the metacontroller on")
    trained = train_gnn(vocab, meta_training_data(vocab, operators, examples), config)
    return GNNMetacontroller(vocab, operators, trained.params), trained.stats
