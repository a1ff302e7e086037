"""The end-effector controller: accuracy, limits, and never raising on bad targets."""

from __future__ import annotations

import mujoco
import numpy as np

from mj_envs.world import POSE_SLICE


def _site_pos(world):
    return world.data.site_xpos[world.model.site("panda/grip_site").id].copy()


def test_reaches_a_20cm_target_within_1mm(cover_env):
    task = cover_env.task(0, 0, True)
    world = task.init.sim.world
    world.load(task.init.sim.flat)
    start = _site_pos(world)
    target = start + np.array([0.1, 0.12, -0.12])  # |d| = 0.2 m
    assert abs(np.linalg.norm(target - start) - 0.2) < 0.01
    for _ in range(60):
        cmd = world.data.userdata[POSE_SLICE][:3]
        world.controller.apply(world.data, POSE_SLICE, target - cmd, None, 0.0)
        world.step_physics()
    assert np.linalg.norm(_site_pos(world) - target) < 1e-3


def test_joint_limits_never_violated_under_random_actions(cover_env):
    rng = np.random.default_rng(3)
    task = cover_env.task(1, 0, True)
    world = task.init.sim.world
    m = world.model
    ids = [m.joint(f"panda/joint{i}").id for i in range(1, 8)]
    lo, hi = m.jnt_range[ids, 0], m.jnt_range[ids, 1]
    state = task.init
    for _ in range(150):
        a = rng.uniform(cover_env.action_low, cover_env.action_high)
        state = cover_env.simulate(state, a)
        q = world.data.qpos[[m.jnt_qposadr[j] for j in ids]]
        ctrl = world.data.ctrl[:7]
        assert np.all(ctrl >= lo - 1e-9) and np.all(ctrl <= hi + 1e-9)
        assert np.all(q >= lo - 0.02) and np.all(q <= hi + 0.02)  # soft joint limits


def test_unreachable_target_holds_instead_of_raising(cover_env):
    task = cover_env.task(2, 0, True)
    world = task.init.sim.world
    world.load(task.init.sim.flat)
    for _ in range(40):  # push far outside the workspace: clipped, solved, never raises
        world.controller.apply(world.data, POSE_SLICE, np.array([1.0, 1.0, 1.0]), None, 0.0)
        world.step_physics()
    assert np.all(np.isfinite(world.data.qpos))
    high = np.array(world.controller.config.workspace_high)
    assert np.all(world.data.userdata[POSE_SLICE][:3] <= high + 1e-12)


def test_orientation_is_kept_without_orientation_deltas(cover_env):
    task = cover_env.task(3, 0, True)
    world = task.init.sim.world
    world.load(task.init.sim.flat)
    sid = world.model.site("panda/grip_site").id
    r0 = world.data.site_xmat[sid].copy()
    for k in range(40):
        world.controller.apply(
            world.data, POSE_SLICE, np.array([0.01, -0.01 * (k % 3), 0.0]), None, 0.0
        )
        world.step_physics()
    for _ in range(10):
        world.controller.apply(world.data, POSE_SLICE, np.zeros(3), None, 0.0)
        world.step_physics()
    err = np.empty(3)
    q0, q1 = np.empty(4), np.empty(4)
    mujoco.mju_mat2Quat(q0, r0)
    mujoco.mju_mat2Quat(q1, world.data.site_xmat[sid])
    mujoco.mju_subQuat(err, q1, q0)
    assert np.linalg.norm(err) < 0.02
