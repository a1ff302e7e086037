"""The Franka Panda as every domain uses it: names, ids, postures, hand features, contacts.

A :class:`Robot` says what a scene needs to hold one robot and what the controller drives:
its MJCF (attached under ``prefix``), the robot-only model the IK solves on, and the
names of the grip site, finger joint and finger pads. Domains read the robot through the
helpers here (:func:`panda_ids`, :func:`hand_xyz_fingers`, :func:`pads_touching`) instead
of their own id caches, so a robot with other names (a Panda on a mobile base) is another
:class:`Robot` value, not a fork of the environment layer.

Geometry a task author needs (the hand points down at the home postures):

* ``grip_site`` is the IK frame, midway between the finger pads; the closed fingertips'
  lowest point is :data:`FINGERTIP_DROP` below it.
* The fingers close along world x at :data:`HOME_QPOS` (Cover: a block is gripped anywhere
  along its width in y) and along world y at :data:`HOME_QPOS_TURNED` (Stick Button,
  Coffee: the hand turned a quarter turn about the vertical).
* Robot geoms collide with the world and objects (contype 2 / conaffinity 1), never with
  each other; objects use contype 1 / conaffinity 3 (``mj_envs.scene``).
* The hand's collision box is 20 cm long along the finger axis: keep other objects that
  far from a grasp, or approach from above.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ik import ControllerConfig

ASSETS_DIR = Path(__file__).resolve().parent.parent.parent / "assets"

# Arm postures at rest (joints 1-7, radians). The last joint turns the hand about the
# vertical: -pi/4 closes the fingers along world x, +pi/4 along world y.
HOME_QPOS = ControllerConfig().home_qpos  # the controller's default posture
HOME_QPOS_TURNED = (*HOME_QPOS[:6], -HOME_QPOS[6])
FINGERTIP_DROP = 0.012  # closed fingertips' lowest point below the grip site (m)


@dataclass(frozen=True)
class Robot:
    """A robot a scene attaches under ``prefix`` and the end-effector controller drives."""

    name: str
    mjcf: Path  # the robot's MJCF file (also the robot-only IK model)
    prefix: str  # namespace of the robot's elements in a scene ("panda/")
    grip_site: str = "grip_site"
    finger_joint: str = "finger_joint1"
    pads: tuple[str, str] = ("left_pad", "right_pad")

    def scene_name(self, element: str) -> str:
        return self.prefix + element


PANDA = Robot(name="panda", mjcf=ASSETS_DIR / "panda.xml", prefix="panda/")


@functools.lru_cache(maxsize=8)
def ik_model(robot: Robot = PANDA) -> mujoco.MjModel:
    """The robot-only kinematic model the IK solves on (a small QP; cached per process)."""
    return mujoco.MjModel.from_xml_path(str(robot.mjcf))


@functools.lru_cache(maxsize=8)
def robot_mjcf_text(robot: Robot = PANDA) -> str:
    return robot.mjcf.read_text()


@dataclass(frozen=True)
class RobotIds:
    """Ids of the robot's elements in one compiled scene."""

    grip_site: int
    finger_qpos: int
    pads: tuple[int, int]


def panda_ids(model: mujoco.MjModel, cache: dict, robot: Robot = PANDA) -> RobotIds:
    """The robot's ids in ``model``, looked up once per scene (``cache`` is the World's)."""
    ids = cache.get(("robot", robot.name))
    if ids is None:
        ids = RobotIds(
            grip_site=model.site(robot.scene_name(robot.grip_site)).id,
            finger_qpos=int(model.joint(robot.scene_name(robot.finger_joint)).qposadr[0]),
            pads=(
                model.geom(robot.scene_name(robot.pads[0])).id,
                model.geom(robot.scene_name(robot.pads[1])).id,
            ),
        )
        cache[("robot", robot.name)] = ids
    return ids


def hand_xyz_fingers(data: mujoco.MjData, ids: RobotIds) -> np.ndarray:
    """(x, y, z) of the grip site and the finger opening: the usual robot features."""
    x, y, z = data.site_xpos[ids.grip_site]
    return np.array([x, y, z, data.qpos[ids.finger_qpos]])


def pads_touching(data: mujoco.MjData, ids: RobotIds, geoms: frozenset[int] | set[int]) -> int:
    """How many finger pads (0, 1, 2) are in MuJoCo's contact list with any of ``geoms``.

    Two means a grasp (Holding, Grasped): the contact list, not a flag, decides.
    """
    n = data.ncon
    if n == 0:
        return 0
    left, right = ids.pads
    touching = 0
    for (a, b), dist in zip(data.contact.geom[:n], data.contact.dist[:n], strict=True):
        if dist > 0.0:
            continue
        if a == left or a == right:
            if b in geoms:
                touching |= 1 if a == left else 2
        elif (b == left or b == right) and a in geoms:
            touching |= 1 if b == left else 2
    return (touching & 1) + (touching >> 1)
