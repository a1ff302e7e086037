"""Intervals spread along a span without rejection (Cover's longer line of blocks)."""

from __future__ import annotations

import numpy as np
import pytest

from mj_envs.parts.objects import spread_intervals


def test_intervals_that_nearly_fill_the_span_lie_inside_it_and_apart():
    halves = [0.05, 0.05, 0.05, 0.05, 0.06, 0.06, 0.06, 0.06]  # 0.88 m of 1.0 m, plus gaps
    for seed in range(20):
        centres = spread_intervals(np.random.default_rng(seed), halves, (-0.5, 0.5), 0.015)
        spans = sorted((c - h, c + h) for c, h in zip(centres, halves, strict=True))
        assert spans[0][0] >= -0.5 - 1e-12 and spans[-1][1] <= 0.5 + 1e-12
        assert all(b[0] - a[1] >= 0.015 - 1e-12 for a, b in zip(spans[:-1], spans[1:], strict=True))


def test_intervals_longer_than_the_span_are_refused():
    with pytest.raises(ValueError, match="more than the span holds"):
        spread_intervals(np.random.default_rng(0), [0.3, 0.3], (0.0, 1.0), 0.1)
