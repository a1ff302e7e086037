"""The mobile base's motion planner: a bidirectional RRT (RRT-Connect) in the plane.

Collision checks are 2D geometry derived from the compiled model, never the live MjData:
walls and obstacles are boxes (their geom pose and half extents), a closed door's leaf is
a box at its closed pose, and the base is a disc (pedestal radius + a margin). Walls stop
below the arm, so the disc is the only part of the robot that can collide. The planner is
deterministic given its inputs: the random numbers come from an explicit generator whose
seed the caller derives from the query (OMPL's RRTConnect was not used: its seed is
process-global, so two planners in one process would perturb each other).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from bpns.errors import BpnsError

CHECK_STEP = 0.02  # metres between collision checks along a segment


@dataclass(frozen=True)
class Boxes2D:
    """Oriented boxes in the plane: centres (N, 2), half extents (N, 2), yaw (N,)."""

    centres: np.ndarray
    halves: np.ndarray
    yaws: np.ndarray

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each point (M, 2) to the nearest box (0 inside)."""
        if len(self.centres) == 0:
            return np.full(len(points), np.inf)
        d = points[:, None, :] - self.centres[None, :, :]
        c, s = np.cos(self.yaws), np.sin(self.yaws)
        lx = d[..., 0] * c + d[..., 1] * s
        ly = -d[..., 0] * s + d[..., 1] * c
        ex = np.maximum(np.abs(lx) - self.halves[:, 0], 0.0)
        ey = np.maximum(np.abs(ly) - self.halves[:, 1], 0.0)
        return np.sqrt(ex * ex + ey * ey).min(axis=1)


def scene_boxes(model: mujoco.MjModel, closed_doors: frozenset[int]) -> Boxes2D:
    """Walls, obstacles and the leaves of ``closed_doors`` as boxes (from the model)."""
    centres, halves, yaws = [], [], []

    def add(pos, quat, size) -> None:
        centres.append(pos[:2])
        halves.append(size[:2])
        yaws.append(2.0 * math.atan2(quat[3], quat[0]))

    for g in range(model.ngeom):
        name = model.geom(g).name
        if name.startswith(("wall", "obstacle")):
            add(model.geom_pos[g], model.geom_quat[g], model.geom_size[g])
    for k in sorted(closed_doors):
        b = model.body(f"door{k}_leaf").id
        add(
            model.body_pos[b],
            model.body_quat[b],
            model.geom_size[model.geom(f"door{k}_leaf_geom").id],
        )
    return Boxes2D(
        np.array(centres, dtype=np.float64).reshape(-1, 2),
        np.array(halves, dtype=np.float64).reshape(-1, 2),
        np.array(yaws),
    )


@dataclass(frozen=True)
class PlannerConfig:
    clearance: float = 0.26  # disc radius: pedestal 0.22 + 4 cm margin
    step: float = 0.15  # RRT extension length
    max_iterations: int = 3000
    goal_bias: float = 0.1
    shortcut_rounds: int = 60


class NoPathFound(BpnsError, RuntimeError):
    """The planner found no collision-free path within its iteration budget."""


@dataclass(frozen=True)
class StartInCollision:
    """A start closer to a box than the clearance (the base pushed against a wall, or in
    a doorway beside a leaf the planner counts as closed), and how close: ``floor``.
    Within ``clearance`` of ``xy`` a point counts as free when it is no closer to a box
    than the start, so that the robot may leave where it stands without going deeper.
    Without it every edge from the start collides, and the planner spent its whole
    iteration budget (0.6-1.4 s) at every control step before giving up."""

    xy: np.ndarray
    floor: float


class BasePlanner:
    """Plans collision-free base paths among fixed boxes inside a rectangle."""

    def __init__(
        self,
        boxes: Boxes2D,
        low: np.ndarray,
        high: np.ndarray,
        config: PlannerConfig = PlannerConfig(),
    ) -> None:
        self.boxes, self.low, self.high, self.config = boxes, low, high, config

    def free(self, points: np.ndarray, escape: StartInCollision | None = None) -> np.ndarray:
        """Which ``points`` keep the clearance (or, near ``escape``'s start, go no deeper)."""
        points = np.atleast_2d(points)
        distance = self.boxes.distance(points)
        ok = distance > self.config.clearance
        if escape is not None:
            near = np.linalg.norm(points - escape.xy, axis=1) <= self.config.clearance
            ok |= near & (distance >= escape.floor)
        return ok

    def segment_free(
        self, a: np.ndarray, b: np.ndarray, escape: StartInCollision | None = None
    ) -> bool:
        n = max(2, int(math.ceil(float(np.linalg.norm(b - a)) / CHECK_STEP)) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        return bool(self.free(a[None] * (1 - t) + b[None] * t, escape).all())

    def start_in_collision(self, start: np.ndarray) -> StartInCollision | None:
        """``start``'s exemption (:class:`StartInCollision`), or None where it is free."""
        distance = float(self.boxes.distance(np.atleast_2d(start))[0])
        if distance > self.config.clearance:
            return None
        return StartInCollision(np.asarray(start, float), distance - 1e-9)

    def plan(
        self, start: np.ndarray, goal: np.ndarray, rng: np.random.Generator
    ) -> list[np.ndarray]:
        """A collision-free polyline start -> goal (the start itself may be too close to a
        box: it is where the robot is; :class:`StartInCollision`). Raises
        :class:`NoPathFound`."""
        start, goal = np.asarray(start, float), np.asarray(goal, float)
        if not self.free(goal)[0]:
            raise NoPathFound(f"the goal {goal.round(3).tolist()} is in collision")
        escape = self.start_in_collision(start)
        if self.segment_free(start, goal, escape):
            return [start, goal]
        path = self._rrt_connect(start, goal, rng, escape)
        return self._shortcut(path, rng, escape)

    def _rrt_connect(
        self, start, goal, rng, escape: StartInCollision | None = None
    ) -> list[np.ndarray]:
        cfg = self.config
        trees = [([start], [-1]), ([goal], [-1])]
        for it in range(cfg.max_iterations):
            a, b = trees[it % 2], trees[(it + 1) % 2]
            q = (
                goal
                if (it % 2 == 0 and rng.random() < cfg.goal_bias)
                else rng.uniform(self.low, self.high)
            )
            new = self._extend(a, q, escape)
            if new is None:
                continue
            # connect: grow the other tree towards the new node until blocked or joined
            while True:
                reached = self._extend(b, a[0][new], escape)
                if reached is None:
                    break
                if np.linalg.norm(b[0][reached] - a[0][new]) < 1e-9:
                    pa, pb = self._branch(a, new), self._branch(b, reached)
                    path = pa[::-1] + pb[1:]
                    return path if it % 2 == 0 else path[::-1]
        raise NoPathFound(f"no path from {start.round(3).tolist()} to {goal.round(3).tolist()}")

    def _extend(self, tree, q, escape: StartInCollision | None = None) -> int | None:
        nodes, parents = tree
        arr = np.asarray(nodes)
        i = int(np.argmin(((arr - q) ** 2).sum(axis=1)))
        d = q - arr[i]
        dist = float(np.linalg.norm(d))
        new = q if dist <= self.config.step else arr[i] + d * (self.config.step / dist)
        if not self.segment_free(arr[i], new, escape):
            return None
        nodes.append(np.asarray(new, float))
        parents.append(i)
        return len(nodes) - 1

    @staticmethod
    def _branch(tree, i: int) -> list[np.ndarray]:
        nodes, parents = tree
        out = []
        while i != -1:
            out.append(nodes[i])
            i = parents[i]
        return out  # node ... root

    def _shortcut(
        self, path: list[np.ndarray], rng, escape: StartInCollision | None = None
    ) -> list[np.ndarray]:
        path = list(path)
        for _ in range(self.config.shortcut_rounds):
            if len(path) < 3:
                break
            i, j = sorted(rng.choice(len(path), size=2, replace=False))
            if j - i > 1 and self.segment_free(path[i], path[j], escape):
                path = path[: i + 1] + path[j:]
        return path


def path_seed(*values: float) -> list[int]:
    """A seed derived from a query (millimetre-rounded numbers): same query, same path."""
    return [int(round(v * 1000)) & 0xFFFFFFFF for v in values]
