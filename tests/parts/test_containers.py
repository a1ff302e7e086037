"""Bins and shelves (mj_envs.parts.containers) in real MuJoCo physics.

Boxes are released above a container and fall under gravity (no teleporting): the bin
must catch one and keep it between its walls, touching its floor; one released beside
it lands on the table; a shelf's board holds one up. Scenes leave the robot out
(``robot=None``): an unactuated arm would sag through the workspace.
"""

from __future__ import annotations

import math
import re

import mujoco
import numpy as np
import pytest

from mj_envs.contacts import Contacts, body_geoms
from mj_envs.parts.containers import Bin, Shelf, add_bin, add_shelf
from mj_envs.parts.objects import add_free_box
from mj_envs.robots.panda import PANDA
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE, make_arena, to_xml

HALF = 0.0225  # the example's 4.5 cm cubes
BIN_XY = (0.5, 0.0)
SETTLE_S = 1.5
ON_BIN_FLOOR_Z = 0.01 + HALF + 0.001  # the default floor plate is 1 cm thick


def _scene(drops: dict[str, tuple[float, float, float]], shelf_support: str = "legs"):
    """An arena with a bin and a shelf, and one free cube per entry of ``drops``."""
    arena = make_arena("containers", robot=None)
    bin_ = add_bin(arena, "bin", *BIN_XY, inner_size=(0.12, 0.12), wall_height=0.05)
    shelf = add_shelf(arena, "shelf", 0.5, 0.3, (0.15, 0.15), 0.12, support=shelf_support)
    for name, pos in drops.items():
        add_free_box(arena.worldbody, name, pos, (HALF,) * 3, 0.1, (0.85, 0.25, 0.2, 1))
    model = mujoco.MjModel.from_xml_string(to_xml(arena))
    return model, mujoco.MjData(model), bin_, shelf


def _settle(model, data, seconds: float = SETTLE_S) -> None:
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)


def _touching(model, data, body: str, geom: str) -> bool:
    own = body_geoms(model, {}, body)
    return Contacts.read(data).touching(own, frozenset({model.geom(geom).id}))


def _at_rest(data, name: str) -> bool:
    return float(np.linalg.norm(data.joint(f"{name}_joint").qvel)) < 1e-3


def test_a_box_released_above_the_bin_comes_to_rest_inside_on_its_floor():
    model, data, bin_, _ = _scene({"cube": (0.51, 0.015, 0.05 + 0.04)})
    mujoco.mj_forward(model, data)
    assert not bin_.contains(data.geom("cube_geom").xpos)  # starts above the rim
    _settle(model, data)
    pos = data.geom("cube_geom").xpos
    assert bin_.contains(pos) and bin_.contains(pos, margin=HALF)
    assert _at_rest(data, "cube")
    assert _touching(model, data, "cube", bin_.floor_geom)
    assert not _touching(model, data, "cube", "table")
    assert pos[2] == pytest.approx(bin_.floor_z + HALF, abs=1e-3)


def test_a_box_released_beside_the_bin_lands_on_the_table_outside_it():
    model, data, bin_, _ = _scene({"cube": (0.6, 0.0, 0.05 + 0.04)})  # outer wall at x 0.57
    _settle(model, data)
    pos = data.geom("cube_geom").xpos
    assert not bin_.contains(pos)
    assert _touching(model, data, "cube", "table")
    assert not any(_touching(model, data, "cube", g) for g in (bin_.floor_geom, *bin_.wall_geoms))


def test_the_walls_keep_a_sliding_box_in_the_bin():
    model, data, bin_, _ = _scene({"cube": (0.5, 0.0, ON_BIN_FLOOR_Z)})
    adr = model.joint("cube_joint").dofadr[0]
    data.qvel[adr] = 1.0  # shoved toward the +x wall at 1 m/s (an initial condition)
    hit = False
    for _ in range(round(SETTLE_S / model.opt.timestep)):
        mujoco.mj_step(model, data)
        hit = hit or _touching(model, data, "cube", "bin_wall_xpos")
    assert hit
    assert bin_.contains(data.geom("cube_geom").xpos)


@pytest.mark.parametrize("support", ["legs", "back"])
def test_the_shelf_holds_a_box_on_top_and_not_one_beneath(support):
    drops = {"top": (0.5, 0.31, 0.12 + 0.05), "under": (0.5, 0.3, HALF + 0.001)}
    model, data, _, shelf = _scene(drops, shelf_support=support)
    _settle(model, data)
    top, under = data.geom("top_geom").xpos, data.geom("under_geom").xpos
    assert shelf.on_top(top) and _at_rest(data, "top")
    assert top[2] == pytest.approx(shelf.top_z + HALF, abs=1e-3)
    assert _touching(model, data, "top", shelf.board_geom)
    assert not shelf.on_top(under)
    assert _touching(model, data, "under", "table")


def test_settling_is_deterministic():
    runs = []
    for _ in range(2):
        model, data, _, _ = _scene({"cube": (0.51, 0.015, 0.09)})
        _settle(model, data, 0.5)
        runs.append(data.qpos.copy())
    np.testing.assert_array_equal(runs[0], runs[1])


def test_container_geoms_are_world_geometry_the_robot_collides_with():
    arena = make_arena("containers")  # with the Panda
    add_bin(arena, "bin", *BIN_XY, (0.12, 0.12))
    add_shelf(arena, "shelf", 0.5, 0.3, (0.15, 0.15), 0.12)
    model = mujoco.MjModel.from_xml_string(to_xml(arena))
    robot = [
        g
        for g in body_geoms(model, {}, PANDA.prefix)  # the attachment body: every link
        if model.geom_contype[g] or model.geom_conaffinity[g]
    ]
    assert robot
    for body in ("bin", "shelf"):
        assert model.body(body).weldid[0] == 0  # static: fixed to the world
        for g in body_geoms(model, {}, body):
            assert (model.geom_contype[g], model.geom_conaffinity[g]) == (
                OBJECT_CONTYPE,
                OBJECT_CONAFFINITY,
            )
            for r in robot:  # MuJoCo's filter: either geom's contype meets the other's affinity
                assert model.geom_contype[r] & model.geom_conaffinity[g] or (
                    model.geom_contype[g] & model.geom_conaffinity[r]
                )


def test_point_tests_are_geometry_only():
    b = Bin("b", (0.5, 0.0, 0.01), (0.06, 0.04), 0.01, 0.05, "b_floor", ("w",) * 4)
    assert b.contains((0.5, 0.0, 0.03))
    assert not b.contains((0.5, 0.05, 0.03))  # beyond the y wall
    assert not b.contains((0.5, 0.0, 0.06))  # above the rim
    assert not b.contains((0.5, 0.0, 0.005))  # below the floor's top
    assert not b.contains((0.55, 0.0, 0.03), margin=0.02)
    assert not b.contains((math.nan, 0.0, 0.03))
    s = Shelf("s", (0.5, 0.3, 0.12), (0.075, 0.075), 0.12, "s_board", ())
    assert s.on_top((0.5, 0.3, 0.14))
    assert not s.on_top((0.5, 0.3, 0.2))  # more than 5 cm above the board
    assert s.on_top((0.5, 0.3, 0.2), max_height=0.1)
    assert not s.on_top((0.5, 0.3, 0.1))  # under it


def _bin(**kw):
    args = {"name": "bin", "x": 0.5, "y": 0.0, "inner_size": (0.1, 0.1)} | kw
    return add_bin(make_arena("bad", robot=None), **args)


def _shelf(**kw):
    args = {"name": "shelf", "x": 0.5, "y": 0.0, "size": (0.1, 0.1), "height": 0.1} | kw
    return add_shelf(make_arena("bad", robot=None), **args)


@pytest.mark.parametrize(
    ("build", "kw", "named"),
    [
        (_bin, {"inner_size": (0.0, 0.1)}, "inner_size[0]"),
        (_bin, {"inner_size": (0.1, -0.2)}, "-0.2"),
        (_bin, {"inner_size": (0.1,)}, "inner_size"),
        (_bin, {"wall_height": math.nan}, "wall_height"),
        (_bin, {"wall_height": math.nan}, "nan"),
        (_bin, {"wall_thickness": 0}, "wall_thickness"),
        (_bin, {"wall_height": 0.01, "wall_thickness": 0.01}, "wall_height (0.01)"),
        (_bin, {"x": math.nan}, "x must be finite"),
        (_bin, {"surface_z": math.inf}, "surface_z"),
        (_bin, {"name": ""}, "name"),
        (_bin, {"rgba": (1, 0, 0)}, "rgba"),
        (_shelf, {"height": -0.1}, "height must be positive (m), got -0.1"),
        (_shelf, {"size": (0.1, math.nan)}, "size[1]"),
        (_shelf, {"height": 0.01}, "board_thickness"),
        (_shelf, {"support": "floating"}, "'floating'"),
        (_shelf, {"support_thickness": 0.06}, "support_thickness (0.06)"),
        (_shelf, {"y": "left"}, "'left'"),
    ],
)
def test_bad_arguments_raise_a_value_error_naming_them(build, kw, named):
    with pytest.raises(ValueError, match=re.escape(named)):
        build(**kw)
