"""Refuse a scene whose physics MuJoCo would compile but cannot simulate.

Scenes come from demonstration and rollouts files too (their ``world`` attribute holds
the task's MJCF), and MuJoCo compiles a timestep of 0, a negative mass or a NaN gravity
without complaint: the step then divides by zero, integrates backwards or fills the state
with NaN far from the file that caused it. :func:`check_physics` names the attribute
instead, before anything is simulated.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from bpns.errors import BpnsError

# one control step may take at most this many physics steps (a timestep of 1e-300
# would otherwise be a loop that never ends)
MAX_SUBSTEPS = 10_000
# attributes that hold names, not numbers (a body may be called "nan")
_NAME_ATTRIBUTES = frozenset(
    {"name", "class", "childclass", "body", "body1", "body2", "joint", "joint1", "joint2"}
    | {"site", "geom", "geom1", "geom2", "material", "texture", "mesh", "target", "tendon"}
    | {"actuator", "objname", "prefix", "hfield", "skin", "camera", "light"}
)
# <option> fields: (condition, what it must be)
_OPTIONS = {
    "timestep": (lambda v: v > 0, "> 0"),
    "impratio": (lambda v: v > 0, "> 0"),
    "density": (lambda v: v >= 0, ">= 0"),
    "viscosity": (lambda v: v >= 0, ">= 0"),
    "tolerance": (lambda v: v >= 0, ">= 0"),
    "ls_tolerance": (lambda v: v >= 0, ">= 0"),
    "noslip_tolerance": (lambda v: v >= 0, ">= 0"),
}
# compiled model arrays that must be >= 0, with the MJCF attribute they come from
_NON_NEGATIVE = {
    "body_mass": "<inertial mass>",
    "body_inertia": "<inertial diaginertia>",
    "geom_friction": "<geom friction>",
    "dof_damping": "<joint damping>",
    "dof_armature": "<joint armature>",
    "dof_frictionloss": "<joint frictionloss>",
    "jnt_stiffness": "<joint stiffness>",
}


class PhysicsError(BpnsError, ValueError):
    """A scene's physics (timestep, masses, friction, gravity ...) cannot be simulated."""


def check_numbers(xml: str) -> None:
    """Refuse NaN or infinite numbers anywhere in ``xml`` (MuJoCo compiles them with a
    warning on stdout, then simulates NaN)."""
    for element in ET.fromstring(xml).iter():
        for name, value in element.attrib.items():
            if name in _NAME_ATTRIBUTES:
                continue
            for token in value.split():
                try:
                    number = float(token)
                except ValueError:
                    continue
                if not math.isfinite(number):
                    raise PhysicsError(
                        f"MJCF <{element.tag} {name}={value!r}>: not a finite number"
                    )


def check_physics(model: mujoco.MjModel, control_dt: float) -> None:
    """Raise :class:`PhysicsError` naming the first physics attribute of ``model`` that
    is not finite or out of its range, or a timestep too small for ``control_dt``."""
    for field, (ok, must) in _OPTIONS.items():
        value = float(getattr(model.opt, field))
        if not (math.isfinite(value) and ok(value)):
            raise PhysicsError(f"MJCF <option {field}={value!r}>: must be finite and {must}")
    for field in ("gravity", "wind", "magnetic", "o_margin", "o_solref", "o_solimp"):
        if not np.all(np.isfinite(getattr(model.opt, field))):
            raise PhysicsError(f"MJCF <option {field}>: must be finite")
    for field, attribute in _NON_NEGATIVE.items():
        values = getattr(model, field)
        if not np.all(np.isfinite(values) & (values >= 0)):
            raise PhysicsError(f"MJCF {attribute}: must be finite and >= 0 ({field})")
    if control_dt / model.opt.timestep > MAX_SUBSTEPS:
        raise PhysicsError(
            f"MJCF <option timestep={model.opt.timestep!r}>: more than {MAX_SUBSTEPS} "
            f"physics steps per {control_dt} s control step"
        )
