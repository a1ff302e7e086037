"""A compiled task scene with scratch data, an end-effector controller and exact state I/O.

A :class:`World` is what a :class:`bpns.structs.SimState` points at. It is built from the
task's MJCF text alone (so datasets can rebuild it), is cached per text within a process,
and pickles as that text. The flat state is MuJoCo's full *integration* state
(``mjSTATE_INTEGRATION``: time, qpos, qvel, act, warm-start, ctrl, mocap, userdata, ...),
and the controller keeps all of its state in ``ctrl`` and ``userdata``, so
``load(save())`` followed by a step is bit-identical to stepping on.
"""

from __future__ import annotations

import functools
import hashlib
from typing import Any

import mujoco
import numpy as np

from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.errors import BpnsError
from ik import ControllerConfig, EndEffectorController
from mj_envs.mjcf_safety import check_mjcf
from mj_envs.perturbation import apply_to_model
from mj_envs.physics_checks import check_numbers, check_physics
from mj_envs.robots.panda import PANDA, Robot, ik_model

STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
# userdata layout: [0:7] the controller's commanded gripper pose, [7:] free for the domain.
POSE_SLICE = slice(0, 7)
DOMAIN_USERDATA_START = 7


class MjcfError(BpnsError, ValueError):
    """The MJCF text of a task could not be compiled."""


class World:
    """Compiled scene + scratch MjData + controller bound to the scene's robot.

    ``perturbation`` edits the compiled model (:mod:`mj_envs.perturbation`); ``queue_size``
    extra userdata (after the domain's) hold a latency queue. ``xml`` stays the nominal
    task's MJCF, what datasets store."""

    def __init__(
        self,
        xml: str,
        controller_config: ControllerConfig,
        robot: Robot = PANDA,
        perturbation: Perturbation = NOMINAL,
        queue_size: int = 0,
    ) -> None:
        check_mjcf(xml)  # scenes also come from demo files: no <include>, no file paths
        check_numbers(xml)  # ... nor NaN (MuJoCo would print a warning and compile it)
        try:
            if queue_size:
                spec = mujoco.MjSpec.from_string(xml)
                base_userdata = spec.nuserdata
                spec.nuserdata = base_userdata + queue_size
                self.model = spec.compile()
            else:
                self.model = mujoco.MjModel.from_xml_string(xml)
                base_userdata = self.model.nuserdata
        except ValueError as err:
            # one line: MuJoCo's message spans several
            raise MjcfError(
                f"the task's MJCF does not compile: {' '.join(str(err).split())}"
            ) from None
        check_physics(self.model, controller_config.control_dt)  # before perturbing it
        self.xml = xml
        self.key = hashlib.sha1(xml.encode()).hexdigest()[:16]
        self.data = mujoco.MjData(self.model)
        self.robot = robot
        self.perturbation = perturbation
        self.queue = slice(base_userdata, base_userdata + queue_size)  # in userdata
        self.controller = EndEffectorController(ik_model(robot), controller_config)
        self.controller.bind(self.model, prefix=robot.prefix)
        # the masses the scene declares, whatever the perturbation makes of them: a domain
        # whose rules read a mass as a task parameter (Doors' latch) reads these
        self.declared_body_mass = self.model.body_mass.copy()
        if perturbation.changes_model:
            names = controller_config.arm_actuators
            arm = [self.model.actuator(robot.prefix + a).id for a in names]
            apply_to_model(self.model, self.data, robot, arm, perturbation)
        self.state_size = mujoco.mj_stateSize(self.model, STATE_SPEC)
        self.substeps = max(1, round(controller_config.control_dt / self.model.opt.timestep))
        self.cache: dict[str, Any] = {}  # the domain's per-scene lookups (ids, slices)

    @staticmethod
    def from_xml(
        xml: str,
        controller_config: ControllerConfig | None = None,
        robot: Robot = PANDA,
        perturbation: Perturbation = NOMINAL,
        queue_size: int = 0,
    ) -> World:
        config = controller_config or ControllerConfig()
        return _cached_world(xml, config, robot, perturbation, queue_size)

    def __reduce__(self):
        return (
            World.from_xml,
            (self.xml, self.controller.config, self.robot, self.perturbation, self.queue_size),
        )

    @property
    def queue_size(self) -> int:
        return self.queue.stop - self.queue.start

    def __repr__(self) -> str:
        return f"World({self.key})"

    # -- exact state ----------------------------------------------------------------
    def save(self) -> np.ndarray:
        flat = np.empty(self.state_size, dtype=np.float64)
        mujoco.mj_getState(self.model, self.data, flat, STATE_SPEC)
        return flat

    def load(self, flat: np.ndarray) -> None:
        if flat.shape != (self.state_size,):
            raise ValueError(
                f"flat simulator state has shape {flat.shape}, "
                f"this scene needs ({self.state_size},)"
            )
        if not np.all(np.isfinite(flat)):  # MuJoCo would reset itself with a warning
            raise ValueError("flat simulator state holds NaN or inf")
        mujoco.mj_setState(self.model, self.data, flat, STATE_SPEC)
        mujoco.mj_forward(self.model, self.data)

    def step_physics(self) -> None:
        """Advance one control period, then refresh derived quantities (contacts)."""
        for _ in range(self.substeps):
            mujoco.mj_step(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)


@functools.lru_cache(maxsize=64)
def _cached_world(
    xml: str,
    controller_config: ControllerConfig,
    robot: Robot,
    perturbation: Perturbation,
    queue_size: int,
) -> World:
    return World(xml, controller_config, robot, perturbation, queue_size)
