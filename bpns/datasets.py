"""Demonstrations on disk: HDF5, one group per episode (robomimic-like).

Layout::

    /                      attrs: env, format, num_demos
    /data/demo_<i>/actions (k, action_dim) float64
    /data/demo_<i>/states  (k+1, state_dim) float64   flat simulator states
    /data/demo_<i>/features/<object>  (k+1, dim) float64
      attrs: world (the task's MJCF text), goal (JSON [[predicate, [objects]]]),
             objects (JSON [[name, type]]), horizon, num_samples

Files are written atomically (temp file + rename); reading validates structure and
turns h5py's low-level errors into one :class:`DatasetError` that names the file.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import h5py
import numpy as np

from bpns.atomic import atomic_path
from bpns.environment import Environment
from bpns.structs import Demonstration, GroundAtom, Object, SimState, State, Task

FORMAT = "bpns-demos-1"


class DatasetError(ValueError):
    """A demonstration file is missing, corrupt, truncated or not of this format."""


def save_demonstrations(
    path: str | os.PathLike, env: Environment, demos: Iterable[Demonstration]
) -> int:
    """Write ``demos`` to ``path`` atomically; returns how many were written."""
    n = 0
    with atomic_path(path, ".h5") as tmp:
        with h5py.File(tmp, "w") as f:
            f.attrs["env"] = env.name
            f.attrs["format"] = FORMAT
            data = f.create_group("data")
            for demo in demos:
                _write_demo(data.create_group(f"demo_{n}"), env, demo)
                n += 1
            f.attrs["num_demos"] = n
    return n


def _write_demo(g: h5py.Group, env: Environment, demo: Demonstration) -> None:
    first = demo.states[0]
    assert first.sim is not None, "demonstration states must carry simulator states"
    g.create_dataset("actions", data=np.asarray(demo.actions, dtype=np.float64))
    g.create_dataset("states", data=np.stack([s.sim.flat for s in demo.states]))
    feats = g.create_group("features")
    for obj in first.objects:
        feats.create_dataset(obj.name, data=np.stack([s.data[obj] for s in demo.states]))
    g.attrs["world"] = env.save_world(first.sim.world)
    g.attrs["goal"] = json.dumps(
        sorted([a.predicate.name, [o.name for o in a.objects]] for a in demo.task.goal)
    )
    g.attrs["objects"] = json.dumps([[o.name, o.type.name] for o in first.objects])
    g.attrs["horizon"] = demo.task.horizon
    g.attrs["num_samples"] = len(demo.actions)


def load_demonstrations(
    path: str | os.PathLike, env: Environment, indices: Iterable[int] | None = None
) -> list[Demonstration]:
    return list(iter_demonstrations(path, env, indices))


def count_demonstrations(path: str | os.PathLike) -> int:
    with _open(path) as f:
        return len(_data(f, path))


def iter_demonstrations(
    path: str | os.PathLike, env: Environment, indices: Iterable[int] | None = None
) -> Iterator[Demonstration]:
    with _open(path) as f:
        data = _data(f, path)
        if f.attrs.get("env") != env.name:
            raise DatasetError(
                f"{path}: holds demonstrations of {f.attrs.get('env')!r}, not {env.name!r}"
            )
        names = sorted(data, key=lambda k: int(k.split("_")[1]))
        chosen = names if indices is None else [f"demo_{i}" for i in indices]
        for name in chosen:
            if name not in data:
                raise DatasetError(f"{path}: has no {name} (it holds {len(names)} demos)")
            try:
                yield _read_demo(data[name], env)
            except (KeyError, ValueError, OSError) as err:
                raise DatasetError(f"{path}: {name} is damaged: {err}") from None


def _open(path: str | os.PathLike) -> h5py.File:
    p = Path(path)
    if not p.is_file():
        raise DatasetError(f"{p}: no such demonstration file")
    try:
        return h5py.File(p, "r")
    except OSError as err:
        raise DatasetError(
            f"{p}: not a readable HDF5 file (corrupt or truncated?): {err}"
        ) from None


def _data(f: h5py.File, path: str | os.PathLike) -> h5py.Group:
    if f.attrs.get("format") != FORMAT or "data" not in f:
        raise DatasetError(f"{path}: not a bpns demonstration file (format {FORMAT!r})")
    return f["data"]


def _read_demo(g: h5py.Group, env: Environment) -> Demonstration:
    types = {t.name: t for t in env.types}
    preds = {p.name: p for p in env.predicates}
    objects = {}
    for name, tname in json.loads(g.attrs["objects"]):
        if tname not in types:
            raise ValueError(f"unknown type {tname!r}")
        objects[name] = Object(name, types[tname])
    world = env.load_world(str(g.attrs["world"]))
    flats = np.asarray(g["states"], dtype=np.float64)
    actions = np.asarray(g["actions"], dtype=np.float64)
    feats = {objects[n]: np.asarray(g["features"][n], dtype=np.float64) for n in objects}
    if len(flats) != len(actions) + 1 or any(len(v) != len(flats) for v in feats.values()):
        raise ValueError("states, features and actions have inconsistent lengths")
    states = tuple(
        State({o: v[i] for o, v in feats.items()}, SimState(world, flats[i]))
        for i in range(len(flats))
    )
    goal = frozenset(
        GroundAtom(preds[p], tuple(objects[o] for o in objs))
        for p, objs in json.loads(g.attrs["goal"])
    )
    task = Task(init=states[0], goal=goal, horizon=int(g.attrs["horizon"]))
    return Demonstration(task=task, states=states, actions=actions)
