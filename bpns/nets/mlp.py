"""Small fully-connected networks: trained with torch, evaluated with plain numpy.

Planning queries policies and samplers hundreds of thousands of times, so inference
must not pay framework overhead: after training, weights are copied to float64 numpy
arrays and input standardisation (and, for regressors, output de-standardisation) is
folded into the first and last layers. A forward pass is then a handful of numpy calls.

Three heads share one trunk type:
- regression: MSE on standardised targets;
- Gaussian: mean and diagonal variance (ELU + 1), Gaussian negative log-likelihood;
- binary classifier: one logit, class-balanced binary cross-entropy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bpns.nets.layers import (
    Adam,
    Layers,
    check_layers,
    count_layers,
    layers_from_arrays,
    layers_to_arrays,
    numpy_mlp,
    standardisation,
    torch_layers,
    torch_linears,
    torch_mlp,
)

if TYPE_CHECKING:
    import torch

# torch is imported inside the training functions only: loading and running learned
# skills (planning, evaluation workers) must not pay for importing it.

# Variance floor in standardised output space: keeps the NLL finite for exact data.
MIN_VARIANCE = 1e-6


@dataclass(frozen=True)
class MLPConfig:
    """Architecture and optimisation of one fully-connected network."""

    hidden_sizes: tuple[int, ...] = (32, 32)
    num_steps: int = 4000
    batch_size: int = 256
    learning_rate: float = 1e-3
    # Standardisation divides by max(std, std_floor), in the features' own units (m, rad):
    # variation below about a centimetre is noise to these networks, and must not be
    # amplified into huge standardised inputs at inference.
    std_floor: float = 1e-2
    # Inference clips inputs into the training range widened by this fraction of its
    # span on each side (mlp.input_box); None: no clipping, as in the paper.
    input_margin: float | None = None

    def __post_init__(self) -> None:
        if (
            self.num_steps < 0
            or self.batch_size < 1
            or self.learning_rate <= 0.0
            or not self.std_floor > 0.0
        ):
            raise ValueError(f"invalid MLPConfig {self}")
        if any(h < 1 for h in self.hidden_sizes):
            raise ValueError(f"hidden sizes must be positive, got {self.hidden_sizes}")
        if self.input_margin is not None and not 0.0 <= self.input_margin < math.inf:
            raise ValueError(
                f"input_margin must be finite and >= 0, or None; got {self.input_margin}"
            )
        if not (math.isfinite(self.learning_rate) and math.isfinite(self.std_floor)):
            raise ValueError(f"learning_rate and std_floor must be finite, got {self}")


@dataclass(frozen=True, eq=False)
class MLPParams:
    """Trained weights (layer k: ``weights[k]`` of shape (fan_in, fan_out)) and the data
    standardisation they were trained under. float64, plain numpy: what is saved."""

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    input_mean: np.ndarray
    input_std: np.ndarray
    output_mean: np.ndarray
    output_std: np.ndarray
    # Inputs are clipped into [input_low, input_high] before the first layer (None: not).
    input_low: np.ndarray | None = None
    input_high: np.ndarray | None = None

    @property
    def input_dim(self) -> int:
        return int(self.weights[0].shape[0])

    @property
    def raw_output_dim(self) -> int:
        return int(self.weights[-1].shape[1])

    @property
    def layers(self) -> Layers:
        return tuple(zip(self.weights, self.biases, strict=True))

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        out = {
            f"{prefix}input_mean": self.input_mean,
            f"{prefix}input_std": self.input_std,
            f"{prefix}output_mean": self.output_mean,
            f"{prefix}output_std": self.output_std,
        }
        if self.input_low is not None and self.input_high is not None:
            out[f"{prefix}input_low"] = self.input_low
            out[f"{prefix}input_high"] = self.input_high
        out.update(layers_to_arrays(self.layers, prefix))
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> MLPParams:
        if count_layers(arrays, prefix) == 0:
            raise KeyError(f"{prefix}w0")  # not one layer under the prefix
        get = lambda key: np.array(arrays[f"{prefix}{key}"], dtype=np.float64)  # noqa: E731
        boxed = f"{prefix}input_low" in arrays and f"{prefix}input_high" in arrays
        layers = layers_from_arrays(arrays, prefix)
        inputs = get("input_mean")
        check_layers(layers, inputs.shape[0] if inputs.ndim == 1 else -1, prefix.rstrip("/"))
        return cls(
            weights=tuple(w for w, _ in layers),
            biases=tuple(b for _, b in layers),
            input_mean=get("input_mean"),
            input_std=get("input_std"),
            output_mean=get("output_mean"),
            output_std=get("output_std"),
            input_low=get("input_low") if boxed else None,
            input_high=get("input_high") if boxed else None,
        )

    def identical(self, other: MLPParams) -> bool:
        """Bit-for-bit equality of all arrays (for reproducibility checks)."""
        a, b = self.to_arrays(), other.to_arrays()
        return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


# ---------------------------------------------------------------------------- training


def input_box(
    data: np.ndarray, margin: float | None
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The training inputs' per-column range widened by ``margin`` times its span on each
    side (None: no box).

    Inference clips inputs into it. A column that was constant in the data (a wrist that
    every demonstration held at 0 while pressing a button) then stays at its constant:
    the network never saw it vary, and a 5 deg drift, 9 floored standard deviations,
    would otherwise be extrapolated into a wild output. A column that varied may still
    step a little outside its range, by the margin."""
    if margin is None:
        return None, None
    low, high = data.min(axis=0), data.max(axis=0)
    span = (high - low) * margin
    return (low - span).astype(np.float64), (high + span).astype(np.float64)


def torch_gaussian_head(raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Split raw outputs into mean and variance (ELU + 1 keeps the variance positive)."""
    # lazy: planning and evaluation run the numpy nets without torch
    import torch.nn.functional as F

    d = raw.shape[-1] // 2
    return raw[..., :d], F.elu(raw[..., d:]) + 1.0 + MIN_VARIANCE


# Losses. ``value`` is the definition (differentiable by autograd); ``grad`` is its
# hand-derived gradient with respect to the raw network output, which training uses:
# for nets this small, torch's per-op overhead dominates, and a hand-written backward
# pass plus Adam on one flat parameter vector needs a third of autograd's operations.
# tests/nets/test_mlp.py checks every ``grad`` against autograd on ``value``.


class MSELoss:
    def value(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        # lazy: planning and evaluation run the numpy nets without torch
        import torch.nn.functional as F

        return F.mse_loss(raw, target)

    def grad(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return (raw - target).mul_(2.0 / raw.numel())


class GaussianNLLLoss:
    """Mean over elements of 0.5 * (log var + (target - mean)^2 / var)."""

    def value(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        mean, var = torch_gaussian_head(raw)
        return 0.5 * (torch.log(var) + (target - mean) ** 2 / var).mean()

    def grad(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        d = raw.shape[1] // 2
        mean, z = raw[:, :d], raw[:, d:]
        var = torch.nn.functional.elu(z) + (1.0 + MIN_VARIANCE)
        diff = mean - target
        scale = 1.0 / diff.numel()
        d_mean = diff / var * scale
        d_var = (1.0 - diff * diff / var) / var * (0.5 * scale)
        d_z = d_var * torch.where(z > 0.0, 1.0, torch.exp(torch.clamp(z, max=0.0)))
        return torch.cat((d_mean, d_z), dim=1)


class WeightedBCELoss:
    """Binary cross-entropy on logits with positives weighted by ``pos_weight``."""

    def __init__(self, pos_weight: float) -> None:
        self.pos_weight = pos_weight

    def value(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        weight = torch.tensor([self.pos_weight], dtype=raw.dtype)
        return torch.nn.functional.binary_cross_entropy_with_logits(raw, target, pos_weight=weight)

    def grad(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        wy = target * self.pos_weight
        return (torch.sigmoid(raw) * (wy + 1.0 - target) - wy).mul_(1.0 / raw.numel())


Loss = MSELoss | GaussianNLLLoss | WeightedBCELoss


class _FlatMLP:
    """ReLU MLP whose parameters are views into one flat tensor, with a hand-written
    backward pass; weights are (fan_in, fan_out) so a layer is ``addmm(b, h, W)``."""

    def __init__(self, sizes: tuple[int, ...], seed: int, dtype: torch.dtype | None = None):
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        # torch.nn.Linear's default initialisation, without touching the global RNG.
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            init = torch_linears(sizes)
        shapes = [s for a, b in zip(sizes[:-1], sizes[1:], strict=True) for s in ((a, b), (b,))]
        total = sum(int(np.prod(s)) for s in shapes)
        dtype = torch.float32 if dtype is None else dtype
        self.flat = torch.zeros(total, dtype=dtype)
        self.grad = torch.zeros(total, dtype=dtype)
        params, grads, offset = [], [], 0
        for shape in shapes:
            size = int(np.prod(shape))
            params.append(self.flat[offset : offset + size].view(shape))
            grads.append(self.grad[offset : offset + size].view(shape))
            offset += size
        self.weights, self.biases = params[0::2], params[1::2]
        self.weight_grads, self.bias_grads = grads[0::2], grads[1::2]
        with torch.no_grad():
            for layer, w, b in zip(init, self.weights, self.biases, strict=True):
                w.copy_(layer.weight.T)
                b.copy_(layer.bias)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """Activations: the input, each hidden layer's ReLU output, the raw output."""
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        acts = [x]
        last = len(self.weights) - 1
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = torch.addmm(b, acts[-1], w)
            acts.append(h.relu_() if k < last else h)
        return acts

    def backward(self, acts: list[torch.Tensor], d_out: torch.Tensor) -> None:
        """Fill ``self.grad`` from dLoss/d(raw output)."""
        import torch  # lazy: planning and evaluation run the numpy nets without torch

        d = d_out
        for k in range(len(self.weights) - 1, -1, -1):
            torch.mm(acts[k].T, d, out=self.weight_grads[k])
            torch.sum(d, dim=0, out=self.bias_grads[k])
            if k > 0:
                # ReLU's derivative: zero where the activation was not positive.
                # threshold_backward is autograd's own ReLU backward, one fused op
                # where masked_fill_(acts[k] <= 0) takes two and 8x longer on CPU.
                d = torch.ops.aten.threshold_backward(torch.mm(d, self.weights[k].T), acts[k], 0.0)

    def numpy_layers(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        weights = tuple(w.numpy().astype(np.float64) for w in self.weights)
        biases = tuple(b.numpy().astype(np.float64) for b in self.biases)
        return weights, biases


def _fit(
    inputs: np.ndarray,
    targets: np.ndarray,
    out_dim: int,
    loss: Loss,
    config: MLPConfig,
    seed: int,
) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """Adam on shuffled minibatches for ``config.num_steps`` steps.

    Each epoch gathers one seeded permutation of the data, after which minibatches are
    contiguous slices. Initial weights come from ``seed`` without disturbing torch's
    global RNG state, and the permutations from a torch.Generator seeded alike: equal
    inputs give equal weights.
    """
    import torch  # lazy: planning and evaluation run the numpy nets without torch

    if len(inputs) == 0:
        raise ValueError("cannot train a network on an empty dataset")
    x = torch.as_tensor(inputs, dtype=torch.float32)
    t = torch.as_tensor(targets, dtype=torch.float32)
    net = _FlatMLP((x.shape[1], *config.hidden_sizes, out_dim), seed)
    adam = Adam([net.flat], config.learning_rate)
    gen = torch.Generator().manual_seed(seed)
    n = len(x)
    bs = min(config.batch_size, n)
    step = 0
    with torch.no_grad():
        while step < config.num_steps:
            if bs < n:
                perm = torch.randperm(n, generator=gen)
                xs, ts = x[perm], t[perm]
            else:
                xs, ts = x, t
            for start in range(0, n - bs + 1, bs):
                if step == config.num_steps:
                    break
                acts = net.forward(xs[start : start + bs])
                net.backward(acts, loss.grad(acts[-1], ts[start : start + bs]))
                adam.step([net.grad])
                step += 1
    return net.numpy_layers()


def _as_2d(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    return a.reshape(len(a), -1)


def train_regressor(
    inputs: np.ndarray, targets: np.ndarray, config: MLPConfig, seed: int
) -> MLPParams:
    """MSE regression on standardised inputs and targets."""
    inputs, targets = _as_2d(inputs), _as_2d(targets)
    in_mean, in_std = standardisation(inputs, config.std_floor)
    out_mean, out_std = standardisation(targets, config.std_floor)
    x, y = (inputs - in_mean) / in_std, (targets - out_mean) / out_std
    w, b = _fit(x, y, targets.shape[1], MSELoss(), config, seed)
    return MLPParams(
        w, b, in_mean, in_std, out_mean, out_std, *input_box(inputs, config.input_margin)
    )


def train_gaussian(
    inputs: np.ndarray, targets: np.ndarray, config: MLPConfig, seed: int
) -> MLPParams:
    """Conditional diagonal Gaussian over standardised targets, by NLL."""
    inputs, targets = _as_2d(inputs), _as_2d(targets)
    in_mean, in_std = standardisation(inputs, config.std_floor)
    out_mean, out_std = standardisation(targets, config.std_floor)
    x, y = (inputs - in_mean) / in_std, (targets - out_mean) / out_std
    w, b = _fit(x, y, 2 * targets.shape[1], GaussianNLLLoss(), config, seed)
    return MLPParams(
        w, b, in_mean, in_std, out_mean, out_std, *input_box(inputs, config.input_margin)
    )


def train_classifier(
    inputs: np.ndarray, labels: np.ndarray, config: MLPConfig, seed: int
) -> MLPParams:
    """Binary classifier by BCE; positives are up-weighted by #neg/#pos so that both
    classes count equally and 0.5 stays a meaningful threshold."""
    inputs = _as_2d(inputs)
    labels = np.asarray(labels, dtype=np.float64).reshape(-1, 1)
    n_pos = float(labels.sum())
    n_neg = float(len(labels) - n_pos)
    if n_pos == 0 or n_neg == 0:
        raise ValueError(
            f"a classifier needs both classes, got {n_pos:.0f} positives, {n_neg:.0f} negatives"
        )
    in_mean, in_std = standardisation(inputs, config.std_floor)
    x = (inputs - in_mean) / in_std
    w, b = _fit(x, labels, 1, WeightedBCELoss(n_neg / n_pos), config, seed)
    low, high = input_box(inputs, config.input_margin)
    return MLPParams(w, b, in_mean, in_std, np.zeros(1), np.ones(1), low, high)


def torch_reference(params: MLPParams, inputs: np.ndarray) -> np.ndarray:
    """Raw outputs (standardised output space, before any head) computed by torch in
    float64 from ``params``: the independent check of the numpy inference path."""
    import torch  # lazy: planning and evaluation run the numpy nets without torch

    layers = torch_layers(params.layers)
    with torch.no_grad():
        x = torch.from_numpy(_as_2d(inputs))
        if params.input_low is not None and params.input_high is not None:
            x = torch.clamp(
                x, torch.from_numpy(params.input_low), torch.from_numpy(params.input_high)
            )
        x = (x - torch.from_numpy(params.input_mean)) / torch.from_numpy(params.input_std)
        return torch_mlp(layers, x).numpy()


# --------------------------------------------------------------------------- inference


class _NumpyNet:
    """ReLU MLP in numpy with input standardisation folded into the first layer (inputs
    clipped into the params' input box first, if they have one)."""

    def __init__(self, params: MLPParams, fold_output: bool) -> None:
        ws = [np.array(w, dtype=np.float64) for w in params.weights]
        bs = [np.array(b, dtype=np.float64) for b in params.biases]
        inv_std = 1.0 / params.input_std
        bs[0] = bs[0] - (params.input_mean * inv_std) @ ws[0]
        ws[0] = ws[0] * inv_std[:, None]
        if fold_output:
            bs[-1] = bs[-1] * params.output_std + params.output_mean
            ws[-1] = ws[-1] * params.output_std[None, :]
        self._layers = tuple((np.ascontiguousarray(w), b) for w, b in zip(ws, bs, strict=True))
        self._box = (
            None
            if params.input_low is None or params.input_high is None
            else (params.input_low, params.input_high)
        )
        self.params = params

    def forward(self, x: np.ndarray) -> np.ndarray:
        """One input vector or a batch (rows); returns a fresh array."""
        h = x if self._box is None else np.minimum(np.maximum(x, self._box[0]), self._box[1])
        return numpy_mlp(self._layers, h)


class Regressor:
    """Numpy inference for :func:`train_regressor` networks."""

    def __init__(self, params: MLPParams) -> None:
        self.params = params
        self._net = _NumpyNet(params, fold_output=True)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self._net.forward(x)


class GaussianRegressor:
    """Numpy inference for :func:`train_gaussian` networks: mean and std per output."""

    def __init__(self, params: MLPParams) -> None:
        self.params = params
        self._net = _NumpyNet(params, fold_output=False)
        self._d = params.raw_output_dim // 2
        self._mean, self._std = params.output_mean, params.output_std

    def mean_std(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raw = self._net.forward(x)
        d = self._d
        mu, z = raw[..., :d], raw[..., d:]
        # ELU(z) + 1 = z + 1 for z > 0, exp(z) otherwise.
        var = np.where(z > 0.0, z + 1.0, np.exp(np.minimum(z, 0.0))) + MIN_VARIANCE
        return mu * self._std + self._mean, np.sqrt(var) * self._std


class BinaryClassifier:
    """Numpy inference for :func:`train_classifier` networks: P(positive)."""

    def __init__(self, params: MLPParams) -> None:
        self.params = params
        self._net = _NumpyNet(params, fold_output=False)

    def prob(self, x: np.ndarray) -> np.ndarray:
        """Shape () for one input, (n,) for a batch; tanh form cannot overflow."""
        z = self._net.forward(x)[..., 0]
        return 0.5 * (1.0 + np.tanh(0.5 * z))
