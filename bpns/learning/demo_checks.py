"""Refuse demonstrations that would silently poison learning.

One NaN or inf in an action or a feature spreads through standardisation into every
weight of a network, and the skills are saved and load fine. Learning checks its input
first and names the demo and step, instead of writing NaN weights.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from bpns.structs import Demonstration


class DemonstrationError(ValueError):
    """Demonstrations that cannot be learned from (non-finite actions or features)."""


def check_demonstrations(demos: Sequence[Demonstration]) -> None:
    """Raise :class:`DemonstrationError` naming the first demo and step with a NaN/inf
    action or feature."""
    for i, demo in enumerate(demos):
        actions = np.asarray(demo.actions, dtype=np.float64)
        bad = np.argwhere(~np.isfinite(actions))
        if bad.size:
            raise DemonstrationError(
                f"demonstration {i}: action at step {int(bad[0][0])} holds NaN or inf"
            )
        for step, state in enumerate(demo.states):
            for obj, vec in state.data.items():
                if not np.all(np.isfinite(vec)):
                    raise DemonstrationError(
                        f"demonstration {i}: features of {obj.name} at step {step} hold NaN or inf"
                    )


# keys whose NaN encodes "None" in a saved skill (LearnedPolicy.to_arrays)
NAN_MEANS_NONE = frozenset({"near_scale"})


def check_finite_arrays(arrays: Mapping[str, np.ndarray], what: str) -> None:
    """Raise ValueError if any of ``arrays`` (a network's saved form) is not finite."""
    for key, value in arrays.items():
        a = np.asarray(value)
        if a.dtype.kind != "f":
            continue
        if key in NAN_MEANS_NONE:
            a = a[~np.isnan(a)]
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what}: array {key!r} holds NaN or inf")
