"""MuJoCo domains for BPNS: generic machinery, robots, parts, oracles and domain packages.

Importing this package registers a Gymnasium id ``bpns/<Name>-v0`` for every environment
in the ``bpns.environments`` entry points (``mj_envs.gym_wrapper.gym_id``).
"""

from mj_envs import gl as _gl  # noqa: F401  (must run before mujoco is imported)
from mj_envs.gym_wrapper import gym_id, register_gymnasium_envs  # noqa: E402

register_gymnasium_envs()

__all__ = ["gym_id", "register_gymnasium_envs"]
