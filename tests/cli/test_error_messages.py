"""Messages that named the wrong cause (issue 24): a huge frame blamed on OSMesa, a FIFO
or device called missing, ``--out ''`` read as ``.``, numeric warnings printed before
an error line."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from bpns.cli import COMMANDS, main
from bpns.cli.common import UserError
from tests.cli_probe import error_line


@pytest.fixture(scope="module")
def demo_file(tmp_path_factory, cover_env, cover_demos):
    from bpns.data.datasets import save_demonstrations

    path = tmp_path_factory.mktemp("messages") / "d.h5"
    save_demonstrations(path, cover_env, cover_demos[:1])
    return path


def test_a_frame_beyond_the_scenes_framebuffer_is_named_so(tmp_path, demo_file, capsys):
    out = tmp_path / "v.mp4"
    argv = ["render", str(demo_file), "--out", str(out), "--width", "100000", "--height", "48"]
    line = error_line(argv, capsys)
    assert line.startswith("bpns: error: 100000 x 48 pixels exceed this scene's offscreen")
    assert "OSMesa" not in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["replay", "learn", "render"])
@pytest.mark.parametrize(
    "make, what",
    [
        (lambda d: os.mkfifo(d / "fifo") or d / "fifo", "not a regular file (a FIFO"),
        (lambda d: "/dev/zero", "not a regular file (a FIFO"),
        (lambda d: d, "is a directory, not a demonstration file"),
        (lambda d: d / "missing.h5", "no such demonstration file"),
    ],
)
def test_an_input_that_is_no_regular_file_is_named_for_what_it_is(
    tmp_path, capsys, command, make, what
):
    path = make(tmp_path)
    argv = {"learn": ["learn", str(path), "--out", str(tmp_path / "sk")]}.get(
        command, [command, str(path)]
    )
    line = error_line(argv, capsys)  # returns at once: a FIFO is never opened
    assert line.startswith(f"bpns: error: {path}: {what}")


@pytest.mark.parametrize(
    "argv",
    [
        ["demos", "--env", "cover", "--out", ""],
        ["learn", "", "--out", "x"],
        ["experiment", "--out", ""],
        ["run", "--env", "cover", "--out", "  "],
        ["eval", "--env", "cover", "--approach", "oracle", "--out", ""],
    ],
)
def test_an_empty_path_is_refused_not_read_as_the_current_directory(argv, capsys):
    line = error_line(argv, capsys, usage=True)
    assert line.endswith("expected a path, got ''") or line.endswith("expected a path, got '  '")


def _warn_then(outcome):
    def run(args):
        np.float64(1e300) * np.float64(1e300)  # RuntimeWarning: overflow
        if isinstance(outcome, Exception):
            raise outcome
        return outcome

    return run


def test_numeric_warnings_never_precede_an_error_line(monkeypatch, capsys):
    monkeypatch.setattr(COMMANDS["skills"], "run", _warn_then(UserError("bad input")))
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        code = main(["skills", "show", "anything"])
    assert code == 2
    assert capsys.readouterr().err == "bpns: error: bad input\n"


def test_numeric_warnings_of_a_command_that_succeeds_are_still_shown(monkeypatch, capsys):
    monkeypatch.setattr(COMMANDS["skills"], "run", _warn_then(0))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["skills", "show", "anything"]) == 0
    assert [w.category for w in seen] == [RuntimeWarning]
