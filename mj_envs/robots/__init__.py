"""Robots a scene can hold: the Panda (names, ids, postures, hand features, contacts)."""

from mj_envs.robots.panda import (
    FINGERTIP_DROP,
    HOME_QPOS,
    HOME_QPOS_TURNED,
    PANDA,
    Robot,
    RobotIds,
    hand_xyz_fingers,
    ik_model,
    pads_touching,
    panda_ids,
)

__all__ = [
    "FINGERTIP_DROP",
    "HOME_QPOS",
    "HOME_QPOS_TURNED",
    "PANDA",
    "Robot",
    "RobotIds",
    "hand_xyz_fingers",
    "ik_model",
    "pads_touching",
    "panda_ids",
]
