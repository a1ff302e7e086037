"""Free rigid objects and where to put them: builders shared by the domains.

A free object is a body with a free joint and one collision geom, named ``name``,
``name_joint`` and ``name_geom`` (features read the geom, e.g. ``name_geom``'s position).
Its friction and ``condim`` 4 (torsional friction) let the finger pads hold it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from dm_control import mjcf

from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE

GRIPPABLE_FRICTION = (1.0, 0.02, 0.001)


def add_free_box(
    parent: mjcf.Element,
    name: str,
    pos: Sequence[float],
    half_size: Sequence[float],
    mass: float,
    rgba: Sequence[float],
    friction: Sequence[float] = GRIPPABLE_FRICTION,
) -> mjcf.Element:
    """A free box the robot can grasp; returns its body."""
    body = parent.add("body", name=name, pos=tuple(pos))
    body.add("freejoint", name=f"{name}_joint")
    body.add(
        "geom",
        name=f"{name}_geom",
        type="box",
        size=tuple(half_size),
        mass=mass,
        rgba=tuple(rgba),
        contype=OBJECT_CONTYPE,
        conaffinity=OBJECT_CONAFFINITY,
        friction=tuple(friction),
        condim=4,
    )
    return body


def sample_disjoint_intervals(
    rng: np.random.Generator,
    halves: Sequence[float],
    span: tuple[float, float],
    gap: float,
    tries: int = 10_000,
) -> list[float]:
    """Centres for intervals of the given half-widths inside ``span``, pairwise apart by
    at least ``gap`` (rejection sampling; raises if the span is too tight)."""
    for _ in range(tries):
        centres = [rng.uniform(span[0] + h, span[1] - h) for h in halves]
        if all(
            abs(centres[i] - centres[j]) >= halves[i] + halves[j] + gap
            for i in range(len(halves))
            for j in range(i + 1, len(halves))
        ):
            return centres
    raise RuntimeError("could not place the objects without overlap; widen the span")


def spread_intervals(
    rng: np.random.Generator,
    halves: Sequence[float],
    span: tuple[float, float],
    gap: float,
) -> list[float]:
    """Centres for intervals of the given half-widths inside ``span``, pairwise apart by
    at least ``gap``, drawn without rejection: a random order along the span and the free
    length split at sorted uniform points. Every order's slack is a simplex of the same
    volume, so this is the uniform distribution rejection sampling aims at, and it never
    spins when the intervals nearly fill the span (raises if they do not fit at all)."""
    k = len(halves)
    free = span[1] - span[0] - 2 * sum(halves) - gap * max(0, k - 1)
    if free < 0:
        raise ValueError(f"{k} intervals need {free:.3f} m more than the span holds")
    order = rng.permutation(k)
    cuts = np.sort(rng.uniform(0.0, free, size=k))
    centres = [0.0] * k
    lo = span[0]
    for pos, (i, cut) in enumerate(zip(order, cuts, strict=True)):
        start = lo + cut + pos * gap + sum(2 * halves[j] for j in order[:pos])
        centres[int(i)] = float(start + halves[int(i)])
    return centres


def sample_separated_points(
    rng: np.random.Generator,
    n: int,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    min_distance: float,
    tries: int = 10_000,
) -> np.ndarray:
    """``n`` (x, y) points in the rectangle, pairwise at least ``min_distance`` apart.

    Choose ``min_distance`` from the largest footprint plus the hand's clearance: the
    Panda's hand box reaches 10 cm either way along the finger axis, so objects a grasp
    must not disturb belong further apart than that (rejection sampling; raises if the
    rectangle is too small).
    """
    for _ in range(tries):
        pts = np.column_stack([rng.uniform(*x_range, size=n), rng.uniform(*y_range, size=n)])
        diff = pts[:, None, :] - pts[None, :, :]
        dist = np.hypot(diff[..., 0], diff[..., 1]) + np.eye(n) * 1e9
        if n < 2 or dist.min() >= min_distance:
            return pts
    raise RuntimeError(f"could not place {n} objects {min_distance} m apart; widen the ranges")
