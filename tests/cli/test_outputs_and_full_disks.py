"""Writes that fail (issue 24): a full disk, a read-only place, a reader that closed the
pipe, an output inside an input, a killed writer's leftovers. Each is one
``bpns: error:`` line (exit 2), and nothing already on disk is lost."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import imageio.v2 as imageio
import numpy as np
import pytest

from bpns import atomic
from bpns.cli import main
from bpns.execution import video
from tests.cli_probe import error_line


@pytest.fixture(scope="module")
def demo_file(tmp_path_factory, cover_env, cover_demos):
    from bpns.data.datasets import save_demonstrations

    path = tmp_path_factory.mktemp("writes") / "d.h5"
    save_demonstrations(path, cover_env, cover_demos[:2])
    return path


@pytest.fixture(scope="module")
def skills_dir(tmp_path_factory, demo_file):
    out = tmp_path_factory.mktemp("writes-skills") / "sk"
    assert main(["learn", str(demo_file), "--out", str(out)]) == 0
    return out


def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


# -- full disk ----------------------------------------------------------------------------
def test_demos_on_a_full_disk_is_one_line_and_keeps_the_old_file(tmp_path, monkeypatch, capsys):
    out = tmp_path / "d.h5"
    out.write_bytes(b"an earlier file")
    monkeypatch.setattr(h5py.Group, "create_dataset", _no_space)
    argv = ["demos", "--env", "cover", "-n", "1", "--workers", "1", "--out", str(out)]
    assert error_line([*argv, "--overwrite"], capsys) == (
        f"bpns: error: cannot write {out}: No space left on device (nothing was replaced; "
        "free space or pick another place and run the command again)"
    )
    assert out.read_bytes() == b"an earlier file"
    assert [p.name for p in tmp_path.iterdir()] == ["d.h5"]  # no temporary left


def test_learn_on_a_full_disk_is_one_line_and_keeps_the_old_skills(
    tmp_path, demo_file, skills_dir, monkeypatch, capsys
):
    import shutil

    out = tmp_path / "sk"
    shutil.copytree(skills_dir, out)
    before = sorted(p.name for p in out.iterdir())
    monkeypatch.setattr(np, "savez_compressed", _no_space)
    monkeypatch.setattr(np, "savez", _no_space)
    line = error_line(["learn", str(demo_file), "--out", str(out), "--overwrite"], capsys)
    assert f"cannot write {out}: No space left on device" in line
    assert sorted(p.name for p in out.iterdir()) == before
    assert [p.name for p in tmp_path.iterdir()] == ["sk"]


def test_more_demos_than_the_disk_can_hold_are_refused_before_collecting(tmp_path, capsys):
    out = tmp_path / "d.h5"
    err = error_line(
        ["demos", "--env", "cover", "-n", "99999999999999999999999", "--out", str(out)], capsys
    )
    assert "99999999999999999999999 demonstrations need at least" in err and "free" in err
    assert not out.exists()


def test_a_run_whose_demos_cannot_fit_is_refused_before_collecting_and_leaves_nothing(
    tmp_path, capsys
):
    out = tmp_path / "r"
    argv = ["run", "--env", "cover", "--demos", "99999999999999999999999", "--out", str(out)]
    err = error_line(argv, capsys)
    assert err.startswith(f"bpns: error: --out {out / 'demos.h5'}: 99999999999999999999999 ")
    assert "demonstrations need at least" in err and "free" in err
    assert not out.exists()


def test_collect_demos_refuses_what_cannot_fit_before_running_the_demonstrator(
    tmp_path, cover_env, monkeypatch
):
    from bpns.data import demos
    from bpns.workflow import collect_demos

    def no_demonstrator(*args, **kwargs):
        raise AssertionError("the demonstrator ran")

    monkeypatch.setattr(demos, "collect_attempts", no_demonstrator)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(atomic.shutil, "disk_usage", lambda p: usage._replace(free=1000))
    with pytest.raises(
        atomic.NotEnoughSpaceError, match=r"3 demonstrations need at least .* 1 kB free"
    ):
        collect_demos(cover_env, 3, 0, tmp_path / "d.h5")
    assert list(tmp_path.iterdir()) == []


def test_a_storage_error_names_the_target_not_its_temporary(tmp_path):
    tmp = tmp_path / f".d.h5{atomic.temporary_prefix(tmp_path / 'd.h5')[len('.d.h5') :]}x.h5"
    err = OSError(errno.EROFS, os.strerror(errno.EROFS), str(tmp))
    assert atomic.storage_problem(err) == (
        f"cannot write {tmp_path / 'd.h5'}: Read-only file system (nothing was replaced; "
        "free space or pick another place and run the command again)"
    )
    assert atomic.storage_problem(OSError(errno.ENOENT, "No such file")) is None
    # refused before writing (a sweep stops on it as on a full disk)
    assert atomic.storage_problem(atomic.NotEnoughSpaceError("d.h5: too big")) == "d.h5: too big"


# -- videos -------------------------------------------------------------------------------
def _frames(n: int = 6) -> list[np.ndarray]:
    return [np.full((48, 64, 3), 20 * i, dtype=np.uint8) for i in range(n)]


def test_a_video_ffmpeg_could_not_finish_is_an_error_and_no_file(tmp_path, monkeypatch):
    """ffmpeg exits quietly when the disk fills up while it writes the trailer: the
    truncated mp4 must not pass for a video."""
    real = imageio.get_writer

    class Truncating:
        def __init__(self, path, **kwargs):
            self.path, self.writer = path, real(path, **kwargs)

        def append_data(self, frame):
            self.writer.append_data(frame)

        def close(self):
            self.writer.close()
            data = Path(self.path).read_bytes()
            Path(self.path).write_bytes(data[: len(data) // 2])

    monkeypatch.setattr(imageio, "get_writer", Truncating)
    out = tmp_path / "v.mp4"
    with pytest.raises(video.VideoError, match=r"cannot write .*v.mp4: 0 of 6 frames readable"):
        video.write_mp4(out, _frames())
    assert list(tmp_path.iterdir()) == []


def test_a_video_whose_encoder_pipe_breaks_is_an_error_and_no_file(tmp_path, monkeypatch):
    real = imageio.get_writer

    class Failing:
        def __init__(self, path, **kwargs):
            self.writer = real(path, **kwargs)

        def append_data(self, frame):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def close(self):
            self.writer.close()

    monkeypatch.setattr(imageio, "get_writer", Failing)
    with pytest.raises(video.VideoError, match="No space left on device"):
        video.write_mp4(tmp_path / "v.mp4", _frames())
    assert list(tmp_path.iterdir()) == []


def test_a_complete_video_is_written_and_reads_back(tmp_path):
    out = tmp_path / "v.mp4"
    assert video.write_mp4(out, _frames()) == 6
    assert len([f for f in imageio.get_reader(str(out))]) == 6


def test_eval_never_writes_its_video_or_results_into_the_skills_it_reads(skills_dir, capsys):
    index = (skills_dir / "skills.json").read_bytes()
    for flag, target in (("--video", skills_dir / "skills.json"), ("--out", skills_dir)):
        argv = ["eval", "--skills", str(skills_dir), flag, str(target), "--overwrite", "-n", "1"]
        assert "this command's input; write it elsewhere" in error_line(argv, capsys)
    assert (skills_dir / "skills.json").read_bytes() == index


# -- a reader that stopped reading ----------------------------------------------------------
def test_skills_show_into_a_closed_pipe_stops_quietly(skills_dir):
    read, write = os.pipe()
    os.close(read)  # like `| head` that has exited
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.run(
        [sys.executable, "-m", "bpns.cli", "skills", "show", str(skills_dir)],
        stdout=write,
        stderr=subprocess.PIPE,
        env=env,
        check=False,
    )
    os.close(write)
    assert proc.stderr.decode() == ""
    assert proc.returncode == 141


# -- a killed writer's leftovers ------------------------------------------------------------
def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_the_next_write_removes_temporaries_of_writers_that_died(tmp_path):
    target = tmp_path / "results.json"
    host = atomic.temporary_prefix(target).split("-")[2]
    dead = tmp_path / f".results.json.tmp-{_dead_pid()}-{host}-abc.json"
    running = tmp_path / f".results.json.tmp-1-{host}-def.json"  # pid 1 runs
    elsewhere = tmp_path / f".results.json.tmp-{_dead_pid()}-0000ffff-ghi.json"  # other host
    other = tmp_path / f".other.json.tmp-{_dead_pid()}-{host}-jkl.json"  # other target
    old_style = tmp_path / ".results.json.tmp-k2j9x_q1"  # named before pids were
    recent_old_style = tmp_path / ".results.json.tmp-a8bz0c3d"
    for p in (dead, running, elsewhere, other, old_style, recent_old_style):
        p.write_text("partial")
    long_ago = atomic._STARTED - 3600
    os.utime(old_style, (long_ago, long_ago))  # older than this process: a crash's
    with atomic.atomic_path(target) as tmp:
        tmp.write_text("{}")
    left = {p.name for p in tmp_path.iterdir()}
    kept = {running.name, elsewhere.name, other.name, recent_old_style.name}
    assert left == {"results.json", *kept}


def test_saving_skills_removes_the_directory_a_killed_save_left(tmp_path, skills_dir):
    from bpns.learning.artifacts.learned import load_learned
    from bpns.learning.artifacts.skills_dir import save_skills

    host = atomic.temporary_prefix(tmp_path / "sk").split("-")[2]
    leftover = tmp_path / f".sk.tmp-{_dead_pid()}-{host}-xyz"
    leftover.mkdir()
    (leftover / "skills.json").write_text("{")
    _, learned = load_learned(skills_dir)
    save_skills(learned, tmp_path / "sk", env_name="cover")
    assert {p.name for p in tmp_path.iterdir()} == {"sk"}
