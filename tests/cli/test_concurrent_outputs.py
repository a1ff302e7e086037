"""Two commands writing one output (issue 41): the one that comes second is refused with
one line while the first runs, instead of both passing the "exists?" check made before
any work and the later one replacing the other's output unasked."""

from __future__ import annotations

import pytest

from bpns.cli.paths import claimed
from tests.cli_probe import error_line, run_cli

EVAL = ["eval", "--env", "cover", "--approach", "oracle", "-n", "1", "--workers", "1"]


@pytest.mark.parametrize(
    "argv, target",
    [
        (["demos", "--env", "cover", "-n", "1", "--workers", "1", "--out", "{w}/d.h5"], "d.h5"),
        (["learn", "{d}", "--workers", "1", "--out", "{w}/skills"], "skills"),
        ([*EVAL, "--out", "{w}/ev"], "ev"),
        ([*EVAL, "--video", "{w}/v.mp4"], "v.mp4"),
        (["render", "{d}", "--out", "{w}/v.mp4"], "v.mp4"),
        (["run", "--env", "cover", "--demos", "1", "--tasks", "1", "--out", "{w}/r"], "r"),
    ],
    ids=lambda a: a[0] if isinstance(a, list) else None,
)
def test_an_output_another_command_is_writing_is_refused_in_one_line(
    tmp_path, cover_demo_file, capsys, argv, target
):
    argv = [a.format(w=tmp_path, d=cover_demo_file) for a in argv]
    with claimed("--out", tmp_path / target):  # as a running command holds it
        line = error_line(argv, capsys)
    assert line.endswith(
        f"{tmp_path / target}: is being written by another running bpns command; "
        "wait for it to finish, or write elsewhere"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_claim_is_released_and_its_lock_file_removed_when_the_command_ends(tmp_path, capsys):
    out = tmp_path / "d.h5"
    argv = ["demos", "--env", "cover", "-n", "1", "--workers", "1", "--out", str(out)]
    code, err = run_cli(argv, capsys)
    assert code == 0, err
    assert [p.name for p in tmp_path.iterdir()] == ["d.h5"]
    with claimed("--out", out):  # free again
        assert (tmp_path / ".d.h5.lock").exists()
    assert not (tmp_path / ".d.h5.lock").exists()
