"""Success split by the world each task met (``bpns.evaluation.by_world``)."""

from __future__ import annotations

from bpns.env.perturbations import NOMINAL, Perturbation
from bpns.evaluation.by_world import world_bins, world_of_label, world_split_table

TRIALS = [
    (Perturbation(latency=0, friction_scale=0.6), True),
    (Perturbation(latency=0, friction_scale=1.0), True),
    (Perturbation(latency=2, friction_scale=1.0), False),
    (Perturbation(latency=2, friction_scale=1.3), False),
    (Perturbation(latency=1, friction_scale=1.25), True),
]


def test_failures_are_attributed_to_the_latency_and_scale_bins_they_met():
    table = {(b.parameter, b.label): (b.solved, b.tasks) for b in world_bins(TRIALS)}
    assert table == {
        ("friction_scale", "< 0.8"): (1, 1),
        ("friction_scale", "0.8-1.25"): (1, 2),
        ("friction_scale", ">= 1.25"): (1, 2),  # 1.25 itself is a fifth off: the top bin
        ("latency", "0 steps"): (2, 2),
        ("latency", "1 step"): (1, 1),
        ("latency", "2 steps"): (0, 2),
    }


def test_tasks_that_all_met_one_world_give_no_split():
    assert world_bins([(NOMINAL, i % 2 == 0) for i in range(4)]) == []
    assert world_split_table([("BPNS", [(NOMINAL, True)] * 3)]) == ""


def test_columns_share_rows_and_mark_bins_a_column_never_met():
    moderate = [(Perturbation(latency=d), d == 0) for d in (0, 1, 0, 1)]
    table = world_split_table([("moderate", moderate), ("hard", TRIALS)])
    lines = table.splitlines()
    assert lines[0] == "| World parameter | Range | moderate | hard |"
    assert "| latency | 2 steps | – | 0/2 [0.0, 65.8] |" in lines
    assert "| latency | 0 steps | 2/2 [34.2, 100.0] | 2/2 [34.2, 100.0] |" in lines
    # parameters in a fixed order (scales, then latency), bins in increasing order
    assert [line.split(" | ")[0] for line in lines[2:]] == ["| friction_scale"] * 3 + [
        "| latency"
    ] * 3


def test_sweep_task_labels_parse_back_to_their_worlds():
    world = Perturbation(mass_scale=1.5, friction_scale=0.7, latency=2, obs_noise=0.005)
    assert world_of_label(world.label()) == world
    assert world_of_label("nominal") == NOMINAL
