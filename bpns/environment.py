"""The small protocol through which bpns talks to any environment.

bpns never imports a simulator or names a domain: an environment declares its types,
predicates (and which of them are contact-related, for segmentation), action bounds,
task distributions and its exact transition function ``simulate``.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator, Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from bpns.structs import Predicate, State, Task, Type


@runtime_checkable
class Environment(Protocol):
    """What bpns needs of an environment. ``mj_envs`` implements it on MuJoCo."""

    name: str

    @property
    def types(self) -> frozenset[Type]: ...

    @property
    def predicates(self) -> frozenset[Predicate]: ...

    @property
    def contact_predicates(self) -> frozenset[Predicate]:
        """Predicates whose truth changes mark skill boundaries (paper §4.1)."""
        ...

    # Optional: contact changes closer than this many steps are one physical event for
    # segmentation (a release that bounces, a touch-down a step after letting go).
    # ``contact_settle_steps: int``
    # Optional: PlanningConfig fields this domain plans with by default, e.g. the
    # paper's ``{"n_abstract": 1000}`` where many abstract plans are not refinable.
    # ``planning_defaults: Mapping[str, object]``
    # Optional: LearningConfig fields this domain learns with by default, e.g.
    # ``{"near_goal_scale": 0.01}`` where the demonstrator switches near its goals.
    # ``learning_defaults: Mapping[str, object]``
    # Optional: the camera videos use unless told (``default_camera: str``, e.g. one that
    # follows a mobile robot); ``perturbed(spec) -> Environment`` (the same environment
    # under a ``bpns.perturbations.Perturbation``) and ``observe(state) -> State`` (what
    # policies see, e.g. noisy features). ``mj_envs.MujocoEnv`` provides all three.

    @property
    def goal_predicates(self) -> frozenset[Predicate]: ...

    @property
    def action_low(self) -> np.ndarray: ...

    @property
    def action_high(self) -> np.ndarray: ...

    def train_tasks(self, n: int, seed: int) -> list[Task]: ...

    def eval_tasks(self, n: int, seed: int) -> list[Task]: ...

    def task(self, index: int, seed: int, train: bool) -> Task:
        """Task ``index`` of the seeded train/eval stream, independent of the others."""
        ...

    def check_action(self, action: np.ndarray) -> np.ndarray:
        """Validate (shape, finite) and clip an action; raises ValueError naming the problem."""
        ...

    def demonstrator(self, task: Task, rng: np.random.Generator) -> Callable[[State], np.ndarray]:
        """A scripted policy for collecting demonstrations (acts through actions only)."""
        ...

    def render(
        self, states: Sequence[State], camera: str, width: int, height: int
    ) -> Iterator[np.ndarray]:
        """RGB frames (height, width, 3) of ``states`` seen from ``camera``."""
        ...

    def simulate(self, state: State, action: np.ndarray) -> State:
        """Exact, deterministic f(x, u): same state and action give a bit-identical state."""
        ...

    def save_world(self, world: Hashable) -> str:
        """Serialise a SimState.world handle (e.g. the task's MJCF) for datasets."""
        ...

    def load_world(self, text: str) -> Hashable: ...

    def state_from_flat(self, world: Hashable, flat: np.ndarray, like: State) -> State:
        """Rebuild a full State (features included) from a flat simulator state."""
        ...
