"""The small protocol through which bpns talks to any environment.

bpns never imports a simulator or names a domain: an environment declares its types,
predicates (and which of them are contact-related, for segmentation), action bounds,
task distributions and its exact transition function ``simulate``. What it may offer
beyond that (planning and learning defaults, hand-written or given skills, perturbed
physics, what policies observe, states from which no goal can be reached) it declares in
one :class:`Capabilities` value, so bpns reads declarations instead of probing for
attributes.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from types import MappingProxyType
from typing import Protocol, runtime_checkable

import numpy as np

from bpns.env.object_counts import PAPER, EvalSet, ObjectCountError, ObjectCounts
from bpns.env.perturbations import Perturbation, PerturbationError
from bpns.env.scene import SceneTrack
from bpns.errors import BpnsError
from bpns.structs import GivenSkill, Predicate, Skill, State, Task, Type


def _frozen(mapping: Mapping[str, object]) -> Mapping[str, object]:
    return MappingProxyType(dict(mapping))


@dataclass(frozen=True)
class Capabilities:
    """The optional part of the contract, declared in one place (``env.capabilities``).

    planning_defaults: ``PlanningConfig`` fields this domain plans with unless the user
                       says otherwise, e.g. the paper's ``{"n_abstract": 1000}`` where many
                       abstract plans are not refinable.
    learning_defaults: ``LearningConfig`` fields, e.g. ``{"near_goal_scale": 0.01}`` where
                       the demonstrator switches near its goals.
    oracle_skills:     makes the hand-written skills (``--approach oracle``); None: none.
    given_skills:      makes the skills learning keeps as given (``bpns.learning.given``);
                       None: every skill is learned.
    demo_noise:        DART noise scale of the scripted demonstrations
                       (``bpns.data.demo_attempts.ActionNoise``); 0.0: plain demonstrations.
    default_camera:    the camera videos use unless told (e.g. one that follows a mobile
                       robot, which leaves a fixed camera's view).
    perturbed:         ``perturbed(env, spec)``: ``env`` under a
                       ``bpns.env.perturbations.Perturbation`` (``bpns eval --perturb``);
                       None: nominal physics only.
    observe:           ``observe(env, state)``: what the skills' policies see of a state
                       (e.g. noisy features); None: the state itself.
    dead_end:          ``dead_end(state)``: can no plan from ``state`` reach any goal any
                       more (e.g. Coffee's spilled coffee: no cup counts as filled again)?
                       Refinement ends a rollout that reaches one at once instead of
                       simulating out the skill's horizon; None: no state is one.
    eval_sets:         named eval distributions beyond ``paper`` (the environment's own
                       eval tasks), as object counts per kind, e.g. ``{"large":
                       ObjectCounts.of({"button": (5, 8)})}`` (``bpns eval --eval-set``).
    object_limits:     the inclusive (lo, hi) count of each kind its scenes can hold;
                       the kinds ``--objects`` may set.
    with_objects:      ``with_objects(env, counts)``: ``env`` drawing its eval tasks with
                       ``counts`` (an :class:`ObjectCounts` within ``object_limits``; kinds
                       it does not name keep their own counts), its train tasks unchanged;
                       None: the paper set only.
    motion_dims:       the action dims that command motion at a rate (hand translation,
                       wrist turns, a base's offsets; not the fingers): what a world-side
                       speed (``ExecutionConfig.world_speed``) scales; None: the
                       environment's skills cannot be slowed.
    back_off:          ``back_off(env, seen, start)``: a recovery motion, one action per
                       observed state ``seen`` (None once done), that takes the robot
                       back towards ``start`` (the task's initial state), e.g. the
                       fingers opened, the hand raised straight up, then back to where
                       it began. The
                       closed loop runs it when a replan finds no plan from where a
                       failed skill left the robot (a hand on the table beside a dropped
                       stick, hovering where no demonstration went), and plans again from
                       there: demonstrations start from such poses. None: no back-off.

    ``observe`` takes the environment because one declaration (a class attribute) serves
    every instance, including the perturbed copies ``perturbed`` returns.
    """

    planning_defaults: Mapping[str, object] = field(default_factory=dict)
    learning_defaults: Mapping[str, object] = field(default_factory=dict)
    oracle_skills: Callable[[], Sequence[Skill]] | None = None
    given_skills: Callable[[], Sequence[GivenSkill]] | None = None
    demo_noise: float = 0.0
    default_camera: str = "overview"
    perturbed: Callable[[Environment, Perturbation], Environment] | None = None
    observe: Callable[[Environment, State], State] | None = None
    dead_end: Callable[[State], bool] | None = None
    eval_sets: Mapping[str, ObjectCounts] = field(default_factory=dict)
    object_limits: Mapping[str, tuple[int, int]] = field(default_factory=dict)
    with_objects: Callable[[Environment, ObjectCounts], Environment] | None = None
    motion_dims: tuple[int, ...] | None = None
    back_off: Callable[[Environment, State, State], np.ndarray | None] | None = None

    def __post_init__(self) -> None:  # read-only: one declaration shared by every instance
        if not 0.0 <= self.demo_noise < float("inf"):
            raise ValueError(f"demo_noise must be finite and >= 0, got {self.demo_noise}")
        dims = self.motion_dims
        if dims is not None and (
            not dims
            or len(set(dims)) != len(dims)
            or not all(isinstance(d, int) and not isinstance(d, bool) and d >= 0 for d in dims)
        ):
            raise ValueError(
                f"motion_dims must be distinct action indices >= 0 (or None), got {dims!r}"
            )
        if PAPER in self.eval_sets:
            raise ValueError(f"eval set {PAPER!r} is the environment's own: do not declare it")
        object.__setattr__(self, "planning_defaults", _frozen(self.planning_defaults))
        object.__setattr__(self, "learning_defaults", _frozen(self.learning_defaults))
        object.__setattr__(self, "eval_sets", _frozen(self.eval_sets))
        object.__setattr__(self, "object_limits", _frozen(self.object_limits))

    @property
    def has_oracle_skills(self) -> bool:
        return self.oracle_skills is not None


# What the optional part of the contract was before ``Capabilities``: attributes of the
# environment itself. An environment still declaring one would have it silently ignored.
MOVED_TO_CAPABILITIES = (
    "planning_defaults",
    "learning_defaults",
    "oracle_skills",
    "given_skills",
    "perturbed",
    "observe",
)


def declaration_problem(env: object) -> str | None:
    """Why ``env`` does not declare its optional part as this contract asks, naming the
    fix (None if it does). The registry refuses such an environment, and
    ``bpns check-env`` reports it."""
    name = getattr(env, "name", type(env).__name__)
    moved = [a for a in MOVED_TO_CAPABILITIES if hasattr(env, a)]
    if moved:
        fields = ", ".join(f"{a}=..." for a in moved)
        return (
            f"environment {name!r} declares {', '.join(moved)} as attributes: declare "
            f"`capabilities = Capabilities({fields})` (bpns.env.environment) instead; "
            "see docs/NEW_TASK.md"
        )
    missing = [a for a in ("capabilities", "contact_settle_steps") if not hasattr(env, a)]
    if missing:
        return (
            f"environment {name!r} lacks {', '.join(missing)} of bpns.env.environment.Environment "
            "(MujocoEnv provides both); see docs/NEW_TASK.md"
        )
    if not isinstance(env.capabilities, Capabilities):  # type: ignore[attr-defined]
        return f"environment {name!r}: capabilities must be a bpns.env.environment.Capabilities"
    return None


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

    # Contact changes closer than this many steps are one physical event for segmentation
    # (a release that bounces, a touch-down a step after letting go); 1 is the paper's
    # literal segmentation.
    contact_settle_steps: int
    # Defaults, skills, perturbed physics and observations the environment offers beyond
    # this protocol (all optional).
    capabilities: Capabilities

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

    def scene(self, states: Sequence[State]) -> SceneTrack | None:
        """The 3D scene of ``states`` (one task's): bodies, their geometry and poses, the
        hand (``bpns view`` records it); None: the environment has none to show."""
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


def perturbed(env: Environment, spec: Perturbation) -> Environment:
    """``env`` under ``spec`` (``env`` itself when nominal); an environment that declares
    no ``Capabilities.perturbed`` is a :class:`PerturbationError`."""
    if spec.nominal:
        return env
    make = env.capabilities.perturbed
    if make is None:
        raise PerturbationError(
            f"environment {env.name!r} does not support perturbations "
            "(its Capabilities declare no perturbed)"
        )
    return make(env, spec)


def eval_set_of(
    env: Environment, name: str = PAPER, objects: ObjectCounts | None = None
) -> EvalSet:
    """The eval set ``name`` with ``objects`` overriding its counts, checked against what
    ``env`` declares (:class:`ObjectCountError` naming the known sets, the kinds or the
    limits), so that a bad choice is refused before any task is drawn."""
    caps = env.capabilities
    if name != PAPER and name not in caps.eval_sets:
        known = ", ".join([PAPER, *sorted(caps.eval_sets)])
        raise ObjectCountError(f"environment {env.name!r} has no eval set {name!r}; known: {known}")
    chosen = EvalSet(name, objects or ObjectCounts())
    _check_counts(env, _counts_of(env, chosen))
    return chosen


def _counts_of(env: Environment, eval_set: EvalSet) -> ObjectCounts:
    named = env.capabilities.eval_sets.get(eval_set.name, ObjectCounts())
    return named.updated(eval_set.objects)


def _check_counts(env: Environment, counts: ObjectCounts) -> None:
    if not counts:
        return
    caps = env.capabilities
    if caps.with_objects is None:
        raise ObjectCountError(
            f"environment {env.name!r} cannot change its object counts (its Capabilities "
            f"declare no with_objects): only the {PAPER!r} eval set"
        )
    limits = caps.object_limits
    for kind, lo, hi in counts.ranges:
        if kind not in limits:
            kinds = ", ".join(sorted(limits)) or "none"
            raise ObjectCountError(
                f"environment {env.name!r} has no object kind {kind!r}; kinds: {kinds}"
            )
        least, most = limits[kind]
        if lo < least or hi > most:
            asked = f"{lo}" if lo == hi else f"{lo}:{hi}"
            raise ObjectCountError(
                f"{kind}={asked}: {env.name} scenes hold {least}..{most} {kind} objects"
            )


def eval_environment(
    env: Environment, eval_set: EvalSet | str = PAPER, objects: ObjectCounts | None = None
) -> Environment:
    """The environment eval tasks of ``eval_set`` (a name or an :class:`EvalSet`; with
    ``objects`` overriding its counts) are drawn from: ``env`` itself for the paper set,
    else the copy its ``Capabilities.with_objects`` returns. Train tasks are unchanged."""
    chosen = eval_set if isinstance(eval_set, EvalSet) else EvalSet(eval_set)
    if objects:
        chosen = EvalSet(chosen.name, chosen.objects.updated(objects))
    if chosen.is_paper:
        return env
    chosen = eval_set_of(env, chosen.name, chosen.objects)
    counts = _counts_of(env, chosen)
    if not counts:  # a named set that declares no counts
        return env
    make = env.capabilities.with_objects
    assert make is not None  # _check_counts refused it otherwise
    return make(env, counts)


def observation_of(env: Environment) -> Callable[[State], State]:
    """What a policy sees of a state: the declared ``Capabilities.observe`` (e.g. noisy
    features), else the state itself."""
    observe = env.capabilities.observe
    if observe is None:
        return _identity
    return partial(observe, env)


def _identity(state: State) -> State:
    return state


class AdoptionError(BpnsError, ValueError):
    """A state of one physics cannot be carried into another."""


def adopt_state(env: Environment, state: State) -> State:
    """``state``, simulated under other physics of the same task (the world it executes
    in), as a state of ``env``'s physics (the planner's model): what a state estimator
    hands the planner. Through the protocol's ``state_from_flat`` in ``env``'s own scene
    of the task, which is handed ``state`` itself as ``like`` so that it can carry a flat
    state laid out by another physics (mj_envs: a latency queue of another length)."""
    if state.sim is None:  # an environment whose features are its whole state
        return state
    world = env.load_world(env.save_world(state.sim.world))
    if world is state.sim.world:  # the same physics: nothing to carry
        return state
    try:
        return env.state_from_flat(world, state.sim.flat, state)
    except ValueError as err:
        raise AdoptionError(
            f"environment {env.name!r} cannot carry a state of its world into its model: {err}"
        ) from None
