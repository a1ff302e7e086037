"""The networks' own Adam against torch.optim.Adam, in one run, start-up included.

    python scripts/bench_optimiser.py [--repeat 3] [--mlp-steps 2000] [--gnn-steps 300]
    python scripts/bench_optimiser.py --gnn-first

Each measurement is a fresh process (so torch.optim's first-use start-up, which imports
torch._dynamo, is paid where a real ``bpns learn`` pays it) that trains one MLP
regressor (policy-sized: 2x32, batch 512) and then one GNN (the baselines' size:
latent 16, 3 message-passing steps, batch 128), either with ``bpns.nets.layers.Adam``
or with torch.optim.Adam put in its place. ``import torch`` happens before the clock
starts in both (``--gnn-first`` swaps the order, so that the start-up lands in the GNN's
time). The two alternate, ``--repeat`` times each; the median seconds of each
and their ratio are printed, and whether the weights came out bit-identical.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import statistics
import subprocess
import sys
import time

import numpy as np


class TorchAdam:
    """torch.optim.Adam behind the interface of ``bpns.nets.layers.Adam``."""

    def __init__(self, params, lr: float) -> None:
        import torch

        self.params = list(params)
        self.opt = torch.optim.Adam(self.params, lr=lr)

    def step(self, grads) -> None:
        for p, g in zip(self.params, grads, strict=True):
            p.grad = g
        self.opt.step()


def _graphs(n: int, seed: int):
    from bpns.baselines.graphs import GraphVocabulary, encode_graph
    from bpns.structs import Object, State, Type

    block, robot = Type("block", ("x", "y", "z")), Type("robot", ("x", "y", "z", "fingers"))
    vocab = GraphVocabulary.build((block, robot), ())
    rng = np.random.default_rng(seed)
    graphs, targets = [], []
    for _ in range(n):
        objs = [Object("robot", robot)] + [
            Object(f"b{i}", block) for i in range(rng.integers(2, 5))
        ]
        state = State({o: rng.normal(size=o.type.dim) for o in objs})
        graphs.append(encode_graph(vocab, state, (), ()))
        targets.append(np.tanh(state.data[objs[0]][:2] - state.data[objs[1]][:2]))
    return vocab, tuple(graphs), np.array(targets)


def child(optimiser: str, mlp_steps: int, gnn_steps: int, gnn_first: bool) -> dict:
    import torch

    from bpns.learning import gnn, mlp
    from bpns.learning.config import MLPConfig

    torch.set_num_threads(1)
    if optimiser == "torch":
        mlp.Adam = gnn.Adam = TorchAdam  # type: ignore[misc,assignment]
    rng = np.random.default_rng(0)
    x = rng.normal(size=(4000, 20))
    y = np.stack([np.sin(x[:, 0]) + x[:, 1], x[:, 2] * x[:, 3]], axis=1)
    vocab, graphs, targets = _graphs(600, 1)
    data = gnn.GNNTrainingData(graphs, targets, None, standardise_outputs=True)
    seconds, arrays = {}, {}
    for kind in ("gnn", "mlp") if gnn_first else ("mlp", "gnn"):
        t0 = time.perf_counter()
        if kind == "mlp":
            reg = mlp.train_regressor(x, y, MLPConfig(num_steps=mlp_steps, batch_size=512), 0)
            arrays.update({f"mlp/{k}": v for k, v in reg.to_arrays().items()})
        else:
            trained = gnn.train_gnn(vocab, data, gnn.GNNConfig(max_steps=gnn_steps, seed=0))
            arrays.update({f"gnn/{k}": v for k, v in trained.params.to_arrays().items()})
        seconds[kind] = time.perf_counter() - t0
    h = hashlib.sha256()
    for k in sorted(arrays):
        h.update(np.ascontiguousarray(arrays[k]).tobytes())
    return {**seconds, "weights": h.hexdigest()[:16]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--mlp-steps", type=int, default=2000)
    parser.add_argument("--gnn-steps", type=int, default=300)
    parser.add_argument("--gnn-first", action="store_true", help="train the GNN first")
    parser.add_argument("--child", choices=("ours", "torch"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args.child, args.mlp_steps, args.gnn_steps, args.gnn_first)))
        return 0
    runs: dict[str, list[dict]] = {"ours": [], "torch": []}
    for r in range(args.repeat):
        for name in ("ours", "torch") if r % 2 == 0 else ("torch", "ours"):
            steps = ["--mlp-steps", str(args.mlp_steps), "--gnn-steps", str(args.gnn_steps)]
            order = ["--gnn-first"] if args.gnn_first else []
            cmd = [sys.executable, __file__, "--child", name, *steps, *order]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            runs[name].append(json.loads(out.strip().splitlines()[-1]))
    med = {
        n: {k: statistics.median(r[k] for r in rs) for k in ("mlp", "gnn")}
        for n, rs in runs.items()
    }
    first = "GNN" if args.gnn_first else "MLP"
    print(f"medians of {args.repeat} fresh processes each, the {first} trained first")
    print(f"{'':8}{'MLP s':>8}{'GNN s':>8}{'total s':>9}")
    for n in ("ours", "torch"):
        m = med[n]
        print(f"{n:8}{m['mlp']:8.2f}{m['gnn']:8.2f}{m['mlp'] + m['gnn']:9.2f}")
    ratio = {k: med["torch"][k] / med["ours"][k] for k in ("mlp", "gnn")}
    total = sum(med["torch"].values()) / sum(med["ours"].values())
    print(
        f"torch.optim / ours: MLP {ratio['mlp']:.2f}x, GNN {ratio['gnn']:.2f}x, total {total:.2f}x"
    )
    same = {r["weights"] for r in runs["ours"]} == {r["weights"] for r in runs["torch"]}
    print(f"weights bit-identical between the two: {same}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
