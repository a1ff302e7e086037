"""``bpns view`` and ``bpns export`` on bad input: one ``bpns: error:`` line, exit 2,
nothing written."""

from __future__ import annotations

import sys

import h5py
import pytest

from tests.cli_probe import error_line
from tests.inspect.conftest import evaluate_oracle


@pytest.fixture(scope="module")
def rollouts(tmp_path_factory):
    out = tmp_path_factory.mktemp("view_errors") / "eval"
    return evaluate_oracle("cover", out, failed=False) / "rollouts_oracle.h5"


def test_view_and_export_refuse_missing_corrupt_and_foreign_files(tmp_path, capsys):
    missing = tmp_path / "missing.h5"
    corrupt = tmp_path / "corrupt.h5"
    corrupt.write_bytes(b"not an hdf5 file at all" * 10)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f.create_dataset("x", data=[1, 2, 3])
    other_kind = tmp_path / "other_kind.h5"
    with h5py.File(other_kind, "w") as f:
        f.attrs["env"] = "cover"
    for command in (["view"], ["export", "--out", str(tmp_path / "ds")]):
        assert "no such demonstration file" in error_line([*command, str(missing)], capsys)
        assert "not a readable HDF5 file" in error_line([*command, str(corrupt)], capsys)
        assert "no env attribute" in error_line([*command, str(foreign)], capsys)
        assert "not a bpns demonstration file" in error_line([*command, str(other_kind)], capsys)
    assert not (tmp_path / "ds").exists() and not list(tmp_path.glob("*.rrd"))


def test_view_refuses_a_task_or_demo_the_file_does_not_hold(
    rollouts, cover_demo_file, tmp_path, capsys
):
    out = ["--out", str(tmp_path / "x.rrd")]
    assert "has no rollout of task 5" in error_line(
        ["view", str(rollouts), "--task", "5", *out], capsys
    )
    assert "say which task with --task" in error_line(["view", str(rollouts), *out], capsys)
    line = error_line(["view", str(cover_demo_file), "--task", "0", *out], capsys)
    assert "--task needs a rollouts file" in line
    assert "has no demo_7" in error_line(
        ["view", str(cover_demo_file), "--demo", "7", *out], capsys
    )
    line = error_line(["view", str(cover_demo_file), "--camera", "nowhere", *out], capsys)
    assert "no camera 'nowhere'" in line
    assert not (tmp_path / "x.rrd").exists()


def test_view_refuses_to_replace_an_output_or_write_a_non_rrd(cover_demo_file, tmp_path, capsys):
    out = tmp_path / "demo.rrd"
    out.write_text("keep me")
    assert "exists; pass --overwrite" in error_line(
        ["view", str(cover_demo_file), "--out", str(out)], capsys
    )
    assert out.read_text() == "keep me"
    line = error_line(["view", str(cover_demo_file), "--out", str(tmp_path / "demo.mp4")], capsys)
    assert "give a .rrd name" in line


def test_view_refuses_an_image_size_without_images(cover_demo_file, tmp_path, capsys):
    out = tmp_path / "demo.rrd"
    for flag in ("--width", "--height"):
        line = error_line(["view", str(cover_demo_file), "--out", str(out), flag, "100000"], capsys)
        assert "size the camera images: pass --images or --camera too" in line
    assert not out.exists()


@pytest.mark.parametrize(
    ("module", "argv", "extra"),
    [
        ("rerun", ["view", "{demos}", "--out", "{tmp}/x.rrd"], "viz"),
        ("pyarrow", ["export", "{demos}", "--out", "{tmp}/ds"], "lerobot"),
        ("rerun", ["eval", "--env", "cover", "--approach", "oracle", "--rerun", "{tmp}/r"], "viz"),
    ],
)
def test_a_missing_extra_names_the_pip_command_that_installs_it(
    module, argv, extra, cover_demo_file, tmp_path, capsys, monkeypatch
):
    monkeypatch.setitem(sys.modules, module, None)  # as if the extra were not installed
    args = [a.format(demos=cover_demo_file, tmp=tmp_path) for a in argv]
    assert f"pip install 'bpns[{extra}]'" in error_line(args, capsys)
    assert list(tmp_path.iterdir()) == []
