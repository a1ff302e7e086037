"""Graph inputs for the GNN baselines: (state, abstract state, goal) -> one graph.

As in the paper's reference (Chitnis et al. 2021's encoding), per task:
- one node per object: its type one-hot, its unary atoms, the goal's unary atoms about
  it, and its raw features (zero-padded to the widest type);
- a directed edge i -> j for every ordered pair of distinct objects with at least one
  binary atom between them, in the state or in the goal, either way round; its features
  are, per binary predicate, P(i, j), P(j, i), goal P(i, j), goal P(j, i);
- global inputs: the nullary atoms and the goal's nullary atoms.

The vocabulary (types, predicates and their order) is fixed at training time from the
environment's declared types and predicates, so a graph has the same feature layout
for any number of objects: evaluation tasks may have more objects than training ones.
Predicates of arity above 2 have no place in this encoding and are refused.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bpns.errors import BpnsError
from bpns.structs import GroundAtom, Object, Predicate, State, Type


class VocabularyError(BpnsError, ValueError):
    """Types or predicates that do not fit a graph vocabulary."""


@dataclass(frozen=True, eq=False)
class GraphVocabulary:
    """Feature layout of graphs: sorted types and sorted predicates by arity."""

    types: tuple[Type, ...]
    nullary: tuple[Predicate, ...]
    unary: tuple[Predicate, ...]
    binary: tuple[Predicate, ...]

    def __post_init__(self) -> None:
        index = lambda items: {x: i for i, x in enumerate(items)}  # noqa: E731
        object.__setattr__(self, "_type_index", index(self.types))
        object.__setattr__(self, "_unary_index", index(self.unary))
        object.__setattr__(self, "_binary_index", index(self.binary))
        object.__setattr__(self, "_nullary_index", index(self.nullary))

    @classmethod
    def build(cls, types: Iterable[Type], predicates: Iterable[Predicate]) -> GraphVocabulary:
        preds = sorted(set(predicates))
        wide = [p.name for p in preds if p.arity > 2]
        if wide:
            raise VocabularyError(
                f"graph inputs encode predicates of arity <= 2 only; {wide} have more"
            )
        all_types = set(types) | {t for p in preds for t in p.types}
        return cls(
            types=tuple(sorted(all_types)),
            nullary=tuple(p for p in preds if p.arity == 0),
            unary=tuple(p for p in preds if p.arity == 1),
            binary=tuple(p for p in preds if p.arity == 2),
        )

    # ------------------------------------------------------------------ dimensions

    @property
    def feature_width(self) -> int:
        """Width of the raw-feature block: the widest type's feature count."""
        return max((t.dim for t in self.types), default=0)

    @property
    def node_dim(self) -> int:
        return len(self.types) + 2 * len(self.unary) + self.feature_width

    @property
    def raw_offset(self) -> int:
        """Column where the raw features start in a node row."""
        return len(self.types) + 2 * len(self.unary)

    @property
    def edge_dim(self) -> int:
        return 4 * len(self.binary)

    @property
    def global_dim(self) -> int:
        return 2 * len(self.nullary)

    def type_index(self, type_: Type) -> int:
        try:
            return self._type_index[type_]
        except KeyError:
            raise VocabularyError(
                f"type {type_.name!r} is not in the graph vocabulary "
                f"({[t.name for t in self.types]})"
            ) from None

    # ----------------------------------------------------------------- persistence

    def to_json(self) -> dict[str, Any]:
        return {
            "types": [{"name": t.name, "features": list(t.feature_names)} for t in self.types],
            "predicates": [
                {"name": p.name, "types": [t.name for t in p.types]}
                for p in (*self.nullary, *self.unary, *self.binary)
            ],
        }

    @classmethod
    def from_json(
        cls, saved: Mapping[str, Any], types: Iterable[Type], predicates: Iterable[Predicate]
    ) -> GraphVocabulary:
        """Bind saved names to the environment's types and predicates; any mismatch
        raises :class:`VocabularyError` naming it."""
        available_types = {t.name: t for t in types}
        bound_types = []
        for entry in saved["types"]:
            t = available_types.get(entry["name"])
            if t is None or list(t.feature_names) != list(entry["features"]):
                raise VocabularyError(
                    f"saved type {entry['name']}{list(entry['features'])} does not match the "
                    f"environment's types {sorted(available_types)}"
                )
            bound_types.append(t)
        available = {p.name: p for p in predicates}
        bound_preds = []
        for entry in saved["predicates"]:
            p = available.get(entry["name"])
            if p is None or [t.name for t in p.types] != list(entry["types"]):
                raise VocabularyError(
                    f"saved predicate {entry['name']}{tuple(entry['types'])} does not match the "
                    f"environment's predicates {sorted(available)}"
                )
            bound_preds.append(p)
        vocab = cls.build(bound_types, bound_preds)
        if vocab.to_json() != {"types": list(saved["types"]), "predicates": saved["predicates"]}:
            raise VocabularyError("saved graph vocabulary is not in canonical order")
        return vocab


@dataclass(frozen=True, eq=False)
class GraphInput:
    """One encoded graph. ``nodes[i]`` belongs to ``objects[i]``; edge k goes from
    ``senders[k]`` to ``receivers[k]``. Raw features are not standardised here."""

    objects: tuple[Object, ...]
    node_types: np.ndarray  # (n,) int64
    nodes: np.ndarray  # (n, node_dim)
    edges: np.ndarray  # (m, edge_dim)
    senders: np.ndarray  # (m,) int64
    receivers: np.ndarray  # (m,) int64
    globals: np.ndarray  # (global_dim,)


def encode_graph(
    vocab: GraphVocabulary,
    state: State,
    atoms: Collection[GroundAtom],
    goal: Collection[GroundAtom],
) -> GraphInput:
    """The graph of (state, its abstract state ``atoms``, ``goal``)."""
    objects = state.objects
    index = {o: i for i, o in enumerate(objects)}
    n_types, n_unary, n_binary = len(vocab.types), len(vocab.unary), len(vocab.binary)
    nodes = np.zeros((len(objects), vocab.node_dim), dtype=np.float64)
    node_types = np.empty(len(objects), dtype=np.int64)
    raw = vocab.raw_offset
    for i, obj in enumerate(objects):
        k = vocab.type_index(obj.type)
        node_types[i] = k
        nodes[i, k] = 1.0
        nodes[i, raw : raw + obj.type.dim] = state.data[obj]
    glob = np.zeros(vocab.global_dim, dtype=np.float64)
    pair_rows: dict[tuple[int, int], np.ndarray] = {}

    def pair(i: int, j: int) -> np.ndarray:
        row = pair_rows.get((i, j))
        if row is None:
            row = pair_rows[(i, j)] = np.zeros(vocab.edge_dim, dtype=np.float64)
        return row

    for is_goal, group in ((0, atoms), (1, goal)):
        for atom in group:
            if any(o not in index for o in atom.objects):
                raise ValueError(f"atom {atom} names objects that are not in the state")
            p = atom.predicate
            if p.arity == 1:
                u = vocab._unary_index.get(p)
                if u is None:
                    raise VocabularyError(f"predicate {p.name} is not in the graph vocabulary")
                nodes[index[atom.objects[0]], n_types + is_goal * n_unary + u] = 1.0
            elif p.arity == 2:
                b = vocab._binary_index.get(p)
                if b is None:
                    raise VocabularyError(f"predicate {p.name} is not in the graph vocabulary")
                i, j = index[atom.objects[0]], index[atom.objects[1]]
                base = 2 * is_goal * n_binary
                pair(i, j)[base + b] = 1.0  # the atom, seen from i -> j
                pair(j, i)[base + n_binary + b] = 1.0  # its reverse, seen from j -> i
            elif p.arity == 0:
                z = vocab._nullary_index.get(p)
                if z is None:
                    raise VocabularyError(f"predicate {p.name} is not in the graph vocabulary")
                glob[is_goal * len(vocab.nullary) + z] = 1.0
            else:
                raise VocabularyError(f"predicate {p.name} has arity {p.arity} > 2")
    keys = sorted(pair_rows)
    edges = (
        np.stack([pair_rows[k] for k in keys])
        if keys
        else np.zeros((0, vocab.edge_dim), dtype=np.float64)
    )
    senders = np.array([k[0] for k in keys], dtype=np.int64)
    receivers = np.array([k[1] for k in keys], dtype=np.int64)
    return GraphInput(objects, node_types, nodes, edges, senders, receivers, glob)


@dataclass(frozen=True, eq=False)
class GraphBatch:
    """Graphs concatenated: node and edge rows of graph g are tagged g; senders and
    receivers index the concatenated nodes."""

    node_types: np.ndarray
    nodes: np.ndarray
    edges: np.ndarray
    senders: np.ndarray
    receivers: np.ndarray
    globals: np.ndarray  # (num_graphs, global_dim)
    node_graph: np.ndarray
    edge_graph: np.ndarray

    @property
    def num_graphs(self) -> int:
        return int(self.globals.shape[0])


def batch_graphs(graphs: Sequence[GraphInput]) -> GraphBatch:
    if not graphs:
        raise ValueError("cannot batch zero graphs")
    n_nodes = np.array([len(g.nodes) for g in graphs], dtype=np.int64)
    n_edges = np.array([len(g.edges) for g in graphs], dtype=np.int64)
    offsets = np.concatenate(([0], np.cumsum(n_nodes)[:-1]))
    edge_offsets = np.repeat(offsets, n_edges)
    return GraphBatch(
        node_types=np.concatenate([g.node_types for g in graphs]),
        nodes=np.concatenate([g.nodes for g in graphs]),
        edges=np.concatenate([g.edges for g in graphs]),
        senders=np.concatenate([g.senders for g in graphs]) + edge_offsets,
        receivers=np.concatenate([g.receivers for g in graphs]) + edge_offsets,
        globals=np.stack([g.globals for g in graphs]),
        node_graph=np.repeat(np.arange(len(graphs)), n_nodes),
        edge_graph=np.repeat(np.arange(len(graphs)), n_edges),
    )
