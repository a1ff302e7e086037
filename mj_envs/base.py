"""Generic MuJoCo environment: everything a domain does not have to write itself.

A domain subclass declares its types, predicates (and which are contact-related), how a
task's scene and objects are sampled, how features are read from the simulation, and
optionally when the gripper may act. This base class provides the exact transition
function ``simulate``, task sampling with seeds, state restoration and action checking.
It implements :class:`bpns.env.environment.Environment`.
"""

from __future__ import annotations

import abc
import copy
from collections import Counter
from collections.abc import Hashable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from bpns.env.environment import Capabilities
from bpns.env.object_counts import ObjectCounts
from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.env.scene import Anchor, SceneTrack, anchors_by_name
from bpns.errors import BpnsError
from bpns.structs import GroundAtom, Object, Predicate, SimState, State, Task, Type
from ik import ControllerConfig
from mj_envs.contacts import Contacts
from mj_envs.perturbation import noise
from mj_envs.render import render_states
from mj_envs.scene_geometry import scene_track
from mj_envs.world import POSE_SLICE, World


class InvalidActionError(BpnsError, ValueError):
    """An action of the wrong shape or with non-finite entries."""


@dataclass(frozen=True)
class TaskLayout:
    """What a domain's task sampler returns: the scene and the task's symbolic parts."""

    xml: str
    objects: tuple[Object, ...]
    goal: frozenset[GroundAtom]
    horizon: int
    init_qpos: dict[str, np.ndarray] | None = None  # joint name -> qpos override
    init_userdata: dict[int, float] | None = None  # domain userdata index -> value


def perturbed(env: MujocoEnv, spec: Perturbation) -> MujocoEnv:
    """``env`` with ``spec``'s physics: every task's world (sampled or loaded) gets the
    perturbed model, and ``simulate`` the noise and latency (``Capabilities.perturbed``)."""
    out = copy.copy(env)
    out.perturbation = spec
    return out


def with_objects(env: MujocoEnv, counts: ObjectCounts) -> MujocoEnv:
    """``env`` drawing its eval tasks with ``counts`` (``Capabilities.with_objects``): a
    copy, so the environment the paper's tasks come from is untouched; the copy samples
    its own ``max_objects`` again (the Gym observation grows with the counts)."""
    out = copy.copy(env)
    out.__dict__.pop("_max_objects", None)
    out.object_counts = counts
    return out


def observe(env: MujocoEnv, state: State) -> State:
    """What the skills' policies see of ``state``: its features plus the perturbation's
    observation noise, the state itself when there is none (``Capabilities.observe``)."""
    p = env.perturbation
    if not p.obs_noise or state.sim is None:
        return state
    world = state.sim.world
    step = env._control_step(float(state.sim.flat[0]))  # mjSTATE_TIME comes first
    sizes = [v.size for v in state.data.values()]
    kicks = np.split(p.obs_noise * noise(p, 1, world.key, step, sum(sizes)), np.cumsum(sizes))
    seen = {o: v + k for (o, v), k in zip(state.data.items(), kicks, strict=False)}
    return State(seen, state.sim)


# the parts of MuJoCo's integration state that are state, not physics: copied as they are
_STATE_FIELDS = (
    "qpos",
    "qvel",
    "act",
    "qacc_warmstart",
    "ctrl",
    "qfrc_applied",
    "xfrc_applied",
    "eq_active",
    "mocap_pos",
    "mocap_quat",
)


def adopt(env: MujocoEnv, state: State) -> State:
    """``state`` (simulated under any physics of this task's scene) as a state of
    ``env``'s physics (what ``bpns.env.environment.adopt_state`` asks for): positions,
    velocities, controls and the controller's and domain's userdata carry over as they
    are; only physics differs. A
    latency queue keeps the most recent commanded actions that fit ``env``'s own queue
    (zeros where it is longer than the source's)."""
    if state.sim is None:
        raise ValueError("the state carries no simulator state")
    src = state.sim.world
    assert isinstance(src, World)
    dst = env.load_world(src.xml)
    if dst is src:
        return state
    src.load(state.sim.flat)
    s, d = src.data, dst.data
    d.time = s.time
    for name in _STATE_FIELDS:
        getattr(d, name)[:] = getattr(s, name)
    base = dst.queue.start
    d.userdata[:base] = s.userdata[:base]
    queue = np.zeros(dst.queue_size)
    pending = s.userdata[src.queue]
    k = min(dst.queue_size, pending.size)
    if k:
        queue[queue.size - k :] = pending[pending.size - k :]
    d.userdata[dst.queue] = queue
    mujoco.mj_forward(dst.model, d)
    return env._state(dst, state.objects)


class MujocoEnv(abc.ABC):
    """Base for the Panda-on-a-table domains."""

    name: str = "mujoco"
    controller_config: ControllerConfig = ControllerConfig()
    settle_steps: int = 5
    # Segmentation merges contact changes closer than this (bpns.learning.segmentation):
    # at 20 Hz a release or touch-down settles within three control steps.
    contact_settle_steps: int = 4
    # Defaults, skills and perturbed physics beyond the required protocol
    # (bpns.env.environment.Capabilities); a domain declaring its own names these two again.
    capabilities: Capabilities = Capabilities(perturbed=perturbed, observe=observe)
    # physics the tasks run under (``perturbed``); mj_envs.perturbation says what changes
    perturbation: Perturbation = NOMINAL
    # the counts eval tasks are drawn with (``with_objects``); empty: the domain's own
    object_counts: ObjectCounts = ObjectCounts()

    # -- what a domain declares -----------------------------------------------------
    @property
    @abc.abstractmethod
    def types(self) -> frozenset[Type]: ...

    @property
    @abc.abstractmethod
    def predicates(self) -> frozenset[Predicate]: ...

    @property
    @abc.abstractmethod
    def contact_predicates(self) -> frozenset[Predicate]: ...

    @property
    @abc.abstractmethod
    def goal_predicates(self) -> frozenset[Predicate]: ...

    @property
    def action_low(self) -> np.ndarray:
        """Default action (dx, dy, dz, grip): hand translation per control step, bounded
        by the controller's ``max_translation``, and a finger command in [-1, 1]. Domains
        with other actions (e.g. wrist rotations) override both bounds."""
        m = self.controller_config.max_translation
        return np.array([-m, -m, -m, -1.0])

    @property
    def action_high(self) -> np.ndarray:
        return -self.action_low

    @abc.abstractmethod
    def sample_layout(self, rng: np.random.Generator, train: bool) -> TaskLayout:
        """Sample a task's scene (MJCF), objects, goal and horizon."""

    @abc.abstractmethod
    def extract_features(self, world: World, objects: Sequence[Object]) -> dict[Object, np.ndarray]:
        """Read every object's feature vector from ``world.data`` (contacts are current)."""

    def command(
        self, action: np.ndarray, world: World
    ) -> tuple[np.ndarray, np.ndarray | None, float]:
        """Map an action to (dpos, world rotation vector or None, dgrip). Default (dx,dy,dz,g).

        ``world`` holds the state the action applies to (its commanded pose is in
        ``userdata[POSE_SLICE]``), for actions relative to the hand such as wrist turns.
        """
        return action[:3], None, float(action[3])

    def before_control(self, action: np.ndarray, world: World) -> None:  # noqa: B027
        """Act on what the arm's controller does not drive (e.g. a mobile base's position
        targets in ``ctrl``), before the arm's targets are set; an optional hook."""

    def demonstrator(self, task: Task, rng: np.random.Generator):
        """A scripted closed-loop policy State -> action for ``task`` (actions only)."""
        raise NotImplementedError(f"{self.name} has no scripted demonstrator")

    def grip_enabled(self, state: State) -> bool:
        """Whether the finger command is obeyed in ``state`` (Cover's allowed regions)."""
        return True

    def after_step(self, world: World) -> None:  # noqa: B027  (an optional hook)
        """Domain physics beyond MuJoCo's (e.g. button latches).

        It may only edit what the flat state saves (userdata, ``eq_active``, ...), so that
        replay stays exact; never the model.
        """

    def decorate(self, world: World) -> None:  # noqa: B027  (an optional hook)
        """Set looks that follow the loaded state (e.g. colours) before a frame is drawn.

        Geom colours live in the model, not in the simulator state, so a domain that wants
        them to show its state sets them here, from ``world.data``, for every frame.
        """

    def eval_counts(self, kind: str, train: bool) -> tuple[int, int] | None:
        """The (lo, hi) count of ``kind`` this environment's eval tasks are drawn with
        (``with_objects``); None for train tasks and when the domain's own count holds,
        so that its own path draws exactly the random numbers it always drew."""
        return None if train else self.object_counts.get(kind)

    def most_objects(self, kind: str, own: int) -> int:
        """The most objects of ``kind`` any task may hold: ``own`` (the domain's own
        distributions) or more, under ``object_counts``."""
        counts = self.object_counts.get(kind)
        return own if counts is None else max(own, counts[1])

    max_objects_samples: int = 8  # layouts per stream the default max_objects looks at

    @property
    def max_objects(self) -> dict[str, int]:
        """Upper bound on objects per type name over train and eval tasks (Gym obs size).

        Default: the most objects of each type in the first ``max_objects_samples``
        layouts of both streams (seed 0), sampled once per instance. Override it when a
        rare task may hold more objects than such a sample shows.
        """
        cached = self.__dict__.get("_max_objects")
        if cached is None:
            cached = {t.name: 0 for t in self.types}
            for train in (True, False):
                for i in range(self.max_objects_samples):
                    rng = np.random.default_rng([0, 0 if train else 1, i])
                    counts = Counter(o.type.name for o in self.sample_layout(rng, train).objects)
                    for name, k in counts.items():
                        cached[name] = max(cached.get(name, 0), k)
            self.__dict__["_max_objects"] = cached
        return dict(cached)

    # -- perturbed physics (declared as Capabilities.perturbed / .observe) -------------
    def _world(self, xml: str) -> World:
        p = self.perturbation
        return World.from_xml(
            xml, self.controller_config, perturbation=p, queue_size=p.latency * self.action_low.size
        )

    def _control_step(self, time: float) -> int:
        return int(round(time / self.controller_config.control_dt))

    def _applied_action(self, action: np.ndarray, world: World) -> np.ndarray:
        """The action that reaches the robot: ``action`` with the perturbation's noise,
        from the latency queue (which then takes ``action``)."""
        p = self.perturbation
        if p.action_noise:
            low, high = self.action_low, self.action_high
            step = self._control_step(world.data.time)
            kick = noise(p, 0, world.key, step, action.size) * (p.action_noise * (high - low) / 2)
            action = np.clip(action + kick, low, high)
        if world.queue_size:
            queue = world.data.userdata[world.queue].reshape(p.latency, action.size)
            out = queue[0].copy()
            world.data.userdata[world.queue] = np.concatenate([queue[1:].ravel(), action])
            action = out
        return action

    # -- tasks ----------------------------------------------------------------------
    def train_tasks(self, n: int, seed: int) -> list[Task]:
        return self._tasks(n, seed, train=True)

    def eval_tasks(self, n: int, seed: int) -> list[Task]:
        return self._tasks(n, seed, train=False)

    def _tasks(self, n: int, seed: int, train: bool) -> list[Task]:
        if n < 0:
            raise ValueError(f"number of tasks must be >= 0, got {n}")
        return [self.task(i, seed, train) for i in range(n)]

    def task(self, index: int, seed: int, train: bool) -> Task:
        """Task ``index`` of the seeded train/eval stream (independent of the others)."""
        rng = np.random.default_rng([seed, 0 if train else 1, index])
        return self.make_task(self.sample_layout(rng, train))

    def make_task(self, layout: TaskLayout) -> Task:
        world = self._world(layout.xml)
        m, d = world.model, world.data
        mujoco.mj_resetData(m, d)
        world.controller.reset(
            d,
            POSE_SLICE,
            np.asarray(self.controller_config.home_qpos),
            self.controller_config.finger_open,
        )
        for joint, q in (layout.init_qpos or {}).items():
            adr = m.joint(joint).qposadr[0]
            d.qpos[adr : adr + len(q)] = q
        for idx, value in (layout.init_userdata or {}).items():
            d.userdata[idx] = value
        mujoco.mj_forward(m, d)
        for _ in range(self.settle_steps):  # let contacts settle with the arm holding still
            world.step_physics()
        d.time = 0.0
        init = self._state(world, layout.objects)
        return Task(init=init, goal=layout.goal, horizon=layout.horizon)

    # -- the transition function ------------------------------------------------------
    def simulate(self, state: State, action: np.ndarray) -> State:
        action = self.check_action(action)
        if state.sim is None:
            raise ValueError("state has no simulator state; it cannot be simulated")
        world = state.sim.world
        assert isinstance(world, World)
        world.load(state.sim.flat)
        if self.perturbation is not NOMINAL:
            action = self._applied_action(action, world)
        self.before_control(action, world)
        dpos, drot, dgrip = self.command(action, world)
        world.controller.apply(world.data, POSE_SLICE, dpos, drot, dgrip, self.grip_enabled(state))
        world.step_physics()
        self.after_step(world)
        return self._state(world, state.objects)

    def check_action(self, action: np.ndarray) -> np.ndarray:
        try:
            a = np.asarray(action, dtype=np.float64)
        except (OverflowError, TypeError, ValueError) as err:  # e.g. 10**400, "x", ragged
            msg = f"{self.name}: action is not an array of floats: {err}"
            raise InvalidActionError(msg) from None
        low, high = self.action_low, self.action_high
        if a.shape != low.shape:
            raise InvalidActionError(
                f"{self.name}: action must have shape {low.shape}, got {a.shape}"
            )
        if not np.all(np.isfinite(a)):
            raise InvalidActionError(f"{self.name}: action contains NaN or inf: {a.tolist()}")
        return np.clip(a, low, high)

    def _state(self, world: World, objects: Sequence[Object]) -> State:
        features = self.extract_features(world, objects)
        return State(features, SimState(world, world.save()))

    def render(
        self, states: Sequence[State], camera: str = "overview", width: int = 640, height: int = 480
    ):
        return render_states(states, camera, width, height, decorate=self.decorate)

    def scene(self, states: Sequence[State]) -> SceneTrack | None:
        """The 3D scene of one task's ``states`` (bodies, geometry, poses, the hand) and
        the 3D points among each type's features (:meth:`anchors`)."""
        if not states:
            return None
        return scene_track(states, {t.name: self.anchors(t) for t in self.types})

    def anchors(self, type_: Type) -> tuple[Anchor, ...]:
        """The 3D points among ``type_``'s features (a recording draws a skill's subgoal
        there). Default: the x/y(/z) feature names (:func:`bpns.env.scene.anchors_by_name`);
        a domain whose features name points otherwise overrides it."""
        return anchors_by_name(type_.feature_names)

    # -- persistence ------------------------------------------------------------------
    def save_world(self, world: Hashable) -> str:
        assert isinstance(world, World)
        return world.xml

    def load_world(self, text: str) -> World:
        return self._world(text)

    def state_from_flat(self, world: Hashable, flat: np.ndarray, like: State) -> State:
        """``flat`` loaded into ``world``; when ``like`` is a state of the same scene under
        other physics and ``flat`` its flat state, it is carried over (:func:`adopt`)."""
        assert isinstance(world, World)
        src = like.sim.world if like.sim is not None else None
        if isinstance(src, World) and src is not world and src.xml == world.xml:
            if flat is like.sim.flat or np.array_equal(flat, like.sim.flat):
                return adopt(self, like)
        world.load(np.asarray(flat, dtype=np.float64))
        return self._state(world, like.objects)

    # -- helpers for domains ----------------------------------------------------------
    @staticmethod
    def contact_pairs(world: World) -> set[tuple[int, int]]:
        """Unordered geom-id pairs currently in contact (distance <= 0), as a set: the
        pairs :meth:`mj_envs.contacts.Contacts.read` reads (one reading of MuJoCo's list)."""
        return set(Contacts.read(world.data).pairs)
