"""The network toolkit both network kinds are built from (MLPs in ``mlp``, GNNs in ``gnn``).

One of each: the ReLU MLP as torch layers (default torch initialisation) and as numpy
layers, per-column standardisation, the Adam update, saving layers into named arrays,
and the conversions between torch and numpy layers. Training runs in torch; planning and
solving run the numpy layers, which pay no framework overhead per call.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from bpns.errors import BpnsError

if TYPE_CHECKING:
    import torch

# torch is imported inside the functions that need it: loading and running learned
# networks (planning, evaluation workers) must not pay for importing it.

Layers = tuple[tuple[np.ndarray, np.ndarray], ...]  # (weight (fan_in, fan_out), bias (fan_out,))


def standardisation(data: np.ndarray, std_floor: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-column mean and std, the std raised to at least ``std_floor``.

    Without the floor a nearly constant column (a block's x on a line, jittering by a
    millimetre) is divided by its tiny std, and at planning time a centimetre of drift
    becomes a 10-sigma input that the network extrapolates wildly from.
    """
    mean = data.mean(axis=0)
    std = np.maximum(data.std(axis=0), std_floor)
    return mean.astype(np.float64), std.astype(np.float64)


# ------------------------------------------------------------------------------- numpy


def numpy_mlp(layers: Layers, x: np.ndarray) -> np.ndarray:
    """ReLU hidden layers and a linear output; returns a fresh array (``x`` untouched)."""
    last = len(layers) - 1
    for k, (w, b) in enumerate(layers):
        x = x @ w
        x += b
        if k < last:
            np.maximum(x, 0.0, out=x)
    return x


def layers_to_arrays(layers: Layers, prefix: str = "") -> dict[str, np.ndarray]:
    """``{prefix}w{k}`` and ``{prefix}b{k}`` per layer: how networks are saved."""
    out = {}
    for k, (w, b) in enumerate(layers):
        out[f"{prefix}w{k}"] = w
        out[f"{prefix}b{k}"] = b
    return out


def count_layers(arrays: Mapping[str, np.ndarray], prefix: str = "") -> int:
    """How many ``{prefix}w{k}`` weights ``arrays`` holds."""
    start = len(prefix) + 1
    return sum(1 for key in arrays if key.startswith(f"{prefix}w") and key[start:].isdigit())


def layers_from_arrays(arrays: Mapping[str, np.ndarray], prefix: str = "") -> Layers:
    """The layers :func:`layers_to_arrays` saved, as float64 copies (empty if there is no
    weight under ``prefix``). KeyError naming the first weight or bias missing from the
    run ``w0, b0 ... wN, bN`` (a hand-edited file that lost a middle or last layer would
    otherwise load as a shorter network)."""
    start = len(prefix) + 1
    indices = {
        int(key[start:])
        for key in arrays
        if key[start - 1 : start] in ("w", "b") and key.startswith(prefix) and key[start:].isdigit()
    }
    layers = []
    for k in range(max(indices, default=-1) + 1):
        for name in (f"{prefix}w{k}", f"{prefix}b{k}"):
            if name not in arrays:
                raise KeyError(name)
        w, b = arrays[f"{prefix}w{k}"], arrays[f"{prefix}b{k}"]
        layers.append((np.array(w, dtype=np.float64), np.array(b, dtype=np.float64)))
    return tuple(layers)


class LayerShapeError(BpnsError, ValueError):
    """A network's saved layers do not chain (a hand-edited or foreign weights file)."""


def check_layers(layers: Layers, fan_in: int, where: str) -> int:
    """The output width of ``layers`` if their shapes chain from ``fan_in`` inputs (each
    layer at least one unit wide); :class:`LayerShapeError` naming the first layer that
    does not."""
    width = fan_in
    for k, (w, b) in enumerate(layers):
        if not (
            w.ndim == 2 and w.shape[0] == width and w.shape[1] >= 1 and b.shape == (w.shape[1],)
        ):
            raise LayerShapeError(
                f"{where}: layer {k} has shapes {w.shape}, {b.shape}; expected ({width}, n), (n,)"
            )
        width = w.shape[1]
    return width


# ------------------------------------------------------------------------------- torch


def torch_linears(sizes: Sequence[int]) -> torch.nn.ModuleList:
    """``torch.nn.Linear`` layers of ``sizes``, initialised from torch's global RNG in
    layer order (seed it, under ``torch.random.fork_rng``, for reproducible weights)."""
    import torch  # lazy: planning and evaluation run the numpy nets without torch

    with warnings.catch_warnings():  # a layer of zero inputs (a GNN with no nullary atoms)
        warnings.filterwarnings("ignore", message="Initializing zero-element tensors")
        return torch.nn.ModuleList(
            torch.nn.Linear(a, b) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
        )


def torch_mlp(layers: torch.nn.ModuleList, x: torch.Tensor) -> torch.Tensor:
    """The forward pass of :func:`numpy_mlp` on torch layers (autograd as usual)."""
    import torch  # lazy: planning and evaluation run the numpy nets without torch

    for layer in layers[:-1]:
        x = torch.relu(layer(x))
    return layers[-1](x)


def numpy_layers(layers: torch.nn.ModuleList) -> Layers:
    """The float64 numpy copy of trained torch layers, weights as (fan_in, fan_out)."""
    return tuple(
        (
            layer.weight.detach().numpy().T.astype(np.float64).copy(),
            layer.bias.detach().numpy().astype(np.float64).copy(),
        )
        for layer in layers
    )


def torch_layers(layers: Layers) -> torch.nn.ModuleList:
    """float64 torch layers holding ``layers`` (the independent check of numpy inference);
    torch's global RNG is left as it was."""
    import torch  # lazy: planning and evaluation run the numpy nets without torch

    with torch.random.fork_rng(devices=[]):  # initial values are overwritten below
        sizes = (layers[0][0].shape[0], *(w.shape[1] for w, _ in layers))
        out = torch_linears(sizes).double()
    with torch.no_grad():
        for lin, (w, b) in zip(out, layers, strict=True):
            lin.weight.copy_(torch.from_numpy(w.T))
            lin.bias.copy_(torch.from_numpy(b))
    return out


class Adam:
    """torch.optim.Adam's update (no weight decay, no amsgrad) on the given tensors, with
    the gradients passed in: a flat parameter vector with a hand-written backward pass
    (MLPs) or autograd's ``.grad`` of each parameter (GNNs).

    Why not torch.optim.Adam: its first ``step`` imports torch._dynamo (seconds of
    start-up for a few milliseconds of work) and every step costs more Python;
    ``scripts/bench_optimiser.py`` measures both in one run. Its bias correction takes
    ``x ** 0.5`` where this takes ``math.sqrt(x)``, which can differ in the last bit, so
    the two agree to rounding, not bit for bit (tests/nets/test_layers.py).
    """

    def __init__(
        self,
        params: Sequence[torch.Tensor],
        lr: float,
        betas: tuple[float, float] = (0.9, 0.999),
        eps: float = 1e-8,
    ) -> None:
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        self.params, self.lr, self.betas, self.eps = list(params), lr, betas, eps
        self.m = [torch.zeros_like(p) for p in self.params]
        self.v = [torch.zeros_like(p) for p in self.params]
        self.t = 0

    def step(self, grads: Sequence[torch.Tensor | None]) -> None:
        """One update; a parameter whose gradient is None is left as it is."""
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        b1, b2 = self.betas
        self.t += 1
        c1, c2 = 1.0 - b1**self.t, math.sqrt(1.0 - b2**self.t)
        with torch.no_grad():
            for p, g, m, v in zip(self.params, grads, self.m, self.v, strict=True):
                if g is None:
                    continue
                m.lerp_(g, 1.0 - b1)
                v.mul_(b2).addcmul_(g, g, value=1.0 - b2)
                p.addcdiv_(m, (v.sqrt() / c2).add_(self.eps), value=-self.lr / c1)
