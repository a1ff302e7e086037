r"""Differential-IK end-effector controller built on mink.

Each control step the commanded end-effector pose :math:`T^\star` is moved by the action's
deltas (translation in the world frame, rotation as a world-frame rotation vector applied
on the left, :math:`R^\star \leftarrow \exp([\omega]_\times) R^\star`), clipped to a
workspace box, and the arm's joint targets :math:`q^\star` are advanced by solving

.. math::

    \min_{\Delta q}\ \|J_{ee}\Delta q - e_{ee}\|^2_{W_{ee}}
        + \|\Delta q - (q_{home} - q^\star)\|^2_{W_{post}} + \lambda\|\Delta q\|^2
    \quad\text{s.t. joint position and velocity limits,}

with mink (FrameTask + PostureTask, ConfigurationLimit + VelocityLimit, daqp).
The IK is linearised at the *commanded* configuration :math:`q^\star`, not at the
measured one, so the targets are a deterministic function of the controller state and
the action; physics then tracks :math:`q^\star` with the position actuators.

The controller keeps no hidden state: the commanded pose lives in the caller's
``MjData.userdata`` slice and :math:`q^\star` in ``MjData.ctrl``, so saving MuJoCo's
integration state saves the controller too (exact replay). An infeasible QP never
raises: the arm keeps its last targets.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mink
import mujoco
import numpy as np


@dataclass(frozen=True)
class ControllerConfig:
    """Static settings of the end-effector controller."""

    site: str = "grip_site"
    arm_joints: tuple[str, ...] = tuple(f"joint{i}" for i in range(1, 8))
    arm_actuators: tuple[str, ...] = tuple(f"act_joint{i}" for i in range(1, 8))
    finger_actuator: str = "act_fingers"
    finger_joints: tuple[str, ...] = ("finger_joint1", "finger_joint2")
    home_qpos: tuple[float, ...] = (0.0, -0.3, 0.0, -2.2, 0.0, 1.9, -0.7854)
    control_dt: float = 0.05
    max_translation: float = 0.02  # metres per control step
    max_rotation: float = 0.15  # radians per control step
    finger_speed: float = 0.1  # m/s per finger, the closing/opening rate limit
    finger_open: float = 0.04  # metres per finger
    workspace_low: tuple[float, float, float] = (0.25, -0.45, 0.005)
    workspace_high: tuple[float, float, float] = (0.75, 0.45, 0.45)
    position_cost: float = 1.0
    orientation_cost: float = 1.0
    posture_cost: float = 1e-2
    damping: float = 1e-3
    max_joint_velocity: float = 2.0  # rad/s, below the Panda's 2.17-2.61 rad/s
    solver: str = "daqp"
    ik_iterations: int = 1

    @property
    def finger_step(self) -> float:
        return self.finger_speed * self.control_dt


@dataclass(frozen=True)
class EndEffectorTarget:
    """A commanded gripper pose: position (3) and orientation quaternion (w, x, y, z)."""

    position: np.ndarray
    quaternion: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))

    def as_array(self) -> np.ndarray:
        return np.concatenate([self.position, self.quaternion])


class EndEffectorController:
    """Turns end-effector deltas into arm joint targets and a finger target.

    ``model`` is the *robot-only* kinematic model used for IK (fast: a 9-dof QP); the
    scene model only has to contain a robot with the same joint and actuator names.
    """

    def __init__(self, ik_model: mujoco.MjModel, config: ControllerConfig = ControllerConfig()):
        self.config = config
        self.ik_model = ik_model
        self._configuration = mink.Configuration(ik_model)
        self._ik_qadr = np.array([ik_model.joint(j).qposadr[0] for j in config.arm_joints])
        self._frame_task = mink.FrameTask(
            frame_name=config.site,
            frame_type="site",
            position_cost=config.position_cost,
            orientation_cost=config.orientation_cost,
            lm_damping=1e-6,
        )
        self._posture_task = mink.PostureTask(ik_model, cost=config.posture_cost)
        q_home = self._configuration.q.copy()
        q_home[self._ik_qadr] = config.home_qpos
        self._posture_task.set_target(q_home)
        velocities = {j: config.max_joint_velocity for j in config.arm_joints}
        self._limits = [
            mink.ConfigurationLimit(ik_model),
            mink.VelocityLimit(ik_model, velocities),
        ]
        self._tasks = [self._frame_task, self._posture_task]
        self._low = np.asarray(config.workspace_low, dtype=np.float64)
        self._high = np.asarray(config.workspace_high, dtype=np.float64)
        self._bound_model: mujoco.MjModel | None = None

    # -- binding to a scene -----------------------------------------------------------
    def bind(self, model: mujoco.MjModel, prefix: str = "") -> None:
        """Resolve actuator ids in a scene model whose robot names carry ``prefix``."""
        cfg = self.config
        try:
            self._arm_act = np.array([model.actuator(prefix + a).id for a in cfg.arm_actuators])
            self._finger_act = model.actuator(prefix + cfg.finger_actuator).id
            self._arm_qadr = np.array([model.joint(prefix + j).qposadr[0] for j in cfg.arm_joints])
            self._site = model.site(prefix + cfg.site).id
            self._finger_qadr = np.array(
                [model.joint(prefix + j).qposadr[0] for j in cfg.finger_joints]
            )
        except KeyError as err:
            raise ValueError(
                f"the scene has no robot element {err}; it needs joints {cfg.arm_joints}, "
                f"prefixed {prefix!r}, "
                f"actuators {cfg.arm_actuators + (cfg.finger_actuator,)} and site {cfg.site!r}"
            ) from None
        self._bound_model = model

    # -- controller state -------------------------------------------------------------
    def reset(
        self, data: mujoco.MjData, pose_slice: slice, q_arm: np.ndarray, finger: float
    ) -> None:
        """Put the arm at ``q_arm`` at rest and make the commanded pose its current pose."""
        data.qpos[self._arm_qadr] = q_arm
        data.qpos[self._finger_qadr] = finger
        data.ctrl[self._arm_act] = q_arm
        data.ctrl[self._finger_act] = finger
        self._configuration.update(self._ik_q(q_arm))
        pose = self._configuration.get_transform_frame_to_world(self.config.site, "site")
        data.userdata[pose_slice] = np.concatenate([pose.translation(), pose.rotation().wxyz])

    def commanded_pose(self, data: mujoco.MjData, pose_slice: slice) -> EndEffectorTarget:
        v = data.userdata[pose_slice]
        return EndEffectorTarget(v[:3].copy(), v[3:7].copy())

    def finger_target(self, data: mujoco.MjData) -> float:
        return float(data.ctrl[self._finger_act])

    # -- one control step -------------------------------------------------------------
    def apply(
        self,
        data: mujoco.MjData,
        pose_slice: slice,
        dpos: np.ndarray,
        drot: np.ndarray | None,
        dgrip: float,
        grip_enabled: bool = True,
    ) -> bool:
        """Move the commanded pose by the deltas and write new joint/finger targets.

        ``dpos`` in metres (clipped to ``max_translation``), ``drot`` a world-frame rotation
        vector in radians (clipped to ``max_rotation``; None keeps the orientation),
        ``dgrip`` in [-1, 1] (+1 opens, -1 closes at ``finger_speed``). Returns False when
        the QP had no solution (the arm then keeps its last targets).
        """
        cfg = self.config
        pose = data.userdata[pose_slice]
        step = np.clip(dpos, -cfg.max_translation, cfg.max_translation)
        pose[:3] = np.clip(pose[:3] + step, self._low, self._high)
        if drot is not None and np.any(drot):
            rotvec = np.clip(drot, -cfg.max_rotation, cfg.max_rotation)
            dq = np.empty(4)
            _rotvec_to_quat(rotvec, dq)
            out = np.empty(4)
            mujoco.mju_mulQuat(out, dq, pose[3:7])
            mujoco.mju_normalize4(out)
            pose[3:7] = out
        if grip_enabled:
            f = data.ctrl[self._finger_act] + float(np.clip(dgrip, -1.0, 1.0)) * cfg.finger_step
            data.ctrl[self._finger_act] = min(max(f, 0.0), cfg.finger_open)
        return self._solve(data, pose)

    def reference_qp(self, data: mujoco.MjData, pose_slice: slice):
        """(configuration, tasks, limits) of the QP ``apply`` would solve now (benchmarks)."""
        self._configuration.update(self._ik_q(data.ctrl[self._arm_act]))
        pose = data.userdata[pose_slice]
        self._frame_task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3(wxyz=pose[3:7].copy()), pose[:3].copy())
        )
        return self._configuration, self._tasks, self._limits

    def _ik_q(self, q_arm: np.ndarray) -> np.ndarray:
        q = self._configuration.q.copy()
        q[self._ik_qadr] = q_arm
        return q

    def _solve(self, data: mujoco.MjData, pose: np.ndarray) -> bool:
        cfg = self.config
        configuration = self._configuration
        configuration.update(self._ik_q(data.ctrl[self._arm_act]))
        self._frame_task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3(wxyz=pose[3:7].copy()), pose[:3].copy())
        )
        try:
            for _ in range(cfg.ik_iterations):
                v = mink.solve_ik(
                    configuration,
                    self._tasks,
                    cfg.control_dt,
                    cfg.solver,
                    damping=cfg.damping,
                    limits=self._limits,
                )
                configuration.integrate_inplace(v, cfg.control_dt)
        except mink.NoSolutionFound:
            return False
        q = configuration.q[self._ik_qadr]
        if not np.all(np.isfinite(q)):
            return False
        data.ctrl[self._arm_act] = q
        return True


def _rotvec_to_quat(rotvec: np.ndarray, out: np.ndarray) -> None:
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        out[:] = (1.0, 0.0, 0.0, 0.0)
    else:
        mujoco.mju_axisAngle2Quat(out, rotvec / angle, angle)
