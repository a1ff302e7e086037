"""The Panda on a planar holonomic base: slide x, slide y and yaw, position-controlled.

The base is a pedestal (a cylinder from the floor up to the arm's mounting plane) on three
joints: ``base_x`` and ``base_y`` (slides along the world axes) and ``base_yaw`` (a hinge
about the vertical). Each has a position actuator; its target lives in ``MjData.ctrl``,
which MuJoCo's integration state saves, so replay stays exact. The arm is attached on top
of the pedestal with the ``panda/`` prefix, so the end-effector controller binds to it
exactly as on a fixed base: its IK model is the fixed-base arm, the commanded hand pose
in ``userdata[POSE_SLICE]`` is in the *base* frame, and the hand moves with the base.

A base command is the offset of the actuators' targets from the *measured* pose,
bounded (8 cm, 0.25 rad): the servo then moves the base at most about 4 cm per control
step, a policy that sees measured poses commands where to go next without knowing the
previous targets, and pushing into a wall never winds up a large force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control import mjcf

from mj_envs.robots.panda import PANDA, robot_mjcf_text

BASE_JOINTS = ("base_x", "base_y", "base_yaw")
BASE_ACTUATORS = ("act_base_x", "act_base_y", "act_base_yaw")
BASE_GEOM = "base_pedestal"
# Robot collision groups (as the arm's): never self-colliding, colliding with the world.
ROBOT_CONTYPE, ROBOT_CONAFFINITY = 2, 1


@dataclass(frozen=True)
class BaseConfig:
    """Geometry and servo settings of the mobile base."""

    radius: float = 0.22  # pedestal radius (the footprint the motion planner uses)
    height: float = 0.75  # floor to the arm's mounting plane
    mass: float = 40.0
    kp_xy: float = 20000.0  # N/m
    damping_xy: float = 2200.0  # N s/m (about critical for base + arm)
    kp_yaw: float = 3000.0  # N m/rad
    damping_yaw: float = 400.0
    max_offset: float = 0.08  # |target - measured| of x and y (m): about 0.7 m/s
    max_yaw_offset: float = 0.25  # ... and of yaw (rad): about 1.9 rad/s


def add_mobile_panda(
    arena: mjcf.RootElement, start: tuple[float, float, float], config: BaseConfig
) -> None:
    """Add the base at ``start`` = (x, y, yaw) with the Panda on top.

    The joints' zero is the start pose (the body is placed there), so qpos and ctrl of the
    base are offsets from it; :func:`base_pose` reads the world pose.
    """
    x, y, yaw = start
    # an outer carriage (world-aligned slides) carries the turning base (yaw hinge)
    carriage = arena.worldbody.add("body", name="base_carriage", pos=(x, y, 0.0))
    carriage.add("joint", name="base_x", type="slide", axis=(1, 0, 0), damping=config.damping_xy)
    carriage.add("joint", name="base_y", type="slide", axis=(0, 1, 0), damping=config.damping_xy)
    carriage.add(
        "geom",
        name="base_carriage_mass",
        type="sphere",
        size=(0.01,),
        mass=1.0,
        contype=0,
        conaffinity=0,
        rgba=(0, 0, 0, 0),
    )
    body = carriage.add(
        "body", name="mobile_base", quat=(math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
    )
    body.add("joint", name="base_yaw", type="hinge", axis=(0, 0, 1), damping=config.damping_yaw)
    body.add(
        "geom",
        name=BASE_GEOM,
        type="cylinder",
        size=(config.radius, config.height / 2),
        pos=(0, 0, -config.height / 2),
        mass=config.mass,
        rgba=(0.3, 0.32, 0.36, 1),
        contype=ROBOT_CONTYPE,
        conaffinity=ROBOT_CONAFFINITY,
    )
    body.add(
        "geom",
        name="base_stripe",
        type="box",
        size=(config.radius * 0.9, 0.02, 0.005),
        pos=(config.radius * 0.1, 0, 0.001),
        rgba=(0.9, 0.6, 0.1, 1),
        contype=0,
        conaffinity=0,
        mass=0.0,
    )
    for joint, act, kp in zip(
        BASE_JOINTS, BASE_ACTUATORS, (config.kp_xy, config.kp_xy, config.kp_yaw), strict=True
    ):
        arena.actuator.add(
            "position", name=act, joint=joint, kp=kp, ctrllimited=False, forcelimited=False
        )
    mount = body.add("site", name="arm_mount", pos=(0, 0, 0))
    mount.attach(mjcf.from_xml_string(robot_mjcf_text(PANDA), model_dir=str(PANDA.mjcf.parent)))


@dataclass(frozen=True)
class BaseIds:
    """Addresses of the base in a compiled scene."""

    qpos: np.ndarray  # (3,) qpos addresses of x, y, yaw
    act: np.ndarray  # (3,) actuator ids
    body: int
    origin: np.ndarray  # (3,) the start pose (world) the joints are offsets from

    @staticmethod
    def of(model: mujoco.MjModel) -> BaseIds:
        body = model.body("mobile_base").id
        carriage = model.body("base_carriage").id
        q = model.body_quat[body]
        yaw0 = 2.0 * math.atan2(q[3], q[0])
        x0, y0 = model.body_pos[carriage][:2]
        return BaseIds(
            qpos=np.array([model.joint(j).qposadr[0] for j in BASE_JOINTS]),
            act=np.array([model.actuator(a).id for a in BASE_ACTUATORS]),
            body=body,
            origin=np.array([x0, y0, yaw0]),
        )


def base_pose(ids: BaseIds, data: mujoco.MjData) -> np.ndarray:
    """Measured world pose (x, y, yaw) of the base."""
    return ids.origin + data.qpos[ids.qpos]


def command_base(ids: BaseIds, data: mujoco.MjData, offset: np.ndarray, config: BaseConfig) -> None:
    """Set the base targets to the measured pose + ``offset`` = (dx, dy, dyaw) (world frame),
    bounded by ``max_offset`` / ``max_yaw_offset``."""
    bound = np.array([config.max_offset, config.max_offset, config.max_yaw_offset])
    data.ctrl[ids.act] = data.qpos[ids.qpos] + np.clip(offset, -bound, bound)


def to_base_frame(yaw: float, v: np.ndarray) -> np.ndarray:
    """World-frame xy vector -> base frame (rotation by -yaw); z unchanged."""
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.array(v, dtype=np.float64, copy=True)
    out[0], out[1] = c * v[0] + s * v[1], -s * v[0] + c * v[1]
    return out
