"""End-effector control: Cartesian deltas -> joint position targets via mink differential IK."""

from ik.controller import ControllerConfig, EndEffectorController, EndEffectorTarget
from ik.orientation import rotation_delta, yaw_tilt

__all__ = [
    "ControllerConfig",
    "EndEffectorController",
    "EndEffectorTarget",
    "rotation_delta",
    "yaw_tilt",
]
