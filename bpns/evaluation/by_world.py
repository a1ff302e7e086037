"""Which part of a perturbed world the failures come from.

A success rate under ``--perturb hard`` mixes tasks with one step of latency and two,
light blocks and heavy ones. Split by each physical parameter that varied across the
tasks (each task records the world it executed in: :attr:`TaskOutcome.world`), the same
outcomes say where a skill breaks, e.g. every failure at two steps of latency and none
at friction below 0.8. Scale parameters are binned about 1 (``< 0.8``, ``0.8-1.25``,
``>= 1.25``: a fifth off nominal either way), the latency by its value; noise levels are
fixed by a preset and so are not split.

The bins are marginal: with several parameters drawn at once a bin's rate also carries
the others' (independent draws make that an average over them, not a bias).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from bpns.env.perturbations import NOMINAL, Perturbation, parse_perturbation
from bpns.evaluation.evaluate import EvalReport
from bpns.evaluation.intervals import wilson_interval

SCALE_PARAMETERS = ("mass_scale", "friction_scale", "gain_scale")
SPLIT_PARAMETERS = (*SCALE_PARAMETERS, "latency")
SCALE_EDGES = (0.8, 1.25)  # a fifth off nominal, either way (1 / 1.25 = 0.8)

Trial = tuple[Perturbation, bool]  # the world a task met, and whether it was solved


@dataclass(frozen=True)
class WorldBin:
    """Tasks whose world had ``parameter`` in the bin ``label`` (``order`` sorts the
    bins of a parameter); ``solved`` of ``tasks``."""

    parameter: str
    order: int
    label: str
    solved: int
    tasks: int

    def text(self) -> str:
        low, high = wilson_interval(self.solved, self.tasks)
        return f"{self.solved}/{self.tasks} [{100 * low:.1f}, {100 * high:.1f}]"


def bin_of(parameter: str, world: Perturbation) -> tuple[int, str]:
    """(order, label) of ``world``'s bin for ``parameter``."""
    value = getattr(world, parameter)
    if parameter == "latency":
        return int(value), f"{int(value)} step{'' if value == 1 else 's'}"
    low, high = SCALE_EDGES
    if value < low:
        return 0, f"< {low:g}"
    if value < high:
        return 1, f"{low:g}-{high:g}"
    return 2, f">= {high:g}"


def world_bins(trials: Iterable[Trial]) -> list[WorldBin]:
    """Success per bin of every parameter that varied across ``trials``' worlds, in
    parameter order, then bin order; empty when every task met the same world."""
    trials = list(trials)
    bins: list[WorldBin] = []
    for parameter in SPLIT_PARAMETERS:
        if len({getattr(world, parameter) for world, _ in trials}) < 2:
            continue
        groups: dict[tuple[int, str], list[bool]] = {}
        for world, solved in trials:
            groups.setdefault(bin_of(parameter, world), []).append(solved)
        for (order, label), solved in sorted(groups.items()):
            bins.append(WorldBin(parameter, order, label, sum(solved), len(solved)))
    return bins


def world_of_label(label: str) -> Perturbation:
    """The world a sweep cell's task record names (``Perturbation.label()``)."""
    return NOMINAL if label == "nominal" else parse_perturbation(label.split(","))


@dataclass(frozen=True)
class WorldSplit:
    """Success per world bin, a column per group of tasks: ``rows`` are (parameter, bin
    label, one text per column: solved/tasks [Wilson 95 %], or "–" where the column's
    tasks had no world in the bin)."""

    headings: tuple[str, ...]
    rows: tuple[tuple[str, str, tuple[str, ...]], ...]


def world_split(columns: Sequence[tuple[str, Iterable[Trial]]]) -> WorldSplit | None:
    """A row per (parameter, bin) met in any column, a column per ``(heading, trials)``
    whose worlds varied; None when no column's worlds varied."""
    split = []
    for heading, trials in columns:
        bins = {(b.parameter, b.order, b.label): b for b in world_bins(trials)}
        if bins:  # a column whose tasks all met one world (nominal) says nothing here
            split.append((heading, bins))
    keys = sorted(
        {k for _, bins in split for k in bins},
        key=lambda k: (SPLIT_PARAMETERS.index(k[0]), k[1]),
    )
    if not keys:
        return None
    rows = tuple(
        (key[0], key[2], tuple(bins[key].text() if key in bins else "–" for _, bins in split))
        for key in keys
    )
    return WorldSplit(tuple(h for h, _ in split), rows)


def world_split_table(columns: Sequence[tuple[str, Iterable[Trial]]]) -> str:
    """:func:`world_split` as a markdown table (empty when no column's worlds varied)."""
    split = world_split(columns)
    if split is None:
        return ""
    head = "| World parameter | Range | " + " | ".join(split.headings) + " |"
    rule = "|---|---|" + "---:|" * len(split.headings)
    lines = [head, rule]
    lines += [f"| {p} | {label} | " + " | ".join(cells) + " |" for p, label, cells in split.rows]
    return "\n".join(lines) + "\n"


def report_columns(reports: Sequence[EvalReport]) -> list[tuple[str, list[Trial]]]:
    """A column per report: its label and each task's (world, solved)."""
    return [(r.label, [(o.world, o.solved) for o in r.outcomes]) for r in reports]


SPLIT_CAPTION = (
    "Solved by the world each task met (tasks binned by each parameter that varied; "
    "Wilson 95 % intervals)"
)


def world_tables(reports: Sequence[EvalReport]) -> str:
    """``reports``' success split by the world each task met (a column per approach;
    empty when the tasks' worlds did not vary), with its caption."""
    table = world_split_table(report_columns(reports))
    return f"{SPLIT_CAPTION}:\n\n{table}" if table else ""
