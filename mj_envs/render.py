"""Offscreen rendering of states with MuJoCo's renderer (OSMesa when headless).

Frames are drawn from the scene's render model (:mod:`mj_envs.robots.panda_looks`: the
same scene with the Panda's real link meshes), fed the simulated state; the simulated
model itself never changes for looks."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator, Sequence

import mujoco
import numpy as np

from bpns.errors import BpnsError
from bpns.execution.video import draw_caption
from bpns.structs import State
from mj_envs.gl import OSMESA_HINT, osmesa_available
from mj_envs.robots.panda_looks import RenderModel, dressed_model
from mj_envs.world import STATE_SPEC, World


class RenderingUnavailable(BpnsError, RuntimeError):
    """No OpenGL backend could be started; the message says how to fix it."""


def _check_backend() -> None:
    backend = os.environ.get("MUJOCO_GL")
    if backend in (None, "osmesa") and not osmesa_available():
        raise RenderingUnavailable(OSMESA_HINT)


def render_states(
    states: Sequence[State],
    camera: str = "overview",
    width: int = 640,
    height: int = 480,
    decorate: Callable[[World], None] | None = None,
) -> Iterator[np.ndarray]:
    """Yield one RGB frame per state; the renderer is always closed afterwards.

    ``camera`` names one of the scene's cameras, or is ``ALL``: every camera of the scene
    (in the model's order), tiled in a grid in one ``width`` x ``height`` frame.
    ``decorate(world)`` runs after each state is loaded, to set state-dependent looks.
    """
    if not states:
        return
    _check_backend()
    world = states[0].sim.world
    assert isinstance(world, World)
    names = camera_names(world)
    if camera != ALL and camera not in names:
        known = ", ".join(sorted(names))
        raise ValueError(f"no camera {camera!r} in this scene; cameras: {known} (or {ALL})")
    cameras = names if camera == ALL else (camera,)
    cols = math.ceil(math.sqrt(len(cameras)))
    rows = math.ceil(len(cameras) / cols)
    tile_w, tile_h = width // cols, height // rows
    dressed = render_model(world)
    model = dressed.model if dressed is not None else world.model
    data = mujoco.MjData(model) if dressed is not None else world.data
    limit = (model.vis.global_.offwidth, model.vis.global_.offheight)
    if width > limit[0] or height > limit[1]:  # MuJoCo's own error would look like no GL
        raise ValueError(
            f"{width} x {height} pixels exceed this scene's offscreen framebuffer, "
            f"{limit[0]} x {limit[1]} (its MJCF's <visual><global offwidth offheight>)"
        )
    try:
        renderer = mujoco.Renderer(model, height=tile_h, width=tile_w)
    except Exception as err:  # noqa: BLE001  (MuJoCo raises bare errors when GL is missing)
        raise RenderingUnavailable(
            f"could not start an OpenGL context ({err}); {OSMESA_HINT}"
        ) from None
    # OSMesa renders in software: shadows and reflections would triple the cost per frame
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
    try:
        for state in states:
            world.load(state.sim.flat)
            if decorate is not None:
                decorate(world)
            if dressed is not None:  # the looks decorate() set, and the state, carried over
                model.geom_rgba[dressed.geom_ids] = world.model.geom_rgba
                mujoco.mj_setState(model, data, state.sim.flat, STATE_SPEC)
                mujoco.mj_forward(model, data)
            if len(cameras) == 1:
                renderer.update_scene(data, camera=camera)
                yield renderer.render().copy()
                continue
            frame = np.zeros((height, width, 3), dtype=np.uint8)
            for k, cam in enumerate(cameras):
                renderer.update_scene(data, camera=cam)
                r, c = divmod(k, cols)
                tile = draw_caption(renderer.render(), cam, at_top=True)
                frame[r * tile_h : (r + 1) * tile_h, c * tile_w : (c + 1) * tile_w] = tile
            yield frame
    finally:
        renderer.close()


ALL = "all"  # the camera name that tiles every camera of the scene


def camera_names(world: World) -> tuple[str, ...]:
    """The scene's cameras, in the model's order."""
    return tuple(world.model.camera(i).name for i in range(world.model.ncam))


def render_model(world: World) -> RenderModel | None:
    """The scene's render model, built once per scene (None: draw the simulated model)."""
    if "render_model" not in world.cache:
        world.cache["render_model"] = dressed_model(world.model, world.xml, world.robot)
    return world.cache["render_model"]
