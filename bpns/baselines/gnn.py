"""Encode-process-decode graph network: trained with torch, evaluated with plain numpy.

Architecture (the paper's GNN baselines, after Battaglia et al.'s graph networks):
independent MLP encoders for nodes, edges and globals into a latent of ``latent`` units;
a core graph-network block applied ``message_steps`` times with shared weights, whose
input is the encoded graph concatenated with the current latent graph:
    edge   e' = phi_e(e, v_sender, v_receiver, u)
    node   v' = phi_v(v, sum of e' over incoming edges, u)
    global u' = phi_u(u, sum of v', sum of e')
and MLP decoders from the final latent nodes and globals to the outputs. Every MLP has
``hidden`` ReLU layers (paper: two of 16). Aggregation is a scatter-sum
(``index_add_``, ``np.add.at``): memory linear in nodes + edges, never a dense
edges x nodes matrix.

Inputs: raw object features are standardised per (type, feature) from the training
data (std raised to ``std_floor``); the boolean type/atom columns are left as they are.
Global outputs of regression heads (GNN BC's action) are trained standardised and
de-standardised at inference.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from bpns.baselines.graphs import GraphBatch, GraphInput, GraphVocabulary, batch_graphs
from bpns.nets.layers import (
    Adam,
    Layers,
    check_layers,
    count_layers,
    layers_from_arrays,
    layers_to_arrays,
    numpy_layers,
    numpy_mlp,
    standardisation,
    torch_layers,
    torch_linears,
    torch_mlp,
)

if TYPE_CHECKING:
    import torch

# torch is imported inside training and the torch reference only: solving tasks with a
# trained GNN (every control step for GNN BC) runs in numpy.

MLP_NAMES = (
    "enc_node",
    "enc_edge",
    "enc_global",
    "core_edge",
    "core_node",
    "core_global",
    "dec_node",
    "dec_global",
)


@dataclass(frozen=True)
class GNNConfig:
    """Architecture and optimisation of one GNN (paper appendix: 3 message-passing
    steps, MLPs with two hidden layers of 16, Adam lr 1e-3, batch 128, 1000 epochs).

    ``max_steps`` caps the gradient steps (epochs x batches per epoch); ``max_examples``
    subsamples the training set (seeded) before training. Both keep learning time
    bounded for large datasets (every demonstrated step for GNN BC); what was used is
    recorded in :class:`GNNTrainingStats`.
    """

    hidden: tuple[int, ...] = (16, 16)
    latent: int = 16
    message_steps: int = 3
    learning_rate: float = 1e-3
    batch_size: int = 128
    epochs: int = 1000
    max_steps: int | None = 20000
    max_examples: int | None = None
    std_floor: float = 1e-2
    seed: int = 0
    torch_threads: int = 1

    def __post_init__(self) -> None:
        if (
            self.latent < 1
            or self.message_steps < 1
            or self.batch_size < 1
            or self.epochs < 0
            or not self.learning_rate > 0
            or not self.std_floor > 0
            or self.torch_threads < 1
        ):
            raise ValueError(f"invalid GNNConfig {self}")
        if any(h < 1 for h in self.hidden):
            raise ValueError(f"hidden sizes must be positive, got {self.hidden}")
        if self.max_steps is not None and self.max_steps < 0:
            raise ValueError(f"max_steps must be >= 0 or None, got {self.max_steps}")
        if self.max_examples is not None and self.max_examples < 1:
            raise ValueError(f"max_examples must be >= 1 or None, got {self.max_examples}")


@dataclass(frozen=True)
class GNNTrainingStats:
    num_examples: int  # examples available
    num_used: int  # after subsampling (max_examples)
    epochs: float  # passes over the used examples actually made
    steps: int  # gradient steps
    seconds: float
    final_loss: float


@dataclass(frozen=True, eq=False)
class GNNParams:
    """Trained weights (float64 numpy) plus input/output standardisation."""

    mlps: Mapping[str, Layers]  # MLP_NAMES; "dec_node" absent when there are no node outputs
    message_steps: int
    raw_mean: np.ndarray  # (num_types, feature_width)
    raw_std: np.ndarray
    out_mean: np.ndarray  # (global_out,)
    out_std: np.ndarray

    @property
    def latent(self) -> int:
        return int(self.mlps["enc_node"][-1][0].shape[1])

    @property
    def node_out_dim(self) -> int:
        return int(self.mlps["dec_node"][-1][0].shape[1]) if "dec_node" in self.mlps else 0

    @property
    def global_out_dim(self) -> int:
        return int(self.mlps["dec_global"][-1][0].shape[1])

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {
            "message_steps": np.array(self.message_steps),
            "raw_mean": self.raw_mean,
            "raw_std": self.raw_std,
            "out_mean": self.out_mean,
            "out_std": self.out_std,
        }
        for name, layers in self.mlps.items():
            out.update(layers_to_arrays(layers, f"{name}/"))
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> GNNParams:
        """Raises KeyError/ValueError on missing keys, broken shapes or non-finite values
        (see :meth:`check`; callers turn these into their artifact error)."""
        mlps: dict[str, Layers] = {}
        for name in MLP_NAMES:
            if count_layers(arrays, f"{name}/") == 0:
                if name == "dec_node":
                    continue
                raise KeyError(f"missing network {name!r}")
            mlps[name] = layers_from_arrays(arrays, f"{name}/")
        get = lambda key: np.array(arrays[key], dtype=np.float64)  # noqa: E731
        return cls(
            mlps=mlps,
            message_steps=int(arrays["message_steps"]),
            raw_mean=get("raw_mean"),
            raw_std=get("raw_std"),
            out_mean=get("out_mean"),
            out_std=get("out_std"),
        )

    def check(self, vocab: GraphVocabulary) -> None:
        """ValueError unless every array is finite and shapes chain for ``vocab``."""
        for key, value in self.to_arrays().items():
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{key} holds non-finite values")
        if self.message_steps < 1:
            raise ValueError(f"message_steps must be >= 1, got {self.message_steps}")
        latent = self.latent
        two = 2 * latent
        inputs = {
            "enc_node": vocab.node_dim,
            "enc_edge": vocab.edge_dim,
            "enc_global": vocab.global_dim,
            "core_edge": 4 * two,
            "core_node": two + latent + two,
            "core_global": two + 2 * latent,
            "dec_node": latent,
            "dec_global": latent,
        }
        for name, layers in self.mlps.items():
            width = check_layers(layers, inputs[name], name)
            if not name.startswith("dec") and width != latent:
                raise ValueError(f"{name} outputs {width} units, the latent has {latent}")
        shape = (len(vocab.types), vocab.feature_width)
        if self.raw_mean.shape != shape or self.raw_std.shape != shape:
            raise ValueError(
                f"feature standardisation has shapes {self.raw_mean.shape}/"
                f"{self.raw_std.shape}, the vocabulary needs {shape}"
            )
        if np.any(self.raw_std <= 0) or np.any(self.out_std <= 0):
            raise ValueError("standard deviations must be positive")
        if self.out_mean.shape != (self.global_out_dim,) or self.out_std.shape != (
            self.global_out_dim,
        ):
            raise ValueError("output standardisation does not match the global output size")


# ------------------------------------------------------------------------ numpy inference


def _segment_sum(values: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros((n, values.shape[1]), dtype=values.dtype)
    np.add.at(out, index, values)
    return out


def standardise_nodes(params: GNNParams, vocab: GraphVocabulary, batch: GraphBatch) -> np.ndarray:
    nodes = batch.nodes.copy()
    raw = vocab.raw_offset
    t = batch.node_types
    nodes[:, raw:] = (nodes[:, raw:] - params.raw_mean[t]) / params.raw_std[t]
    return nodes


class NumpyGNN:
    """Inference of a trained GNN in plain numpy (float64)."""

    def __init__(self, params: GNNParams, vocab: GraphVocabulary) -> None:
        params.check(vocab)
        self.params = params
        self.vocab = vocab
        self._m = params.mlps

    def __call__(self, batch: GraphBatch) -> tuple[np.ndarray, np.ndarray]:
        """(node outputs (N, node_out), global outputs (G, global_out)), the global
        outputs de-standardised."""
        m = self._m
        g = batch.num_graphs
        n = len(batch.nodes)
        v0 = numpy_mlp(m["enc_node"], standardise_nodes(self.params, self.vocab, batch))
        e0 = numpy_mlp(m["enc_edge"], batch.edges)
        u0 = numpy_mlp(m["enc_global"], batch.globals)
        v, e, u = v0, e0, u0
        s, r, ng, eg = batch.senders, batch.receivers, batch.node_graph, batch.edge_graph
        for _ in range(self.params.message_steps):
            vc = np.concatenate((v0, v), axis=1)
            ec = np.concatenate((e0, e), axis=1)
            uc = np.concatenate((u0, u), axis=1)
            e = numpy_mlp(m["core_edge"], np.concatenate((ec, vc[s], vc[r], uc[eg]), axis=1))
            v = numpy_mlp(
                m["core_node"], np.concatenate((vc, _segment_sum(e, r, n), uc[ng]), axis=1)
            )
            u = numpy_mlp(
                m["core_global"],
                np.concatenate((uc, _segment_sum(v, ng, g), _segment_sum(e, eg, g)), axis=1),
            )
        node_out = numpy_mlp(m["dec_node"], v) if "dec_node" in m else np.zeros((n, 0))
        glob = numpy_mlp(m["dec_global"], u) * self.params.out_std + self.params.out_mean
        return node_out, glob


# ----------------------------------------------------------------------------- training


def _build_torch(
    vocab: GraphVocabulary, config: GNNConfig, node_out: int, global_out: int
) -> torch.nn.ModuleDict:
    import torch  # lazy: planning runs NumpyGNN, without torch

    lat, hid = config.latent, config.hidden
    two = 2 * lat
    sizes = {
        "enc_node": (vocab.node_dim, *hid, lat),
        "enc_edge": (vocab.edge_dim, *hid, lat),
        "enc_global": (vocab.global_dim, *hid, lat),
        "core_edge": (4 * two, *hid, lat),
        "core_node": (two + lat + two, *hid, lat),
        "core_global": (two + 2 * lat, *hid, lat),
        "dec_global": (lat, *hid, global_out),
    }
    if node_out > 0:
        sizes["dec_node"] = (lat, *hid, node_out)
    return torch.nn.ModuleDict({k: torch_linears(v) for k, v in sizes.items()})


@dataclass(frozen=True, eq=False)
class _TorchBatch:
    nodes: torch.Tensor
    edges: torch.Tensor
    globals: torch.Tensor
    senders: torch.Tensor
    receivers: torch.Tensor
    node_graph: torch.Tensor
    edge_graph: torch.Tensor
    num_graphs: int


def _torch_forward(
    net: torch.nn.ModuleDict, b: _TorchBatch, steps: int
) -> tuple[torch.Tensor | None, torch.Tensor]:
    import torch  # lazy: planning runs NumpyGNN, without torch

    lat = net["enc_node"][-1].out_features
    n = b.nodes.shape[0]
    f = lambda name, x: torch_mlp(net[name], x)  # noqa: E731
    v0, e0, u0 = f("enc_node", b.nodes), f("enc_edge", b.edges), f("enc_global", b.globals)
    v, e, u = v0, e0, u0
    for _ in range(steps):
        vc, ec, uc = torch.cat((v0, v), 1), torch.cat((e0, e), 1), torch.cat((u0, u), 1)
        e = f("core_edge", torch.cat((ec, vc[b.senders], vc[b.receivers], uc[b.edge_graph]), 1))
        incoming = e.new_zeros((n, lat)).index_add_(0, b.receivers, e)
        v = f("core_node", torch.cat((vc, incoming, uc[b.node_graph]), 1))
        node_sum = v.new_zeros((b.num_graphs, lat)).index_add_(0, b.node_graph, v)
        edge_sum = e.new_zeros((b.num_graphs, lat)).index_add_(0, b.edge_graph, e)
        u = f("core_global", torch.cat((uc, node_sum, edge_sum), 1))
    node_out = f("dec_node", v) if "dec_node" in net else None
    return node_out, f("dec_global", u)


def _params_from_torch(
    net: torch.nn.ModuleDict,
    steps: int,
    raw_mean: np.ndarray,
    raw_std: np.ndarray,
    out_mean: np.ndarray,
    out_std: np.ndarray,
) -> GNNParams:
    mlps = {name: numpy_layers(net[name]) for name in MLP_NAMES if name in net}
    return GNNParams(mlps, steps, raw_mean, raw_std, out_mean, out_std)


def raw_standardisation(
    vocab: GraphVocabulary, graphs: Sequence[GraphInput], std_floor: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per (type, feature) mean and floored std of the raw features over all nodes of
    ``graphs``; padding columns and unseen types get mean 0, std 1."""
    shape = (len(vocab.types), vocab.feature_width)
    mean, std = np.zeros(shape), np.ones(shape)
    raw = vocab.raw_offset
    types = np.concatenate([g.node_types for g in graphs])
    rows = np.concatenate([g.nodes[:, raw:] for g in graphs])
    for k, t in enumerate(vocab.types):
        sel = rows[types == k, : t.dim]
        if len(sel):
            mean[k, : t.dim], std[k, : t.dim] = standardisation(sel, std_floor)
    return mean, std


@dataclass(frozen=True, eq=False)
class GNNTrainingData:
    """Graphs with targets: ``global_targets[i]`` for graph i, and for node heads
    ``node_targets[i]`` of shape (nodes of graph i, node_out)."""

    graphs: tuple[GraphInput, ...]
    global_targets: np.ndarray
    node_targets: tuple[np.ndarray, ...] | None = None
    standardise_outputs: bool = False

    def __post_init__(self) -> None:
        if len(self.graphs) != len(self.global_targets):
            raise ValueError("one global target per graph needed")
        if self.node_targets is not None and len(self.node_targets) != len(self.graphs):
            raise ValueError("one node target array per graph needed")


@dataclass(frozen=True, eq=False)
class TrainedGNN:
    params: GNNParams
    stats: GNNTrainingStats = field(compare=False)


def train_gnn(vocab: GraphVocabulary, data: GNNTrainingData, config: GNNConfig) -> TrainedGNN:
    """MSE on global (and node) outputs with Adam on shuffled minibatches of graphs.

    Seeded: same data and config give the same weights (for the configured thread
    count). torch's thread count is set to ``config.torch_threads`` for the duration.
    """
    t0 = time.perf_counter()
    n_all = len(data.graphs)
    if n_all == 0:
        raise ValueError("cannot train a GNN on zero examples")
    rng = np.random.default_rng(config.seed)
    graphs, gt, node_t = _subsample(data, config, rng)
    raw_mean, raw_std = raw_standardisation(vocab, graphs, config.std_floor)
    if data.standardise_outputs:
        out_mean, out_std = standardisation(gt, config.std_floor)
    else:
        out_mean, out_std = np.zeros(gt.shape[1]), np.ones(gt.shape[1])
    examples = _examples(vocab, graphs, (gt - out_mean) / out_std, node_t, raw_mean, raw_std)
    schedule = _Schedule.of(config, len(graphs))
    net, step, loss_value = _fit(vocab, examples, schedule, config, rng)
    params = _params_from_torch(net, config.message_steps, raw_mean, raw_std, out_mean, out_std)
    stats = GNNTrainingStats(
        num_examples=n_all,
        num_used=len(graphs),
        epochs=step / schedule.per_epoch,
        steps=step,
        seconds=time.perf_counter() - t0,
        final_loss=loss_value,
    )
    return TrainedGNN(params, stats)


def _subsample(
    data: GNNTrainingData, config: GNNConfig, rng: np.random.Generator
) -> tuple[list[GraphInput], np.ndarray, list[np.ndarray] | None]:
    """(graphs, global targets as rows, node targets) of the examples trained on: all of
    them, or ``config.max_examples`` drawn (in their order) to bound the training time."""
    n_all = len(data.graphs)
    chosen = np.arange(n_all)
    if config.max_examples is not None and n_all > config.max_examples:
        chosen = np.sort(rng.choice(n_all, size=config.max_examples, replace=False))
    graphs = [data.graphs[i] for i in chosen]
    gt = np.asarray(data.global_targets, dtype=np.float64)[chosen].reshape(len(chosen), -1)
    node_t = None if data.node_targets is None else [data.node_targets[i] for i in chosen]
    return graphs, gt, node_t


@dataclass(frozen=True, eq=False)
class _Layout:
    """Where each graph's rows lie in the concatenation, and its edges' endpoints
    numbered within the graph: what a minibatch needs to gather its graphs."""

    n_nodes: np.ndarray
    n_edges: np.ndarray
    node_start: np.ndarray
    edge_start: np.ndarray
    local_s: np.ndarray
    local_r: np.ndarray

    @staticmethod
    def of(graphs: Sequence[GraphInput], whole: GraphBatch) -> _Layout:
        n_nodes = np.array([len(g.nodes) for g in graphs])
        n_edges = np.array([len(g.edges) for g in graphs])
        node_start = np.concatenate(([0], np.cumsum(n_nodes)[:-1]))
        edge_start = np.concatenate(([0], np.cumsum(n_edges)[:-1]))
        local_s = whole.senders - np.repeat(node_start, n_edges)
        local_r = whole.receivers - np.repeat(node_start, n_edges)
        return _Layout(n_nodes, n_edges, node_start, edge_start, local_s, local_r)

    def gather(self, ids: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """:func:`_gather` of the graphs ``ids``."""
        return _gather(
            ids,
            self.n_nodes,
            self.n_edges,
            self.node_start,
            self.edge_start,
            self.local_s,
            self.local_r,
        )


@dataclass(frozen=True, eq=False)
class _Examples:
    """The examples concatenated once, inputs and targets standardised, so that a
    minibatch is only a gather."""

    nodes: np.ndarray
    edges: np.ndarray
    globals: np.ndarray
    global_targets: np.ndarray
    node_targets: np.ndarray | None
    node_out: int  # 0: no node head
    layout: _Layout


def _examples(
    vocab: GraphVocabulary,
    graphs: Sequence[GraphInput],
    global_targets: np.ndarray,
    node_targets: Sequence[np.ndarray] | None,
    raw_mean: np.ndarray,
    raw_std: np.ndarray,
) -> _Examples:
    """``graphs`` concatenated with their raw features standardised per type."""
    whole = batch_graphs(graphs)
    nodes_std = whole.nodes.copy()
    raw = vocab.raw_offset
    nodes_std[:, raw:] = (nodes_std[:, raw:] - raw_mean[whole.node_types]) / raw_std[
        whole.node_types
    ]
    return _Examples(
        nodes_std,
        whole.edges,
        whole.globals,
        global_targets,
        None if node_targets is None else np.concatenate(node_targets),
        0 if node_targets is None else int(node_targets[0].shape[1]),
        _Layout.of(graphs, whole),
    )


@dataclass(frozen=True)
class _Schedule:
    """Minibatch size and gradient steps: ``config.epochs`` passes over ``n``
    examples, capped at ``config.max_steps``."""

    batch_size: int
    per_epoch: int
    total: int

    @staticmethod
    def of(config: GNNConfig, n: int) -> _Schedule:
        bs = min(config.batch_size, n)
        per_epoch = math.ceil(n / bs)
        total = config.epochs * per_epoch
        if config.max_steps is not None:
            total = min(total, config.max_steps)
        return _Schedule(bs, per_epoch, total)


def _fit(
    vocab: GraphVocabulary,
    examples: _Examples,
    schedule: _Schedule,
    config: GNNConfig,
    rng: np.random.Generator,
) -> tuple[torch.nn.ModuleDict, int, float]:
    """(net, steps taken, last loss) of Adam on minibatches shuffled by ``rng``; torch's
    thread count is ``config.torch_threads`` meanwhile, and the net's initial weights
    come from ``config.seed`` without touching torch's global generator."""
    import torch  # lazy: planning runs NumpyGNN, without torch

    before = torch.get_num_threads()
    torch.set_num_threads(config.torch_threads)
    try:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(config.seed)
            net = _build_torch(vocab, config, examples.node_out, examples.global_targets.shape[1])
        T = lambda a, dt=torch.float32: torch.as_tensor(a, dtype=dt)  # noqa: E731
        all_nodes, all_edges = T(examples.nodes), T(examples.edges)
        all_glob = T(examples.globals)
        all_gt = T(examples.global_targets)
        all_nt = T(examples.node_targets) if examples.node_targets is not None else None
        params = list(net.parameters())
        adam = Adam(params, config.learning_rate)
        n, bs, total = len(examples.layout.n_nodes), schedule.batch_size, schedule.total
        step, loss_value = 0, float("nan")
        while step < total:
            perm = rng.permutation(n)
            for start in range(0, n, bs):
                if step == total:
                    break
                ids = perm[start : start + bs]
                b, node_idx = examples.layout.gather(ids)
                tb = _TorchBatch(
                    all_nodes[T(node_idx, torch.long)],
                    all_edges[T(b["edge_idx"], torch.long)],
                    all_glob[T(ids, torch.long)],
                    T(b["senders"], torch.long),
                    T(b["receivers"], torch.long),
                    T(b["node_graph"], torch.long),
                    T(b["edge_graph"], torch.long),
                    len(ids),
                )
                node_pred, glob_pred = _torch_forward(net, tb, config.message_steps)
                loss = torch.mean((glob_pred - all_gt[T(ids, torch.long)]) ** 2)
                if node_pred is not None and all_nt is not None:
                    loss = loss + torch.mean((node_pred - all_nt[T(node_idx, torch.long)]) ** 2)
                for p in params:
                    p.grad = None
                loss.backward()
                adam.step([p.grad for p in params])
                loss_value = float(loss.detach())
                step += 1
    finally:
        torch.set_num_threads(before)
    return net, step, loss_value


def _gather(
    ids: np.ndarray,
    n_nodes: np.ndarray,
    n_edges: np.ndarray,
    node_start: np.ndarray,
    edge_start: np.ndarray,
    local_s: np.ndarray,
    local_r: np.ndarray,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Row indices and renumbered senders/receivers of the graphs ``ids``."""
    nn_, ne = n_nodes[ids], n_edges[ids]
    new_node_start = np.concatenate(([0], np.cumsum(nn_)[:-1]))
    node_idx = _ranges(node_start[ids], nn_)
    edge_idx = _ranges(edge_start[ids], ne)
    shift = np.repeat(new_node_start, ne)
    return {
        "edge_idx": edge_idx,
        "senders": local_s[edge_idx] + shift,
        "receivers": local_r[edge_idx] + shift,
        "node_graph": np.repeat(np.arange(len(ids)), nn_),
        "edge_graph": np.repeat(np.arange(len(ids)), ne),
    }, node_idx


def _ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenation of arange(s, s + c) for each (s, c)."""
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    offsets = np.repeat(starts - np.concatenate(([0], np.cumsum(counts)[:-1])), counts)
    return offsets + np.arange(total)


def torch_module(params: GNNParams) -> torch.nn.ModuleDict:
    """A float64 torch module holding ``params`` (for :func:`torch_forward`)."""
    import torch  # lazy: planning runs NumpyGNN, without torch

    return torch.nn.ModuleDict({name: torch_layers(layers) for name, layers in params.mlps.items()})


def torch_forward(
    net: torch.nn.ModuleDict, params: GNNParams, vocab: GraphVocabulary, batch: GraphBatch
) -> tuple[np.ndarray, np.ndarray]:
    """The forward pass of :class:`NumpyGNN` computed by torch (no autograd)."""
    import torch  # lazy: planning runs NumpyGNN, without torch

    L = lambda a: torch.as_tensor(a, dtype=torch.long)  # noqa: E731
    with torch.no_grad():
        tb = _TorchBatch(
            torch.from_numpy(standardise_nodes(params, vocab, batch)),
            torch.from_numpy(batch.edges.astype(np.float64)),
            torch.from_numpy(batch.globals.astype(np.float64)),
            L(batch.senders),
            L(batch.receivers),
            L(batch.node_graph),
            L(batch.edge_graph),
            batch.num_graphs,
        )
        node_out, glob = _torch_forward(net, tb, params.message_steps)
    nodes = node_out.numpy() if node_out is not None else np.zeros((len(batch.nodes), 0))
    return nodes, glob.numpy() * params.out_std + params.out_mean


def torch_reference(
    params: GNNParams, vocab: GraphVocabulary, batch: GraphBatch
) -> tuple[np.ndarray, np.ndarray]:
    """The same forward pass computed by torch in float64 from ``params`` (the check of
    the numpy inference path); global outputs de-standardised."""
    return torch_forward(torch_module(params), params, vocab, batch)
