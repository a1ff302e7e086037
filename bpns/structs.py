"""Frozen core structs of BPNS: types, objects, states, atoms, operators, skills, tasks.

Everything here is environment-agnostic. A :class:`State` carries per-object feature
vectors (what learning and predicates see) *and* an opaque exact simulator state
(:class:`SimState`) so the environment's transition function can be replayed from it
bit-for-bit. bpns never looks inside a :class:`SimState`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bpns.errors import BpnsError


@dataclass(frozen=True, order=True)
class Type:
    """An object type: a name and the names of its real-valued features.

    ``angles``: the features that are angles in radians read from a rotation, so that
    values 2*pi apart are the same pose (a base's yaw, a hand's yaw from ``atan2``).
    Learned networks see their sine and cosine, and subgoal offsets along them wrapped
    into [-pi, pi): a hand turning past +-pi would otherwise jump by 2*pi in a policy's
    input mid-skill."""

    name: str
    feature_names: tuple[str, ...]
    angles: tuple[str, ...] = ()
    # predicates read features by name millions of times while a dataset is segmented:
    # the index and the hash are computed once (again on unpickling: string hashes
    # differ between processes)
    _index: dict[str, int] = field(init=False, repr=False, compare=False)
    _hash: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        unknown = [a for a in self.angles if a not in self.feature_names]
        if unknown:
            raise ValueError(
                f"type {self.name!r}: angles {unknown} are not among its features "
                f"{self.feature_names}"
            )
        object.__setattr__(self, "_index", {f: i for i, f in enumerate(self.feature_names)})
        object.__setattr__(self, "_hash", hash((self.name, self.feature_names, self.angles)))

    def __hash__(self) -> int:
        return self._hash

    def __reduce__(self) -> tuple[type[Type], tuple[str, tuple[str, ...], tuple[str, ...]]]:
        return (Type, (self.name, self.feature_names, self.angles))

    @property
    def angle_indices(self) -> tuple[int, ...]:
        """The indices of :attr:`angles` among the features."""
        return tuple(self._index[a] for a in self.angles)

    @property
    def dim(self) -> int:
        return len(self.feature_names)

    def feature_index(self, feature: str) -> int:
        try:
            return self._index[feature]
        except KeyError:
            raise KeyError(
                f"type {self.name!r} has no feature {feature!r}; it has {self.feature_names}"
            ) from None


@dataclass(frozen=True, order=True)
class Object:
    """A named object of a type (e.g. ``block0:block``).

    Objects key every state's feature dict and sit in every atom, so the hash is computed
    once (a loaded dataset builds ~10^5 state dicts); it is recomputed on unpickling,
    since string hashes differ between processes."""

    name: str
    type: Type
    _hash: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_hash", hash((self.name, self.type)))

    def __hash__(self) -> int:
        return self._hash

    def __reduce__(self) -> tuple[type[Object], tuple[str, Type]]:
        return (Object, (self.name, self.type))

    def __str__(self) -> str:
        return f"{self.name}:{self.type.name}"

    __repr__ = __str__


@dataclass(frozen=True, order=True)
class Variable:
    """A typed placeholder for an object in lifted atoms and operators (``?b:block``)."""

    name: str
    type: Type

    def __post_init__(self) -> None:
        if not self.name.startswith("?"):
            raise ValueError(f"variable names start with '?', got {self.name!r}")

    def __str__(self) -> str:
        return f"{self.name}:{self.type.name}"

    __repr__ = __str__


@dataclass(frozen=True, eq=False)
class SimState:
    """Exact simulator state, opaque to bpns.

    ``world`` is an environment-owned, picklable handle on the physical world the state
    lives in (for MuJoCo domains: the compiled task scene); ``flat`` is the full
    integration state including the controller's internal state.
    """

    world: Hashable
    flat: np.ndarray


@dataclass(frozen=True, eq=False)
class State:
    """Object-centric state: feature vector per object plus the exact simulator state."""

    data: Mapping[Object, np.ndarray]
    sim: SimState | None = None

    @functools.cached_property
    def objects(self) -> tuple[Object, ...]:
        return tuple(sorted(self.data))

    @classmethod
    def over_sorted(
        cls, objects: tuple[Object, ...], data: Mapping[Object, np.ndarray], sim: SimState | None
    ) -> State:
        """A state whose ``objects`` are given already sorted (the keys of ``data``).

        Why: a demonstration's thousands of states share one object set; loading sorts
        it once instead of once per state (segmentation asks every state for it).
        """
        state = cls(data, sim)
        state.__dict__["objects"] = objects  # the cached_property's slot
        return state

    def get(self, obj: Object, feature: str) -> float:
        return float(self.data[obj][obj.type.feature_index(feature)])

    def vec(self, objects: Sequence[Object]) -> np.ndarray:
        """Concatenated features of ``objects`` in order (the skill-scope vector)."""
        if not objects:
            return np.zeros(0, dtype=np.float64)
        return np.concatenate([self.data[o] for o in objects])

    def objects_of_type(self, type_: Type) -> tuple[Object, ...]:
        # identity first: the objects of one environment share their Type instances, and
        # comparing two frozen dataclasses field by field is what made this slow (nothing
        # is cached per state: a dataset holds ~10^5 of them)
        return tuple(o for o in self.objects if o.type is type_ or o.type == type_)

    def allclose(self, other: State, atol: float = 0.0) -> bool:
        """Feature-wise equality (exact by default)."""
        if set(self.data) != set(other.data):
            return False
        return all(np.allclose(self.data[o], other.data[o], rtol=0.0, atol=atol) for o in self.data)


Classifier = Callable[[State, Sequence[Object]], bool]


@dataclass(frozen=True, order=True)
class Predicate:
    """A named classifier over a typed tuple of objects."""

    name: str
    types: tuple[Type, ...]
    classifier: Classifier = field(compare=False, hash=False, repr=False)

    @property
    def arity(self) -> int:
        return len(self.types)

    def holds(self, state: State, objects: Sequence[Object]) -> bool:
        return bool(self.classifier(state, objects))

    def __str__(self) -> str:
        return self.name

    __repr__ = __str__


@dataclass(frozen=True, order=True)
class GroundAtom:
    predicate: Predicate
    objects: tuple[Object, ...]

    def __post_init__(self) -> None:
        _check_arguments(self.predicate, self.objects)

    def holds(self, state: State) -> bool:
        return self.predicate.holds(state, self.objects)

    def lift(self, sub: Mapping[Object, Variable]) -> LiftedAtom:
        return LiftedAtom(self.predicate, tuple(sub[o] for o in self.objects))

    def __str__(self) -> str:
        return f"{self.predicate.name}({', '.join(o.name for o in self.objects)})"

    __repr__ = __str__


@dataclass(frozen=True, order=True)
class LiftedAtom:
    predicate: Predicate
    variables: tuple[Variable, ...]

    def __post_init__(self) -> None:
        _check_arguments(self.predicate, self.variables)

    def ground(self, sub: Mapping[Variable, Object]) -> GroundAtom:
        return GroundAtom(self.predicate, tuple(sub[v] for v in self.variables))

    def __str__(self) -> str:
        return f"{self.predicate.name}({', '.join(v.name for v in self.variables)})"

    __repr__ = __str__


def _check_arguments(predicate: Predicate, args: Sequence[Object | Variable]) -> None:
    got = tuple(a.type for a in args)
    if got != predicate.types:
        raise TypeError(
            f"{predicate.name} takes types {[t.name for t in predicate.types]}, "
            f"got {[t.name for t in got]}"
        )


@dataclass(frozen=True, order=True)
class STRIPSOperator:
    """Lifted operator <parameters, preconditions, add effects, delete effects>."""

    name: str
    parameters: tuple[Variable, ...]
    preconditions: frozenset[LiftedAtom]
    add_effects: frozenset[LiftedAtom]
    delete_effects: frozenset[LiftedAtom]
    # Where planning orders this operator among others (grounding and so search
    # tie-breaks); None: by ``name``. Learned operators keep their index name here, so
    # renaming them never changes a plan.
    order_key: str | None = field(default=None, compare=False)

    @property
    def sort_name(self) -> str:
        return self.name if self.order_key is None else self.order_key

    def ground(self, objects: Sequence[Object]) -> GroundOperator:
        objects = tuple(objects)
        if tuple(o.type for o in objects) != tuple(v.type for v in self.parameters):
            raise TypeError(f"{self.name}: objects {objects} do not match {self.parameters}")
        sub = dict(zip(self.parameters, objects, strict=True))
        return GroundOperator(
            self,
            objects,
            frozenset(a.ground(sub) for a in self.preconditions),
            frozenset(a.ground(sub) for a in self.add_effects),
            frozenset(a.ground(sub) for a in self.delete_effects),
        )

    def __str__(self) -> str:
        def fmt(atoms: frozenset[LiftedAtom]) -> str:
            return ", ".join(sorted(map(str, atoms))) or "-"

        return (
            f"{self.name}({', '.join(map(str, self.parameters))})\n"
            f"    pre: {fmt(self.preconditions)}\n"
            f"    add: {fmt(self.add_effects)}\n"
            f"    del: {fmt(self.delete_effects)}"
        )


@dataclass(frozen=True, order=True)
class GroundOperator:
    operator: STRIPSOperator
    objects: tuple[Object, ...]
    preconditions: frozenset[GroundAtom] = field(compare=False)
    add_effects: frozenset[GroundAtom] = field(compare=False)
    delete_effects: frozenset[GroundAtom] = field(compare=False)

    @property
    def name(self) -> str:
        return self.operator.name

    def applicable(self, atoms: frozenset[GroundAtom]) -> bool:
        return self.preconditions <= atoms

    def apply(self, atoms: frozenset[GroundAtom]) -> frozenset[GroundAtom]:
        return (atoms - self.delete_effects) | self.add_effects

    def __str__(self) -> str:
        return f"{self.operator.name}({', '.join(o.name for o in self.objects)})"

    __repr__ = __str__


class SubgoalPolicy(Protocol):
    """pi(objects, state, subgoal) -> action. ``subgoal`` is an absolute scope vector."""

    def __call__(
        self, state: State, objects: Sequence[Object], subgoal: np.ndarray
    ) -> np.ndarray: ...


class NoSubgoal(BpnsError):
    """Raised by a subgoal sampler that has no subgoal worth simulating from this state
    (a hand-written sampler: beyond the arm's reach; a learned one: every draw lies where
    no demonstration went, :mod:`bpns.learning.support`). The planner counts a failed
    sample without simulating anything."""


class SubgoalSampler(Protocol):
    """sigma(objects, state) -> absolute subgoal scope vector, drawn with ``rng``. A
    sampler with no subgoal worth simulating from ``state`` raises :class:`NoSubgoal`."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class Skill:
    """Neuro-symbolic skill: operator + subgoal-conditioned policy + subgoal sampler.

    ``policy`` and ``sampler`` take the operator's parameters (same order) as objects.
    Subgoals are vectors over the scope ``state.vec(objects)``.
    """

    operator: STRIPSOperator
    policy: SubgoalPolicy
    sampler: SubgoalSampler
    # Most actions one rollout of this skill may take (None: only the planner's limit).
    # Learned skills derive it from the longest demonstrated segment: a rollout that runs
    # far longer than any demonstration of the skill has failed.
    horizon: int | None = None

    @property
    def name(self) -> str:
        return self.operator.name


@dataclass(frozen=True)
class GivenSkill:
    """A skill supplied by the environment (``bpns.learning.given``: how learning keeps
    it). ``signature`` names its parameters (in the order its policy and sampler take
    objects) and the effects that identify it."""

    name: str
    signature: STRIPSOperator
    policy: SubgoalPolicy
    sampler: SubgoalSampler


@dataclass(frozen=True)
class Task:
    """<objects, initial state, goal, horizon>; objects are those of ``init``."""

    init: State = field(compare=False)
    goal: frozenset[GroundAtom]
    horizon: int

    @property
    def objects(self) -> tuple[Object, ...]:
        return self.init.objects

    def goal_holds(self, atoms: Iterable[GroundAtom]) -> bool:
        return self.goal <= frozenset(atoms)


@dataclass(frozen=True, eq=False)
class Demonstration:
    """A solved task: states s_0..s_k and actions a_1..a_k with s_i = f(s_{i-1}, a_i).

    ``expert_actions`` (same shape as ``actions``) are what the demonstrator commanded
    when the executed ``actions`` were perturbed on purpose (DART-style noise injection,
    :mod:`bpns.data.demo_attempts`); None when they are the executed ones. Replay uses
    ``actions``; imitation learns ``labels``: the demonstrator's correction at every
    visited state, including the ones off its own path.
    """

    task: Task
    states: tuple[State, ...]
    actions: np.ndarray  # shape (k, action_dim)
    expert_actions: np.ndarray | None = None

    def __post_init__(self) -> None:
        if len(self.states) != len(self.actions) + 1:
            raise ValueError(
                f"a demonstration needs len(states) == len(actions) + 1, "
                f"got {len(self.states)} states and {len(self.actions)} actions"
            )
        if self.expert_actions is not None and np.shape(self.expert_actions) != np.shape(
            self.actions
        ):
            raise ValueError(
                f"expert_actions must have the shape of actions {np.shape(self.actions)}, "
                f"got {np.shape(self.expert_actions)}"
            )

    @property
    def labels(self) -> np.ndarray:
        """The actions to imitate: the demonstrator's own commands."""
        return self.actions if self.expert_actions is None else self.expert_actions


@dataclass(frozen=True, eq=False)
class Segment:
    """A contiguous piece of a demonstration between two contact switch points.

    ``states`` has one more element than ``actions``; ``init_atoms``/``final_atoms`` are
    the abstractions of the first and last state.
    """

    states: tuple[State, ...]
    actions: np.ndarray
    init_atoms: frozenset[GroundAtom]
    final_atoms: frozenset[GroundAtom]

    @property
    def add_effects(self) -> frozenset[GroundAtom]:
        return self.final_atoms - self.init_atoms

    @property
    def delete_effects(self) -> frozenset[GroundAtom]:
        return self.init_atoms - self.final_atoms

    @property
    def affected_objects(self) -> frozenset[Object]:
        return frozenset(o for a in self.add_effects | self.delete_effects for o in a.objects)
