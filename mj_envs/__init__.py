"""MuJoCo domains for BPNS: scenes, features, contact predicates, tasks, oracles.

Importing this package registers the Gymnasium ids ``bpns/<Name>-v0``.
"""

from mj_envs import gl as _gl  # noqa: F401  (must run before mujoco is imported)
from mj_envs.gym_wrapper import register_gymnasium_envs  # noqa: E402
from mj_envs.registry import ENVIRONMENTS, make_env  # noqa: E402

register_gymnasium_envs()

__all__ = ["ENVIRONMENTS", "make_env"]
