"""A sweep with an object-count axis (`bpns experiment --objects-axis KIND=N1,N2`): one
eval cell per count drawing eval tasks with it, rows per count (success and time against
count); bad counts are refused before any cell runs; sweeps without it keep their cells."""

from __future__ import annotations

import dataclasses

import pytest

from bpns.env.object_counts import EvalSet, ObjectCounts
from bpns.experiments.aggregate import aggregate, markdown_table
from bpns.experiments.cells import EVAL
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
