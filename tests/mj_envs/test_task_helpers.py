"""The helpers a new task is built from: contact relations, placement, derived defaults."""

from __future__ import annotations

import numpy as np
import pytest

from mj_envs.base import MujocoEnv
from mj_envs.contacts import Contacts, body_geoms, geom_ids, relation_features
from mj_envs.domains.cover.env import CoverEnv
from mj_envs.parts.objects import sample_separated_points


def test_separated_points_keep_their_distance_inside_the_rectangle():
    rng = np.random.default_rng(0)
    for _ in range(20):
        pts = sample_separated_points(rng, 3, (0.4, 0.6), (-0.2, 0.2), 0.13)
        assert np.all((pts[:, 0] >= 0.4) & (pts[:, 0] <= 0.6))
        d = [np.hypot(*(pts[i] - pts[j])) for i in range(3) for j in range(i + 1, 3)]
        assert min(d) >= 0.13


def test_separated_points_say_when_the_rectangle_is_too_small():
    with pytest.raises(RuntimeError, match="widen the ranges"):
        sample_separated_points(np.random.default_rng(0), 4, (0, 0.1), (0, 0.1), 0.2, tries=50)


def test_contacts_give_relations_between_named_bodies(cover_env):
    task = cover_env.task(0, 7, True)
    world = task.init.sim.world
    world.load(task.init.sim.flat)
    m = world.model
    contacts = Contacts.read(world.data)
    (table,) = geom_ids(m, world.cache, "table")
    blocks = [body_geoms(m, world.cache, f"block{i}") for i in range(2)]
    assert blocks[0] == frozenset({m.geom("block0_geom").id})
    assert contacts.touching(blocks[0], table) and contacts.touching(table, blocks[1])
    assert not contacts.touching(blocks[0], blocks[1])
    assert relation_features(contacts, blocks[0], blocks).tolist() == [0.0, 0.0]


def test_max_objects_default_matches_covers_declared_bound():
    derived = MujocoEnv.max_objects.fget(CoverEnv())
    assert derived == CoverEnv().max_objects
