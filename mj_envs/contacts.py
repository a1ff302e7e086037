"""Contacts as features: read MuJoCo's contact list once per state, then ask relations.

Predicates see only feature vectors, so a relation such as On(a, b) or Touching(a, b)
must first become a feature of ``a`` (e.g. ``touching_b``). :class:`Contacts` is the
contact list of one state as a set of geom pairs; :func:`relation_features` turns it into
one 0/1 feature per named partner, in the order the type declares them.

Ids are looked up once per compiled scene through the World's ``cache``
(:func:`geom_ids`, :func:`body_geoms`), never per step.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class Contacts:
    """Unordered geom-id pairs in contact (distance <= 0) in one simulator state."""

    pairs: frozenset[tuple[int, int]]

    @classmethod
    def read(cls, data: mujoco.MjData) -> Contacts:
        n = data.ncon
        if n == 0:
            return cls(frozenset())
        geoms, dist = data.contact.geom[:n], data.contact.dist[:n]
        return cls(
            frozenset(
                (int(min(a, b)), int(max(a, b)))
                for (a, b), x in zip(geoms, dist, strict=True)
                if x <= 0.0
            )
        )

    def touching(self, a: Collection[int] | int, b: Collection[int] | int) -> bool:
        """Whether any geom of ``a`` touches any geom of ``b``."""
        sa = {a} if isinstance(a, int) else a
        sb = {b} if isinstance(b, int) else b
        return any((x in sa and y in sb) or (x in sb and y in sa) for x, y in self.pairs)


def geom_ids(model: mujoco.MjModel, cache: dict, *names: str) -> tuple[int, ...]:
    """Ids of named geoms, looked up once per scene (``cache`` is ``World.cache``)."""
    table: dict[str, int] = cache.setdefault("geom_ids", {})
    out = []
    for name in names:
        g = table.get(name)
        if g is None:
            g = table[name] = model.geom(name).id
        out.append(g)
    return tuple(out)


def body_geoms(model: mujoco.MjModel, cache: dict, body: str) -> frozenset[int]:
    """Every geom of ``body`` and its descendants (e.g. a multi-geom object), cached."""
    table: dict[str, frozenset[int]] = cache.setdefault("body_geoms", {})
    found = table.get(body)
    if found is None:
        root = model.body(body).id
        bodies = {root}
        for b in range(root + 1, model.nbody):  # children follow their parent in MuJoCo
            if int(model.body_parentid[b]) in bodies:
                bodies.add(b)
        found = table[body] = frozenset(
            g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies
        )
    return found


def relation_features(
    contacts: Contacts, own: Collection[int], partners: Sequence[Collection[int]]
) -> np.ndarray:
    """1.0 where ``own`` touches partner k, else 0.0 (a partner equal to ``own`` is 0)."""
    return np.array(
        [float(p is not own and contacts.touching(own, p)) for p in partners], dtype=np.float64
    )
