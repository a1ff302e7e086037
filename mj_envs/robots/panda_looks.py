"""Draw the Panda with Franka's real link meshes, in rendered frames only.

``assets/panda.xml`` models the arm with primitive capsules and boxes: they are its
collision geometry and keep contacts fast. Videos should still show a recognisable
Panda, so :func:`dressed_model` compiles a *render model* of a task's scene: the same
MJCF plus Franka's visual link meshes (shipped, Apache-2.0, in the ``gymnasium-robotics``
wheel's kitchen assets, read from the installed package) as geoms that never collide, with
the primitives they replace moved to a geom group renders hide. The fingers keep their
primitive boxes and pads in view: ours are shorter than Franka's, and the pads are what
grasps.

Why only at render time: the simulated scene stays exactly as it was (the same MJCF
text in datasets, the same compile time and the same cost of every step: meshes in the
simulated model would make MuJoCo pose 9 more geoms on every substep, ~1-2 % of a step),
and a dataset never depends on the mesh package. Adding geoms adds no degree of freedom,
actuator or userdata, so the render model takes the simulated model's flat state as it is.
Without ``gymnasium-robotics`` frames fall back to the primitives with one warning.
"""

from __future__ import annotations

import functools
import importlib.util
import warnings
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from mj_envs.robots.panda import PANDA, Robot

VISUAL_GROUP = 2  # drawn by default (MuJoCo shows groups 0-2)
HIDDEN_COLLISION_GROUP = 3  # hidden by default: the primitives the meshes replace
MESH_PACKAGE = "gymnasium_robotics"
MESH_SUBDIR = ("envs", "assets", "kitchen_franka", "franka_assets", "meshes", "visual")
FACES_PER_MESH = 1500  # after decimation: ~14k triangles for the whole arm
VISUAL_SUFFIX = "_visual"

WHITE = (0.93, 0.93, 0.95, 1.0)
DARK = (0.2, 0.2, 0.22, 1.0)
# body of assets/panda.xml -> (mesh file stem, colour); each mesh is in its body's frame
LINK_MESHES: dict[str, tuple[str, tuple[float, float, float, float]]] = {
    "link0": ("link0", WHITE),
    "link1": ("link1", WHITE),
    "link2": ("link2", WHITE),
    "link3": ("link3", WHITE),
    "link4": ("link4", WHITE),
    "link5": ("link5", WHITE),
    "link6": ("link6", WHITE),
    "link7": ("link7", DARK),
    "hand": ("hand", WHITE),
}


@dataclass(frozen=True, eq=False)
class Mesh:
    vertices: np.ndarray  # (n, 3) metres, in the link's frame
    faces: np.ndarray  # (m, 3) vertex indices


def franka_mesh_dir() -> Path | None:
    """Where the installed ``gymnasium-robotics`` keeps Franka's visual STL files.

    Found without importing the package (its import registers many environments).
    """
    spec = importlib.util.find_spec(MESH_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        return None
    folder = Path(next(iter(spec.submodule_search_locations))).joinpath(*MESH_SUBDIR)
    return folder if folder.is_dir() else None


def decimated(path: Path, faces: int = FACES_PER_MESH) -> Mesh:
    """The mesh at ``path`` reduced to about ``faces`` triangles."""
    mesh = trimesh.load_mesh(path, file_type="stl")
    if len(mesh.faces) > faces:
        mesh = mesh.simplify_quadric_decimation(face_count=faces)
    return Mesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, np.int32))


@functools.lru_cache(maxsize=1)
def franka_meshes() -> dict[str, Mesh] | None:
    """Decimated visual meshes per link stem, or None (one warning) when unavailable."""
    folder = franka_mesh_dir()
    if folder is None or not all((folder / f"{s}.stl").is_file() for s, _ in LINK_MESHES.values()):
        warnings.warn(
            "Franka link meshes not found (install `gymnasium-robotics`); "
            "the Panda is drawn from its collision primitives",
            stacklevel=2,
        )
        return None
    return {stem: decimated(folder / f"{stem}.stl") for stem, _ in LINK_MESHES.values()}


@dataclass(frozen=True, eq=False)
class RenderModel:
    """A scene's render model and, for each geom of the simulated model, its id here."""

    model: mujoco.MjModel
    geom_ids: np.ndarray


def dressed_model(sim_model: mujoco.MjModel, xml: str, robot: Robot = PANDA) -> RenderModel | None:
    """``xml`` (the scene of ``sim_model``) with the robot's link meshes, or None when the
    meshes are unavailable (then render the simulated model itself)."""
    meshes = franka_meshes()
    if meshes is None:
        return None
    spec = mujoco.MjSpec.from_string(xml)
    spec.nuserdata = sim_model.nuserdata  # a perturbed scene's latency queue is state too
    for body_name, (stem, colour) in LINK_MESHES.items():
        body = spec.body(robot.scene_name(body_name))
        for geom in body.geoms:
            geom.group = HIDDEN_COLLISION_GROUP
        mesh = spec.add_mesh()
        mesh.name = robot.scene_name(stem + VISUAL_SUFFIX)
        mesh.uservert = meshes[stem].vertices.ravel()
        mesh.userface = meshes[stem].faces.ravel()
        geom = body.add_geom()
        geom.name = robot.scene_name(body_name + VISUAL_SUFFIX)
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh.name
        geom.rgba = colour
        geom.contype = geom.conaffinity = 0
        geom.group = VISUAL_GROUP
        geom.mass = 0.0
    model = spec.compile()
    added = {model.geom(robot.scene_name(b + VISUAL_SUFFIX)).id for b in LINK_MESHES}
    kept = np.array([g for g in range(model.ngeom) if g not in added], dtype=np.int64)
    if kept.size != sim_model.ngeom or (
        mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION)
        != mujoco.mj_stateSize(sim_model, mujoco.mjtState.mjSTATE_INTEGRATION)
    ):
        raise RuntimeError("the render model does not match the simulated scene")
    return RenderModel(model, kept)
