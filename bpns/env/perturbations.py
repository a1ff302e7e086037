"""Physical perturbations an evaluation runs under: a typed, validated spec.

bpns only carries the spec; the environment implements it (its declared
``Capabilities.perturbed`` returns the same environment with perturbed physics, applied
through ``bpns.env.environment.perturbed``; ``mj_envs`` documents what each one changes in
MuJoCo). The spec is stored in every rollouts file, so a perturbed
rollout replays and renders exactly.

Names (``bpns eval --perturb NAME=VALUE``):

- ``mass_scale``: factor on the mass and inertia of every body that is not the robot's.
- ``friction_scale``: factor on every geom's friction coefficients (so on every contact's).
- ``gain_scale``: factor on the stiffness (kp) of the arm's position actuators.
- ``action_noise``: std of Gaussian noise added to every action, as a fraction of each
  action dimension's half range; seeded, a function of the state it acts on.
- ``obs_noise``: std of Gaussian noise on the features the skills' policies see (feature
  units); the simulator state, predicates and the goal test see the true features.
- ``latency``: the action applied is the one commanded ``latency`` control steps earlier
  (zero actions before that); the queue is part of the saved simulator state.
- ``seed``: seed of both noises.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass

from bpns.errors import BpnsError


class PerturbationError(BpnsError, ValueError):
    """An unknown perturbation name or a value out of its range."""


MAX_LATENCY = 50


@dataclass(frozen=True)
class Perturbation:
    """What differs from the nominal physics; the defaults change nothing."""

    mass_scale: float = 1.0
    friction_scale: float = 1.0
    gain_scale: float = 1.0
    action_noise: float = 0.0
    obs_noise: float = 0.0
    latency: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("mass_scale", "gain_scale"):
            _check(name, getattr(self, name), lambda v: v > 0, "> 0")
        _check("friction_scale", self.friction_scale, lambda v: v >= 0, ">= 0")
        for name in ("action_noise", "obs_noise"):
            _check(name, getattr(self, name), lambda v: v >= 0, ">= 0")
        if not isinstance(self.latency, int) or not 0 <= self.latency <= MAX_LATENCY:
            raise PerturbationError(
                f"latency must be a whole number of control steps in [0, {MAX_LATENCY}], "
                f"got {self.latency!r}"
            )
        if not isinstance(self.seed, int) or self.seed < 0:
            raise PerturbationError(f"seed must be a whole number >= 0, got {self.seed!r}")

    @property
    def nominal(self) -> bool:
        return self == NOMINAL

    @property
    def changes_model(self) -> bool:
        """Whether the compiled model differs (masses, friction, gains, the latency queue)."""
        return (self.mass_scale, self.friction_scale, self.gain_scale, self.latency) != (
            1.0,
            1.0,
            1.0,
            0,
        )

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Perturbation:
        try:
            values = json.loads(text)
        except (TypeError, ValueError) as err:
            raise PerturbationError(f"not a perturbation record: {err}") from None
        if not isinstance(values, dict):
            raise PerturbationError("not a perturbation record: expected a JSON object")
        return cls(**_typed(values))

    def label(self) -> str:
        """The settings that differ from nominal, ``name=value`` joined by commas."""
        diff = [
            f"{f.name}={getattr(self, f.name):g}"
            for f in dataclasses.fields(self)
            if getattr(self, f.name) != f.default and f.name != "seed"
        ]
        return ",".join(diff) or "nominal"


NAMES = tuple(f.name for f in dataclasses.fields(Perturbation))
# axis labels of figures: each name with its unit
AXIS_LABELS = {
    "mass_scale": "object mass scale",
    "friction_scale": "friction scale",
    "gain_scale": "arm stiffness (kp) scale",
    "action_noise": "action noise (std, fraction of half range)",
    "obs_noise": "observation noise (std, feature units)",
    "latency": "latency (control steps)",
}
_INTS = {"latency", "seed"}


def _check(name: str, value: object, ok, bound: str) -> None:
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise PerturbationError(f"{name} must be a finite number, got {value!r}")
    if not ok(value):
        raise PerturbationError(f"{name} must be {bound}, got {value!r}")


def _typed(values: dict) -> dict:
    unknown = sorted(set(values) - set(NAMES))
    if unknown:
        raise PerturbationError(f"unknown perturbation {unknown[0]!r}; known: {', '.join(NAMES)}")
    out = {}
    for name, value in values.items():
        if name in _INTS:
            if isinstance(value, float) and value.is_integer():
                value = int(value)
        elif isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        out[name] = value
    return out


NOMINAL = Perturbation()


def parse_value(name: str, text: str) -> int | float:
    """``text`` as the value of perturbation ``name`` (a whole number for latency/seed)."""
    if name not in NAMES:
        raise PerturbationError(f"unknown perturbation {name!r}; known: {', '.join(NAMES)}")
    try:
        return int(text) if name in _INTS else float(text)
    except ValueError:
        kind = "a whole number" if name in _INTS else "a number"
        raise PerturbationError(f"{name} must be {kind}, got {text!r}") from None


def parse_perturbation(items: Iterable[str], base: Perturbation = NOMINAL) -> Perturbation:
    """``NAME=VALUE`` items over ``base``; one :class:`PerturbationError` for any problem."""
    values = dataclasses.asdict(base)
    for item in items:
        name, sep, text = item.partition("=")
        if not sep:
            raise PerturbationError(f"perturbation {item!r} is not NAME=VALUE")
        values[name.strip()] = parse_value(name.strip(), text.strip())
    return Perturbation(**values)


def parse_axis(text: str) -> tuple[str, tuple[int | float, ...]]:
    """``NAME=V1,V2,...`` (a perturbation axis of an experiment) -> (name, values)."""
    name, sep, rest = text.partition("=")
    name = name.strip()
    if not sep or not rest.strip():
        raise PerturbationError(f"perturbation axis {text!r} is not NAME=V1,V2,...")
    if name == "seed":
        raise PerturbationError("seed is not a perturbation axis")
    values = tuple(parse_value(name, v.strip()) for v in rest.split(","))
    for v in values:  # each level must be a valid perturbation by itself
        Perturbation(**{name: v})
    if len(set(values)) != len(values):
        raise PerturbationError(f"perturbation axis {text!r} repeats a value")
    return name, values
