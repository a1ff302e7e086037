r"""Confidence intervals of success rates.

The Wilson score interval of k successes in n trials at confidence z (1.96: 95 %),

.. math::

    \frac{\hat p + \frac{z^2}{2n} \pm z\sqrt{\frac{\hat p(1-\hat p)}{n}
    + \frac{z^2}{4n^2}}}{1 + \frac{z^2}{n}}, \qquad \hat p = k / n,

stays inside [0, 1] and is honest at 0 % and 100 % (the normal approximation there
claims no uncertainty at all), which is where robustness results often sit.
"""

from __future__ import annotations

import math


def wilson_interval(successes: int, trials: int, z: float = 1.96) -> tuple[float, float]:
    """(low, high) of the success probability, as fractions; (0, 1) without trials."""
    if trials <= 0:
        return 0.0, 1.0
    if not 0 <= successes <= trials:
        raise ValueError(f"successes must be in [0, {trials}], got {successes}")
    p = successes / trials
    z2 = z * z
    centre = p + z2 / (2 * trials)
    spread = z * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials))
    scale = 1 + z2 / trials
    return max(0.0, (centre - spread) / scale), min(1.0, (centre + spread) / scale)


def wilson_text(successes: int, trials: int) -> str:
    """``92.0 % [81.2, 96.8]``: the rate and its 95 % Wilson interval, in percent."""
    low, high = wilson_interval(successes, trials)
    rate = 100.0 * successes / trials if trials else float("nan")
    return f"{rate:.1f} % [{100 * low:.1f}, {100 * high:.1f}]"
