"""Gymnasium view of every registered environment: ``gymnasium.make("bpns/Cover-v0")``.

Gymnasium ids come from the one registry of environments, the ``bpns.environments``
entry points: ``stick_button`` is ``bpns/StickButton-v0``, and a plugin package's
environment gets its id the same way (``import mj_envs`` registers them all, or use
``gymnasium.make("mj_envs:bpns/Name-v0")``).

Observation: every object's features concatenated in a fixed order, zero-padded to the
domain's ``max_objects`` so its size is the same for every task. Reward 1 when the goal
holds (then terminated); truncated at the task horizon. ``info["goal"]`` lists the goal
atoms; ``env.unwrapped.state`` is the full bpns State (with its exact simulator state)
for planners and learners.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from bpns.env.abstraction import abstract
from bpns.env.environment import Environment
from bpns.env.registry import environment_names, make_environment
from bpns.structs import State, Task

NAMESPACE = "bpns"


def gym_id(env_name: str) -> str:
    """``stick_button`` -> ``bpns/StickButton-v0``."""
    camel = "".join(part[:1].upper() + part[1:] for part in env_name.split("_"))
    return f"{NAMESPACE}/{camel}-v0"


class BPNSGymEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        env_name: str = "cover",
        train: bool = True,
        render_mode: str | None = None,
        camera: str = "overview",
    ) -> None:
        self.env: Environment = make_environment(env_name)
        self.train = train
        self.render_mode = render_mode
        self.camera = camera
        types = {t.name: t for t in self.env.types}
        self._slots = [
            (types[name], k)
            for name in sorted(self.env.max_objects)
            for k in range(self.env.max_objects[name])
        ]
        size = sum(t.dim for t, _ in self._slots)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (size,), np.float64)
        self.action_space = gym.spaces.Box(
            self.env.action_low, self.env.action_high, dtype=np.float64
        )
        self._task: Task | None = None
        self._state: State | None = None
        self._t = 0

    def _obs(self, state: State) -> np.ndarray:
        parts = []
        by_type: dict[str, list] = {}
        for obj in state.objects:
            by_type.setdefault(obj.type.name, []).append(obj)
        for type_, k in self._slots:
            objs = by_type.get(type_.name, [])
            parts.append(state.data[objs[k]] if k < len(objs) else np.zeros(type_.dim))
        return np.concatenate(parts).astype(np.float64)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        task_seed = int(self.np_random.integers(0, 2**31 - 1))
        self._task = self.env.task(0, task_seed, self.train)
        self._state = self._task.init
        self._t = 0
        return self._obs(self._state), self._info()

    def step(self, action):
        assert self._task is not None and self._state is not None, "call reset() first"
        self._state = self.env.simulate(self._state, np.asarray(action, dtype=np.float64))
        self._t += 1
        done = self._task.goal_holds(abstract(self._state, self.env.goal_predicates))
        truncated = not done and self._t >= self._task.horizon
        return (self._obs(self._state), float(done), done, truncated, self._info())

    def _info(self) -> dict[str, Any]:
        return {"goal": sorted(map(str, self._task.goal))}

    @property
    def state(self) -> State | None:
        return self._state

    def render(self):
        if self._state is None:
            return None
        return next(iter(self.env.render([self._state], self.camera)))


def register_gymnasium_envs() -> list[str]:
    """Register a Gymnasium id for every environment in the registry; returns the ids."""
    ids = []
    for name in environment_names():
        id_ = gym_id(name)
        if id_ not in gym.registry:
            gym.register(
                id=id_, entry_point="mj_envs.gym_wrapper:BPNSGymEnv", kwargs={"env_name": name}
            )
        ids.append(id_)
    return ids
