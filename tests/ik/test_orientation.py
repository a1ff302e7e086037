"""Hand-relative (yaw, tilt) orientation deltas (ik.orientation) and their use in the IK."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ik.orientation import (
    mat_to_rotvec,
    quat_to_mat,
    rotation_delta,
    yaw_tilt,
    yaw_tilt_matrix,
)

DOWN = np.array([0.0, 1.0, 0.0, 0.0])  # gripper z pointing down (180 deg about x)
Y = np.array([0.0, 1.0, 0.0])


def _quat(r: np.ndarray) -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, r.reshape(-1))
    return q


def _exp(v: np.ndarray) -> np.ndarray:
    q = np.empty(4)
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.eye(3)
    mujoco.mju_axisAngle2Quat(q, v / angle, angle)
    return quat_to_mat(q)


@pytest.mark.parametrize("yaw,tilt", [(0.0, 0.0), (0.7, 0.0), (-1.9, 0.4), (2.5, -0.3), (1.0, 1.2)])
def test_yaw_tilt_round_trip(yaw, tilt):
    base = quat_to_mat(DOWN)
    q = _quat(yaw_tilt_matrix(yaw, tilt, base, Y))
    got = yaw_tilt(q, DOWN, Y)
    assert np.allclose(got, (yaw, tilt), atol=1e-9)


def test_positive_tilt_turns_the_axis_perpendicular_to_it_downwards():
    base = quat_to_mat(DOWN)
    for yaw in (0.0, 0.8, -1.2):
        r = yaw_tilt_matrix(yaw, 0.5, base, Y)
        rel = r @ base.T
        moved = rel @ np.array([1.0, 0.0, 0.0])  # +x turned by the yaw, then dipped
        assert np.isclose(moved[2], -np.sin(0.5))
        assert np.allclose(moved[:2] / np.linalg.norm(moved[:2]), [np.cos(yaw), np.sin(yaw)])
        axis = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        assert np.allclose(rel @ np.array([0.0, 1.0, 0.0]), axis)  # the axis turns with it


def test_rotation_delta_is_the_world_rotation_vector_between_the_two_poses():
    base = quat_to_mat(DOWN)
    rng = np.random.default_rng(0)
    for _ in range(20):
        yaw, tilt = rng.uniform(-2, 2), rng.uniform(-0.5, 1.0)
        dyaw, dtilt = rng.uniform(-0.1, 0.1, 2)
        q = _quat(yaw_tilt_matrix(yaw, tilt, base, Y))
        w = rotation_delta(q, dyaw, dtilt, DOWN, Y)
        expected = yaw_tilt_matrix(yaw + dyaw, tilt + dtilt, base, Y)
        assert np.allclose(_exp(w) @ quat_to_mat(q), expected, atol=1e-9)
        assert np.linalg.norm(w) <= np.hypot(dyaw, dtilt) + 1e-9


def test_rotation_delta_clips_to_the_limits_and_is_zero_for_a_zero_delta():
    base = quat_to_mat(DOWN)
    q = _quat(yaw_tilt_matrix(0.95, 0.0, base, Y))
    w = rotation_delta(q, 0.1, 0.0, DOWN, Y, yaw_limits=(-1.0, 1.0))
    assert np.allclose(w, [0.0, 0.0, 0.05], atol=1e-9)
    assert np.allclose(rotation_delta(q, 0.0, 0.0, DOWN, Y), 0.0)


def test_mat_to_rotvec_near_pi():
    v = np.array([0.0, 0.0, np.pi - 1e-8])
    assert np.allclose(np.abs(mat_to_rotvec(_exp(v))), np.abs(v), atol=1e-6)
