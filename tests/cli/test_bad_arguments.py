"""Hostile inputs to the CLI (issue 14): each is one `bpns: error:` line, exit 2, before
any work, and nothing on disk changes. One row per probe."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from bpns.cli import main
from bpns.cli.paths import capped_to_cores, usable_cores


@pytest.fixture(scope="module")
def demo_file(tmp_path_factory, cover_env, cover_demos):
    from bpns.data.datasets import save_demonstrations

    path = tmp_path_factory.mktemp("probes") / "d.h5"
    save_demonstrations(path, cover_env, cover_demos[:1])
    return path


def _snapshot(root: Path) -> dict[str, str]:
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_symlink():
            out[str(p)] = "-> " + os.readlink(p)
        elif p.is_file():
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[str(p)] = "dir"
    return out


EVAL = ("eval", "--env", "cover", "--approach", "oracle", "-n", "1")
RUN = ("run", "--env", "cover", "--demos", "1", "--tasks", "1")

# (arguments with {d}: a demo file, {w}: the work directory; expected message)
PROBES = [
    (("demos", "--env", "cover", "--seed", "-1", "--out", "{w}/a.h5"), "whole number >= 0"),
    ((*EVAL, "--seed", "-1"), "whole number >= 0"),
    ((*EVAL, "--planner-seed", "-7"), "whole number >= 0"),
    ((*RUN, "--seed", "-1", "--out", "{w}/r"), "whole number >= 0"),
    (("render", "{d}", "--demo", "-1"), "whole number >= 0"),
    (("demos", "--env", "cover", "--out", "{w}/dir"), "is a directory"),
    (("demos", "--env", "cover", "--out", ""), "expected a path, got ''"),
    (("demos", "--env", "cover", "--out", "."), "expected a file name"),
    (("demos", "--env", "cover", "--out", "/proc/a.h5"), "cannot write in /proc"),
    (("demos", "--env", "cover", "--out", "{w}/file/a.h5"), "is not a directory"),
    (("demos", "--env", "cover", "--out", "{w}/file"), "exists; pass --overwrite"),
    (("demos", "--env", "cover", "--out", "/dev/null", "--overwrite"), "not a regular file"),
    (("demos", "--env", "cover", "--out", "{w}/link", "--overwrite"), "symbolic link"),
    (("render", "{d}", "--out", "{d}", "--overwrite"), "is this command's input"),
    (("render", "{d}", "--out", "{w}/v.mp4", "--png", "{w}/dir"), "is a directory"),
    (("render", "{d}", "--out", "{w}/v.mp4", "--png", "{w}/v.mp4"), "the same file as --out"),
    (("render", "{d}", "--out", "{w}/v.txt"), "give an .mp4 name"),
    (("render", "{d}", "--out", "{w}/v.mp4", "--png", "{w}/v.jpg"), "give a .png name"),
    (("learn", "{d}", "--out", "{d}", "--overwrite"), "holds this command's input"),
    (("learn", "{w}/dir/d.h5", "--out", "{w}/dir", "--overwrite"), "holds this command's input"),
    (("learn", "{d}", "--out", "{w}/dir", "--overwrite"), "not a skills directory"),
    (("learn", "{d}", "--out", "{w}/skills"), "exists; pass --overwrite"),
    (("learn", "{d}", "--out", "{w}/sk", "--input-margin", "inf"), "finite"),
    (("learn", "{d}", "--out", "{w}/sk", "--near-goal-scale", "inf"), "finite"),
    ((*EVAL, "--timeout", "inf"), "finite"),
    ((*EVAL, "--timeout", "nan"), "finite number > 0"),
    ((*EVAL, "--timeout", "-3"), "finite number > 0"),
    ((*RUN, "--timeout", "inf", "--out", "{w}/r"), "finite"),
    ((*EVAL, "--world-speed", "0"), "--world-speed: expected a number in (0, 1]"),
    ((*EVAL, "--world-speed", "nan"), "--world-speed: expected a number in (0, 1]"),
    ((*EVAL, "--world-speed", "1.5"), "--world-speed: expected a number in (0, 1]"),
    (("experiment", "--world-speed", "2"), "--world-speed: expected a number in (0, 1]"),
    (("experiment", "--check-ahead", "0"), "--check-ahead"),
    (("experiment", "--check-ahead", "-1"), "--check-ahead"),
    ((*EVAL, "--world-speed", "0.5", "--env", "stack"), "declares no motion_dims"),
    (("experiment", "--env", "stack", "--world-speed", "0.5"), "declares no motion_dims"),
    (("learn", "{d}", "--out", "{w}/sk", "--correction-rounds", "2"), "add --corrections"),
    (("learn", "{d}", "--out", "{w}/sk", "--keep-demonstrator-labels"), "add --corrections"),
    (("learn", "{d}", "--out", "{w}/sk", "--keep-last-round"), "add --corrections"),
    (
        ("learn", "{d}", "--out", "{w}/sk", "--corrections", "moderate")
        + ("--keep-demonstrator-labels", "--correction-expert", "demonstrator"),
        "applies to corrections by the oracle",
    ),
    (("learn", "{d}", "--out", "{w}/sk", "--corrections", "mass_scale=-1"), "--corrections: "),
    (("learn", "{d}", "--out", "{w}/sk", "--corrections", "moderat"), "--corrections: "),
    (("learn", "{d}", "--out", "{w}/sk", "--corrections", "moderate"), "collect them again"),
    (
        (
            "learn",
            "{d}",
            "--out",
            "{w}/sk",
            "--corrections",
            "moderate",
            "--correction-rounds",
            "0",
        ),
        "--correction-rounds",
    ),
    (
        (
            "learn",
            "{d}",
            "--out",
            "{w}/sk",
            "--corrections",
            "moderate",
            "--correction-expert",
            "me",
        ),
        "invalid choice: 'me'",
    ),
    ((*EVAL, "--out", "{w}/file"), "exists and is not a directory"),
    ((*EVAL, "--out", "{w}/results"), "exists; pass --overwrite"),
    ((*EVAL, "--video", "{w}/dir"), "is a directory"),
    ((*EVAL, "--video", "{w}/v.png"), "give an .mp4 name"),
    ((*RUN, "--approach", "bogus", "--out", "{w}/r"), "invalid choice: 'bogus'"),
    ((*RUN, "--out", "/proc/bpns"), "cannot write in /proc"),
    ((*RUN, "--out", "{w}/done"), "exists; pass --overwrite"),
    ((*RUN, "--out", "{w}/file"), "exists and is not a directory"),
]


@pytest.mark.parametrize("args, message", PROBES, ids=[" ".join(a) for a, _ in PROBES])
def test_bad_arguments_and_outputs_are_refused_before_any_work(
    tmp_path, demo_file, capsys, args, message
):
    work = tmp_path / "w"
    (work / "dir").mkdir(parents=True)
    (work / "dir" / "d.h5").write_bytes(demo_file.read_bytes())
    (work / "file").write_text("not yours")
    (work / "link").symlink_to(work / "file")
    (work / "skills").mkdir()
    (work / "skills" / "skills.json").write_text("{}")
    (work / "results").mkdir()
    (work / "results" / "results.json").write_text("[]")
    (work / "done").mkdir()
    (work / "done" / "demos.h5").write_text("an earlier run's")
    before, demo_before = _snapshot(work), hashlib.sha256(demo_file.read_bytes()).hexdigest()
    argv = [a.format(d=demo_file, w=work) for a in args]
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's own errors
        code = exit_.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err
    assert len(err.strip().splitlines()) == 1 or "usage:" in err
    assert _snapshot(work) == before
    assert hashlib.sha256(demo_file.read_bytes()).hexdigest() == demo_before


def test_workers_and_threads_are_capped_at_the_cores_with_a_note(capsys):
    cores = usable_cores()
    assert capped_to_cores(cores, "--workers") == cores
    assert capsys.readouterr().err == ""
    assert capped_to_cores(cores + 1000, "--threads") == cores
    err = capsys.readouterr().err.strip()
    assert err == f"bpns: note: --threads {cores + 1000} capped at {cores}, this machine's cores"


def test_overwrite_replaces_an_existing_output_of_the_same_kind(tmp_path, demo_file, capsys):
    out = tmp_path / "v.mp4"
    args = ["render", str(demo_file), "--out", str(out), "--width", "64", "--height", "48"]
    assert main(args) == 0
    first = out.stat().st_mtime_ns
    assert main(args) == 2 and "pass --overwrite" in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0 and out.stat().st_mtime_ns >= first
