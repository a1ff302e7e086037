"""Refuse demonstrations that would silently poison learning.

One NaN or inf in an action or a feature spreads through standardisation into every
weight of a network, and the skills are saved and load fine. Learning checks its input
first and names the demo and step, instead of writing NaN weights.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from bpns.errors import BpnsError
from bpns.structs import Demonstration

#: the largest magnitude accepted in an action or feature: far beyond any physical
#: quantity in metres, radians or newtons, and far below where float32 training (whose
#: losses square these) overflows; 1e300 is finite but would poison the networks
MAX_MAGNITUDE = 1e9


class DemonstrationError(BpnsError, ValueError):
    """Demonstrations that cannot be learned from (non-finite actions or features)."""


def check_demonstrations(demos: Sequence[Demonstration]) -> None:
    """Raise :class:`DemonstrationError` naming the first demo and step with a NaN/inf
    or absurdly large (> MAX_MAGNITUDE) action or feature."""
    for i, demo in enumerate(demos):
        actions = np.asarray(demo.actions, dtype=np.float64)
        step = _first_bad_row(actions)
        if step is not None:
            raise DemonstrationError(
                f"demonstration {i}: action at step {step} {_why(actions[step])}"
            )
        for obj in demo.states[0].data:
            rows = np.stack([state.data[obj] for state in demo.states])
            step = _first_bad_row(rows)
            if step is not None:
                raise DemonstrationError(
                    f"demonstration {i}: features of {obj.name} at step {step} "
                    + _why(rows[step]).replace("holds", "hold", 1)
                )


def _first_bad_row(rows: np.ndarray) -> int | None:
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(rows) <= MAX_MAGNITUDE)  # NaN compares False
    if not bad.any():
        return None
    return int(np.argwhere(bad)[0][0])


def _why(row: np.ndarray) -> str:
    if not np.all(np.isfinite(row)):
        return "holds NaN or inf"
    return (
        f"holds {float(np.max(np.abs(row))):.3g}, beyond the {MAX_MAGNITUDE:.0e} a "
        "demonstration can hold (float32 training would overflow)"
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
