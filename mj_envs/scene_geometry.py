"""The 3D scene of a task's states as arrays (``MujocoEnv.scene``, for ``bpns view``).

Geometry comes from the scene's render model (:mod:`mj_envs.robots.panda_looks`: the
task's MJCF plus Franka's link meshes), so a recording shows the Panda as videos do:
every geom MuJoCo draws by default (groups 0-2, not fully transparent) as a primitive or
a triangle mesh in its body's frame. Poses are the simulated model's forward kinematics
of each flat state on a scratch ``MjData`` (adding looks adds no body, so the bodies and
their poses are the same in both models).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from bpns.env.scene import Anchor, SceneGeom, SceneTrack
from bpns.structs import State
from mj_envs.render import render_model
from mj_envs.robots.panda import panda_ids
from mj_envs.world import STATE_SPEC, World

_SHAPES = {
    mujoco.mjtGeom.mjGEOM_PLANE: "plane",
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_MESH: "mesh",
}
VISIBLE_GROUPS = 3  # MuJoCo's viewer and renderer show geom groups 0, 1 and 2
INFINITE_PLANE_HALF_SIZE = 2.0  # metres drawn of a plane MJCF declares infinite (size 0)
_DEFAULT_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)


def scene_track(states: Sequence[State], anchors: Mapping[str, tuple[Anchor, ...]]) -> SceneTrack:
    """The scene of ``states``, which share one task's world."""
    world = states[0].sim.world
    assert isinstance(world, World)
    body_ids, bodies, geoms = scene_geoms(world)
    grip = panda_ids(world.model, world.cache, world.robot).grip_site
    data = mujoco.MjData(world.model)
    n = len(states)
    positions = np.empty((n, len(bodies), 3))
    quats = np.empty((n, len(bodies), 4))
    hand = np.empty((n, 3))
    times = np.empty(n)
    for t, state in enumerate(states):
        if state.sim is None or state.sim.world is not world:
            raise ValueError("the states of one scene track must share one task's world")
        mujoco.mj_setState(world.model, data, state.sim.flat, STATE_SPEC)
        mujoco.mj_kinematics(world.model, data)
        positions[t] = data.xpos[body_ids]
        quats[t] = data.xquat[body_ids]
        hand[t] = data.site_xpos[grip]
        times[t] = data.time
    return SceneTrack(tuple(bodies), geoms, positions, quats, hand, times, anchors)


def scene_geoms(world: World) -> tuple[list[int], tuple[str, ...], tuple[SceneGeom, ...]]:
    """(ids and names of the bodies that carry visible geoms, those geoms), cached per
    scene (body ids are the same in the render model and the simulated one)."""
    key = "scene_geoms"
    if key not in world.cache:
        dressed = render_model(world)
        model = dressed.model if dressed is not None else world.model
        world.cache[key] = _visible_geoms(model)
    return world.cache[key]


def _visible_geoms(
    model: mujoco.MjModel,
) -> tuple[list[int], tuple[str, ...], tuple[SceneGeom, ...]]:
    bodies: dict[int, int] = {}  # model body id -> index in the track
    geoms = []
    for g in range(model.ngeom):
        shape = _SHAPES.get(int(model.geom_type[g]))
        rgba = _rgba(model, g)
        if shape is None or model.geom_group[g] >= VISIBLE_GROUPS or rgba[3] <= 0.0:
            continue
        body = int(model.geom_bodyid[g])
        index = bodies.setdefault(body, len(bodies))
        vertices = faces = None
        size = tuple(float(s) for s in model.geom_size[g])
        if shape == "mesh":
            m = int(model.geom_dataid[g])
            v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
            f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
            vertices = np.array(model.mesh_vert[v0 : v0 + nv], dtype=np.float32)
            faces = np.array(model.mesh_face[f0 : f0 + nf], dtype=np.int32)
        elif shape == "plane":
            size = tuple(s if s > 0 else INFINITE_PLANE_HALF_SIZE for s in size[:2]) + (0.0,)
        geoms.append(
            SceneGeom(
                name=model.geom(g).name or f"geom{g}",
                body=index,
                shape=shape,
                size=size,  # type: ignore[arg-type]
                rgba=tuple(float(c) for c in rgba),  # type: ignore[arg-type]
                pos=tuple(float(p) for p in model.geom_pos[g]),  # type: ignore[arg-type]
                quat=tuple(float(q) for q in model.geom_quat[g]),  # type: ignore[arg-type]
                vertices=vertices,
                faces=faces,
            )
        )
    ids = sorted(bodies, key=bodies.__getitem__)
    names = tuple(model.body(b).name or ("world" if b == 0 else f"body{b}") for b in ids)
    return ids, names, tuple(geoms)


def _rgba(model: mujoco.MjModel, g: int) -> np.ndarray:
    """A geom's colour about as MuJoCo draws it: its material's unless it sets its own,
    times the mean colour of the material's texture (a table's wood, a floor's checks)."""
    rgba = np.array(model.geom_rgba[g], dtype=np.float64)
    mat = int(model.geom_matid[g])
    if mat < 0:
        return rgba
    if np.array_equal(model.geom_rgba[g], _DEFAULT_RGBA):
        rgba = np.array(model.mat_rgba[mat], dtype=np.float64)
    tex = int(model.mat_texid[mat, mujoco.mjtTextureRole.mjTEXROLE_RGB])
    if tex >= 0 and model.tex_nchannel[tex] >= 3:
        n = model.tex_height[tex] * model.tex_width[tex] * model.tex_nchannel[tex]
        start = model.tex_adr[tex]
        pixels = model.tex_data[start : start + n].reshape(-1, model.tex_nchannel[tex])
        rgba[:3] *= pixels[:, :3].mean(axis=0) / 255.0
    return rgba
