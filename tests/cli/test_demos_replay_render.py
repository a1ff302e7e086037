"""End-to-end CLI smoke runs and one-line errors for bad input."""

from __future__ import annotations

import subprocess
import sys

import imageio.v2 as imageio
import pytest

from bpns.cli import main


def test_demos_replay_render_end_to_end(tmp_path, capsys):
    out = tmp_path / "d.h5"
    assert (
        main(
            [
                "demos",
                "--env",
                "cover",
                "-n",
                "2",
                "--seed",
                "3",
                "--out",
                str(out),
                "--workers",
                "1",
            ]
        )
        == 0
    )
    assert main(["replay", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2/2 exact" in text and "max |state diff| = 0" in text
    mp4, png = tmp_path / "v.mp4", tmp_path / "v.png"
    assert (
        main(
            [
                "render",
                str(out),
                "--demo",
                "1",
                "--out",
                str(mp4),
                "--png",
                str(png),
                "--width",
                "160",
                "--height",
                "120",
            ]
        )
        == 0
    )
    reader = imageio.get_reader(mp4)
    assert reader.get_meta_data()["fps"] == 30
    frames = [f for f in reader]
    assert len(frames) > 30 and frames[0].shape == (120, 160, 3)
    assert frames[0].std() > 5  # not a blank image
    assert imageio.imread(png).shape == (120, 160, 3)


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "bpns.cli", *args], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (("demos", "--env", "nope", "--out", "x.h5"), "unknown environment 'nope'"),
        (("replay", "missing.h5"), "no such demonstration file"),
        (("demos", "--env", "cover", "-n", "0", "--out", "x.h5"), "expected a number >= 1"),
    ],
)
def test_bad_input_is_one_line_without_traceback(tmp_path, args, message):
    proc = subprocess.run(
        [sys.executable, "-m", "bpns.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert proc.returncode == 2
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "x.h5").exists()


def test_corrupt_h5_is_one_line_without_traceback(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n" + b"0" * 100)
    proc = subprocess.run(
        [sys.executable, "-m", "bpns.cli", "replay", str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "corrupt or truncated" in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
