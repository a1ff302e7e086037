"""What a sweep covers, as frozen dataclasses; named presets; command-line overrides.

A sweep's settings decide its results. How it runs (workers, backend) does not, so it
is not part of :class:`SweepConfig`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from bpns.acting.config import MODES, ExecutionConfig, ExecutionConfigError
from bpns.env.perturbations import Perturbation, PerturbationError
from bpns.env.registry import environment_names
from bpns.env.worlds import parse_model, parse_world
from bpns.errors import BpnsError
from bpns.experiments.approach_info import approach_names


class SweepConfigError(BpnsError, ValueError):
    """A sweep whose settings make no sense (empty, negative, repeated)."""


def level_label(value: float) -> str:
    """A perturbation level as it names a cell (and its file): 6 significant digits."""
    return f"{value:g}"


@dataclass(frozen=True)
class SweepConfig:
    """Environments x demo counts x seeds x approaches, evaluated on ``eval_tasks`` tasks.

    A seed picks the train tasks (hence the demonstrations and the skills' network
    initialisation) and the eval tasks and the planner's sampling.
    """

    name: str
    envs: tuple[str, ...]
    demo_counts: tuple[int, ...]
    seeds: tuple[int, ...]
    approaches: tuple[str, ...]
    eval_tasks: int
    timeout: float  # seconds of planning per eval task
    # (perturbation name, levels): every eval cell once per level (bpns.env.perturbations)
    perturb_axis: tuple[str, tuple[float, ...]] | None = None
    # (object kind, counts): every eval cell once per count (``bpns eval --objects``)
    objects_axis: tuple[str, tuple[int, ...]] | None = None
    # worlds (bpns.env.worlds: "nominal", a preset, or "NAME=SPREAD ...") x executions
    # ("closed-loop", "open-loop"): every eval cell once per pair; () for neither axis
    worlds: tuple[str, ...] = ()
    executions: tuple[str, ...] = ()
    model: str = "nominal"  # what the planner simulates (``bpns eval --model``)
    # PlanningConfig.demote_refuted for every eval cell (None: the environment's)
    demote_refuted: float | None = None
    # ExecutionConfig.world_speed of every closed-loop cell (None: full speed), and when
    # it takes effect (ExecutionConfig.slow_from; None: from the start)
    world_speed: float | None = None
    slow_from: str | None = None
    # ExecutionConfig.predict_latency of every closed-loop cell
    predict_latency: bool = False
    # ExecutionConfig.check_ahead of every closed-loop cell (None: the whole rest)
    check_ahead: int | None = None
    # ExecutionConfig.watch_releases of every closed-loop cell
    watch_releases: bool = False
    # skills retrained on the oracle's corrections in these worlds (``bpns learn
    # --corrections``; None: none), over this many rounds (None: 2)
    corrections: str | None = None
    correction_rounds: int | None = None

    def __post_init__(self) -> None:
        for field in ("envs", "demo_counts", "seeds", "approaches"):
            values = getattr(self, field)
            if not values:
                raise SweepConfigError(f"{field} must not be empty")
            if len(set(values)) != len(values):
                raise SweepConfigError(f"{field} has repeated values: {list(values)}")
        if min(self.demo_counts) < 1:
            raise SweepConfigError(f"demo counts must be >= 1, got {list(self.demo_counts)}")
        if min(self.seeds) < 0:
            raise SweepConfigError(f"seeds must be >= 0, got {list(self.seeds)}")
        if self.eval_tasks < 1:
            raise SweepConfigError(f"eval_tasks must be >= 1, got {self.eval_tasks}")
        if not (self.timeout > 0 and math.isfinite(self.timeout)):
            raise SweepConfigError(f"timeout must be a number of seconds > 0, got {self.timeout}")
        if self.perturb_axis is not None:
            name, levels = self.perturb_axis
            try:
                for level in levels:
                    Perturbation(**{name: level})
            except (TypeError, PerturbationError) as err:
                raise SweepConfigError(f"perturbation axis {name}: {err}") from None
            if not levels or len(set(levels)) != len(levels):
                raise SweepConfigError(f"perturbation axis {name}: empty or repeated levels")
            labels = [level_label(level) for level in levels]
            same = sorted({x for x in labels if labels.count(x) > 1})
            if same:
                clash = [str(v) for v, x in zip(levels, labels, strict=True) if x == same[0]]
                raise SweepConfigError(
                    f"perturbation axis {name}: levels {' and '.join(clash)} would share the "
                    f"cell {name}={same[0]} (cells are named to 6 significant digits); give "
                    "levels that differ in their first 6 digits"
                )
        if self.demote_refuted is not None and not 0 < self.demote_refuted < math.inf:
            raise SweepConfigError(
                f"demote_refuted must be a finite cost > 0, got {self.demote_refuted}"
            )
        try:  # the execution settings every closed-loop cell will run with
            ExecutionConfig(
                world_speed=1.0 if self.world_speed is None else self.world_speed,
                slow_from="start" if self.slow_from is None else self.slow_from,
                check_ahead=self.check_ahead,
            )
        except ExecutionConfigError as err:
            raise SweepConfigError(str(err)) from None
        self._check_worlds()
        self._check_corrections()
        if self.perturb_axis is not None and self.worlds:
            raise SweepConfigError("sweep either a perturbation axis or worlds, not both")
        self._check_objects_axis()

    def _check_objects_axis(self) -> None:
        if self.objects_axis is None:
            return
        kind, counts = self.objects_axis
        if not counts or len(set(counts)) != len(counts) or min(counts) < 0:
            raise SweepConfigError(f"object axis {kind}: empty, repeated or negative counts")
        if self.perturb_axis is not None or self.worlds:
            raise SweepConfigError("sweep one axis: objects, a perturbation or worlds")

    def _check_corrections(self) -> None:
        if self.corrections is None:
            if self.correction_rounds is not None:
                raise SweepConfigError("correction_rounds applies to corrections: give them")
            return
        try:
            parse_world(self.corrections.split())
        except PerturbationError as err:
            raise SweepConfigError(f"corrections {self.corrections!r}: {err}") from None
        rounds = self.correction_rounds
        if rounds is not None and (not isinstance(rounds, int) or rounds < 1):
            raise SweepConfigError(f"correction_rounds must be a whole number >= 1, got {rounds}")

    def _check_worlds(self) -> None:
        for world in self.worlds:
            try:
                parse_world(world.split())
            except PerturbationError as err:
                raise SweepConfigError(f"world {world!r}: {err}") from None
        try:
            parse_model(self.model.split())
        except PerturbationError as err:
            raise SweepConfigError(f"model {self.model!r}: {err}") from None
        for name in ("worlds", "executions"):
            values = getattr(self, name)
            if len(set(values)) != len(values):
                raise SweepConfigError(f"{name} has repeated values: {list(values)}")
        bad = [e for e in self.executions if e not in MODES]
        if bad:
            raise SweepConfigError(f"unknown execution {bad[0]!r}; known: {', '.join(MODES)}")

    def conditions(self) -> list[tuple[str | None, str | None]]:
        """(world, execution) of each eval cell; [(None, None)] when neither is swept."""
        if not self.worlds and not self.executions:
            return [(None, None)]
        worlds = self.worlds or ("nominal",)
        executions = self.executions or (MODES[0],)
        return [(w, e) for w in worlds for e in executions]

    def levels(self) -> list[Perturbation | None]:
        """The physics of each eval cell: one per level of the axis (None: no axis)."""
        if self.perturb_axis is None:
            return [None]
        name, levels = self.perturb_axis
        return [Perturbation(**{name: level}) for level in levels]

    def object_levels(self) -> list[str | None]:
        """The object counts of each eval cell, as ``--objects`` texts (None: no axis)."""
        if self.objects_axis is None:
            return [None]
        kind, counts = self.objects_axis
        return [f"{kind}={n}" for n in counts]

    @property
    def axis_name(self) -> str | None:
        """The swept axis the report draws success against (a perturbation or an
        object kind), None without one."""
        for axis in (self.perturb_axis, self.objects_axis):
            if axis is not None:
                return axis[0]
        return None

    @property
    def max_demos(self) -> int:
        return max(self.demo_counts)

    def with_overrides(self, **overrides: object) -> SweepConfig:
        """A copy with the fields given (not None) replaced; tuples sorted where order is
        meaningless so that the same sweep always has the same cells."""
        fields = {k: v for k, v in overrides.items() if v is not None}
        for key in ("demo_counts", "seeds"):
            if key in fields:
                fields[key] = tuple(sorted(fields[key]))  # type: ignore[arg-type]
        for key in ("envs", "approaches", "worlds", "executions"):
            if key in fields:
                fields[key] = tuple(fields[key])  # type: ignore[arg-type]
        return dataclasses.replace(self, **fields)  # type: ignore[arg-type]

    def to_json(self) -> dict[str, object]:
        d = dataclasses.asdict(self)
        if self.perturb_axis is None:  # (absent: configs stored before keep comparing equal)
            del d["perturb_axis"]
        if self.objects_axis is None:  # (absent, likewise)
            del d["objects_axis"]
        if self.demote_refuted is None:  # (absent, likewise)
            del d["demote_refuted"]
        if self.world_speed is None:  # (absent, likewise)
            del d["world_speed"]
        if self.slow_from is None:  # (absent, likewise)
            del d["slow_from"]
        if not self.predict_latency:  # (absent, likewise)
            del d["predict_latency"]
        if self.check_ahead is None:  # (absent, likewise)
            del d["check_ahead"]
        if not self.watch_releases:  # (absent, likewise)
            del d["watch_releases"]
        if self.corrections is None:  # (absent, likewise)
            del d["corrections"], d["correction_rounds"]
        if not self.worlds and not self.executions and self.model == "nominal":
            del d["worlds"], d["executions"], d["model"]  # (absent, likewise)
        return d


# Presets sweep every registered environment (the four domains, and any plugin you
# installed); `--env` picks some. bpns names no environment itself.
PAPER = SweepConfig(
    name="paper",
    envs=tuple(environment_names()),
    demo_counts=(50, 100, 250, 500, 1000),
    seeds=tuple(range(10)),
    approaches=approach_names(),
    eval_tasks=50,
    timeout=300.0,
)

# Fits 2 cores in a few hours per environment.
SMALL = SweepConfig(
    name="small",
    envs=tuple(environment_names()),
    demo_counts=(100, 250, 1000),
    seeds=(0, 1, 2),
    approaches=approach_names(),
    eval_tasks=50,
    timeout=60.0,
)

# For tests and a first try: about a minute per environment on one core.
SMOKE = SweepConfig(
    name="smoke",
    envs=tuple(environment_names()),
    demo_counts=(4, 8),
    seeds=(0, 1),
    approaches=("bpns", "oracle"),
    eval_tasks=2,
    timeout=10.0,
)

PRESETS: dict[str, SweepConfig] = {p.name: p for p in (PAPER, SMALL, SMOKE)}
