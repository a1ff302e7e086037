"""Pick the headless OpenGL backend before MuJoCo or dm_control is imported.

``MUJOCO_GL=osmesa`` without Debian's ``libosmesa6`` breaks ``import mujoco`` itself, so
we only choose OSMesa when the library is present, and otherwise leave rendering off
and explain how to fix it when a user actually asks for pixels.
"""

from __future__ import annotations

import ctypes.util
import os

OSMESA_HINT = (
    "headless rendering needs OSMesa: install it with `sudo apt-get install libosmesa6` "
    "(Debian/Ubuntu), or set MUJOCO_GL=egl on a machine with a GPU"
)


def osmesa_available() -> bool:
    return ctypes.util.find_library("OSMesa") is not None


def configure_gl() -> None:
    """Default MUJOCO_GL (and PyOpenGL's platform) to OSMesa when it is installed."""
    if "MUJOCO_GL" not in os.environ and osmesa_available():
        os.environ["MUJOCO_GL"] = "osmesa"
    if os.environ.get("MUJOCO_GL") == "osmesa":
        os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")


configure_gl()
