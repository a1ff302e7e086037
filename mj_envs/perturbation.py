"""What each :class:`bpns.env.perturbations.Perturbation` changes in MuJoCo.

Model edits, made once on each task's compiled model (the MJCF text, which datasets
store, stays the nominal one; the perturbation is stored beside it):

- ``mass_scale``: ``body_mass`` and ``body_inertia`` of every body outside the robot's
  kinematic tree (blocks, sticks, buttons' caps, pots, cups, door leaves) times the
  factor: density scaled uniformly, so centres of mass and shapes stay; then
  ``mj_setConst`` recomputes the derived constants.
- ``friction_scale``: ``geom_friction`` (sliding, torsional, rolling) of every geom times
  the factor; MuJoCo takes the larger of the two geoms' coefficients for a contact, so
  every contact's friction scales by it (the finger pads' grip included).
- ``gain_scale``: the arm's position actuators' stiffness: ``gainprm[0]`` (kp) and
  ``biasprm[1]`` (-kp) times the factor; damping and force limits stay.
- ``latency``: ``latency * action_dim`` extra userdata at the end of the domain's (the
  queue of commanded actions, oldest first), so the queue is saved with the state.

Transition-time effects (``MujocoEnv.simulate``), both deterministic functions of the
state acted on, so ``simulate`` stays exact and replay reproduces them:

- ``action_noise``: ``a + std * (high - low) / 2 * N(0, 1)``, clipped into bounds, with
  the normal drawn from ``default_rng([seed, scene key, control step])``.
- ``obs_noise``: ``observe(state)`` adds ``std * N(0, 1)`` to every feature (drawn the
  same way); only policies see it.
"""

from __future__ import annotations

import mujoco
import numpy as np

from bpns.env.perturbations import Perturbation
from mj_envs.robots.panda import Robot


def apply_to_model(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    robot: Robot,
    arm_actuators: list[int],
    p: Perturbation,
) -> None:
    """Edit ``model`` in place for ``p``'s model perturbations (see the module docstring)."""
    if p.mass_scale != 1.0:
        robot_root = model.body_rootid[model.site(robot.scene_name(robot.grip_site)).bodyid[0]]
        bodies = [b for b in range(1, model.nbody) if model.body_rootid[b] != robot_root]
        model.body_mass[bodies] *= p.mass_scale
        model.body_inertia[bodies] *= p.mass_scale
    if p.friction_scale != 1.0:
        model.geom_friction[:] *= p.friction_scale
    if p.gain_scale != 1.0:
        model.actuator_gainprm[arm_actuators, 0] *= p.gain_scale
        model.actuator_biasprm[arm_actuators, 1] *= p.gain_scale
    if p.mass_scale != 1.0:
        mujoco.mj_setConst(model, data)


def noise(p: Perturbation, stream: int, scene_key: str, step: int, size: int) -> np.ndarray:
    """Standard normal noise for ``stream`` (0: actions, 1: features) at control ``step``
    of the scene with ``scene_key``: the same state always draws the same noise."""
    rng = np.random.default_rng([p.seed, stream, int(scene_key, 16), step])
    return rng.standard_normal(size)
