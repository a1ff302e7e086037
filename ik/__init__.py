"""End-effector control: Cartesian deltas -> joint position targets via mink differential IK."""

from ik.controller import ControllerConfig, EndEffectorController, EndEffectorTarget

__all__ = ["ControllerConfig", "EndEffectorController", "EndEffectorTarget"]
