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

import numpy as np

Z_AXIS = np.array([0.0, 0.0, 1.0])


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (w, x, y, z) quaternion (normalised first)."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def axis_angle_mat(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: rotation by ``angle`` about the unit vector ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def mat_to_rotvec(r: np.ndarray) -> np.ndarray:
    """Logarithm of a rotation matrix as a rotation vector (angle * axis)."""
    cos = float(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))
    angle = float(np.arccos(cos))
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-9:
        return v / 2.0
    if np.pi - angle < 1e-6:  # near pi: axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
        i = int(np.argmax(axis))
        axis[:] = (r[:, i] + r[i, :]) / 2.0
        axis[i] = np.sqrt(max((r[i, i] + 1.0) / 2.0, 0.0))
        axis /= np.linalg.norm(axis)
        return angle * axis
    return angle * v / (2.0 * np.sin(angle))


def _horizontal_unit(axis: np.ndarray) -> np.ndarray:
    a = np.asarray(axis, dtype=np.float64)
    a = a - a[2] * Z_AXIS
    n = float(np.linalg.norm(a))
    if n < 1e-9:
        raise ValueError("the tilt axis must not be vertical")
    return a / n


def yaw_tilt_matrix(yaw: float, tilt: float, base: np.ndarray, tilt_axis: np.ndarray) -> np.ndarray:
    """:math:`R_z(\\psi) R_a(\\tau) R_0` for base rotation matrix ``base``."""
    a = _horizontal_unit(tilt_axis)
    return axis_angle_mat(Z_AXIS, yaw) @ axis_angle_mat(a, tilt) @ base


def yaw_tilt(quat: np.ndarray, base_quat: np.ndarray, tilt_axis: np.ndarray) -> tuple[float, float]:
    """(yaw, tilt) in radians of orientation ``quat`` relative to ``base_quat``.

    ``tilt_axis`` is the horizontal tilt axis at yaw 0 (world frame). Yaw lies in
    (-pi, pi], tilt in (-pi/2, pi/2) for orientations of the form above.
    """
    return yaw_tilt_from_matrix(quat_to_mat(quat), quat_to_mat(base_quat), tilt_axis)


def yaw_tilt_from_matrix(
    r: np.ndarray, base: np.ndarray, tilt_axis: np.ndarray
) -> tuple[float, float]:
    a = _horizontal_unit(tilt_axis)
    rel = r @ base.T  # = Rz(yaw) Ra(tilt): it maps a to Rz(yaw) a
    ra = rel @ a
    yaw = float(np.arctan2(a[0] * ra[1] - a[1] * ra[0], a[0] * ra[0] + a[1] * ra[1]))
    tilt_rot = axis_angle_mat(Z_AXIS, -yaw) @ rel  # = Ra(tilt)
    # the tilt turns z about a: angle of Ra z around a
    rz = tilt_rot @ Z_AXIS
    b = np.cross(a, Z_AXIS)  # Ra(tilt) z = cos(tilt) z + sin(tilt) (a x z)
    tilt = float(np.arctan2(float(rz @ b), float(rz @ Z_AXIS)))
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
    new_yaw = float(np.clip(yaw + dyaw, *yaw_limits))
    new_tilt = float(np.clip(tilt + dtilt, *tilt_limits))
    if new_yaw == yaw and new_tilt == tilt:
        return np.zeros(3)
    target = yaw_tilt_matrix(new_yaw, new_tilt, base, tilt_axis)
    return mat_to_rotvec(target @ r.T)
