"""What `bpns demos` says when it ends: how many tasks succeeded, and why the others failed."""

from __future__ import annotations

from pathlib import Path

from bpns.workflow.collect import DemosWritten


def test_the_summary_counts_successes_out_of_tasks_tried_and_gives_each_failures_reason():
    written = DemosWritten(
        Path("demos.h5"), "cover", 98, (3, 17), 12.0, ("stalled picking", "block fell")
    )
    head, *reasons = written.lines()
    assert head.endswith(": 98/100 tasks succeeded; the demonstrator failed on tasks [3, 17]")
    assert reasons == ["  task 3: stalled picking", "  task 17: block fell"]


def test_a_run_without_failures_says_every_task_succeeded():
    (line,) = DemosWritten(Path("demos.h5"), "cover", 8, (), 2.0).lines()
    assert line == "wrote 8 demonstrations of cover to demos.h5 in 2.0 s: 8/8 tasks succeeded"
