"""Subgoal samplers: Gaussian generator + rejection classifier (paper §4.2, appendix B).

The generator predicts the relative subgoal (scope at the segment's end minus scope at
its start, over the changing dims) from the start scope. A Gaussian is unimodal; the
classifier, trained to tell demonstrated subgoals from subgoals that are wrong for the
given objects, carves multimodal or binding-specific structure out of its samples.

Negatives for skill k:
(a) wrong bindings: the start state of one of k's own segments under another binding of
    k's operator whose preconditions hold there, with the subgoal that binding's objects
    actually reached (e.g. "pick block1" paired with the robot ending at block0);
(b) other skills' data: a segment of another skill whose start state satisfies k's
    preconditions under some binding, with that binding's end-state subgoal.
Bindings under which the segment's effects are exactly k's ground effects are equally
valid explanations of the segment and are never used as negatives.

The generator's mean is a linear map of the start scope plus the network's output,
which learns the residual (:class:`bpns.nets.linear.LinearBase`;
``LearningConfig.linear_sampler_base``).

Many subgoals are affine in the start state (the hand goes to the button's x and y;
the stick's tip to the button), and a ridge fit recovers such a map from a few dozen
segments, where a 2x32 network trained by NLL on them overfits: at 250 Stick Button
demos the hand press from one button to the next (16-33 segments) had its generator's
held-out hand-y error at 8 mm (p90 5 cm) with a learned std of 0.9 mm.

The paper's generator draws each subgoal dim independently. Dims that move together
(a held block and the hand holding it) then get independent noise: a place subgoal
whose block and hand disagree by about 1.4 standard deviations, which the nominal model
forgives and a noisy world does not. With ``LearningConfig.correlated_subgoal_noise``
the draw is ``mean + std * (L @ eps)``, ``L`` the Cholesky factor of the correlation of
the generator's standardised training residuals ``(y - mean(x)) / std(x)``
(:class:`NoiseCorrelation`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bpns.learning.config import MLPConfig
from bpns.learning.operators import SkillDataset, applicable_bindings
from bpns.learning.policies import ScopeDims
from bpns.nets.linear import LinearBase
from bpns.nets.mlp import (
    BinaryClassifier,
    GaussianRegressor,
    MLPParams,
)
from bpns.structs import NoSubgoal, Object, Segment, State, STRIPSOperator


class LearnedSampler:
    """SubgoalSampler: draw relative subgoals from the generator, keep the first the
    classifier accepts (prob > 0.5), else the last of ``max_tries``; return it absolute.
    With a ``base`` the generator's mean is ``base(s)`` plus the network's. With a
    ``novelty`` test it refuses novel starts with :class:`~bpns.structs.NoSubgoal`,
    which the planner counts as a failed sample without simulating it."""

    def __init__(
        self,
        dims: ScopeDims,
        generator: MLPParams,
        classifier: MLPParams | None,
        max_tries: int = 100,
        base: LinearBase | None = None,
        novelty: Novelty | None = None,
        correlation: NoiseCorrelation | None = None,
    ) -> None:
        width = len(dims.subgoal_dims)
        if correlation is not None and correlation.chol.shape != (width, width):
            raise ValueError(
                f"noise/chol has shape {correlation.chol.shape}, the sampler draws {width} "
                f"subgoal dims: expected ({width}, {width})"
            )
        self.dims = dims
        self.correlation = correlation
        self.generator_params = generator
        self.classifier_params = classifier
        self.max_tries = max_tries
        self.base = base
        self.novelty = novelty
        self._gen = GaussianRegressor(generator)
        self._cls = None if classifier is None else BinaryClassifier(classifier)

    def mean_std(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The generator's Gaussian over the relative subgoal, given state dims ``s``."""
        mean, std = self._gen.mean_std(s)
        return (mean if self.base is None else mean + self.base(s)), std

    def _start(self, state: State, objects: Sequence[Object]) -> np.ndarray:
        x = state.vec(self.dims.scope(objects))
        if x.shape[0] != self.dims.size:
            raise ValueError(
                f"scope has {x.shape[0]} features, the sampler expects {self.dims.size}"
            )
        return x

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        x = self._start(state, objects)
        s = self.dims.inputs(x)
        if self.novel(s):
            raise NoSubgoal("the skill was never demonstrated from a start like this one")
        mean, std = self.mean_std(s)
        rel = self._draw(s, mean, std, rng)
        subgoal = x.copy()
        subgoal[self.dims.subgoal_dims] += rel
        return subgoal

    def novel(self, s: np.ndarray) -> bool:
        """Does the start (state dims ``s``) lie in a world none of the skill's segments
        started in (:class:`Novelty`)?"""
        return self.novelty is not None and self.novelty.novel(s)

    def _draw(
        self, s: np.ndarray, mean: np.ndarray, std: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        first = mean + std * self._noise(rng, mean.shape)
        if self._cls is None or self._cls.prob(np.concatenate((s, first))) > 0.5:
            return first
        if self.max_tries == 1:
            return first
        # The remaining tries in one batch: same random stream as one-by-one draws.
        rest = mean + std * self._noise(rng, (self.max_tries - 1, mean.shape[0]))
        probs = self._cls.prob(
            np.concatenate((np.broadcast_to(s, (len(rest), s.shape[0])), rest), axis=1)
        )
        accepted = np.flatnonzero(probs > 0.5)
        return rest[accepted[0]] if accepted.size else rest[-1]

    def _noise(self, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """Standard normal draws of ``shape`` (last axis: the subgoal dims), correlated
        where the sampler learnt a :class:`NoiseCorrelation`."""
        eps = rng.standard_normal(shape)
        return eps if self.correlation is None else self.correlation.mix(eps)

    def accept_probability(
        self, state: State, objects: Sequence[Object], subgoal: np.ndarray
    ) -> float:
        """Classifier's P(valid) for an absolute subgoal (1.0 when there is no classifier)."""
        if self._cls is None:
            return 1.0
        x = self._start(state, objects)
        dims = self.dims
        return float(self._cls.prob(np.concatenate((dims.inputs(x), dims.offsets(subgoal, x)))))

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {
            **self.dims.to_arrays("dims/"),
            **self.generator_params.to_arrays("generator/"),
            "max_tries": np.array(self.max_tries),
        }
        if self.classifier_params is not None:
            out.update(self.classifier_params.to_arrays("classifier/"))
        if self.base is not None:
            out.update(self.base.to_arrays("linear/"))
        if self.novelty is not None:
            out.update(self.novelty.to_arrays("novelty/"))
        if self.correlation is not None:
            out.update(self.correlation.to_arrays("noise/"))
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> LearnedSampler:
        has_classifier = any(k.startswith("classifier/") for k in arrays)
        has_base = any(k.startswith("linear/") for k in arrays)  # absent in older skills
        return cls(
            ScopeDims.from_arrays(arrays, "dims/"),
            MLPParams.from_arrays(arrays, "generator/"),
            MLPParams.from_arrays(arrays, "classifier/") if has_classifier else None,
            int(arrays["max_tries"]),
            LinearBase.from_arrays(arrays, "linear/") if has_base else None,
            Novelty.from_arrays(arrays, "novelty/") if "novelty/dims" in arrays else None,
            NoiseCorrelation.from_arrays(arrays, "noise/") if "noise/chol" in arrays else None,
        )


class CurrentStateSampler:
    """Placeholder sampler for skills without subgoals (BPNS-NoSubgoal): returns the
    current scope, which such policies ignore. Consumes no randomness."""

    def __call__(
        self, state: State, objects: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        return state.vec(objects)

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {}


# -------------------------------------------------------------------------- training data


def _row(start: State, end: State, objects: Sequence[Object], dims: ScopeDims) -> np.ndarray:
    scope = dims.scope(objects)
    s0, s1 = start.vec(scope), end.vec(scope)
    return np.concatenate((dims.inputs(s0), dims.offsets(s1, s0)))


def _explains(operator: STRIPSOperator, binding: tuple[Object, ...], segment: Segment) -> bool:
    ground = operator.ground(binding)
    return (
        ground.add_effects == segment.add_effects
        and ground.delete_effects == segment.delete_effects
    )


def _negative_bindings(
    operator: STRIPSOperator,
    segment: Segment,
    exclude: tuple[Object, ...] | None,
    cap: int | None,
    rng: np.random.Generator,
) -> list[tuple[Object, ...]]:
    bindings = [
        b
        for b in applicable_bindings(operator, segment.init_atoms, segment.states[0].objects)
        if b != exclude and not _explains(operator, b, segment)
    ]
    if cap is not None and len(bindings) > cap:
        keep = np.sort(rng.choice(len(bindings), size=cap, replace=False))
        bindings = [bindings[i] for i in keep]
    return bindings


def sampler_training_data(
    dataset: SkillDataset,
    scopes: Sequence[np.ndarray],
    dims: ScopeDims,
    other_segments: Sequence[Segment],
    max_negative_bindings_per_segment: int | None,
    seed: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(generator inputs, generator targets, classifier rows + labels as last column).

    Generator: start scope (state dims) -> relative subgoal (subgoal dims), one row per
    segment. Classifier rows: start scope (state dims) + relative subgoal.
    """
    starts = np.stack([sc[0] for sc in scopes])
    ends = np.stack([sc[-1] for sc in scopes])
    gen_x = dims.inputs(starts)
    gen_y = dims.offsets(ends, starts)
    positives = np.concatenate((gen_x, gen_y), axis=1)
    rng = np.random.default_rng(seed)
    cap = max_negative_bindings_per_segment
    negatives = []
    for seg, binding in zip(dataset.segments, dataset.bindings, strict=True):
        for b in _negative_bindings(dataset.operator, seg, binding, cap, rng):
            negatives.append(_row(seg.states[0], seg.states[-1], b, dims))
    for seg in other_segments:
        for b in _negative_bindings(dataset.operator, seg, None, cap, rng):
            negatives.append(_row(seg.states[0], seg.states[-1], b, dims))
    width = positives.shape[1]
    neg = np.array(negatives, dtype=np.float64).reshape(-1, width)
    rows = np.concatenate((positives, neg), axis=0)
    labels = np.concatenate((np.ones(len(positives)), np.zeros(len(neg))))
    return gen_x, gen_y, np.concatenate((rows, labels[:, None]), axis=1)


CONTEXT_MOVE = 0.1  # a context dim moves less than this fraction of its spread over starts
RANGE_MARGIN = 0.1  # ... and may lie this fraction of its spread beyond the demonstrated range
MIN_NOVELTY_SEGMENTS = 10  # fewer segments say too little about where a skill can start


@dataclass(frozen=True, eq=False)
class Novelty:
    """A sampler's test of its start: is a *context* dim (``dims``, indices into the state
    dims; see :func:`context_dims`) outside ``[low, high]``, the range its segments
    started from widened on each side by ``max(RANGE_MARGIN, 2 / (n - 1))`` of the spread
    plus ``novelty_floor``? The range of n draws misses about 1 / (n + 1) of their
    distribution's spread at each end; the second term covers that where n is small.
    With fewer than ``MIN_NOVELTY_SEGMENTS`` segments there is no test at all (Doors from
    six demonstrations: the door's mass and friction ranges of six doors refused the next).

    Networks see such a dim clipped into their input box, so they answer for another
    world: at 250 Stick Button demonstrations the hand press at a button 0.92 m away
    proposed the hand at 0.65 m, the policy got there, the press never happened, and the
    rollout ran 60-90 simulated steps until "stuck" (92 % of all simulated steps).
    """

    dims: np.ndarray
    low: np.ndarray
    high: np.ndarray

    def novel(self, s: np.ndarray) -> bool:
        x = s[self.dims]
        return bool(((x < self.low) | (x > self.high)).any())

    @classmethod
    def of(
        cls, gen_x: np.ndarray, gen_y: np.ndarray, dims: ScopeDims, floor: float
    ) -> Novelty | None:
        """The test learned from a skill's segments (rows of ``gen_x``/``gen_y``), or None
        when there are too few of them."""
        n = len(gen_x)
        if n < MIN_NOVELTY_SEGMENTS:
            return None
        j = context_dims(gen_x, gen_y, dims)
        lo, hi = gen_x[:, j].min(axis=0), gen_x[:, j].max(axis=0)
        pad = max(RANGE_MARGIN, 2.0 / (n - 1)) * (hi - lo) + floor
        return cls(j, lo - pad, hi + pad)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {
            f"{prefix}dims": self.dims.astype(np.int64),
            f"{prefix}low": self.low.astype(np.float64),
            f"{prefix}high": self.high.astype(np.float64),
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str) -> Novelty:
        return cls(
            np.asarray(arrays[f"{prefix}dims"], dtype=np.int64),
            np.asarray(arrays[f"{prefix}low"], dtype=np.float64),
            np.asarray(arrays[f"{prefix}high"], dtype=np.float64),
        )


def context_dims(gen_x: np.ndarray, gen_y: np.ndarray, dims: ScopeDims) -> np.ndarray:
    """The state dims (indices into ``gen_x``'s columns) a skill takes as given: they
    varied between its segments' starts, and no segment moved them by more than
    ``CONTEXT_MOVE`` of that spread (the button's place for a press, the pot's rotation
    for a pick; physics moves them a hair). A novel value of one of them is a world the
    skill was never shown. Dims the skill sets are not context: its closed-loop policy
    moves them, and they drift with the task's length (Coffee's pot tilts further for a
    third cup than in any demonstration's second)."""
    spread = gen_x.max(axis=0) - gen_x.min(axis=0) if len(gen_x) else np.zeros(gen_x.shape[1])
    where = {int(d): k for k, d in enumerate(dims.subgoal_dims)}
    periodic = dims.angle_input_columns  # a sine's range is no interval of starts
    keep = []
    for j, d in enumerate(dims.state_dims):
        if j in periodic:
            continue
        k = where.get(int(d))
        moved = 0.0 if k is None or not len(gen_y) else float(np.abs(gen_y[:, k]).max())
        if spread[j] > 0 and moved <= CONTEXT_MOVE * spread[j]:
            keep.append(j)
    return np.asarray(keep, dtype=np.int64)


@dataclass(frozen=True, eq=False)
class NoiseCorrelation:
    """Correlated draws for a Gaussian generator: ``mix(eps) = L @ eps`` with ``L`` the
    lower Cholesky factor of ``C``, the correlation of the standardised residuals
    ``r = (y - mu(x)) / sigma(x)`` over the training set, shrunk towards the identity
    (``C = (1 - SHRINK) corr(r) + SHRINK I``) so that a few dozen segments give a factor
    that exists and does not trust a spurious correlation fully. Dims whose residuals do
    not vary keep independent noise. Marginals are unchanged: ``diag(C) = 1``."""

    chol: np.ndarray  # (d, d), lower triangular

    SHRINK = 0.05

    def mix(self, eps: np.ndarray) -> np.ndarray:
        """``L @ eps`` for one draw ``(d,)`` or a batch ``(n, d)``."""
        return eps @ self.chol.T

    @classmethod
    def of(cls, x: np.ndarray, y: np.ndarray, generator: MLPParams) -> NoiseCorrelation | None:
        """None when there is nothing to correlate (one dim, or fewer than 3 examples)."""
        n, d = y.shape
        if d < 2 or n < 3:
            return None
        mean, std = GaussianRegressor(generator).mean_std(x)
        r = (y - mean) / std
        r = r - r.mean(axis=0)
        scale = np.sqrt((r * r).mean(axis=0))
        varies = scale > 1e-9
        corr = np.eye(d)
        v = np.flatnonzero(varies)
        if v.size >= 2:
            z = r[:, v] / scale[v]
            corr[np.ix_(v, v)] = (z.T @ z) / n
        corr = (1.0 - cls.SHRINK) * corr + cls.SHRINK * np.eye(d)
        return cls(np.linalg.cholesky(corr))

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {f"{prefix}chol": self.chol}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], prefix: str) -> NoiseCorrelation:
        chol = np.asarray(arrays[f"{prefix}chol"], dtype=np.float64)
        if chol.ndim != 2 or chol.shape[0] != chol.shape[1] or not np.isfinite(chol).all():
            raise ValueError(f"{prefix}chol must be a finite square matrix, got {chol.shape}")
        return cls(chol)


@dataclass(frozen=True, eq=False)
class SamplerFit:
    """A sampler before its networks: what the generator and the classifier are trained
    on, and the parts fitted without them (the ridge base, the novelty test). The two
    networks are independent (each seeded on its own), so learning can train them in
    different processes and :meth:`assemble` the sampler from what comes back."""

    dims: ScopeDims
    gen_x: np.ndarray
    gen_target: np.ndarray  # what the generator learns: the subgoal, minus the base
    classifier_x: np.ndarray
    classifier_labels: np.ndarray | None  # None: no negatives, no classifier
    max_tries: int
    base: LinearBase | None
    novelty: Novelty | None
    correlated: bool = False  # fit a NoiseCorrelation once the generator is trained

    @classmethod
    def of(
        cls,
        gen_x: np.ndarray,
        gen_y: np.ndarray,
        classifier_data: np.ndarray,
        dims: ScopeDims,
        generator_config: MLPConfig,
        max_tries: int = 100,
        linear_base: bool = False,
        novelty_floor: float | None = None,
        correlated: bool = False,
    ) -> SamplerFit | None:
        """None for a skill whose scope never changes in the data: it has nothing to
        sample (:class:`CurrentStateSampler`)."""
        if gen_y.shape[1] == 0:
            return None
        base = None
        if linear_base and gen_x.shape[1] > 0:
            margin = generator_config.input_margin
            base = LinearBase.fit_if_it_helps(
                gen_x, gen_y, generator_config.std_floor, 0.1 if margin is None else margin
            )
        target = gen_y if base is None else gen_y - base(gen_x)
        labels = classifier_data[:, -1]
        novelty = None if novelty_floor is None else Novelty.of(gen_x, gen_y, dims, novelty_floor)
        return cls(
            dims,
            gen_x,
            target,
            classifier_data[:, :-1],
            labels if (labels == 0).any() else None,
            max_tries,
            base,
            novelty,
            correlated,
        )

    def assemble(self, generator: MLPParams, classifier: MLPParams | None) -> LearnedSampler:
        correlation = None
        if self.correlated:
            correlation = NoiseCorrelation.of(self.gen_x, self.gen_target, generator)
        return LearnedSampler(
            self.dims,
            generator,
            classifier,
            self.max_tries,
            self.base,
            self.novelty,
            correlation,
        )
