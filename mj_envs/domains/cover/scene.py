"""Cover's task scenes: blocks, target pads and allowed regions on a line across the table."""

from __future__ import annotations

import numpy as np

from bpns.structs import GroundAtom, Object
from mj_envs.base import TaskLayout
from mj_envs.domains.cover.rules import (
    BLOCK,
    BLOCK_DEPTH,
    BLOCK_HEIGHT,
    BLOCK_MASS,
    BLOCK_WIDTH_RANGE,
    COVERS,
    HORIZON,
    LINE_X,
    N_BLOCKS,
    REGION,
    REGION_X_HALF,
    ROBOT,
    TARGET,
    TARGET_REGION_HALF,
    TARGET_WIDTH_RANGE,
    WIDE_Y_RANGE,
    Y_RANGE,
)
from mj_envs.parts.objects import add_free_box, sample_disjoint_intervals, spread_intervals
from mj_envs.scene import make_arena, to_xml

BLOCK_COLOURS = [(0.85, 0.25, 0.2, 1), (0.2, 0.4, 0.85, 1)]


def sample_layout(
    rng: np.random.Generator, train: bool, blocks: tuple[int, int] | None = None
) -> TaskLayout:
    """Two blocks and two targets at random disjoint spans; goal: one or two Covers.

    ``blocks``: (lo, hi) blocks (and as many targets) instead, for eval tasks beyond the
    paper's; up to two they lie on the paper's line and draw as it does."""
    n = N_BLOCKS if blocks is None else _count(rng, blocks)
    widths = rng.uniform(*BLOCK_WIDTH_RANGE, size=n)
    twidths = rng.uniform(*TARGET_WIDTH_RANGE, size=n)
    # Spans that must not overlap: each block, and each target's landing zone.
    landing = BLOCK_WIDTH_RANGE[1] / 2 + 0.01
    halves = [w / 2 for w in widths] + [landing] * n
    if n <= N_BLOCKS:
        centres = sample_disjoint_intervals(rng, halves, Y_RANGE, gap=0.015)
    else:
        centres = spread_intervals(rng, halves, WIDE_Y_RANGE, gap=0.015)
    bys, tys = centres[:n], centres[n:]

    arena = make_arena("cover")
    wb = arena.worldbody
    region_spans = [(by - w / 2, by + w / 2) for by, w in zip(bys, widths, strict=True)]
    region_spans += [(ty - TARGET_REGION_HALF, ty + TARGET_REGION_HALF) for ty in tys]
    for i, (lo, hi) in enumerate(region_spans):
        wb.add(
            "geom",
            name=f"region{i}",
            type="box",
            contype=0,
            conaffinity=0,
            size=(REGION_X_HALF, (hi - lo) / 2, 0.0004),
            pos=(LINE_X, (lo + hi) / 2, 0.0004),
            rgba=(0.95, 0.85, 0.2, 0.45),
        )
    for i, (ty, tw) in enumerate(zip(tys, twidths, strict=True)):
        wb.add(
            "geom",
            name=f"target{i}",
            type="box",
            contype=0,
            conaffinity=0,
            size=(0.03, tw / 2, 0.0008),
            pos=(LINE_X, ty, 0.0008),
            rgba=(0.2, 0.75, 0.3, 1),
        )
    for i, (by, w) in enumerate(zip(bys, widths, strict=True)):
        add_free_box(
            wb,
            f"block{i}",
            pos=(LINE_X, by, BLOCK_HEIGHT / 2),
            half_size=(BLOCK_DEPTH / 2, w / 2, BLOCK_HEIGHT / 2),
            mass=BLOCK_MASS,
            rgba=BLOCK_COLOURS[i % 2],
        )

    robot = Object("robot", ROBOT)
    block_objs = [Object(f"block{i}", BLOCK) for i in range(n)]
    targets = [Object(f"target{i}", TARGET) for i in range(n)]
    regions = [Object(f"region{i}", REGION) for i in range(len(region_spans))]
    n_goal = int(rng.integers(1, n + 1))
    perm = rng.permutation(n)
    chosen = rng.choice(n, size=n_goal, replace=False)
    goal = frozenset(GroundAtom(COVERS, (block_objs[b], targets[perm[b]])) for b in chosen)
    return TaskLayout(
        xml=to_xml(arena),
        objects=(robot, *block_objs, *targets, *regions),
        goal=goal,
        horizon=HORIZON * max(n, N_BLOCKS) // N_BLOCKS,
    )


def _count(rng: np.random.Generator, counts: tuple[int, int]) -> int:
    """A count in ``counts`` (inclusive); a single count draws nothing, so that
    ``block=2`` draws the paper's tasks."""
    lo, hi = counts
    return lo if lo == hi else int(rng.integers(lo, hi + 1))
