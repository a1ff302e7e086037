"""Subgoal-conditioned skill policies by behaviour cloning (paper §4.2, "Policy Learning").

A skill sees only its scope: the features of its parameters' objects, concatenated in
parameter order. The policy input is the scope without static dimensions, followed by
the *relative* subgoal (subgoal - current) over the dimensions that change in the data;
because the relative subgoal is recomputed every step, a policy conditioned on an
absolute subgoal gets closed-loop feedback for free. Features an environment declares
angles (``Type.angles``) enter as their sine and cosine, and their relative subgoal is
wrapped into [-pi, pi) (:class:`ScopeDims`).

Optionally the relative subgoal is given twice, the second time as
``tanh(relative / near_scale)``. Demonstrators switch behaviour within millimetres of
a goal (close the fingers on arrival, start pushing); after standardisation by a
spread of decimetres that region is a sliver of input space that a small network
blurs, and the cloned skill closes its fingers early or hovers short of a button. The
squashed copy resolves exactly that region (and is flat far away).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.learning.config import MLPConfig
from bpns.learning.operators import SkillDataset
from bpns.nets.linear import LinearBase
from bpns.nets.mlp import MLPParams, Regressor, train_regressor
from bpns.structs import Object, State, Type


@dataclass(frozen=True, eq=False)
class ScopeDims:
    """Which scope dimensions a skill's networks look at.

    ``state_dims``: dims not constant over every state of the skill's data (the others
    carry no information). ``subgoal_dims``: dims where a segment's final scope differs
    from its initial scope in at least one segment (the only ones a subgoal sets).
    ``num_objects``: how many leading operator objects form the scope (None: all); an
    operator's anchored parameters come last and are symbolic only. ``objects``, when
    given, overrides it: the operator parameters (by index, in this order) that form the
    scope, e.g. only those of the add effects when a skill learns from the segments of
    operators that achieve the same effects from elsewhere (:mod:`bpns.learning.sharing`).
    ``angles``: the scope dims its objects' types declare angles (``Type.angles``); the
    networks see them through :meth:`inputs` and :meth:`offsets`, which are periodic
    there. Skills learned before angles were declared have none.
    """

    size: int
    state_dims: np.ndarray
    subgoal_dims: np.ndarray
    num_objects: int | None = None
    objects: tuple[int, ...] | None = None
    angles: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        periodic = set(np.asarray(self.angles).tolist())
        sd, gd = self.state_dims, self.subgoal_dims
        # the state dims' columns that are angles (sines there, cosines appended)
        cols = [j for j, d in enumerate(sd.tolist()) if d in periodic]
        object.__setattr__(self, "_sin_cols", np.asarray(cols, dtype=np.int64))
        object.__setattr__(self, "_cos_dims", sd[cols] if cols else np.zeros(0, np.int64))
        wrap = [k for k, d in enumerate(gd.tolist()) if d in periodic]
        object.__setattr__(self, "_wrap_cols", np.asarray(wrap, dtype=np.int64))

    @property
    def input_width(self) -> int:
        """How many numbers :meth:`inputs` gives per scope."""
        return len(self.state_dims) + len(self._sin_cols)

    @property
    def angle_input_columns(self) -> frozenset[int]:
        """The columns of :meth:`inputs` that carry an angle (its sine or cosine)."""
        n = len(self.state_dims)
        cos = range(n, n + len(self._sin_cols))
        return frozenset((*self._sin_cols.tolist(), *cos))

    def inputs(self, x: np.ndarray) -> np.ndarray:
        """The networks' view of scope vectors ``x`` (..., size): the state dims, with
        an angle's sine in its place and its cosine appended after them."""
        s = x[..., self.state_dims]
        if not len(self._sin_cols):
            return s
        s = s.copy()
        s[..., self._sin_cols] = np.sin(s[..., self._sin_cols])
        return np.concatenate((s, np.cos(x[..., self._cos_dims])), axis=-1)

    def offsets(self, goal: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``goal - x`` over the subgoal dims, angles wrapped into [-pi, pi)."""
        rel = goal[..., self.subgoal_dims] - x[..., self.subgoal_dims]
        if len(self._wrap_cols):
            rel[..., self._wrap_cols] = wrap_angle(rel[..., self._wrap_cols])
        return rel

    def scope(self, objects: Sequence[Object]) -> Sequence[Object]:
        if self.objects is not None:
            return tuple(objects[i] for i in self.objects)
        return objects if self.num_objects is None else objects[: self.num_objects]

    def scope_indices(self, num_parameters: int) -> tuple[int, ...]:
        """The parameter indices of the scope for an operator of ``num_parameters``."""
        if self.objects is not None:
            return self.objects
        return tuple(range(num_parameters if self.num_objects is None else self.num_objects))

    @classmethod
    def from_scopes(
        cls,
        scopes: Sequence[np.ndarray],
        tolerance: float = 0.0,
        num_objects: int | None = None,
        objects: tuple[int, ...] | None = None,
        types: Sequence[Type] = (),
    ) -> ScopeDims:
        """``scopes[i]`` is the (steps + 1, size) scope trajectory of segment i;
        ``types``: the scope's object types in order (where its angles are)."""
        if not scopes:
            raise ValueError("no segments to compute scope dimensions from")
        allrows = np.concatenate(scopes, axis=0)
        angles = scope_angles(types)
        spread = allrows.max(axis=0) - allrows.min(axis=0)
        ends = np.stack([s[-1] - s[0] for s in scopes])
        ends[:, angles] = wrap_angle(ends[:, angles])
        change = np.abs(ends).max(axis=0)
        return cls(
            size=allrows.shape[1],
            state_dims=np.flatnonzero(spread > tolerance),
            subgoal_dims=np.flatnonzero(change > tolerance),
            num_objects=num_objects,
            objects=objects,
            angles=angles,
        )

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        out = {
            f"{prefix}size": np.array(self.size),
            f"{prefix}state_dims": self.state_dims,
            f"{prefix}subgoal_dims": self.subgoal_dims,
            f"{prefix}num_objects": np.array(-1 if self.num_objects is None else self.num_objects),
        }
        if self.objects is not None:
            out[f"{prefix}objects"] = np.array(self.objects, dtype=np.int64)
        if len(self.angles):
            out[f"{prefix}angles"] = np.asarray(self.angles, dtype=np.int64)
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str = "") -> ScopeDims:
        num = int(arrays.get(f"{prefix}num_objects", -1))  # absent in older skills
        chosen = arrays.get(f"{prefix}objects")  # absent unless the scope was chosen
        return cls(
            size=int(arrays[f"{prefix}size"]),
            state_dims=np.array(arrays[f"{prefix}state_dims"], dtype=np.int64),
            subgoal_dims=np.array(arrays[f"{prefix}subgoal_dims"], dtype=np.int64),
            num_objects=None if num < 0 else num,
            objects=None if chosen is None else tuple(int(i) for i in chosen),
            angles=np.array(arrays.get(f"{prefix}angles", ()), dtype=np.int64),
        )


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles (radians) wrapped into [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def scope_angles(types: Sequence[Type]) -> np.ndarray:
    """The indices of declared angles (``Type.angles``) in a scope of ``types``."""
    out, offset = [], 0
    for t in types:
        out.extend(offset + i for i in t.angle_indices)
        offset += t.dim
    return np.asarray(out, dtype=np.int64)


def scope_trajectories(dataset: SkillDataset) -> list[np.ndarray]:
    """Scope vectors of every state of every segment, one (steps + 1, size) array each
    (the scope: the first ``dataset.scope_size`` parameters' objects)."""
    k = dataset.scope_size
    return [
        np.stack([s.vec(objs[:k]) for s in seg.states])
        for seg, objs in zip(dataset.segments, dataset.bindings, strict=True)
    ]


def policy_training_data(
    scopes: Sequence[np.ndarray],
    actions: Sequence[np.ndarray],
    dims: ScopeDims,
    use_subgoals: bool = True,
    near_scale: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(inputs, targets): one row per step i of each segment, input = scope_i[state dims]
    (+ rel_i = (scope_end - scope_i)[subgoal dims], + tanh(rel_i / near_scale)),
    target = action_i."""
    xs, ys = [], []
    for scope, acts in zip(scopes, actions, strict=True):
        current = scope[:-1]
        parts = [dims.inputs(current)]
        if use_subgoals:
            rel = dims.offsets(scope[-1], current)
            parts.append(rel)
            if near_scale is not None:
                parts.append(np.tanh(rel / near_scale))
        xs.append(np.concatenate(parts, axis=1))
        ys.append(np.asarray(acts, dtype=np.float64).reshape(len(current), -1))
    return np.concatenate(xs, axis=0), np.concatenate(ys, axis=0)


class LearnedPolicy:
    """SubgoalPolicy backed by a numpy MLP (plus an affine ``base`` of its input, when
    learned: :mod:`bpns.nets.linear`). Outputs are returned unclipped and unchecked
    (non-finite values included): action limits and validity are the planner's job."""

    def __init__(
        self,
        dims: ScopeDims,
        params: MLPParams,
        use_subgoals: bool = True,
        near_scale: float | None = None,
        base: LinearBase | None = None,
    ) -> None:
        self.dims = dims
        self.params = params
        self.use_subgoals = use_subgoals
        self.near_scale = near_scale
        self.base = base
        self._net = Regressor(params)

    def __call__(self, state: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        dims = self.dims
        x = state.vec(dims.scope(objects))
        if x.shape[0] != dims.size:
            raise ValueError(f"scope has {x.shape[0]} features, the policy expects {dims.size}")
        s = dims.inputs(x)
        if self.use_subgoals:
            rel = dims.offsets(subgoal, x)
            if self.near_scale is None:
                x = np.concatenate((s, rel))
            else:
                x = np.concatenate((s, rel, np.tanh(rel / self.near_scale)))
        else:
            x = s
        out = self._net(x)
        return out if self.base is None else out + self.base(x)

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {
            **self.dims.to_arrays("dims/"),
            **self.params.to_arrays("net/"),
            "use_subgoals": np.array(self.use_subgoals),
            "near_scale": np.array(np.nan if self.near_scale is None else self.near_scale),
        }
        if self.base is not None:
            out.update(self.base.to_arrays("linear/"))
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> LearnedPolicy:
        near = float(arrays["near_scale"]) if "near_scale" in arrays else float("nan")
        has_base = any(k.startswith("linear/") for k in arrays)
        return cls(
            ScopeDims.from_arrays(arrays, "dims/"),
            MLPParams.from_arrays(arrays, "net/"),
            bool(arrays["use_subgoals"]),
            None if np.isnan(near) else near,
            LinearBase.from_arrays(arrays, "linear/") if has_base else None,
        )


def train_policy(
    scopes: Sequence[np.ndarray],
    actions: Sequence[np.ndarray],
    dims: ScopeDims,
    config: MLPConfig,
    seed: int,
    use_subgoals: bool = True,
    near_scale: float | None = None,
    linear_base: bool = False,
) -> LearnedPolicy:
    """``linear_base``: the network learns the residual of an affine map of its input,
    where that map predicts held-out rows better than their mean (:mod:`bpns.nets.linear`)."""
    inputs, targets = policy_training_data(scopes, actions, dims, use_subgoals, near_scale)
    base = None
    if linear_base and inputs.shape[1] > 0:
        margin = 0.1 if config.input_margin is None else config.input_margin
        base = LinearBase.fit_if_it_helps(inputs, targets, config.std_floor, margin)
    residual = targets if base is None else targets - base(inputs)
    params = train_regressor(inputs, residual, config, seed)
    return LearnedPolicy(dims, params, use_subgoals, near_scale, base)
