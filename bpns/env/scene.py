"""A rollout's 3D scene as plain arrays: what an environment shows of its states.

Recordings (``bpns view``) draw the scene's bodies at every control step without bpns
knowing the simulator: the environment answers ``Environment.scene(states)`` with a
:class:`SceneTrack` (static geometry per body, body poses per state, the robot's hand)
and says which features of each object type are 3D points (:class:`Anchor`), so that a
skill's subgoal, a vector of object features, can be drawn where it aims.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

#: the shapes a :class:`SceneGeom` can have (MuJoCo's primitive geoms and triangle meshes)
SHAPES = ("plane", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")


@dataclass(frozen=True, eq=False)
class SceneGeom:
    """One visible piece of a body. ``size`` follows MuJoCo's conventions: half extents
    (box, ellipsoid, plane), radius (sphere), radius and half length along z (capsule,
    cylinder); ``pos``/``quat`` (w, x, y, z) place it in its body's frame; a mesh has
    ``vertices`` (n, 3) in its own frame and ``faces`` (m, 3)."""

    name: str
    body: int  # index into SceneTrack.bodies
    shape: str
    size: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    vertices: np.ndarray | None = field(default=None, repr=False)
    faces: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"unknown geom shape {self.shape!r} (one of {', '.join(SHAPES)})")
        if self.shape == "mesh" and (self.vertices is None or self.faces is None):
            raise ValueError(f"mesh geom {self.name!r} needs vertices and faces")


@dataclass(frozen=True)
class Anchor:
    """A 3D point among a type's features: the indices of its x, y and z (None: on the
    table, z = 0), e.g. a block's centre or a stick's tip."""

    label: str
    x: int
    y: int
    z: int | None = None

    def point(self, features: np.ndarray) -> np.ndarray:
        z = 0.0 if self.z is None else float(features[self.z])
        return np.array([features[self.x], features[self.y], z], dtype=np.float64)


def anchors_by_name(feature_names: tuple[str, ...]) -> tuple[Anchor, ...]:
    """The points a type's feature names spell: each prefix ``p`` with features ``px``
    and ``py`` (and ``pz``, else on the table), e.g. ``x, y, z`` and ``tip_x, tip_y,
    tip_z``. The convention most environments follow; an environment may declare others."""
    index = {n: i for i, n in enumerate(feature_names)}
    out = []
    for name, i in index.items():
        if not name.endswith("x") or (prefix := name[:-1]) + "y" not in index:
            continue
        if prefix and not prefix.endswith("_"):
            continue
        out.append(
            Anchor(prefix.rstrip("_") or "centre", i, index[prefix + "y"], index.get(prefix + "z"))
        )
    return tuple(out)


@dataclass(frozen=True, eq=False)
class SceneTrack:
    """The scene of ``T`` states: its bodies' world poses per state, their geometry, the
    hand (the robot's grip point) per state, simulated time per state, and the 3D points
    among each object type's features (type name -> anchors)."""

    bodies: tuple[str, ...]
    geoms: tuple[SceneGeom, ...]
    positions: np.ndarray  # (T, len(bodies), 3), world frame
    quaternions: np.ndarray  # (T, len(bodies), 4), (w, x, y, z)
    hand: np.ndarray  # (T, 3)
    times: np.ndarray  # (T,) simulated seconds
    anchors: Mapping[str, tuple[Anchor, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t, n = len(self.times), len(self.bodies)
        if self.positions.shape != (t, n, 3) or self.quaternions.shape != (t, n, 4):
            raise ValueError(
                f"poses of shape {self.positions.shape} / {self.quaternions.shape} "
                f"for {t} states of {n} bodies"
            )
        if self.hand.shape != (t, 3):
            raise ValueError(f"hand positions of shape {self.hand.shape} for {t} states")
        if any(not 0 <= g.body < n for g in self.geoms):
            raise ValueError("a geom names a body the scene does not have")
        object.__setattr__(self, "anchors", MappingProxyType(dict(self.anchors)))

    def __len__(self) -> int:
        return len(self.times)
