"""A sweep with an object-count axis (`bpns experiment --objects-axis KIND=N1,N2`): one
eval cell per count drawing eval tasks with it, rows per count (success and time against
count); bad counts are refused before any cell runs; sweeps without it keep their cells."""

from __future__ import annotations

import dataclasses

import pytest

from bpns.env.object_counts import EvalSet, ObjectCounts
from bpns.experiments.aggregate import aggregate, markdown_table
from bpns.experiments.cells import EVAL
from bpns.experiments.growth import growth_of, growth_table, power_law_exponent
from bpns.experiments.plots import cost_vs_objects, save_figure
from bpns.experiments.presets import SweepConfigError
from bpns.experiments.sweep import sweep_cells
from bpns.experiments.work import _eval_set_of
from tests.cli_probe import error_line
from tests.experiments.test_sweeps import TINY, _eval_record

AXIS = dataclasses.replace(TINY, objects_axis=("block", (2, 3)))


def test_each_eval_cell_runs_once_per_count_with_those_eval_tasks(cover_env):
    plain = [c for c in sweep_cells(TINY, {"cover": cover_env}) if c.kind == EVAL]
    cells = [c for c in sweep_cells(AXIS, {"cover": cover_env}) if c.kind == EVAL]
    assert len(cells) == 2 * len(plain) and len({c.key for c in cells}) == len(cells)
    assert any(c.key.endswith("-block3-seed0") for c in cells)
    assert {c.settings["objects"] for c in cells} == {"block=2", "block=3"}
    three = next(c for c in cells if c.objects == "block=3")
    assert _eval_set_of(three) == EvalSet(objects=ObjectCounts.parse("block=3"))
    assert all("objects" not in c.settings for c in plain)
    assert "objects_axis" not in TINY.to_json()


def test_an_object_axis_is_the_only_axis_and_its_counts_distinct():
    with pytest.raises(SweepConfigError, match="repeated"):
        dataclasses.replace(TINY, objects_axis=("block", (3, 3)))
    with pytest.raises(SweepConfigError, match="one axis"):
        dataclasses.replace(AXIS, perturb_axis=("friction_scale", (1.0, 0.5)))


@pytest.mark.parametrize(
    ("axis", "message"),
    [
        ("button=3,4", "no object kind 'button'; kinds: block"),
        ("block=2,9", "block=9: cover scenes hold 1..4"),
        ("block", "expected KIND=N1,N2,..."),
        ("block=a,b", "expected KIND=N1,N2,..."),
    ],
)
def test_bad_object_axes_are_one_error_line_before_any_cell(axis, message, capsys, tmp_path):
    argv = ["experiment", "--env", "cover", "--objects-axis", axis, "--out", str(tmp_path / "x")]
    assert message in error_line(argv, capsys)
    assert not (tmp_path / "x").exists()


def _record(approach: str, count: int, solved: int):
    record = _eval_record(0, approach, None, [1.0] * solved + [None] * (4 - solved))
    record["settings"]["objects"] = f"block={count}"
    return record


def test_rows_are_per_count_and_the_table_names_the_kind():
    rows = aggregate([_record("oracle", 3, 2), _record("oracle", 2, 4)])
    assert [(r.axis, r.level) for r in rows] == [("block", 2.0), ("block", 3.0)]
    assert "| Demos | block | Seeds |" in markdown_table(rows)
    assert rows[1].to_json()["objects"] == {"block": 3.0}


# ------------------------------------------------------------------ how the cost grows


def test_power_law_exponent_recovers_exact_power_laws_and_needs_two_counts():
    assert power_law_exponent([2, 4, 8], [0.3 * c**2 for c in (2, 4, 8)]) == pytest.approx(2.0)
    assert power_law_exponent([3, 5, 7, 9], [1.5 * c for c in (3, 5, 7, 9)]) == pytest.approx(1.0)
    assert power_law_exponent([2, 4, 8], [None, 0.5, 0.5]) == pytest.approx(0.0)
    assert power_law_exponent([2, 4], [None, 0.5]) is None  # one point left
    assert power_law_exponent([3, 3], [1.0, 2.0]) is None  # one distinct count
    with pytest.raises(ValueError, match="differ in length"):
        power_law_exponent([1, 2], [1.0])


def _costly_record(approach: str, count: int, seconds: float, plan_steps: int):
    record = _record(approach, count, 4)
    record["result"]["median_seconds"] = seconds
    record["result"]["mean_nodes_created"] = 10.0 * count**3
    for task in record["result"]["tasks"]:
        task.update(seconds=seconds, plan_steps=plan_steps, sim_steps=2 * count, num_actions=2)
        # the CPU seconds grow as count^3 (the world's share taken off)
        task.update(cpu_seconds=0.01 * count**3 + 1.0, world_cpu_seconds=1.0)
    return record


GROWING = [  # oracle: time ∝ count^2 with plans of 2*count steps; bpns: linear
    *(_costly_record("oracle", c, 0.1 * c**2, 2 * c) for c in (2, 4, 8)),
    *(_costly_record("bpns", c, 0.5 * c, 2 * c) for c in (2, 4, 8)),
]


def test_growth_table_fits_time_against_count_and_plan_length():
    growth = {g.label: g for g in growth_of(aggregate(GROWING))}
    assert growth["Oracle"].counts == (2.0, 4.0, 8.0)
    assert growth["Oracle"].time_vs_count == pytest.approx(2.0)
    assert growth["Oracle"].time_vs_plan_steps == pytest.approx(2.0)
    assert growth["Oracle"].nodes_vs_count == pytest.approx(3.0)
    assert growth["Oracle"].sim_steps_vs_count == pytest.approx(1.0)
    assert growth["BPNS"].time_vs_count == pytest.approx(1.0)
    assert growth["Oracle"].cpu_time_vs_plan_steps == pytest.approx(3.0)
    table = growth_table(aggregate(GROWING))
    assert "| cover | Oracle | – | 2, 4, 8 | 2.00 | 2.00 | 3.00 | 3.00 | 1.00 |" in table
    assert growth_table(aggregate([_eval_record(0, "oracle", None, [1.0])])) == ""


def test_cells_without_cpu_records_fit_no_cpu_exponent():
    old = [_costly_record("oracle", c, 0.1 * c**2, 2 * c) for c in (2, 4, 8)]
    for record in old:
        for task in record["result"]["tasks"]:
            del task["cpu_seconds"], task["world_cpu_seconds"]
    (growth,) = growth_of(aggregate(old))
    assert growth.time_vs_plan_steps == pytest.approx(2.0)
    assert growth.cpu_time_vs_plan_steps is None
    assert "| 2.00 | 2.00 | – | 3.00 |" in growth_table(aggregate(old))


def test_cost_figure_has_a_row_of_panels_per_environment(tmp_path):
    fig = cost_vs_objects(aggregate(GROWING))
    assert len(fig.axes) == 3
    assert {ax.get_xscale() for ax in fig.axes} == {"log"}
    assert any("k=2.00" in text.get_text() for text in fig.legends[0].get_texts())
    written = save_figure(fig, tmp_path / "cost_vs_block")
    assert [p.name for p in written] == ["cost_vs_block.png", "cost_vs_block.svg"]


def test_a_sweep_can_demote_refuted_achievers_in_every_eval_cell(cover_env):
    demoting = dataclasses.replace(AXIS, demote_refuted=4.0)
    plain = [c for c in sweep_cells(AXIS, {"cover": cover_env}) if c.kind == EVAL]
    cells = [c for c in sweep_cells(demoting, {"cover": cover_env}) if c.kind == EVAL]
    assert {c.settings["planning"]["demote_refuted"] for c in cells} == {4.0}
    assert all("demote_refuted" not in c.settings["planning"] for c in plain)
    # same names, other settings: a sweep directory made without it refuses to mix them
    assert all(c.settings != p.settings for c, p in zip(cells, plain, strict=True))
    assert "demote_refuted" not in AXIS.to_json() and demoting.to_json()["demote_refuted"] == 4.0
    with pytest.raises(SweepConfigError, match="finite cost > 0"):
        dataclasses.replace(AXIS, demote_refuted=float("inf"))
