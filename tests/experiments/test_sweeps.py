"""Experiment sweeps: resumable cells, the same results on the pool and on Ray, mean ±
std over seeds, figures written as PNG and SVG."""

from __future__ import annotations

import dataclasses
import json
import math
import xml.etree.ElementTree as ET

import pytest

from bpns.cli import main as cli_main
from bpns.experiments.aggregate import Stat, aggregate, markdown_table
from bpns.experiments.backends import PoolBackend
from bpns.experiments.cells import DEMOS, EVAL, SKILLS, Cell
from bpns.experiments.plots import save_figure, success_vs_demos, success_vs_time
from bpns.experiments.presets import PRESETS, SweepConfig, SweepConfigError
from bpns.experiments.report import write_report
from bpns.experiments.store import FORMAT, CellStore, CellStoreError
from bpns.experiments.sweep import load_finished, run_sweep, sweep_cells

TINY = SweepConfig(
    name="tiny",
    envs=("cover",),
    demo_counts=(3,),
    seeds=(0,),
    approaches=("bpns", "oracle"),
    eval_tasks=1,
    timeout=60.0,
)


def _quick(cell: Cell) -> Cell:
    """The harness is under test, not learning or planning: networks train for 100 steps
    and planning gives up after 2 abstract plans x 2 samples, long before the timeout
    (so that a loaded machine cannot change which tasks are solved)."""
    if cell.planning is not None:
        planning = dataclasses.replace(cell.planning, n_abstract=2, n_samples=2)
        return dataclasses.replace(cell, planning=planning)
    if cell.learning is None:
        return cell
    small = {
        role: dataclasses.replace(getattr(cell.learning, role), num_steps=100)
        for role in ("policy", "generator", "classifier")
    }
    return dataclasses.replace(cell, learning=dataclasses.replace(cell.learning, **small))


@pytest.fixture(scope="module")
def tiny_cells(cover_env):
    return [_quick(c) for c in sweep_cells(TINY, {"cover": cover_env})]


class _Interrupt(Exception):
    pass


@pytest.fixture(scope="module")
def resumed_sweep(tiny_cells, tmp_path_factory):
    """A sweep interrupted after its second finished cell, then run again, then again."""
    store = CellStore(tmp_path_factory.mktemp("sweep"))
    seen: list[str] = []

    def interrupt_after_two(record):
        seen.append(record["key"])
        if len(seen) == 2:
            raise _Interrupt

    with pytest.raises(_Interrupt):
        run_sweep(tiny_cells, store, PoolBackend(1), on_finished=interrupt_after_two, log=print)
    stamps = {k: _stamp(store, k) for k in seen}
    second = run_sweep(tiny_cells, store, PoolBackend(1), log=print)
    third = run_sweep(tiny_cells, store, PoolBackend(1), log=print)
    return store, seen, stamps, second, third


def _stamp(store: CellStore, key: str) -> tuple[int, str]:
    path = store.record_path(key)
    return path.stat().st_mtime_ns, json.loads(path.read_text())["id"]


def test_sweep_has_demos_skills_and_eval_cells_with_dependencies(tiny_cells):
    keys = [c.key for c in tiny_cells]
    assert keys == [
        "demos/cover-seed0",
        "skills/cover-n3-seed0",
        "eval/cover-oracle-seed0",
        "eval/cover-bpns-n3-seed0",
    ]
    by_key = {c.key: c for c in tiny_cells}
    assert by_key["skills/cover-n3-seed0"].deps == ("demos/cover-seed0",)
    assert by_key["eval/cover-bpns-n3-seed0"].deps == ("skills/cover-n3-seed0",)
    assert by_key["eval/cover-oracle-seed0"].deps == ()
    assert by_key["eval/cover-oracle-seed0"].settings["planning"]["timeout"] == 60.0


def test_interrupted_sweep_keeps_finished_cells_and_computes_only_the_rest(
    resumed_sweep, tiny_cells
):
    store, first, stamps, second, third = resumed_sweep
    all_keys = {c.key for c in tiny_cells}
    assert len(first) == 2
    assert set(second.reused) == set(first)
    assert set(second.computed) == all_keys - set(first)
    assert second.complete and not second.failed
    for key, stamp in stamps.items():  # finished cells were not rewritten
        assert _stamp(store, key) == stamp
    assert third.computed == [] and set(third.reused) == all_keys


def test_finished_cells_hold_results_and_point_at_their_inputs(resumed_sweep):
    store = resumed_sweep[0]
    demos = json.loads(store.record_path("demos/cover-seed0").read_text())
    skills = json.loads(store.record_path("skills/cover-n3-seed0").read_text())
    bpns = json.loads(store.record_path("eval/cover-bpns-n3-seed0").read_text())
    oracle = json.loads(store.record_path("eval/cover-oracle-seed0").read_text())
    assert demos["result"]["solved_tasks"] == [0, 1, 2]
    assert skills["inputs"] == {"demos/cover-seed0": demos["id"]}
    assert skills["result"]["num_demos"] == 3
    assert bpns["inputs"] == {"skills/cover-n3-seed0": skills["id"]}
    assert bpns["result"]["learning_seconds"] == skills["result"]["learning_seconds"]
    assert skills["result"]["learning_seconds"] == pytest.approx(
        sum(skills["result"]["stage_seconds"].values())
    )
    assert oracle["result"]["num_solved"] == 1  # the hand-written skills solve the task
    assert len(oracle["result"]["tasks"]) == 1
    (task,) = oracle["result"]["tasks"]  # the nominal world: nothing simulated apart
    assert task["world_seconds"] == 0.0 and task["seconds"] > 0.0
    assert task["world_cpu_seconds"] == 0.0 and task["cpu_seconds"] > 0.0
    assert (store.root / "artifacts/skills/cover-n3-seed0/skills.json").is_file()
    assert (store.root / "artifacts/demos/cover-seed0.h5").is_file()


def test_rerun_with_other_settings_is_refused(resumed_sweep, cover_env):
    store = resumed_sweep[0]
    longer = dataclasses.replace(TINY, timeout=61.0)
    cells = [_quick(c) for c in sweep_cells(longer, {"cover": cover_env})]
    with pytest.raises(CellStoreError, match=r"planning\.timeout: stored 60\.0, wanted 61\.0"):
        load_finished(cells, store)


def test_cli_refuses_a_sweep_directory_made_with_other_settings(resumed_sweep, capsys):
    store = resumed_sweep[0]
    argv = ["experiment", "--preset", "smoke", "--env", "cover", "--out", str(store.root)]
    argv += ["--demos", "3"]
    code = cli_main([*argv, "--seeds", "0", "--tasks", "1", "--timeout", "60", "--report-only"])
    assert code == 2
    err = capsys.readouterr().err
    assert "other settings than this sweep's" in err and "learning.policy.num_steps" in err


def test_cli_rejects_unknown_environment_and_approach(capsys):
    assert cli_main(["experiment", "--preset", "smoke", "--env", "nowhere", "--dry-run"]) == 2
    assert "unknown environment" in capsys.readouterr().err
    assert cli_main(["experiment", "--preset", "smoke", "--approach", "magic", "--dry-run"]) == 2
    assert "unknown approach" in capsys.readouterr().err


def test_report_writes_table_and_figures(resumed_sweep, tiny_cells, tmp_path):
    store = resumed_sweep[0]
    rows, written = write_report(tmp_path, tiny_cells, store, TINY, "bpns experiment ...")
    assert [(r.approach, r.demos) for r in rows] == [("oracle", None), ("bpns", 3)]
    assert {p.name for p in written} >= {"results.md", "success_vs_demos.png"}
    assert "| cover | Oracle | – | 1 | 100.0 ± 0.0 |" in (tmp_path / "results.md").read_text()


def test_ray_backend_solves_the_same_tasks_as_the_pool(resumed_sweep, tiny_cells, tmp_path):
    pytest.importorskip("ray")
    from bpns.experiments.backends import RayBackend

    pool_store = resumed_sweep[0]
    ray_store = CellStore(tmp_path)
    summary = run_sweep(tiny_cells, ray_store, RayBackend(num_cpus=2), log=print)
    assert summary.complete and len(summary.computed) == len(tiny_cells)
    for cell in tiny_cells:
        pool, ray = pool_store.load(cell)["result"], ray_store.load(cell)["result"]
        if cell.kind == DEMOS:
            assert ray["solved_tasks"] == pool["solved_tasks"]
        elif cell.kind == SKILLS:
            assert ray["skills"] == pool["skills"]
        else:
            assert [t["solved"] for t in ray["tasks"]] == [t["solved"] for t in pool["tasks"]]


def test_a_directory_runs_one_sweep_at_a_time(tmp_path):
    with CellStore(tmp_path).exclusive():
        with pytest.raises(CellStoreError, match="in use by another running sweep"):
            with CellStore(tmp_path).exclusive():
                pass
    with CellStore(tmp_path).exclusive():  # released
        pass


def test_temporaries_of_interrupted_cells_are_removed(tmp_path):
    store = CellStore(tmp_path)
    partial_dir = tmp_path / "artifacts/skills/.cover-n3-seed0.tmp-x1"
    partial_dir.mkdir(parents=True)
    (partial_dir / "skills.json").write_text("{")
    partial_file = tmp_path / "artifacts/demos/.cover-seed0.h5.abc.h5"
    partial_file.parent.mkdir()
    partial_file.write_bytes(b"")
    finished = tmp_path / "artifacts/demos/cover-seed1.h5"
    finished.write_bytes(b"data")
    assert store.remove_partial_artifacts() == [partial_file, partial_dir]
    assert finished.exists() and not partial_dir.exists() and not partial_file.exists()


# ------------------------------------------------------------------ synthetic cell files


def _eval_record(seed: int, approach: str, demos: int | None, solved: list[float | None]):
    """An eval cell of ``len(solved)`` tasks: a number is a solved task's seconds."""
    times = [t for t in solved if t is not None]
    return {
        "format": FORMAT,
        "settings": {
            "kind": EVAL,
            "env": "cover",
            "seed": seed,
            "approach": approach,
            "demo_count": demos,
        },
        "result": {
            "num_tasks": len(solved),
            "solved_percent": 100.0 * len(times) / len(solved),
            "median_seconds": sorted(times)[len(times) // 2] if times else None,
            "mean_seconds": sum(times) / len(times) if times else None,
            "mean_nodes_created": 10.0 + seed,
            "learning_seconds": None if demos is None else 2.0 * (seed + 1),
            "tasks": [{"solved": t is not None, "seconds": t or 5.0} for t in solved],
        },
    }


SYNTHETIC = [
    _eval_record(0, "bpns", 10, [1.0, None, None, None]),  # 25 %
    _eval_record(1, "bpns", 10, [1.0, 3.0, 2.0, None]),  # 75 %, median 2.0
    _eval_record(0, "bpns", 20, [None, None]),  # nothing solved: no times
    _eval_record(1, "bpns", 20, [0.5, 0.5]),
    _eval_record(0, "oracle", None, [0.1, 0.1]),
    _eval_record(1, "oracle", None, [0.3, 0.3]),
]


def test_aggregate_takes_mean_and_population_std_over_seeds():
    rows = aggregate(SYNTHETIC)
    assert [(r.approach, r.demos, len(r.seeds)) for r in rows] == [
        ("bpns", 10, 2),
        ("bpns", 20, 2),
        ("oracle", None, 2),
    ]
    ten, twenty, oracle = rows
    assert ten.solved_percent == Stat(50.0, 25.0, 2)
    assert ten.median_seconds == Stat(1.5, 0.5, 2)
    assert ten.learning_seconds == Stat(3.0, 1.0, 2)
    assert twenty.solved_percent == Stat(50.0, 50.0, 2)
    assert twenty.median_seconds == Stat(0.5, 0.0, 1)  # the seed that solved nothing has no time
    assert oracle.learning_seconds == Stat(None, None, 0)
    assert math.isclose(oracle.mean_seconds.mean, 0.2) and math.isclose(
        oracle.mean_seconds.std, 0.1
    )
    assert ten.seeds[1].fraction_solved_within(2.0) == 0.5


def test_markdown_table_shows_mean_plus_minus_std():
    table = markdown_table(aggregate(SYNTHETIC))
    assert "| cover | BPNS | 10 | 2 | 50.0 ± 25.0 | 1.50 ± 0.50 |" in table
    assert "| cover | Oracle | – | 2 | 100.0 ± 0.0 |" in table
    assert table.rstrip().endswith("| – |")  # the oracle learns nothing


def test_figures_are_written_as_valid_png_and_svg(tmp_path):
    rows = aggregate(SYNTHETIC)
    paths = save_figure(success_vs_demos(rows), tmp_path / "demos")
    paths += save_figure(success_vs_time(rows, timeout=5.0), tmp_path / "time")
    assert [p.name for p in paths] == ["demos.png", "demos.svg", "time.png", "time.svg"]
    for path in paths:
        if path.suffix == ".png":
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        else:
            assert ET.parse(path).getroot().tag.endswith("svg")
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind
    again = save_figure(success_vs_demos(rows), tmp_path / "again")
    # a rebuilt report changes no figure bytes
    for first, second in zip(paths[:2], again, strict=True):
        assert first.read_bytes() == second.read_bytes()


def test_figure_legend_lists_every_approach_once_and_covers_no_panel():
    rows = aggregate(SYNTHETIC)
    for fig in (success_vs_demos(rows), success_vs_time(rows, timeout=5.0)):
        fig.canvas.draw()  # lays out the constrained figure
        assert all(ax.get_legend() is None for ax in fig.axes)
        (legend,) = fig.legends
        labels = [t.get_text() for t in legend.get_texts()]
        assert len(labels) == len(set(labels)) == len({r.approach for r in rows})
        box = legend.get_window_extent()
        for ax in fig.axes:
            assert not box.overlaps(ax.get_window_extent())
            assert box.y1 <= ax.get_window_extent().y0  # below the panels


def test_presets_are_frozen_and_overrides_are_checked():
    small = PRESETS["small"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        small.timeout = 1.0  # type: ignore[misc]
    assert small.with_overrides(demo_counts=[250, 100], timeout=None).demo_counts == (100, 250)
    assert PRESETS["paper"].seeds == tuple(range(10)) and PRESETS["paper"].timeout == 300.0
    with pytest.raises(SweepConfigError, match="repeated"):
        small.with_overrides(seeds=[1, 1])
    with pytest.raises(SweepConfigError, match="eval_tasks"):
        small.with_overrides(eval_tasks=0)


def test_each_approach_is_charged_for_the_learning_it_uses():
    from bpns.experiments.approach_info import learning_seconds

    skills = {
        "learning_seconds": 15.0,
        "stage_seconds": {
            "segment": 1.0,
            "partition": 1.0,
            "operators": 1.0,
            "policies": 5.0,
            "samplers": 7.0,
        },
        "baseline_seconds": {"gnn_meta": 100.0, "gnn_bc": 200.0, "nosubgoal": 10.0},
    }
    assert learning_seconds("bpns", skills) == learning_seconds("samples1", skills) == 15.0
    assert learning_seconds("nosubgoal", skills) == 10.0  # its own whole pipeline
    assert learning_seconds("gnn-meta", skills) == 115.0  # GNN + the skills it executes
    assert learning_seconds("gnn-meta-nosubgoal", skills) == 110.0
    assert learning_seconds("gnn-bc", skills) == 200.0  # the demonstrations alone
    assert learning_seconds("gnn-bc", {"learning_seconds": 15.0}) is None  # not recorded
