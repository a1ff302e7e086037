"""An episode as a Rerun recording (.rrd): the 3D scene and the symbolic state, lined up.

Timelines ``step`` (control step: state ``i`` follows action ``i - 1``) and ``sim_time``.
Entities (docs/INSPECT.md):

- ``world/bodies/<body>``: each body's pose at every step, its geoms (primitives and
  meshes) beneath it; ``world/hand``: the robot's grip point; ``world/subgoal``: the
  points the current skill's subgoal aims at (its objects' 3D features);
- ``atoms/<atom>``: every ground atom's truth (0/1) at every step; ``atoms_true``: the
  abstract state (the atoms true), where it changes;
- ``features/<object>``: every object's features at every step (the states' own);
- ``plan/skill`` (index of the skill being executed), ``plan/log`` (each skill as it
  starts and how it ended, the episode's outcome), ``plan/current`` (the skill, its
  objects, subgoal and outcome), ``events`` (the execution monitor's, if any),
  ``planner/attempts`` (a failed task: the abstract plans tried and why each failed);
- ``cameras/<name>``: rendered camera images, when asked for.

This module imports ``rerun``, an optional extra: import it only where a recording is
asked for (:func:`bpns.inspect.extras.require`).
"""

from __future__ import annotations

import errno
import io
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from PIL import Image

from bpns.atomic import atomic_path, nearly_full
from bpns.env.scene import SceneGeom, SceneTrack
from bpns.errors import BpnsError
from bpns.execution.rollouts import REACHED, PlanStep
from bpns.execution.video import VideoError
from bpns.inspect.episodes import Episode, atom_label, atom_timeline, skill_per_state
from bpns.inspect.explain import explanation_markdown

APP_ID = "bpns"
STEP = "step"
SIM_TIME = "sim_time"
EVENT_LEVELS = {
    "replanned": "INFO",
    "rerefined": "INFO",
    "slowed": "INFO",
    "replan_failed": "ERROR",
}


class RecordingError(BpnsError):
    """A recording could not be written (the partial file is removed)."""


@dataclass(frozen=True)
class RecordingOptions:
    """What a recording holds beyond the scene and the timelines."""

    cameras: tuple[str, ...] = ()  # render these cameras' images at every step
    width: int = 320
    height: int = 240


def write_recording(
    episode: Episode, out: str | os.PathLike, options: RecordingOptions | None = None
) -> int:
    """Write ``episode`` to ``out`` (atomically); returns the number of steps recorded."""
    states = episode.demo.states
    options = options or RecordingOptions()
    with atomic_path(out, ".rrd") as tmp:
        rec = rr.RecordingStream(APP_ID, recording_id=f"{episode.title}")
        rr.set_log_time_enabled(False, recording=rec)  # the steps are the time here
        track = episode.env.scene(states)
        rec.save(tmp, default_blueprint=_blueprint(episode, options, track))
        rec.send_recording_name(episode.title)
        index = _index(len(states), track)
        if track is not None:
            _log_scene(rec, track, index)
            _log_subgoals(rec, episode, track)
        _log_atoms(rec, episode, index)
        _log_features(rec, episode, index)
        _log_plan(rec, episode, index)
        _log_events(rec, episode)
        _log_attempts(rec, episode)
        for camera in options.cameras:
            _log_camera(rec, episode, camera, options)
        try:
            rec.flush()
        except RuntimeError as err:  # rerun's file writer died: it says only that
            raise _write_failure(out, err) from None
        rec.disconnect()
    return len(states)


def _write_failure(out: str | os.PathLike, err: RuntimeError) -> Exception:
    """Why rerun could not write ``out``: a full disk as the OSError a command reports in
    one line (:func:`bpns.atomic.storage_problem`), else :class:`RecordingError`."""
    if nearly_full(out) is not None:
        return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out))
    return RecordingError(f"cannot write {out}: rerun's file writer stopped ({err})")


def _index(n: int, track: SceneTrack | None) -> list[rr.TimeColumn]:
    columns = [rr.TimeColumn(STEP, sequence=np.arange(n))]
    if track is not None:
        columns.append(rr.TimeColumn(SIM_TIME, duration=np.asarray(track.times)))
    return columns


def _eye(track: SceneTrack | None) -> rrb.EyeControls3D | None:
    """A view of the whole episode from the front, above, to the side: around the box
    every body and the hand went through."""
    if track is None:
        return None
    points = np.concatenate([track.positions.reshape(-1, 3), track.hand])
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2
    extent = max(float(np.max(high - low)), 0.8)
    position = centre + extent * np.array([1.1, -0.9, 0.7])
    return rrb.EyeControls3D(position=position, look_target=centre, eye_up=(0.0, 0.0, 1.0))


def _blueprint(
    episode: Episode, options: RecordingOptions, track: SceneTrack | None
) -> rrb.Blueprint:
    side = [
        rrb.TextDocumentView(origin="atoms_true", name="true atoms"),
        rrb.TimeSeriesView(origin="atoms", name="ground atoms (1 = true)"),
        rrb.TextLogView(origin="/", contents=["plan/log", "events"], name="skills and events"),
        rrb.TextDocumentView(origin="plan/current", name="current skill"),
    ]
    if episode.solved is False:
        side.append(rrb.TextDocumentView(origin="planner/attempts", name="planner attempts"))
    main: list = [rrb.Spatial3DView(origin="world", name="scene", eye_controls=_eye(track))]
    main += [rrb.Spatial2DView(origin=f"cameras/{c}", name=c) for c in options.cameras]
    main.append(rrb.TimeSeriesView(origin="features", name="features"))
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Tabs(*main), rrb.Vertical(*side), column_shares=[3, 2]),
        collapse_panels=False,
    )


# ----------------------------------------------------------------------------- the scene


def _xyzw(wxyz: np.ndarray) -> np.ndarray:
    return np.asarray(wxyz, dtype=np.float64)[..., [1, 2, 3, 0]]


def _log_scene(rec: rr.RecordingStream, track: SceneTrack, index: list[rr.TimeColumn]) -> None:
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for k, body in enumerate(track.bodies):
        path = f"world/bodies/{rr.escape_entity_path_part(body)}"
        rec.send_columns(
            path,
            indexes=index,
            columns=rr.Transform3D.columns(
                translation=track.positions[:, k], quaternion=_xyzw(track.quaternions[:, k])
            ),
        )
    for geom in track.geoms:
        body = rr.escape_entity_path_part(track.bodies[geom.body])
        path = f"world/bodies/{body}/{rr.escape_entity_path_part(geom.name)}"
        rec.log(
            path,
            rr.Transform3D(translation=geom.pos, quaternion=_xyzw(np.array(geom.quat))),
            static=True,
        )
        rec.log(path, _shape(geom), static=True)
    rec.send_columns(
        "world/hand",
        indexes=index,
        columns=rr.Points3D.columns(positions=track.hand, radii=np.full(len(track), 0.012)),
    )
    rec.log("world/hand", rr.Points3D.from_fields(colors=[(255, 200, 0)]), static=True)


def _shape(geom: SceneGeom) -> rr.AsComponents:
    colour = [int(round(255 * c)) for c in geom.rgba]
    sx, sy, sz = geom.size
    if geom.shape == "box":
        return rr.Boxes3D(half_sizes=[(sx, sy, sz)], colors=[colour], fill_mode="solid")
    if geom.shape == "plane":
        return rr.Boxes3D(half_sizes=[(sx, sy, 0.0)], colors=[colour], fill_mode="solid")
    if geom.shape == "sphere":
        return rr.Ellipsoids3D(half_sizes=[(sx, sx, sx)], colors=[colour], fill_mode="solid")
    if geom.shape == "ellipsoid":
        return rr.Ellipsoids3D(half_sizes=[(sx, sy, sz)], colors=[colour], fill_mode="solid")
    if geom.shape == "capsule":
        return rr.Capsules3D(
            lengths=[2 * sy], radii=[sx], translations=[(0, 0, -sy)], colors=[colour]
        )
    if geom.shape == "cylinder":
        return rr.Cylinders3D(lengths=[2 * sy], radii=[sx], colors=[colour], fill_mode="solid")
    assert geom.vertices is not None and geom.faces is not None
    return rr.Mesh3D(
        vertex_positions=geom.vertices,
        triangle_indices=geom.faces,
        vertex_normals=_vertex_normals(geom.vertices, geom.faces),
        albedo_factor=colour,
    )


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals, for smooth shading of a mesh."""
    v = vertices.astype(np.float64)
    face_normals = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    normals = np.zeros_like(v)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_normals)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return (normals / np.where(length > 0, length, 1.0)).astype(np.float32)


def _log_subgoals(rec: rr.RecordingStream, episode: Episode, track: SceneTrack) -> None:
    """At each skill's first step, the points its subgoal aims at (cleared when a skill
    has none, or its subgoal is not over its objects' features)."""
    objects = {o.name: o for o in episode.demo.states[0].objects}
    for step in episode.steps:
        rec.set_time(STEP, sequence=_first_state(step))
        points, labels = _subgoal_points(step, objects, track)
        if points:
            rec.log(
                "world/subgoal",
                rr.Points3D(points, labels=labels, colors=[(230, 40, 200)], radii=0.015),
            )
        else:
            rec.log("world/subgoal", rr.Clear(recursive=False))
    rec.reset_time()


def _first_state(step: PlanStep) -> int:
    """The state a skill's first action applies to (a recording shows it from there)."""
    return step.start


def _subgoal_points(step: PlanStep, objects: dict, track: SceneTrack) -> tuple[list, list]:
    if step.subgoal is None or any(name not in objects for name in step.objects):
        return [], []
    scope = [objects[name] for name in step.objects]
    if len(step.subgoal) != sum(o.type.dim for o in scope):
        return [], []
    values = np.asarray(step.subgoal, dtype=np.float64)
    points, labels, at = [], [], 0
    for obj in scope:
        features = values[at : at + obj.type.dim]
        at += obj.type.dim
        for anchor in track.anchors.get(obj.type.name, ()):
            points.append(anchor.point(features))
            labels.append(f"{obj.name} {anchor.label}" if anchor.label != "centre" else obj.name)
    return points, labels


# ------------------------------------------------------------------ symbolic timelines


def _log_atoms(rec: rr.RecordingStream, episode: Episode, index: list[rr.TimeColumn]) -> None:
    atoms, truth = atom_timeline(episode)
    for k, atom in enumerate(atoms):
        label = atom_label(atom)
        path = f"atoms/{rr.escape_entity_path_part(label)}"
        rec.log(path, rr.SeriesLines(names=[label]), static=True)
        rec.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=truth[:, k]))
    # the abstract state: the atoms true at a step, logged where it changes
    for t in range(len(truth)):
        if t and np.array_equal(truth[t], truth[t - 1]):
            continue
        rec.set_time(STEP, sequence=t)
        true = [f"- {atom_label(a)}" for a, holds in zip(atoms, truth[t], strict=True) if holds]
        text = f"### true at step {t}\n\n" + "\n".join(true)
        rec.log("atoms_true", rr.TextDocument(text, media_type="text/markdown"))
    rec.reset_time()


def _log_features(rec: rr.RecordingStream, episode: Episode, index: list[rr.TimeColumn]) -> None:
    states = episode.demo.states
    for obj in states[0].objects:
        values = np.stack([s.data[obj] for s in states])
        path = f"features/{rr.escape_entity_path_part(obj.name)}"
        rec.log(path, rr.SeriesLines(names=list(obj.type.feature_names)), static=True)
        columns = rr.Scalars.columns(scalars=values.ravel()).partition([obj.type.dim] * len(values))
        rec.send_columns(path, indexes=index, columns=columns)


def _log_plan(rec: rr.RecordingStream, episode: Episode, index: list[rr.TimeColumn]) -> None:
    n = len(episode.demo.states)
    current = skill_per_state(episode.steps, n)
    rec.log("plan/skill", rr.SeriesLines(names=["skill being executed (1 = first)"]), static=True)
    rec.send_columns("plan/skill", indexes=index, columns=rr.Scalars.columns(scalars=current + 1.0))
    for k, step in enumerate(episode.steps):
        rec.set_time(STEP, sequence=_first_state(step))
        text = f"{k + 1}/{len(episode.steps)} {step.label}: {step.outcome}"
        level = "INFO" if step.outcome == REACHED else "WARN"
        rec.log("plan/log", rr.TextLog(text, level=level))
        rec.log(
            "plan/current",
            rr.TextDocument(_step_markdown(k, episode.steps), media_type="text/markdown"),
        )
    rec.set_time(STEP, sequence=n - 1)
    if episode.is_rollout:
        level = "INFO" if episode.solved else "ERROR"
        rec.log("plan/log", rr.TextLog(f"{episode.title}: {episode.outcome}", level=level))
    rec.reset_time()


def _step_markdown(k: int, steps: Sequence[PlanStep]) -> str:
    step = steps[k]
    subgoal = "none" if step.subgoal is None else ", ".join(f"{x:.3f}" for x in step.subgoal)
    return (
        f"### skill {k + 1} of {len(steps)}: {step.label}\n\n"
        f"- outcome: **{step.outcome}**\n- from action {step.start}\n- subgoal: {subgoal}\n"
    )


def _log_events(rec: rr.RecordingStream, episode: Episode) -> None:
    for event in episode.events:
        rec.set_time(STEP, sequence=event.at)
        level = EVENT_LEVELS.get(event.kind, "WARN")
        rec.log("events", rr.TextLog(f"{event.kind}: {event.text}", level=level))
    rec.reset_time()


def _log_attempts(rec: rr.RecordingStream, episode: Episode) -> None:
    if episode.solved is False:
        text = explanation_markdown(episode.explanation)
        rec.log("planner/attempts", rr.TextDocument(text, media_type="text/markdown"), static=True)


def _log_camera(
    rec: rr.RecordingStream, episode: Episode, camera: str, options: RecordingOptions
) -> None:
    frames = episode.env.render(list(episode.demo.states), camera, options.width, options.height)
    try:
        for i, frame in enumerate(frames):
            buffer = io.BytesIO()
            Image.fromarray(frame).save(buffer, format="JPEG", quality=85)
            rec.set_time(STEP, sequence=i)
            image = rr.EncodedImage(contents=buffer.getvalue(), media_type="image/jpeg")
            rec.log(f"cameras/{camera}", image)
    except (ValueError, RuntimeError) as err:  # e.g. a camera the scene does not have
        raise VideoError(f"camera images: {err}") from None
    rec.reset_time()
