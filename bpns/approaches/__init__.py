"""Approaches: ways of solving tasks, found by name in a registry.

- :mod:`~bpns.approaches.base`: the :class:`Approach` interface, :class:`Solution`,
  :class:`ApproachEntry` (a registry entry: name, label, what it needs, how to build it).
- :mod:`~bpns.approaches.registry`: ``get_approach(name)``, ``approach_names()`` over
  the ``bpns.approaches`` entry points.
- :mod:`~bpns.approaches.bilevel`: bilevel planning with learned or oracle skills (the
  rows BPNS, Oracle, Samples=1, AbstractPlans=1).
- :mod:`~bpns.approaches.metacontroller`: base of approaches that pick one skill at a time.
- :mod:`~bpns.approaches.policy`: base of model-free policies acting every step.
"""

from bpns.approaches.base import (
    Approach,
    ApproachEntry,
    NoOracleSkillsError,
    SkillSource,
    Solution,
)
from bpns.approaches.registry import UnknownApproachError, approach_names, get_approach

__all__ = [
    "Approach",
    "ApproachEntry",
    "NoOracleSkillsError",
    "SkillSource",
    "Solution",
    "UnknownApproachError",
    "approach_names",
    "get_approach",
]
