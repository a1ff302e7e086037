"""An affine map under a network: the part of a target that is linear in the inputs.

Subgoals and demonstrator commands are often affine in the state: the hand goes to the
button's x and y, a proportional controller commands 0.7 times the remaining offset. A
ridge fit recovers such a map from a few dozen examples, where a 2x32 network trained on
them blurs it (a generator overconfident by an order of magnitude, a policy whose
commands fade to nothing two centimetres short of its goal). The network then learns the
residual. The map is kept only where it predicts held-out examples better than their
mean (:meth:`LinearBase.fit_if_it_helps`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class LinearBase:
    """``y ~ clip(x) @ weight + bias``, fit by ridge regression on standardised inputs.

    The generator network then learns ``y - base(x)``. Inputs are clipped into the
    training range widened by ``margin`` of its span, as every network's are
    (``MLPConfig.input_margin``): a few dozen segments fix no weight on a dimension
    that barely varied, and an unclipped map would extrapolate along it."""

    weight: np.ndarray  # (inputs, outputs)
    bias: np.ndarray  # (outputs,)
    low: np.ndarray  # (inputs,) the clipping box
    high: np.ndarray

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(x, self.low), self.high) @ self.weight + self.bias

    @classmethod
    def fit(
        cls,
        x: np.ndarray,
        y: np.ndarray,
        ridge: float = 1e-3,
        std_floor: float = 1e-2,
        margin: float = 0.1,
    ) -> LinearBase:
        """Least squares with an L2 penalty ``ridge * n`` on the standardised weights
        (inputs divided by ``max(std, std_floor)``, as the networks standardise)."""
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        mu, sd = x.mean(axis=0), np.maximum(x.std(axis=0), std_floor)
        z = (x - mu) / sd
        y_mean = y.mean(axis=0)
        gram = z.T @ z + ridge * len(x) * np.eye(z.shape[1])
        w = np.linalg.solve(gram, z.T @ (y - y_mean))
        weight = w / sd[:, None]
        lo, hi = x.min(axis=0), x.max(axis=0)
        pad = margin * (hi - lo)
        return cls(weight, y_mean - mu @ weight, lo - pad, hi + pad)

    @classmethod
    def fit_if_it_helps(
        cls, x: np.ndarray, y: np.ndarray, std_floor: float = 1e-2, margin: float = 0.1
    ) -> LinearBase | None:
        """The base fit on all rows if, fit on three quarters of them, it predicts the
        held-out quarter (every fourth row) better than their mean does, else None:
        with few segments per input dimension a ridge map interpolates noise (12 demos of
        the stacking example: BPNS solved 0 of 3 tasks with it, 3 of 3 without)."""
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        held = np.arange(len(x)) % 4 == 3
        if held.sum() < 2 or len(x) - held.sum() <= x.shape[1]:
            return None
        trial = cls.fit(x[~held], y[~held], std_floor=std_floor, margin=margin)
        scale = np.maximum(y[~held].std(axis=0), 1e-12)
        base_error = np.mean(((trial(x[held]) - y[held]) / scale) ** 2)
        mean_error = np.mean(((y[~held].mean(axis=0) - y[held]) / scale) ** 2)
        if not base_error < mean_error:
            return None
        return cls.fit(x, y, std_floor=std_floor, margin=margin)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {
            f"{prefix}w0": self.weight,
            f"{prefix}b0": self.bias,
            f"{prefix}input_low": self.low,
            f"{prefix}input_high": self.high,
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str) -> LinearBase:
        def get(key: str) -> np.ndarray:
            return np.array(arrays[f"{prefix}{key}"], np.float64)

        weight = get("w0")
        if f"{prefix}input_low" not in arrays:  # saved before bases were clipped: no box
            unbounded = np.full(weight.shape[0], np.inf)
            return cls(weight, get("b0"), -unbounded, unbounded)
        return cls(weight, get("b0"), get("input_low"), get("input_high"))
