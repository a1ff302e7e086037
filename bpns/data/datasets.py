"""Demonstrations on disk: HDF5, one group per episode (robomimic-like).

Layout::

    /                      attrs: env, format, num_demos
    /data/demo_<i>/actions (k, action_dim) float64   executed (replay uses these)
    /data/demo_<i>/expert_actions (k, action_dim)    optional: the demonstrator's commands
                                                     where noise was injected (learning
                                                     imitates these)
    /data/demo_<i>/states  (k+1, state_dim) float64   flat simulator states
    /data/demo_<i>/features/<object>  (k+1, dim) float64
      attrs: world (the task's MJCF text), goal (JSON [[predicate, [objects]]]),
             objects (JSON [[name, type]]), horizon, num_samples

``num_demos`` is for other readers of the file: bpns never reads it, and counts the
``demo_<i>`` groups instead (an edited attribute misleads nothing here). Files are
written atomically (temp file + rename); reading validates structure and
turns h5py's low-level errors into one :class:`DatasetError` that names the file.
Learning reads only features, actions and goals: ``features_only=True`` loads those
(3-5x faster, ``scripts/bench_loading.py``) without compiling each demo's scene (the
flat states are still read and checked finite).
"""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import h5py
import numpy as np

from bpns.atomic import atomic_path
from bpns.data import dataset_checks as checks
from bpns.env.environment import Environment, perturbed
from bpns.env.perturbations import Perturbation, PerturbationError
from bpns.errors import BpnsError
from bpns.structs import Demonstration, GroundAtom, Object, SimState, State, Task

FORMAT = "bpns-demos-1"


class DatasetError(BpnsError, ValueError):
    """A demonstration file is missing, corrupt, truncated or not of this format."""


def save_demonstrations(
    path: str | os.PathLike, env: Environment, demos: Iterable[Demonstration]
) -> int:
    """Write ``demos`` to ``path`` atomically; returns how many were written."""
    return write_demonstrations(path, env, ((d, {}) for d in demos))


def write_demonstrations(
    path: str | os.PathLike,
    env: Environment,
    items: Iterable[tuple[Demonstration, Mapping[str, str | int]]],
    attrs: Mapping[str, str | int] | None = None,
) -> int:
    """:func:`save_demonstrations` with extra attributes: ``attrs`` on the root and each
    item's own on its demo group (rollouts files keep their plans there)."""
    n = 0
    with atomic_path(path, ".h5") as tmp:
        with h5py.File(tmp, "w") as f:
            f.attrs["env"] = env.name
            f.attrs["format"] = FORMAT
            f.attrs.update(dict(attrs or {}))
            data = f.create_group("data")
            for demo, extra in items:
                g = data.create_group(f"demo_{n}")
                _write_demo(g, env, demo)
                g.attrs.update(dict(extra))
                n += 1
            f.attrs["num_demos"] = n
    return n


# Where each demonstration's task came from (``bpns demos`` since 2026-12-06): the task
# stream's seed on the root, each demonstration's task index on its group, so that its
# task (``env.task(index, seed, train=True)``) and its demonstrator (seeded
# ``[seed, index]``) can be made again, e.g. to ask the demonstrator about other states.
TASK_SEED, TASK_INDEX = "task_seed", "task"


def task_origins(path: str | os.PathLike) -> list[tuple[int, int]]:
    """(task seed, task index) of every demonstration in ``path``, in file order; a
    :class:`DatasetError` when the file does not record them (older files: collect the
    demonstrations again with ``bpns demos``)."""
    root, demos = read_attributes(path)
    seed = root.get(TASK_SEED)
    indices = [d.get(TASK_INDEX) for d in demos]
    if not _is_count(seed) or not all(_is_count(i) for i in indices):
        raise DatasetError(
            f"{path} does not record which task each demonstration solved (written before "
            "task origins were stored, or not by `bpns demos`): collect them again with "
            "`bpns demos`"
        )
    return [(int(seed), int(i)) for i in indices]  # type: ignore[arg-type]


def _is_count(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool) and value >= 0


def read_attributes(path: str | os.PathLike) -> tuple[dict, list[dict]]:
    """The root attributes and each demo's own (those besides the format's), as stored."""
    own = {"world", "goal", "objects", "horizon", "num_samples"}
    with _open(path) as f:
        data = _data(f, path)
        root = {k: _plain(v) for k, v in f.attrs.items()}
        demos = [
            {k: _plain(v) for k, v in data[name].attrs.items() if k not in own}
            for name in _names(data, path)
        ]
    return root, demos


def _plain(value: object) -> object:
    return value.item() if isinstance(value, np.generic) else value


def min_demo_bytes(env: Environment, task: Task) -> int:
    """A lower bound of the bytes one demonstration of ``task`` takes in a file: its
    scene's MJCF and two state rows (its first and last) and one action. Real ones are
    several times larger (every step is a row), so ``n`` times this that does not fit
    on a disk is certain not to fit."""
    init = task.init
    assert init.sim is not None, "a task's initial state carries its simulator state"
    row = init.sim.flat.nbytes + sum(np.asarray(v).nbytes for v in init.data.values())
    return len(env.save_world(init.sim.world).encode()) + 2 * row + 8 * len(env.action_low)


def _write_demo(g: h5py.Group, env: Environment, demo: Demonstration) -> None:
    first = demo.states[0]
    assert first.sim is not None, "demonstration states must carry simulator states"
    actions = np.asarray(demo.actions, dtype=np.float64)
    if actions.size == 0:  # a rollout that never acted: still (0, action_dim)
        actions = np.zeros((0, len(env.action_low)))
    g.create_dataset("actions", data=actions)
    if demo.expert_actions is not None:  # noise-injected demos: what the expert commanded
        g.create_dataset("expert_actions", data=np.asarray(demo.expert_actions, np.float64))
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
    path: str | os.PathLike,
    env: Environment,
    indices: Iterable[int] | None = None,
    *,
    features_only: bool = False,
) -> list[Demonstration]:
    return list(iter_demonstrations(path, env, indices, features_only=features_only))


def count_demonstrations(path: str | os.PathLike) -> int:
    with _open(path) as f:
        return len(_names(_data(f, path), path))


def iter_demonstrations(
    path: str | os.PathLike,
    env: Environment,
    indices: Iterable[int] | None = None,
    *,
    features_only: bool = False,
) -> Iterator[Demonstration]:
    """The demonstrations at ``indices`` (default: all), checked as they are read.

    ``features_only``: states carry their object features but no simulator state
    (``State.sim`` is None), and the task's scene is not compiled. That is all learning
    reads, and compiling one MJCF scene per demonstration is most of the loading time;
    replaying, rendering or planning from the loaded states needs the default."""
    with _open(path) as f:
        data = _data(f, path)
        stored_env = checks.root_text_attr(f, "env")
        if stored_env != env.name:
            raise DatasetError(f"{path}: holds demonstrations of {stored_env!r}, not {env.name!r}")
        names = _names(data, path)
        chosen = names if indices is None else [f"demo_{i}" for i in indices]
        for name in chosen:
            if name not in data:
                raise DatasetError(f"{path}: has no {name} (it holds {len(names)} demos)")
            try:
                demo = _read_demo(data[name], env, features_only)
            except (KeyError, ValueError, TypeError, OSError, RuntimeError) as err:
                raise DatasetError(f"{path}: {name} is damaged: {err}") from None
            yield demo


def _names(data: h5py.Group, path: str | os.PathLike) -> list[str]:
    try:
        return checks.demo_names(data)
    except (KeyError, ValueError, TypeError, OSError, RuntimeError) as err:
        raise DatasetError(f"{path}: {err}") from None


def not_a_demo_file(path: Path) -> str | None:
    """Why ``path`` cannot be a demonstration file without opening it (missing, a
    directory, a FIFO or device: reading one could block or never end), else None."""
    if not path.exists():
        return f"{path}: no such demonstration file"
    mode = path.stat().st_mode
    if stat.S_ISDIR(mode):
        return f"{path}: is a directory, not a demonstration file"
    if not stat.S_ISREG(mode):
        return f"{path}: not a regular file (a FIFO, socket or device), not a demonstration file"
    return None


def _open(path: str | os.PathLike) -> h5py.File:
    p = Path(path)
    problem = not_a_demo_file(p)
    if problem is not None:
        raise DatasetError(problem)
    try:
        return h5py.File(p, "r")
    except OSError as err:
        raise DatasetError(
            f"{p}: not a readable HDF5 file (corrupt or truncated?): {err}"
        ) from None


def _data(f: h5py.File, path: str | os.PathLike) -> h5py.Group:
    found = checks.root_text_attr(f, "format")
    what = None
    if found is None:
        what = "it has no format attribute"
    elif found != FORMAT:
        what = f"its format is {found!r}"
    elif "data" not in f:
        what = "it has no /data group"
    if what is not None:
        raise DatasetError(
            f"{path}: not a bpns demonstration file ({what}; expected format {FORMAT!r})"
        )
    try:
        return checks.member(f, "data", h5py.Group)
    except ValueError as err:
        raise DatasetError(f"{path}: /data: {err}") from None


def _read_demo(g: h5py.Group, env: Environment, features_only: bool) -> Demonstration:
    """Read and check one demo group (see :mod:`bpns.data.dataset_checks`); ValueError naming
    the first problem."""
    types = {t.name: t for t in env.types}
    preds = {p.name: p for p in env.predicates}
    objects = {}
    for name, tname in checks.parse_objects(checks.json_attr(g, "objects")):
        if tname not in types:
            raise ValueError(f"object {name!r} has unknown type {tname!r}")
        objects[name] = Object(name, types[tname])
    goal_spec = checks.parse_goal(checks.json_attr(g, "goal"))
    horizon = checks.int_attr(g, "horizon", 1, checks.MAX_ROWS)
    actions = checks.read_matrix(g, "actions", len(env.action_low))
    expert = (
        checks.read_matrix(g, "expert_actions", len(env.action_low))
        if "expert_actions" in g
        else None
    )
    if expert is not None and expert.shape != actions.shape:
        raise ValueError(f"expert_actions has shape {expert.shape}, actions {actions.shape}")
    feat_group = checks.member(g, "features", h5py.Group)
    if set(feat_group) != set(objects):
        raise ValueError(
            f"features are stored for {sorted(feat_group)}, the objects are {sorted(objects)}"
        )
    feats = {o: checks.read_matrix(feat_group, n, o.type.dim) for n, o in objects.items()}
    ds = checks.member(g, "states", h5py.Dataset)
    declared = ds.shape if len(ds.shape) == 2 else (-1, -1)  # (rows, flat state size)
    # read (and checked finite) also when learning skips them: a file with damaged
    # simulator states is refused by every command alike, not only by replay and render
    flats = checks.read_matrix(g, "states", declared[1])
    rows = len(flats)
    if rows != len(actions) + 1 or any(len(v) != rows for v in feats.values()):
        raise ValueError("states, features and actions have inconsistent lengths")
    sims: list[SimState | None] = [None] * rows
    if not features_only:
        env = _own_physics(g, env)
        try:
            world = env.load_world(checks.text_attr(g, "world"))
        except ValueError as err:  # does not compile, or its physics cannot be simulated
            raise ValueError(
                f"its stored scene (attribute 'world') is unusable: {err}; write "
                "the file again (`bpns demos --out` or `bpns eval --out`)"
            ) from None
        # only the environment knows its flat state size: let it load the first state
        env.state_from_flat(world, flats[0], State({o: v[0] for o, v in feats.items()}))
        sims = [SimState(world, flat) for flat in flats]
    keys = tuple(sorted(feats))
    # row views, made once per object (every length was checked above)
    per_row = zip(*(list(feats[o]) for o in keys), strict=True)
    states = tuple(
        State.over_sorted(keys, dict(zip(keys, row, strict=True)), sim)
        for row, sim in zip(per_row, sims, strict=True)
    )
    goal = set()
    for pname, args in goal_spec:
        if pname not in preds:
            raise ValueError(f"goal uses unknown predicate {pname!r}")
        if any(a not in objects for a in args):
            raise ValueError(f"goal atom {pname}{tuple(args)} names an unknown object")
        goal.add(GroundAtom(preds[pname], tuple(objects[o] for o in args)))  # TypeError: arity
    task = Task(init=states[0], goal=frozenset(goal), horizon=horizon)
    return Demonstration(task=task, states=states, actions=actions, expert_actions=expert)


def _own_physics(g: h5py.Group, env: Environment) -> Environment:
    """``env`` under the physics the demo was recorded in (its ``physics`` attribute:
    ``bpns demos --perturb``, a rollout's world), so its simulator states load into a
    scene of their own size (latency adds a queue to the state)."""
    if "physics" not in g.attrs:
        return env
    try:
        physics = Perturbation.from_json(checks.text_attr(g, "physics"))
        return perturbed(env, physics)
    except (PerturbationError, TypeError) as err:
        raise ValueError(f"its 'physics' record is unusable: {err}") from None
