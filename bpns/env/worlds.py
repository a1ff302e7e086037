"""The world a task executes in and the model the planner believes in.

A :class:`~bpns.env.perturbations.Perturbation` is one physics. Evaluation draws one
per task from a :class:`WorldDistribution`: each perturbation name is fixed, or drawn
from a range or a set of values, from the distribution's seed and the task's index, so
the same task always meets the same world (and the world is stored with its rollout).
Unless the user gives one (``seed=K``), the seed is the task stream's (``bpns eval
--seed``, a sweep's seed, ``bpns demos --seed``): other seeds, other worlds, so results
checked on seeds never seen meet worlds never seen too.
Scale factors (``*_scale``) are drawn log-uniformly (a factor and its inverse are
equally likely), noises uniformly, latency uniformly from its set of control steps.

The *model* is what planning and refinement simulate: the nominal physics, the world
itself (``world``: the closed world of the paper, where the planner knows every
perturbation and even the noise), or a belief of the user's (a fixed perturbation).

Named presets (``bpns eval --perturb moderate``):

- ``moderate``: mass x[0.67, 1.5], friction x[0.7, 1.4], arm kp x[0.8, 1.25], action noise
  2 %, observation noise 2 mm, latency in {0, 1};
- ``hard``: mass x[0.5, 2], friction x[0.5, 1.5], arm kp x[0.7, 1.4], action noise 5 %,
  observation noise 5 mm, latency in {0, 1, 2}.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from bpns.env.perturbations import (
    _INTS,
    NAMES,
    NOMINAL,
    Perturbation,
    PerturbationError,
    parse_value,
)

Number = int | float


@dataclass(frozen=True)
class Spread:
    """How one perturbation varies from task to task: a fixed ``value``, a closed range
    ``[low, high]``, or one of ``choices``."""

    value: Number | None = None
    low: Number | None = None
    high: Number | None = None
    choices: tuple[Number, ...] = ()

    @property
    def fixed(self) -> bool:
        return self.value is not None

    def draw(self, name: str, rng: np.random.Generator) -> Number:
        if self.value is not None:
            return self.value
        if self.choices:
            return self.choices[int(rng.integers(len(self.choices)))]
        assert self.low is not None and self.high is not None
        if name in _INTS:
            return int(rng.integers(int(self.low), int(self.high) + 1))
        if name.endswith("_scale") and self.low > 0:
            return float(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))
        return float(rng.uniform(self.low, self.high))

    def text(self) -> str:
        if self.value is not None:
            return f"{self.value:g}"
        if self.choices:
            return ",".join(f"{c:g}" for c in self.choices)
        return f"{self.low:g}:{self.high:g}"

    def to_json(self) -> object:
        if self.value is not None:
            return self.value
        if self.choices:
            return {"choices": list(self.choices)}
        return {"range": [self.low, self.high]}

    @classmethod
    def from_json(cls, name: str, d: object) -> Spread:
        if isinstance(d, dict) and "choices" in d:
            return cls(choices=tuple(_number(name, v) for v in d["choices"]))
        if isinstance(d, dict) and "range" in d and len(d["range"]) == 2:
            low, high = (_number(name, v) for v in d["range"])
            return cls(low=low, high=high)
        return cls(value=_number(name, d))


def _number(name: str, value: object) -> Number:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise PerturbationError(f"{name}: expected a number, got {value!r}")
    if name in _INTS:
        if isinstance(value, float) and not value.is_integer():
            raise PerturbationError(f"{name} must be a whole number, got {value!r}")
        return int(value)
    return float(value)


@dataclass(frozen=True)
class WorldDistribution:
    """Per-task worlds: each name in ``spreads`` fixed, ranged or chosen (the others
    nominal). ``seed`` seeds both the draws and the worlds' noises; None: the seed of the
    task stream the worlds are drawn for (:meth:`seeded`; drawn as 0 until then).
    ``preset`` names the preset it came from, if any (for labels)."""

    spreads: Mapping[str, Spread] | tuple[tuple[str, Spread], ...] = ()
    seed: int | None = None
    preset: str | None = None

    def __post_init__(self) -> None:
        given = dict(self.spreads)  # stored as (name, spread) pairs: hashable, picklable
        unknown = sorted(set(given) - set(NAMES) | ({"seed"} & set(given)))
        if unknown:
            raise PerturbationError(f"unknown perturbation {unknown[0]!r}; known: {_known()}")
        seed = self.seed
        if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool) or seed < 0):
            raise PerturbationError(f"seed must be a whole number >= 0, got {seed!r}")
        for name, spread in given.items():
            _check_spread(name, spread)
        object.__setattr__(self, "spreads", tuple((n, given[n]) for n in NAMES if n in given))

    @property
    def by_name(self) -> dict[str, Spread]:
        return dict(self.spreads)

    @property
    def fixed(self) -> bool:
        """Every task meets the same physics (a plain ``Perturbation``)."""
        return all(s.fixed for _, s in self.spreads)

    @property
    def nominal(self) -> bool:
        return self.fixed and self.draw(0).nominal

    def seeded(self, stream_seed: int) -> WorldDistribution:
        """These worlds drawn for the task stream of ``stream_seed``: its seed, unless the
        user gave one. Nominal physics keeps seed 0 (there is nothing to draw)."""
        if self.seed is not None:
            return self
        return dataclasses.replace(self, seed=stream_seed if self.spreads else 0)

    def draw(self, index: int) -> Perturbation:
        """The physics of task ``index`` (the same index always draws the same)."""
        seed = 0 if self.seed is None else self.seed
        rng = np.random.default_rng([seed, 0x5EED, index])
        values: dict[str, Number] = {"seed": seed}
        for name, spread in self.spreads:
            values[name] = spread.draw(name, rng)
        return Perturbation(**values)

    def label(self) -> str:
        """``moderate``, ``nominal``, or the settings, ``name=spread`` joined by commas."""
        if self.preset is not None and self.spreads == PRESETS[self.preset].spreads:
            return self.preset
        if self.fixed:
            return self.draw(0).label()
        text = ",".join(f"{n}={s.text()}" for n, s in self.spreads)
        return text or "nominal"

    def to_json(self) -> str:
        return json.dumps(
            {
                "spreads": {n: s.to_json() for n, s in self.spreads},
                "seed": self.seed,
                "preset": self.preset,
            },
            sort_keys=True,
        )

    @classmethod
    def from_json(cls, text: str) -> WorldDistribution:
        try:
            d = json.loads(text)
        except (TypeError, ValueError) as err:
            raise PerturbationError(f"not a world distribution record: {err}") from None
        if not isinstance(d, dict) or not isinstance(d.get("spreads"), dict):
            raise PerturbationError("not a world distribution record: expected its spreads")
        spreads = {n: Spread.from_json(n, v) for n, v in d["spreads"].items()}
        seed = d.get("seed", 0)  # records before per-stream seeds drew from seed 0
        return cls(spreads, None if seed is None else int(seed), d.get("preset"))

    @classmethod
    def of(cls, p: Perturbation) -> WorldDistribution:
        """The distribution that always draws ``p``."""
        defaults = Perturbation()
        spreads = {
            f.name: Spread(value=getattr(p, f.name))
            for f in dataclasses.fields(p)
            if f.name != "seed" and getattr(p, f.name) != getattr(defaults, f.name)
        }
        return cls(spreads, p.seed)


def _known() -> str:
    return ", ".join(n for n in NAMES if n != "seed")


def _check_spread(name: str, s: Spread) -> None:
    """Every value a spread can draw must be a valid perturbation by itself."""
    given = [s.value is not None, s.low is not None or s.high is not None, bool(s.choices)]
    if sum(given) != 1:
        raise PerturbationError(f"{name}: give one value, one LOW:HIGH range or a set of values")
    points = [s.value] if s.value is not None else list(s.choices) or [s.low, s.high]
    if None in points:
        raise PerturbationError(f"{name}: a range needs both ends, LOW:HIGH")
    for v in points:
        Perturbation(**{name: v})  # raises PerturbationError naming the bound
    if s.low is not None and s.high is not None and not s.low <= s.high:
        raise PerturbationError(f"{name}: range {s.low:g}:{s.high:g} has its ends reversed")
    if len(set(s.choices)) != len(s.choices):
        raise PerturbationError(f"{name}: the set {s.text()} repeats a value")


def _preset(**spreads: Spread) -> WorldDistribution:
    return WorldDistribution(spreads)


PRESETS: Mapping[str, WorldDistribution] = MappingProxyType(
    {
        "moderate": _preset(
            mass_scale=Spread(low=0.67, high=1.5),
            friction_scale=Spread(low=0.7, high=1.4),
            gain_scale=Spread(low=0.8, high=1.25),
            action_noise=Spread(value=0.02),
            obs_noise=Spread(value=0.002),
            latency=Spread(choices=(0, 1)),
        ),
        "hard": _preset(
            mass_scale=Spread(low=0.5, high=2.0),
            friction_scale=Spread(low=0.5, high=1.5),
            gain_scale=Spread(low=0.7, high=1.4),
            action_noise=Spread(value=0.05),
            obs_noise=Spread(value=0.005),
            latency=Spread(choices=(0, 1, 2)),
        ),
    }
)
NOMINAL_WORLD = WorldDistribution()


def parse_spread(name: str, text: str) -> Spread:
    """``VALUE``, ``LOW:HIGH`` or ``V1,V2,...`` as the spread of perturbation ``name``."""
    text = text.strip()
    if ":" in text:
        low, _, high = text.partition(":")
        return Spread(low=parse_value(name, low.strip()), high=parse_value(name, high.strip()))
    if "," in text:
        return Spread(choices=tuple(parse_value(name, v.strip()) for v in text.split(",")))
    return Spread(value=parse_value(name, text))


def parse_world(items: Iterable[str]) -> WorldDistribution:
    """``[PRESET] [NAME=SPREAD ...]`` (``bpns eval --perturb``): a preset's spreads, each
    ``NAME=`` replacing its name's; one :class:`PerturbationError` for any problem (an
    unknown or misspelt name, a bad value, a name given twice)."""
    items = [i.strip() for i in items]
    base: WorldDistribution = NOMINAL_WORLD
    if items and "=" not in items[0] and items[0] not in NAMES:
        name = items.pop(0)
        if name == "nominal":
            base = NOMINAL_WORLD
        elif name in PRESETS:
            base = dataclasses.replace(PRESETS[name], preset=name)
        else:
            raise PerturbationError(_unknown_preset(name))
    spreads = base.by_name
    seed = base.seed
    seen: set[str] = set()
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep:
            if name in PRESETS or name == "nominal":
                raise PerturbationError(f"the preset {name!r} must come first, before NAME=VALUE")
            raise PerturbationError(f"perturbation {item!r} is not NAME=VALUE")
        if name in seen:
            raise PerturbationError(f"perturbation {name!r} is given twice")
        seen.add(name)
        if name not in NAMES:
            close = difflib.get_close_matches(name, NAMES, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise PerturbationError(f"unknown perturbation {name!r}{hint}; known: {_known()}")
        if name == "seed":
            seed = int(parse_value(name, text))
            if seed < 0:
                raise PerturbationError(f"seed must be a whole number >= 0, got {seed}")
            continue
        if not text.strip():
            raise PerturbationError(f"perturbation {name!r} has no value")
        spreads[name] = parse_spread(name, text)
    return WorldDistribution(spreads, seed, base.preset)


def _unknown_preset(name: str) -> str:
    names = [*PRESETS, "nominal"]
    close = difflib.get_close_matches(name, names, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return (
        f"unknown perturbation preset {name!r}{hint}; presets: {', '.join(names)}, "
        "or give NAME=VALUE items"
    )


@dataclass(frozen=True)
class ModelSpec:
    """What the planner's simulator knows of the world: ``knows_world`` (the paper's
    closed world: the model is the drawn world itself, noise included), else the fixed
    ``belief`` (nominal physics unless the user believes otherwise)."""

    knows_world: bool = False
    belief: Perturbation = NOMINAL

    def physics(self, world: Perturbation) -> Perturbation:
        """The physics the planner simulates when the world is ``world``."""
        return world if self.knows_world else self.belief

    def label(self) -> str:
        return "world" if self.knows_world else self.belief.label()

    def to_json(self) -> str:
        return json.dumps({"knows_world": self.knows_world, "belief": self.belief.to_json()})

    @classmethod
    def from_json(cls, text: str) -> ModelSpec:
        try:
            d = json.loads(text)
            return cls(bool(d["knows_world"]), Perturbation.from_json(d["belief"]))
        except (TypeError, ValueError, KeyError) as err:
            raise PerturbationError(f"not a model record: {err}") from None


NOMINAL_MODEL = ModelSpec()
WORLD_MODEL = ModelSpec(knows_world=True)


def parse_model(items: Iterable[str]) -> ModelSpec:
    """``nominal``, ``world`` or ``NAME=VALUE ...`` (a fixed belief) (``bpns eval --model``)."""
    items = [i.strip() for i in items]
    if items == ["nominal"] or not items:
        return NOMINAL_MODEL
    if items == ["world"]:
        return WORLD_MODEL
    bad = next((i for i in items if "=" not in i), None)
    if bad is not None:
        raise PerturbationError(
            f"{bad!r}: expected 'nominal', 'world' or NAME=VALUE items (a belief)"
        )
    belief = parse_world(items)
    if not belief.fixed:
        raise PerturbationError("a belief is one physics: give values, not ranges")
    return ModelSpec(belief=belief.draw(0))
