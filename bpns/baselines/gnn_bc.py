"""GNN behavioural cloning (the paper's "GNN BC" baseline): (state, abstract state,
goal) -> action on the global node, trained on demonstrated steps.

Abstracting every state of every demonstration is the costly part of preparing the data
(every predicate on every state), so steps are subsampled (seeded) *before* they are
abstracted when ``max_examples`` is set.
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
from bpns.baselines.graphs import GraphVocabulary, batch_graphs, encode_graph
from bpns.env.abstraction import abstract
from bpns.structs import Demonstration, GroundAtom, Predicate, State


@dataclass(frozen=True, eq=False)
class BCExample:
    state: State
    atoms: frozenset[GroundAtom]
    goal: frozenset[GroundAtom]
    action: np.ndarray


def bc_examples(
    demos: Sequence[Demonstration],
    predicates: Collection[Predicate],
    max_examples: int | None = None,
    seed: int = 0,
) -> tuple[list[BCExample], int]:
    """(examples, number of demonstrated steps available); at most ``max_examples``
    steps drawn uniformly without replacement (all if None)."""
    steps = [(d, t) for d, demo in enumerate(demos) for t in range(len(demo.actions))]
    chosen = range(len(steps))
    if max_examples is not None and len(steps) > max_examples:
        rng = np.random.default_rng(seed)
        chosen = np.sort(rng.choice(len(steps), size=max_examples, replace=False))
    out = []
    for i in chosen:
        d, t = steps[int(i)]
        demo = demos[d]
        state = demo.states[t]
        out.append(
            BCExample(state, abstract(state, predicates), demo.task.goal, demo.labels[t].copy())
        )
    return out, len(steps)


class GNNPolicy:
    """A goal-conditioned GNN policy (numpy inference, one call per control step)."""

    def __init__(self, vocab: GraphVocabulary, params: GNNParams) -> None:
        self.vocab = vocab
        self.params = params
        self._net = NumpyGNN(params, vocab)

    @property
    def action_dim(self) -> int:
        return self.params.global_out_dim

    def __call__(
        self, state: State, atoms: Collection[GroundAtom], goal: Collection[GroundAtom]
    ) -> np.ndarray:
        _, glob = self._net(batch_graphs([encode_graph(self.vocab, state, atoms, goal)]))
        return glob[0]

    def to_json(self) -> dict[str, Any]:
        return {"vocabulary": self.vocab.to_json(), "action_dim": self.action_dim}


def train_bc_policy(
    vocab: GraphVocabulary, examples: Sequence[BCExample], config: GNNConfig
) -> tuple[GNNPolicy, GNNTrainingStats]:
    if not examples:
        raise ValueError("no demonstrated steps to train the BC policy on")
    graphs = tuple(encode_graph(vocab, ex.state, ex.atoms, ex.goal) for ex in examples)
    data = GNNTrainingData(
        graphs, np.stack([ex.action for ex in examples]), None, standardise_outputs=True
    )
    trained = train_gnn(vocab, data, config)
    return GNNPolicy(vocab, trained.params), trained.stats
