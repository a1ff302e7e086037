"""A sweep with a perturbation axis: one eval cell per level, rows per level, and a
success-vs-level figure per approach; sweeps without an axis keep their cells."""

from __future__ import annotations

import dataclasses

import pytest

from bpns.cli import main
from bpns.env.perturbations import Perturbation
from bpns.experiments.aggregate import aggregate, markdown_table
from bpns.experiments.cells import EVAL
from bpns.experiments.plots import save_figure, success_vs_perturbation, success_vs_world
from bpns.experiments.presets import SweepConfigError
from bpns.experiments.report import world_split_section
from bpns.experiments.sweep import sweep_cells
from tests.experiments.test_sweeps import TINY, _eval_record

BASE = TINY  # the harness tests' sweep: cover, 3 demos, seed 0, bpns + oracle


def test_each_eval_cell_runs_once_per_level_of_the_axis(cover_env):
    axis = dataclasses.replace(BASE, perturb_axis=("friction_scale", (1.0, 0.5)))
    plain = [c for c in sweep_cells(BASE, {"cover": cover_env}) if c.kind == EVAL]
    cells = [c for c in sweep_cells(axis, {"cover": cover_env}) if c.kind == EVAL]
    assert len(cells) == 2 * len(plain)
    assert len({c.key for c in cells}) == len(cells)
    assert {c.perturbation for c in cells} == {Perturbation(), Perturbation(friction_scale=0.5)}
    assert any(c.key.endswith("-friction_scale0.5-seed0") for c in cells)
    assert all(c.settings["perturb_axis"] == "friction_scale" for c in cells)
    # without an axis, keys and settings are those of sweeps stored before the axis
    assert all("perturbation" not in c.settings and "friction" not in c.key for c in plain)
    assert "perturb_axis" not in BASE.to_json()


def test_a_bad_axis_is_a_config_error_and_a_cli_error(capsys):
    with pytest.raises(SweepConfigError, match="mass_scale"):
        dataclasses.replace(BASE, perturb_axis=("mass_scale", (1.0, 0.0)))
    assert main(["experiment", "--env", "cover", "--perturb-axis", "friction=1,2"]) == 2
    assert "unknown perturbation 'friction'" in capsys.readouterr().err


def _record(approach: str, demos: int | None, level: float, solved: int):
    """An eval cell of 4 tasks at friction level ``level``, ``solved`` of them solved."""
    record = _eval_record(0, approach, demos, [1.0] * solved + [None] * (4 - solved))
    physics = dataclasses.asdict(Perturbation(friction_scale=level))
    record["settings"].update(perturbation=physics, perturb_axis="friction_scale")
    return record


RECORDS = [
    _record("oracle", None, 1.0, 4),
    _record("oracle", None, 0.5, 2),
    _record("bpns", 3, 0.5, 1),
    _record("bpns", 3, 1.0, 3),
]


def test_rows_are_per_level_and_the_table_names_the_level():
    rows = aggregate(RECORDS)
    assert [(r.approach, r.level) for r in rows] == [
        ("oracle", 0.5),
        ("oracle", 1.0),
        ("bpns", 0.5),
        ("bpns", 1.0),
    ]
    table = markdown_table(rows)
    assert "| Demos | friction_scale | Seeds |" in table
    assert "| cover | Oracle | – | 0.5 | 1 | 50.0 ± 0.0 |" in table
    assert rows[0].to_json()["perturbation"] == {"friction_scale": 0.5}


def test_the_robustness_figure_draws_success_at_each_level_per_approach(tmp_path):
    fig = success_vs_perturbation(aggregate(RECORDS))
    (ax,) = fig.axes
    got = {  # errorbar containers: (data line, caps, bars), labelled by approach
        c.get_label().split(" (")[0]: sorted(zip(*c.lines[0].get_data(), strict=True))
        for c in ax.containers
    }
    assert [round(y) for _, y in got["Oracle"]] == [50, 100]
    assert [round(y) for _, y in got["BPNS"]] == [25, 75]
    assert ax.get_xlabel() == "friction scale"
    paths = save_figure(fig, tmp_path / "robust")
    assert all(p.stat().st_size > 0 for p in paths)


def _world_record(
    approach: str, demos: int | None, world: str, execution: str, solved: int, tasks: int = 4
):
    """An eval cell of ``tasks`` tasks in world ``world`` executed ``execution``."""
    record = _eval_record(0, approach, demos, [1.0] * solved + [None] * (tasks - solved))
    record["settings"].update(world=world, execution=execution)
    return record


def test_the_world_figure_pools_each_world_closed_solid_open_dashed_with_intervals():
    records = [
        _world_record("oracle", None, w, e, n)
        for w, e, n in [
            ("nominal", "closed-loop", 4),
            ("hard", "closed-loop", 3),
            ("nominal", "open-loop", 4),
            ("hard", "open-loop", 1),
        ]
    ]
    fig = success_vs_world(aggregate(records))
    (ax,) = fig.axes
    got = {c.get_label().split(" (")[0]: c for c in ax.containers}
    closed, opened = got["Oracle, closed-loop"], got["Oracle, open-loop"]
    assert [round(y) for y in closed.lines[0].get_ydata()] == [100, 75]
    assert [round(y) for y in opened.lines[0].get_ydata()] == [100, 25]
    assert closed.lines[0].get_linestyle() == "-" and opened.lines[0].get_linestyle() == "--"
    assert [t.get_text() for t in ax.get_xticklabels()] == ["nominal", "hard"]
    # the bars are the Wilson interval of 1 of 4: about [4.6, 69.9] %
    (bars,) = opened.lines[2]
    lows = [seg[0][1] for seg in bars.get_segments()]
    assert 4 < min(lows) < 5


def test_the_world_figure_draws_worlds_where_all_or_nothing_was_solved():
    # Wilson's upper bound of 20 of 20 is 1 only up to rounding: no negative error bar
    records = [
        _world_record("bpns", 3, w, "open-loop", n, tasks=20)
        for w, n in [("nominal", 20), ("hard", 0)]
    ]
    (ax,) = success_vs_world(aggregate(records)).axes
    (container,) = ax.containers
    assert [round(y) for y in container.lines[0].get_ydata()] == [100, 0]


def test_a_world_speed_slows_closed_loop_cells_only_and_names_them(cover_env):
    worlds = dataclasses.replace(
        BASE, worlds=("moderate",), executions=("closed-loop", "open-loop")
    )
    slow = dataclasses.replace(worlds, world_speed=0.6)
    before = {c.key: c for c in sweep_cells(worlds, {"cover": cover_env}) if c.kind == EVAL}
    cells = [c for c in sweep_cells(slow, {"cover": cover_env}) if c.kind == EVAL]
    closed = [c for c in cells if c.execution == "closed-loop"]
    opened = [c for c in cells if c.execution == "open-loop"]
    assert closed and all(c.world_speed == 0.6 for c in closed)
    assert all(c.key.endswith("-speed0.6-seed0") for c in closed)
    assert all(c.settings["world_speed"] == 0.6 for c in closed)
    # open loop replays the model's actions: at full speed, the very cells of before
    assert opened and all(c.world_speed == 1.0 and c.key in before for c in opened)
    assert all(before[c.key].settings == c.settings for c in opened)
    assert "world_speed" not in worlds.to_json() and slow.to_json()["world_speed"] == 0.6
    lazy = dataclasses.replace(slow, slow_from="deviation")
    lazy_closed = [c for c in sweep_cells(lazy, {"cover": cover_env}) if c.kind == EVAL]
    lazy_closed = [c for c in lazy_closed if c.execution == "closed-loop"]
    assert all(c.key.endswith("-speed0.6-fromdeviation-seed0") for c in lazy_closed)
    assert all(c.settings["slow_from"] == "deviation" for c in lazy_closed)
    assert "slow_from" not in slow.to_json() and lazy.to_json()["slow_from"] == "deviation"
    with pytest.raises(SweepConfigError, match="world_speed"):
        dataclasses.replace(BASE, world_speed=0.0)
    with pytest.raises(SweepConfigError, match="slow_from"):
        dataclasses.replace(BASE, slow_from="later")


def test_corrected_skills_are_cells_of_their_own_and_only_learned_evals_use_them(cover_env):
    """`--corrections`: the skills cells and the eval cells of learned approaches are
    named and keyed by the corrections; the oracle's cells and a sweep without
    corrections keep the keys and settings stored before."""
    plain = {c.key: c for c in sweep_cells(BASE, {"cover": cover_env})}
    corrected = dataclasses.replace(BASE, corrections="moderate")
    cells = sweep_cells(corrected, {"cover": cover_env})
    (skills,) = [c for c in cells if c.kind == "skills"]
    assert skills.key.endswith("-corrmoderatex2-seed0")
    assert skills.settings["corrections"] == {"worlds": "moderate", "rounds": 2}
    learned = [c for c in cells if c.kind == EVAL and c.approach == "bpns"]
    assert learned and all(skills.key in c.deps and "-corrmoderatex2" in c.key for c in learned)
    others = [c for c in cells if c.kind == EVAL and c.approach != "bpns"]
    assert others and all(c.key in plain and plain[c.key].settings == c.settings for c in others)
    assert all("corrections" not in c.settings and "corr" not in c.key for c in plain.values())
    assert "corrections" not in BASE.to_json()
    three = dataclasses.replace(corrected, correction_rounds=3)
    assert any(
        c.key.endswith("-corrmoderatex3-seed0") for c in sweep_cells(three, {"cover": cover_env})
    )
    with pytest.raises(SweepConfigError, match="corrections 'moderat'"):
        dataclasses.replace(BASE, corrections="moderat")
    with pytest.raises(SweepConfigError, match="correction_rounds applies"):
        dataclasses.replace(BASE, correction_rounds=2)


def test_the_world_table_compares_the_agents_time_without_the_worlds_simulation():
    records = [
        _world_record("oracle", None, "nominal", "closed-loop", 2, tasks=2),
        _world_record("oracle", None, "moderate", "closed-loop", 2, tasks=2),
    ]
    # nominal: 1 s, nothing simulated in the world; moderate: 4 s of which the world 2.5
    for t in records[0]["result"]["tasks"]:
        t.update(seconds=1.0, world_seconds=0.0)
    for t in records[1]["result"]["tasks"]:
        t.update(seconds=4.0, world_seconds=2.5)
    records[1]["result"]["median_seconds"] = 4.0
    table = markdown_table(aggregate(records))
    assert "| Time vs nominal | Agent time vs nominal |" in table
    assert "| 4.00 ± 0.00 | 4.00x | 1.50x |" in table
    # cells stored before the world's time was recorded: no agent time, not a wrong one
    for t in records[1]["result"]["tasks"]:
        del t["world_seconds"]
    assert "| 4.00x | – |" in markdown_table(aggregate(records))


def test_the_world_table_also_compares_the_agents_cpu_time_where_recorded():
    records = [
        _world_record("oracle", None, "nominal", "closed-loop", 2, tasks=2),
        _world_record("oracle", None, "moderate", "closed-loop", 2, tasks=2),
    ]
    # wall-clock time inflated by a loaded machine in the moderate cell; CPU time is not
    for t in records[0]["result"]["tasks"]:
        t.update(seconds=1.0, world_seconds=0.0, cpu_seconds=1.0, world_cpu_seconds=0.0)
    for t in records[1]["result"]["tasks"]:
        t.update(seconds=6.0, world_seconds=2.0, cpu_seconds=2.5, world_cpu_seconds=1.0)
    table = markdown_table(aggregate(records))
    assert "| Agent time vs nominal | Agent CPU vs nominal |" in table
    assert "| 4.00x | 1.50x |" in table
    # a cell stored before CPU time was recorded (or recorded as None): no ratio
    for t in records[0]["result"]["tasks"]:
        t["cpu_seconds"] = None
    assert "| 4.00x | – |" in markdown_table(aggregate(records))


def test_rows_of_corrected_skills_are_their_own_and_say_so():
    plain = _world_record("bpns", 10, "moderate", "closed-loop", 1, tasks=2)
    fixed = _world_record("bpns", 10, "moderate", "closed-loop", 2, tasks=2)
    fixed["settings"]["corrections"] = {"worlds": "moderate", "rounds": 2}
    rows = aggregate([plain, fixed])
    assert [r.label for r in rows] == ["BPNS", "BPNS + corrections (moderate x2)"]
    assert [r.pooled for r in rows] == [(1, 2), (2, 2)]
    assert "| cover | BPNS + corrections (moderate x2) | 10 | moderate |" in markdown_table(rows)


def test_cells_over_worlds_say_their_worlds_follow_the_seed_and_others_are_as_before(cover_env):
    # a cell stored when every seed drew its worlds from seed 0 must not pass for one
    # whose worlds follow the seed: its settings differ, so the store refuses to mix them
    worlds = dataclasses.replace(BASE, worlds=("hard",))
    cells = [c for c in sweep_cells(worlds, {"cover": cover_env}) if c.kind == EVAL]
    assert cells and all(c.settings["world_draws"] == "per-seed" for c in cells)
    plain = [c for c in sweep_cells(BASE, {"cover": cover_env}) if c.kind == EVAL]
    assert all("world_draws" not in c.settings for c in plain)


def test_predicting_the_commands_in_flight_names_closed_loop_cells_only(cover_env):
    worlds = dataclasses.replace(BASE, worlds=("hard",), executions=("closed-loop", "open-loop"))
    before = {c.key: c for c in sweep_cells(worlds, {"cover": cover_env}) if c.kind == EVAL}
    predict = dataclasses.replace(worlds, predict_latency=True)
    cells = [c for c in sweep_cells(predict, {"cover": cover_env}) if c.kind == EVAL]
    closed = [c for c in cells if c.execution == "closed-loop"]
    opened = [c for c in cells if c.execution == "open-loop"]
    assert closed and all(c.key.endswith("-predict-seed0") for c in closed)
    assert all(c.settings["predict_latency"] is True for c in closed)
    assert opened and all(before[c.key].settings == c.settings for c in opened)
    assert "predict_latency" not in worlds.to_json() and predict.to_json()["predict_latency"]


def test_checking_fewer_steps_ahead_names_closed_loop_cells_only(cover_env):
    worlds = dataclasses.replace(BASE, worlds=("hard",), executions=("closed-loop", "open-loop"))
    before = {c.key: c for c in sweep_cells(worlds, {"cover": cover_env}) if c.kind == EVAL}
    ahead = dataclasses.replace(worlds, check_ahead=1)
    cells = [c for c in sweep_cells(ahead, {"cover": cover_env}) if c.kind == EVAL]
    closed = [c for c in cells if c.execution == "closed-loop"]
    opened = [c for c in cells if c.execution == "open-loop"]
    assert closed and all(c.key.endswith("-ahead1-seed0") for c in closed)
    assert all(c.settings["check_ahead"] == 1 and c.check_ahead == 1 for c in closed)
    assert opened and all(before[c.key].settings == c.settings for c in opened)
    assert "check_ahead" not in worlds.to_json() and ahead.to_json()["check_ahead"] == 1
    with pytest.raises(SweepConfigError, match="check_ahead"):
        dataclasses.replace(worlds, check_ahead=0)


def test_watching_releases_names_closed_loop_cells_only(cover_env):
    worlds = dataclasses.replace(BASE, worlds=("hard",), executions=("closed-loop", "open-loop"))
    before = {c.key: c for c in sweep_cells(worlds, {"cover": cover_env}) if c.kind == EVAL}
    watch = dataclasses.replace(worlds, watch_releases=True)
    cells = [c for c in sweep_cells(watch, {"cover": cover_env}) if c.kind == EVAL]
    closed = [c for c in cells if c.execution == "closed-loop"]
    opened = [c for c in cells if c.execution == "open-loop"]
    assert closed and all(c.key.endswith("-releases-seed0") for c in closed)
    assert all(c.settings["watch_releases"] is True for c in closed)
    assert opened and all(before[c.key].settings == c.settings for c in opened)
    assert "watch_releases" not in worlds.to_json() and watch.to_json()["watch_releases"]


def test_a_worlds_sweep_splits_each_perturbed_row_by_the_world_its_tasks_met():
    hard = [Perturbation(latency=d, obs_noise=0.005) for d in (0, 1, 2, 2)]
    records = []
    for seed in (0, 1):
        record = _world_record("bpns", 3, "hard", "closed-loop", 2)
        record["settings"]["seed"] = seed
        for task, world in zip(record["result"]["tasks"], hard, strict=True):
            task["world"] = world.label()
        records.append(record)
    nominal = _world_record("bpns", 3, "nominal", "closed-loop", 4)
    for task in nominal["result"]["tasks"]:
        task["world"] = "nominal"
    section = world_split_section(aggregate([nominal, *records]))
    assert "cover, BPNS, 3 demonstrations: solved by the world each task met" in section
    assert "| World parameter | Range | hard, closed-loop |" in section  # nominal: no split
    # each seed solved its first two tasks (latency 0 and 1); pooled over both seeds
    assert "| latency | 0 steps | 2/2 [34.2, 100.0] |" in section
    assert "| latency | 2 steps | 0/4 [0.0, 49.0] |" in section
    assert world_split_section(aggregate([nominal])) == ""
    # a hand-edited world record leaves its task out of the split, not the report
    records[0]["result"]["tasks"][0]["world"] = "latency=banana"
    section = world_split_section(aggregate([nominal, *records]))
    assert "(1 tasks whose world record is unreadable left out)" in section
    assert "| latency | 0 steps | 1/1 [20.7, 100.0] |" in section
