"""Drawers and hinged doors (mj_envs.parts.articulated) in real MuJoCo physics.

Every motion here is physics: a force applied at the handle (``mj_applyFT`` into
``qfrc_applied``, the way a hand pulling there acts on the part) opens or closes the part
against its damping, and its joint limits stop it. The only state set by hand is the
initial one. Scenes leave the robot out (``robot=None``): an unactuated arm would sag
through the workspace.
"""

from __future__ import annotations

import math
import re

import mujoco
import numpy as np
import pytest

from mj_envs.contacts import Contacts, body_geoms
from mj_envs.parts.articulated import (
    PART_GAP,
    Drawer,
    add_drawer,
    add_hinged_door,
    drawer_ids,
    handle_xyz,
    hinged_door_ids,
    is_open,
    open_fraction,
    opening,
)
from mj_envs.parts.objects import add_free_box
from mj_envs.robots.panda import PANDA
from mj_envs.scene import OBJECT_CONAFFINITY, OBJECT_CONTYPE, make_arena, to_xml

HALF = 0.0225  # the example's 4.5 cm cubes
SIZE, TRAVEL = (0.3, 0.3, 0.12), 0.2
PULL = 3.0  # N at the handle: against 10 N s/m of damping the drawer comes out at 0.3 m/s
# how far a part may pass its soft joint limit when it runs into it (a drawer at 0.3 m/s,
# a door at 1.5 rad/s) or is pressed against it
LIMIT_TOL, ANGLE_TOL = 0.002, 0.01  # m, rad


def _drawer_scene(box: bool = False, **kw):
    arena = make_arena("drawer", robot=None)
    drawer = add_drawer(arena, "cab", 0.6, 0.0, SIZE, TRAVEL, **kw)
    if box:
        cx, cy, floor_z = drawer.floor_centre
        add_free_box(
            arena.worldbody, "box", (cx, cy, floor_z + HALF + 0.001), (HALF,) * 3, 0.1, (1, 0, 0, 1)
        )
    model = mujoco.MjModel.from_xml_string(to_xml(arena))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, drawer, drawer_ids(model, "cab")


def _door_scene(side: str = "right", **kw):
    arena = make_arena("door", robot=None)
    door = add_hinged_door(arena, "cup", 0.6, 0.0, 0.3, 0.3, side, **kw)
    model = mujoco.MjModel.from_xml_string(to_xml(arena))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, door, hinged_door_ids(model, "cup")


def _along_x(newtons: float):
    return lambda data, ids: np.array([newtons, 0.0, 0.0])


def _off_the_panel(newtons: float):
    """A force perpendicular to the door panel, pulling its front face away from the
    cabinet (the door body's -x axis)."""
    return lambda data, ids: -newtons * data.xmat[ids.body].reshape(3, 3)[:, 0]


def _run(model, data, ids, force, seconds: float) -> np.ndarray:
    """Step for ``seconds`` with ``force(data, ids)`` (world frame, N; None: released)
    applied at the handle's current position; returns the opening after each step."""
    out = []
    for _ in range(round(seconds / model.opt.timestep)):
        data.qfrc_applied[:] = 0.0
        if force is not None:
            point = handle_xyz(data, ids)
            f = force(data, ids)
            mujoco.mj_applyFT(model, data, f, np.zeros(3), point, ids.body, data.qfrc_applied)
        mujoco.mj_step(model, data)
        out.append(opening(data, ids))
    return np.array(out)


def _rotate_z(v, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


def test_the_description_matches_the_compiled_drawer():
    model, data, drawer, ids = _drawer_scene()
    assert opening(data, ids) == 0.0 and open_fraction(data, ids) == 0.0
    assert not is_open(data, ids)
    assert ids.limit == pytest.approx(TRAVEL, abs=1e-12)
    np.testing.assert_allclose(handle_xyz(data, ids), drawer.handle_closed, atol=1e-12)
    front = data.geom("cab_drawer_front")
    assert front.xpos[0] - model.geom("cab_drawer_front").size[0] == pytest.approx(
        drawer.front_x, abs=1e-12
    )  # flush with the carcass front
    bar_back = drawer.handle_closed[0] + model.geom(drawer.handle_geom).size[0]
    assert drawer.front_x - bar_back == pytest.approx(0.035, abs=1e-12)  # the clearance
    floor = data.geom("cab_drawer_floor")
    assert floor.xpos[2] + model.geom("cab_drawer_floor").size[2] == pytest.approx(
        drawer.floor_z, abs=1e-12
    )
    assert drawer.contains(drawer.floor_centre[:2] + (drawer.floor_z + HALF,), margin=HALF)
    assert model.body_mass[ids.body] == pytest.approx(0.5)
    for geom in (*drawer.carcass_geoms, *drawer.drawer_geoms, drawer.handle_geom):
        model.geom(geom)  # every named geom exists


def test_pulling_the_handle_opens_the_drawer_to_its_travel_then_it_stays_and_pushing_closes_it():
    model, data, drawer, ids = _drawer_scene()
    carcass = [model.geom(g).id for g in drawer.carcass_geoms]
    carcass_xpos = data.geom_xpos[carcass].copy()
    pulled = _run(model, data, ids, _along_x(-PULL), 1.2)  # towards the robot
    assert pulled[0] > 0.0 and np.all(np.diff(pulled[: np.argmax(pulled)]) > 0)
    assert pulled.max() <= TRAVEL + LIMIT_TOL  # the joint limit stops it
    assert pulled[-1] == pytest.approx(TRAVEL, abs=5e-4)
    assert is_open(data, ids) and open_fraction(data, ids) == 1.0
    released = _run(model, data, ids, None, 1.0)
    assert np.all((released > TRAVEL - LIMIT_TOL) & (released <= TRAVEL + LIMIT_TOL))
    assert np.all(np.diff(released) <= 0.0)  # eases off the soft limit; no bounce
    assert abs(data.qvel[ids.dof]) < 1e-6  # damped to rest, no spring pulling it back
    pushed = _run(model, data, ids, _along_x(PULL), 1.2)
    assert pushed.min() >= -LIMIT_TOL and pushed[-1] == pytest.approx(0.0, abs=5e-4)
    assert not is_open(data, ids)
    assert model.body(drawer.carcass_body).weldid[0] == 0  # static: fixed to the world
    np.testing.assert_array_equal(data.geom_xpos[carcass], carcass_xpos)


def test_a_box_in_the_drawer_rides_out_with_it():
    model, data, drawer, ids = _drawer_scene(box=True)
    _run(model, data, ids, None, 0.3)  # the box settles on the drawer's floor
    start = data.geom("box_geom").xpos.copy()
    _run(model, data, ids, _along_x(-PULL), 1.2)
    _run(model, data, ids, None, 0.3)
    mujoco.mj_forward(model, data)
    now, out = data.geom("box_geom").xpos.copy(), opening(data, ids)
    assert out == pytest.approx(TRAVEL, abs=LIMIT_TOL)
    assert now[0] - start[0] == pytest.approx(-out, abs=0.01)  # moved out by the opening
    assert now[1:] == pytest.approx(start[1:], abs=1e-3)
    assert drawer.contains(now, opening=out, margin=HALF)
    assert not drawer.contains(now)  # where the closed drawer's inside was
    floor = frozenset({model.geom("cab_drawer_floor").id})
    assert Contacts.read(data).touching(body_geoms(model, {}, "box"), floor)


@pytest.mark.parametrize(("side", "max_angle"), [("right", math.pi / 2), ("left", 1.0)])
def test_the_hinged_door_swings_open_under_a_force_at_its_handle_and_stops_at_its_range(
    side, max_angle
):
    model, data, door, ids = _door_scene(side, max_angle=max_angle)
    assert ids.limit == pytest.approx(max_angle, abs=1e-12)  # radians, not degrees
    np.testing.assert_allclose(handle_xyz(data, ids), door.handle_closed, atol=1e-12)
    np.testing.assert_allclose(data.joint("cup_hinge").xanchor, door.hinge_xyz, atol=1e-12)
    np.testing.assert_allclose(data.joint("cup_hinge").xaxis, door.hinge_axis, atol=1e-12)
    carcass = [model.geom(g).id for g in door.carcass_geoms]
    carcass_xpos = data.geom_xpos[carcass].copy()
    swung = _run(model, data, ids, _off_the_panel(PULL), 1.5)
    assert swung.max() <= max_angle + ANGLE_TOL
    assert swung[-1] == pytest.approx(max_angle, abs=1e-3)
    assert is_open(data, ids)
    released = _run(model, data, ids, None, 1.0)
    assert np.all((released > max_angle - ANGLE_TOL) & (released <= max_angle + ANGLE_TOL))
    assert abs(data.qvel[ids.dof]) < 1e-6
    mujoco.mj_forward(model, data)
    hinge, handle = np.array(door.hinge_xyz), handle_xyz(data, ids)
    turn = opening(data, ids) * door.hinge_axis[2]  # the axis is +z or -z
    np.testing.assert_allclose(
        handle, hinge + _rotate_z(np.subtract(door.handle_closed, hinge), turn), atol=1e-9
    )
    assert handle[0] < door.handle_closed[0] - 0.1  # swung out towards the robot
    np.testing.assert_array_equal(data.geom_xpos[carcass], carcass_xpos)
    assert model.body(door.carcass_body).weldid[0] == 0
    shut = _run(model, data, ids, _off_the_panel(-PULL), 1.5)
    assert shut.min() >= -ANGLE_TOL and shut[-1] == pytest.approx(0.0, abs=1e-3)


def test_a_hinge_side_is_the_robots_left_or_right():
    _, _, right, _ = _door_scene("right")
    _, _, left, _ = _door_scene("left")
    assert right.hinge_xyz[1] < 0.0 < right.handle_closed[1]  # hinge on -y, handle on +y
    assert left.handle_closed[1] < 0.0 < left.hinge_xyz[1]
    assert right.hinge_axis == (0.0, 0.0, 1.0) and left.hinge_axis == (0.0, 0.0, -1.0)


@pytest.mark.parametrize("part", ["drawer", "door"])
def test_open_fraction_and_is_open_flip_exactly_when_the_joint_passes_the_threshold(part):
    if part == "drawer":
        model, data, _, ids = _drawer_scene()
        force = _along_x(-PULL)
    else:
        model, data, _, ids = _door_scene()
        force = _off_the_panel(PULL)
    readings = []
    for _ in range(750):
        _run(model, data, ids, force, model.opt.timestep)
        q = opening(data, ids)
        readings.append((q, open_fraction(data, ids), is_open(data, ids), is_open(data, ids, 0.5)))
    qs = np.array([r[0] for r in readings])
    assert qs.max() >= ids.limit * 0.99  # the run reaches the stop
    for q, frac, flag, half in readings:
        assert frac == min(1.0, max(0.0, q / ids.limit)) and 0.0 <= frac <= 1.0
        assert flag == (q / ids.limit >= 0.8) and half == (q / ids.limit >= 0.5)
    flags = [r[2] for r in readings]
    k = flags.index(True)
    assert not any(flags[:k]) and all(flags[k:])  # one flip, and it stays open
    assert qs[k - 1] / ids.limit < 0.8 <= qs[k] / ids.limit
    with pytest.raises(ValueError, match=re.escape("got 0.0")):
        is_open(data, ids, 0.0)
    with pytest.raises(ValueError, match="nan"):
        is_open(data, ids, math.nan)


def test_the_same_run_twice_is_bit_identical():
    runs = []
    for _ in range(2):
        model, data, _, ids = _drawer_scene(box=True)
        _run(model, data, ids, _along_x(-PULL), 0.8)
        door_model, door_data, _, door_ids = _door_scene("left")
        _run(door_model, door_data, door_ids, _off_the_panel(PULL), 0.5)
        runs.append((data.qpos.copy(), data.qvel.copy(), door_data.qpos.copy()))
    for a, b in zip(runs[0], runs[1], strict=True):
        np.testing.assert_array_equal(a, b)


def test_parts_are_world_geometry_the_robot_collides_with():
    arena = make_arena("articulated")  # with the Panda: its MJCF sets radians
    add_drawer(arena, "cab", 0.6, -0.2, SIZE, TRAVEL)
    add_hinged_door(arena, "cup", 0.6, 0.25, 0.3, 0.3, "left", max_angle=2.0)
    model = mujoco.MjModel.from_xml_string(to_xml(arena))
    assert hinged_door_ids(model, "cup").limit == pytest.approx(2.0)
    assert drawer_ids(model, "cab").limit == pytest.approx(TRAVEL)
    robot = [
        g
        for g in body_geoms(model, {}, PANDA.prefix)
        if model.geom_contype[g] or model.geom_conaffinity[g]
    ]
    assert robot
    for carcass, moving in (("cab", "cab_drawer"), ("cup", "cup_door")):
        assert model.body(carcass).weldid[0] == 0
        assert model.body(moving).dofnum[0] == 1  # one joint
        for g in body_geoms(model, {}, carcass):  # the moving part's geoms included
            assert (model.geom_contype[g], model.geom_conaffinity[g]) == (
                OBJECT_CONTYPE,
                OBJECT_CONAFFINITY,
            )
            for r in robot:
                assert model.geom_contype[r] & model.geom_conaffinity[g] or (
                    model.geom_contype[g] & model.geom_conaffinity[r]
                )


def test_the_drawer_point_test_follows_the_opening():
    d = Drawer(
        name="d",
        joint="d_slide",
        carcass_body="d",
        drawer_body="d_drawer",
        handle_geom="d_handle",
        handle_post_geoms=("d_handle_post0", "d_handle_post1"),
        carcass_geoms=(),
        drawer_geoms=("f",) * 5,
        travel=0.2,
        handle_closed=(0.4, 0.0, 0.06),
        front_x=0.45,
        floor_centre=(0.6, 0.0, 0.02),
        inner_half=(0.1, 0.1),
        floor_z=0.02,
        rim_z=0.1,
    )
    assert d.contains((0.6, 0.0, 0.05))
    assert not d.contains((0.6, 0.0, 0.05), opening=0.15)  # the drawer has moved away
    assert d.contains((0.45, 0.0, 0.05), opening=0.15)
    assert not d.contains((0.6, 0.0, 0.11))  # above the rim
    assert not d.contains((0.6, 0.0, 0.01))  # below the floor's top
    assert not d.contains((0.6, 0.095, 0.05), margin=0.01)
    assert not d.contains((math.nan, 0.0, 0.05))


def _drawer(**kw):
    args = {"name": "cab", "x": 0.6, "y": 0.0, "size": SIZE, "travel": TRAVEL} | kw
    return add_drawer(make_arena("bad", robot=None), **args)


def _door(**kw):
    args = {"name": "cup", "x": 0.6, "y": 0.0, "width": 0.3, "height": 0.3} | kw
    args.setdefault("hinge_side", "right")
    return add_hinged_door(make_arena("bad", robot=None), **args)


@pytest.mark.parametrize(
    ("build", "kw", "named"),
    [
        (_drawer, {"size": (0.3, 0.0, 0.12)}, "size[1] must be positive (m), got 0.0"),
        (_drawer, {"size": (0.3, 0.3)}, "size must be three lengths"),
        (_drawer, {"size": (0.3, 0.3, math.nan)}, "size[2] must be finite (m), got nan"),
        (_drawer, {"size": (0.03, 0.3, 0.12)}, "leaves no inside"),
        (_drawer, {"travel": -0.1}, "travel must be positive (m), got -0.1"),
        (_drawer, {"travel": math.nan}, "travel must be finite"),
        (_drawer, {"travel": 0.3}, "travel (0.3) exceeds the drawer's depth"),
        (_drawer, {"x": math.inf}, "x must be finite"),
        (_drawer, {"y": "left"}, "'left'"),
        (_drawer, {"damping": -1.0}, "damping must not be negative (N s/m), got -1.0"),
        (_drawer, {"mass": 0}, "mass must be positive (kg)"),
        (_drawer, {"handle_length": 0.5}, "handle_length (0.5)"),
        (_drawer, {"handle_clearance": 0.0}, "handle_clearance"),
        (_drawer, {"handle_radius": 0.06}, "handle_radius (0.06)"),
        (_drawer, {"wall_thickness": -0.01}, "wall_thickness"),
        (_drawer, {"name": ""}, "name"),
        (_drawer, {"rgba": (1, 0, 0)}, "rgba"),
        (_door, {"hinge_side": "top"}, "hinge_side must be 'left' or 'right', got 'top'"),
        (_door, {"width": 0.0}, "width must be positive (m), got 0.0"),
        (_door, {"height": math.nan}, "height must be finite (m), got nan"),
        (_door, {"depth": -0.2}, "depth"),
        (_door, {"max_angle": 4.0}, "max_angle must be at most pi (rad), got 4.0"),
        (_door, {"max_angle": 0.0}, "max_angle must be positive (rad)"),
        (_door, {"damping": math.inf}, "damping must be finite (N m s/rad)"),
        (_door, {"handle_inset": 0.2}, "handle_inset (0.2)"),
        (_door, {"handle_length": 0.01}, "handle_length (0.01)"),
        (_door, {"wall_thickness": 0.2}, "leave no inside"),
        (_door, {"door_rgba": (0, 0, 0, 2)}, "rgba"),
    ],
)
def test_bad_arguments_raise_a_value_error_naming_them(build, kw, named):
    with pytest.raises(ValueError, match=re.escape(named)):
        build(**kw)


def _clearance(model, data, a, b) -> float:
    """The least distance between any geom of ``a`` and any of ``b`` (contacts between
    them are excluded, so measure it)."""
    return min(mujoco.mj_geomDistance(model, data, i, j, 1.0, None) for i in a for j in b)


def test_the_moving_parts_stay_clear_of_their_carcass_closed_and_open():
    model, data, drawer, ids = _drawer_scene()
    moving = body_geoms(model, {}, drawer.drawer_body)
    carcass = [model.geom(g).id for g in drawer.carcass_geoms]
    assert _clearance(model, data, moving, carcass) == pytest.approx(PART_GAP, abs=1e-9)
    _run(model, data, ids, _along_x(-PULL), 1.2)
    mujoco.mj_forward(model, data)
    assert _clearance(model, data, moving, carcass) == pytest.approx(PART_GAP, abs=1e-9)
    model, data, door, ids = _door_scene()
    moving = body_geoms(model, {}, door.door_body)
    carcass = [model.geom(g).id for g in door.carcass_geoms]
    assert _clearance(model, data, moving, carcass) >= PART_GAP - 1e-9
    _run(model, data, ids, _off_the_panel(PULL), 1.5)
    mujoco.mj_forward(model, data)
    assert _clearance(model, data, moving, carcass) >= PART_GAP - 1e-9
