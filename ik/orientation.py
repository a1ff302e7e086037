r"""Hand-relative orientation deltas: (yaw, tilt) of a gripper that points down.

A gripper's orientation is parametrised relative to a *base* orientation :math:`R_0`
(e.g. the home pose, pointing down) by two angles,

.. math::

    R(\psi, \tau) = R_z(\psi)\, R_a(\tau)\, R_0,

where :math:`\psi` ("wrist", yaw) turns the hand about the world vertical and :math:`\tau`
("tilt") turns it about a horizontal axis :math:`a` that turns with the wrist, so in the
world the tilt axis is :math:`R_z(\psi)\,a`. With :math:`a` chosen as the axis the fingers
close along (hand-relative), tilting turns the fingers about their own closing axis: a held
object pivots about the grasp, as in pouring.

:func:`yaw_tilt` reads :math:`(\psi, \tau)` from any quaternion of that form (and projects
others onto it); :func:`rotation_delta` turns deltas :math:`(\Delta\psi, \Delta\tau)` of a
commanded quaternion into the world-frame rotation vector :math:`\omega` with
:math:`R(\psi + \Delta\psi, \tau + \Delta\tau) = \exp([\omega]_\times) R(\psi, \tau)`, the
form :meth:`ik.controller.EndEffectorController.apply` takes as ``drot``. The angles after
the step can be clipped to limits, so an orientation bound is kept exactly by the command.
Quaternions are (w, x, y, z), as in MuJoCo and mink.
"""

from __future__ import annotations

import math

import numpy as np

# These run several times per control step (features and commands), so they work on
# Python floats: numpy's per-call overhead on 3-vectors cost more than the maths.


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (w, x, y, z) quaternion (normalised first)."""
    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def axis_angle_mat(axis: np.ndarray, angle: float) -> np.ndarray:
    r"""Rodrigues: rotation by ``angle`` about the unit vector ``axis``,
    :math:`\cos\theta\, I + \sin\theta\, [a]_\times + (1 - \cos\theta)\, a a^T`."""
    x, y, z = (float(v) for v in axis)
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    return np.array(
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    )


def mat_to_rotvec(r: np.ndarray) -> np.ndarray:
    """Logarithm of a rotation matrix as a rotation vector (angle * axis)."""
    cos = min(max((float(r[0, 0] + r[1, 1] + r[2, 2]) - 1.0) / 2.0, -1.0), 1.0)
    angle = math.acos(cos)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-9:
        return v / 2.0
    if math.pi - angle < 1e-6:  # near pi: axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
        i = int(np.argmax(axis))
        axis[:] = (r[:, i] + r[i, :]) / 2.0
        axis[i] = np.sqrt(max((r[i, i] + 1.0) / 2.0, 0.0))
        axis /= np.linalg.norm(axis)
        return angle * axis
    return angle * v / (2.0 * math.sin(angle))


def _horizontal_unit(axis: np.ndarray) -> tuple[float, float]:
    """(x, y) of ``axis`` projected on the horizontal plane and normalised."""
    x, y = float(axis[0]), float(axis[1])
    n = math.hypot(x, y)
    if n < 1e-9:
        raise ValueError("the tilt axis must not be vertical")
    return x / n, y / n


def yaw_tilt_matrix(yaw: float, tilt: float, base: np.ndarray, tilt_axis: np.ndarray) -> np.ndarray:
    """:math:`R_z(\\psi) R_a(\\tau) R_0` for base rotation matrix ``base``."""
    ax, ay = _horizontal_unit(tilt_axis)
    return axis_angle_mat((0.0, 0.0, 1.0), yaw) @ axis_angle_mat((ax, ay, 0.0), tilt) @ base


def yaw_tilt(quat: np.ndarray, base_quat: np.ndarray, tilt_axis: np.ndarray) -> tuple[float, float]:
    """(yaw, tilt) in radians of orientation ``quat`` relative to ``base_quat``.

    ``tilt_axis`` is the horizontal tilt axis at yaw 0 (world frame). Yaw lies in
    (-pi, pi], tilt in (-pi/2, pi/2) for orientations of the form above.
    """
    return yaw_tilt_from_matrix(quat_to_mat(quat), quat_to_mat(base_quat), tilt_axis)


def yaw_tilt_from_matrix(
    r: np.ndarray, base: np.ndarray, tilt_axis: np.ndarray
) -> tuple[float, float]:
    r"""(yaw, tilt) of rotation matrix ``r`` relative to ``base`` (see :func:`yaw_tilt`).

    With :math:`M = R R_0^T = R_z(\psi) R_a(\tau)`: :math:`M a = R_z(\psi) a` gives the
    yaw, and :math:`R_z(-\psi) M e_z = \cos\tau\, e_z + \sin\tau\, (a \times e_z)` the
    tilt, where :math:`a \times e_z = (a_y, -a_x, 0)` for a horizontal :math:`a`."""
    ax, ay = _horizontal_unit(tilt_axis)
    (m00, m01, m02), (m10, m11, m12), (_, _, m22) = (r @ base.T).tolist()
    ra_x, ra_y = m00 * ax + m01 * ay, m10 * ax + m11 * ay
    yaw = math.atan2(ax * ra_y - ay * ra_x, ax * ra_x + ay * ra_y)
    c, s = math.cos(yaw), math.sin(yaw)
    rz_x, rz_y = c * m02 + s * m12, -s * m02 + c * m12
    tilt = math.atan2(rz_x * ay - rz_y * ax, m22)
    return yaw, tilt


def rotation_delta(
    quat: np.ndarray,
    dyaw: float,
    dtilt: float,
    base_quat: np.ndarray,
    tilt_axis: np.ndarray,
    yaw_limits: tuple[float, float] = (-np.pi, np.pi),
    tilt_limits: tuple[float, float] = (-np.pi / 2, np.pi / 2),
) -> np.ndarray:
    """World rotation vector taking ``quat`` to yaw + dyaw, tilt + dtilt (within limits).

    The current (yaw, tilt) are read from ``quat`` (normally the *commanded* orientation,
    so deltas integrate exactly); the new angles are clipped to the limits and the result
    is :math:`\\log(R_{new} R^T)`: a zero delta at a pose inside the limits gives zero.
    """
    base = quat_to_mat(base_quat)
    r = quat_to_mat(quat)
    yaw, tilt = yaw_tilt_from_matrix(r, base, tilt_axis)
    new_yaw = min(max(yaw + float(dyaw), yaw_limits[0]), yaw_limits[1])
    new_tilt = min(max(tilt + float(dtilt), tilt_limits[0]), tilt_limits[1])
    if new_yaw == yaw and new_tilt == tilt:
        return np.zeros(3)
    target = yaw_tilt_matrix(new_yaw, new_tilt, base, tilt_axis)
    return mat_to_rotvec(target @ r.T)
