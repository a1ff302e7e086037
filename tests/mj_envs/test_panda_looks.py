"""The Panda's link meshes are looks only: drawn in frames, never in the simulated scene."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from bpns.env.registry import make_environment
from mj_envs.robots import panda_looks
from mj_envs.robots.panda import ik_model
from mj_envs.robots.panda_looks import (
    HIDDEN_COLLISION_GROUP,
    LINK_MESHES,
    VISUAL_GROUP,
    dressed_model,
)
from mj_envs.world import STATE_SPEC

DOMAINS = ("cover", "stick_button", "coffee")


@pytest.fixture
def no_mesh_package(monkeypatch):
    """Pretend gymnasium-robotics is not installed (the cached meshes are dropped)."""
    panda_looks.franka_meshes.cache_clear()
    monkeypatch.setattr(panda_looks, "franka_mesh_dir", lambda: None)
    yield
    monkeypatch.undo()
    panda_looks.franka_meshes.cache_clear()


@pytest.mark.parametrize("name", DOMAINS)
def test_render_model_adds_visual_only_meshes_and_keeps_the_state_layout(name):
    world = make_environment(name).task(0, 3, True).init.sim.world
    assert world.model.nmesh == 0 and "mesh" not in world.xml  # the simulated scene: unchanged
    render = dressed_model(world.model, world.xml)
    assert render is not None
    m = render.model
    assert m.nmesh == len(LINK_MESHES)
    for body in LINK_MESHES:
        g = m.geom(f"panda/{body}_visual").id
        assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        assert (m.geom_contype[g], m.geom_conaffinity[g], m.geom_group[g]) == (0, 0, VISUAL_GROUP)
        assert m.geom_group[m.geom(f"panda/{body}_col").id] == HIDDEN_COLLISION_GROUP
    # the fingers and their pads are what grasps: they stay in view
    for geom in ("left_finger_col", "right_finger_col", "left_pad", "right_pad"):
        assert m.geom_group[m.geom(f"panda/{geom}").id] == 0
    for field in ("nq", "nv", "nu", "na", "nbody", "nuserdata", "neq"):
        assert getattr(m, field) == getattr(world.model, field)
    assert mujoco.mj_stateSize(m, STATE_SPEC) == mujoco.mj_stateSize(world.model, STATE_SPEC)
    # every simulated geom has its counterpart (colours set by decorate() carry over)
    names = [world.model.geom(i).name for i in range(world.model.ngeom)]
    assert [m.geom(int(j)).name for j in render.geom_ids] == names


def test_render_model_poses_the_arm_as_the_simulation_does(cover_env, cover_demos):
    state = cover_demos[0].states[40]
    world = state.sim.world
    render = dressed_model(world.model, world.xml)
    data = mujoco.MjData(render.model)
    mujoco.mj_setState(render.model, data, state.sim.flat, STATE_SPEC)
    mujoco.mj_forward(render.model, data)
    world.load(state.sim.flat)
    for body in ("panda/link3", "panda/hand", "block0"):
        np.testing.assert_array_equal(
            data.xpos[render.model.body(body).id], world.data.xpos[world.model.body(body).id]
        )


def test_each_mesh_sits_on_its_link_in_metres(cover_env):
    """A coarse guard against wrong units or frames: each mesh's box (in its body's frame)
    has the size of a Panda link and is centred within 7 cm of its collision primitive's."""
    world = cover_env.task(0, 3, True).init.sim.world
    m = dressed_model(world.model, world.xml).model
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])

    def body_frame_box(geom: int) -> tuple[np.ndarray, np.ndarray]:
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, m.geom_quat[geom])
        centre, half = m.geom_aabb[geom, :3], m.geom_aabb[geom, 3:]
        points = m.geom_pos[geom] + (centre + corners * half) @ rot.reshape(3, 3).T
        return points.min(0), points.max(0)

    for body in LINK_MESHES:
        lo_v, hi_v = body_frame_box(m.geom(f"panda/{body}_visual").id)
        lo_c, hi_c = body_frame_box(m.geom(f"panda/{body}_col").id)
        assert 0.1 < np.max(hi_v - lo_v) < 0.4, body
        assert np.linalg.norm((lo_v + hi_v) / 2 - (lo_c + hi_c) / 2) < 0.07, body


def test_ik_model_has_no_meshes():
    assert ik_model().nmesh == 0


def test_frames_show_the_meshes_and_fall_back_to_primitives_with_one_warning(
    cover_env, monkeypatch
):
    state = cover_env.task(1, 3, True).init
    dressed = next(iter(cover_env.render([state], "overview", 160, 120)))
    panda_looks.franka_meshes.cache_clear()
    monkeypatch.setattr(panda_looks, "franka_mesh_dir", lambda: None)
    try:
        plain_state = cover_env.task(2, 3, True).init  # another scene: no cached render model
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            frames = [next(iter(cover_env.render([plain_state], "overview", 160, 120)))]
            frames.append(next(iter(cover_env.render([plain_state], "overview", 160, 120))))
    finally:
        monkeypatch.undo()
        panda_looks.franka_meshes.cache_clear()
    assert sum("Franka link meshes not found" in str(w.message) for w in caught) == 1
    assert dressed.shape == frames[0].shape == (120, 160, 3)
    assert np.array_equal(frames[0], frames[1])
    assert plain_state.sim.world.cache["render_model"] is None


def test_dressed_model_is_none_without_the_mesh_package(no_mesh_package, cover_env):
    world = cover_env.task(0, 3, True).init.sim.world
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert dressed_model(world.model, world.xml) is None
