"""Output paths checked before any work, under one overwrite policy.

A command names every path it will write and checks them all first, so a long
learning or evaluation run is never thrown away at the end for want of a writable
place. The policy: an existing output is replaced only with ``--overwrite``, and never
when it is one of the command's inputs, not a regular file (a directory, a device, a
FIFO), a symbolic link (the link would be replaced, not what it points to), or, for a
skills directory, a directory that is not one.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
import sys
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

from bpns.atomic import NotEnoughSpaceError, require_free_space, storage_problem
from bpns.cli.common import UserError

SKILLS_INDEX = "skills.json"  # what marks a directory as a skills directory


def _same(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _inside(path: Path, directory: Path) -> bool:
    try:
        return path.resolve().is_relative_to(directory.resolve())
    except (OSError, RuntimeError):
        return False


def _check_writable_place(path: Path, flag: str, shown: Path | None = None) -> None:
    """The deepest existing ancestor of ``path`` must be a directory we can create
    files in (parents that do not exist yet are created when writing). Messages name
    ``shown`` (default: ``path``)."""
    shown = path if shown is None else shown
    ancestor = path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        if ancestor.is_symlink():  # a dangling link
            raise UserError(f"{flag} {shown}: {ancestor} is a broken symbolic link")
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise UserError(f"{flag} {shown}: {ancestor} is not a directory")
    try:
        fd, probe = tempfile.mkstemp(prefix=".bpns-write-check-", dir=ancestor)
    except OSError as err:
        raise UserError(f"{flag} {shown}: cannot write in {ancestor} ({err.strerror})") from None
    os.close(fd)
    os.unlink(probe)


def check_output_file(path: Path, flag: str, overwrite: bool, inputs: Sequence[Path] = ()) -> None:
    """``path`` can be written as a new or replaced regular file (see the module doc)."""
    if str(path) in ("", ".") or path.name in ("", ".", ".."):
        raise UserError(f"{flag} {str(path)!r}: expected a file name")
    if path.is_symlink():
        raise UserError(f"{flag} {path}: is a symbolic link; give the path it points to")
    if path.exists():
        mode = path.stat().st_mode
        if stat.S_ISDIR(mode):
            raise UserError(f"{flag} {path}: is a directory; expected a file name")
        if not stat.S_ISREG(mode):
            raise UserError(f"{flag} {path}: not a regular file; refusing to replace it")
        for source in inputs:
            if _same(path, source):
                raise UserError(f"{flag} {path}: is this command's input; refusing to replace it")
        if not overwrite:
            raise UserError(f"{flag} {path}: exists; pass --overwrite to replace it")
    _check_writable_place(path, flag)


def check_skills_dir(path: Path, flag: str, overwrite: bool, inputs: Sequence[Path] = ()) -> None:
    """``path`` can be written as a new or replaced skills directory."""
    if str(path) in ("", ".") or path.name in ("", ".", ".."):
        raise UserError(f"{flag} {str(path)!r}: expected a new directory name")
    if path.is_symlink():
        raise UserError(f"{flag} {path}: is a symbolic link; give the path it points to")
    for source in inputs:
        if _same(path, source) or _inside(source, path):
            raise UserError(f"{flag} {path}: holds this command's input; refusing to replace it")
    if path.exists():
        if not path.is_dir():
            raise UserError(f"{flag} {path}: exists and is not a directory")
        if not (path / SKILLS_INDEX).is_file():
            raise UserError(
                f"{flag} {path}: exists and is not a skills directory; refusing to replace it"
            )
        if not overwrite:
            raise UserError(f"{flag} {path}: exists; pass --overwrite to replace it")
    _check_writable_place(path, flag)


def check_output_dir(path: Path, flag: str) -> None:
    """``path`` is a directory that exists or can be created (its files are checked
    one by one)."""
    if path.is_symlink() and not path.is_dir():
        raise UserError(f"{flag} {path}: is a broken symbolic link")
    if path.exists() and not path.is_dir():
        raise UserError(f"{flag} {path}: exists and is not a directory")
    _check_writable_place(path / "x", flag, shown=path)


@contextlib.contextmanager
def writing(path: Path | None, flag: str | None = None) -> Iterator[None]:
    """A full disk or read-only filesystem while writing ``path`` becomes one line
    naming it (the write is atomic: nothing was replaced), as does a write refused
    before it started for want of space (named by ``flag``, the option that chose it)."""
    try:
        yield
    except NotEnoughSpaceError as err:
        raise UserError(f"{flag} {err}" if flag else str(err)) from None
    except OSError as err:
        problem = storage_problem(err, path)
        if problem is None:
            raise
        raise UserError(problem) from None


@contextlib.contextmanager
def claimed(flag: str, *paths: Path | None) -> Iterator[None]:
    """Hold ``paths`` (the outputs ``flag`` named; None: none) for this command: another
    ``bpns`` command claiming one of them while this one runs is refused with one line.
    Each had checked before any work that the output did not exist yet (or that
    --overwrite was given), so without the claim two commands started together both
    passed, and the later one replaced the other's output unasked. The claim is an
    ``flock`` on ``.NAME.lock`` beside the output, deleted when the command ends (the
    kernel releases it when a killed process dies)."""
    with contextlib.ExitStack() as held:
        for path in dict.fromkeys(p for p in paths if p is not None):
            held.enter_context(_claim(path, flag))
        yield


@contextlib.contextmanager
def _claim(path: Path, flag: str) -> Iterator[None]:
    lock = path.parent / f".{path.name}.lock"
    lock.parent.mkdir(parents=True, exist_ok=True)  # its checks found the place writable
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise UserError(
                f"{flag} {path}: is being written by another running bpns command; "
                "wait for it to finish, or write elsewhere"
            ) from None
        try:
            same = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:  # its holder finished and deleted it as we opened it
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)  # still held: a command opening it now retries on a new one
        os.close(fd)


def check_free_space(path: Path, needed: int, flag: str, what: str) -> None:
    """Refuse before any work when the filesystem of ``path`` has fewer than ``needed``
    bytes free (:func:`bpns.atomic.require_free_space`)."""
    try:
        require_free_space(path, needed, what)
    except NotEnoughSpaceError as err:
        raise UserError(f"{flag} {err}") from None


def usable_cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def capped_to_cores(value: int, flag: str) -> int:
    """``value``, or the machine's core count with a one-line note when it is more."""
    cores = usable_cores()
    if value <= cores:
        return value
    print(f"bpns: note: {flag} {value} capped at {cores}, this machine's cores", file=sys.stderr)
    return cores


def check_not_inside(path: Path, flag: str, directory: Path | None, what: str) -> None:
    """Refuse ``path`` inside ``directory``, an input directory (e.g. the skills read)."""
    if directory is not None and directory.exists() and _inside(path, directory):
        raise UserError(
            f"{flag} {path}: is inside {what} {directory}, this command's input; write it elsewhere"
        )


def check_eval_outputs(
    out: Path | None,
    video: Path | None,
    approaches: Sequence[str],
    overwrite: bool,
    skills_dir: Path | None = None,
) -> None:
    """The files an evaluation writes: results.json, results.md and plans_<approach>.npz
    in ``out``; ``video`` and the PNG of its last frame next to it. None of them may be
    inside ``skills_dir``, the skills it reads."""
    if out is not None:
        check_not_inside(out, "--out", skills_dir, "the skills directory")
        check_output_dir(out, "--out")
        names = ["results.json", "results.md", *(f"plans_{a}.npz" for a in approaches)]
        names += [f"rollouts_{a}.h5" for a in approaches]
        for name in names:
            check_output_file(out / name, "--out", overwrite)
    if video is not None:
        png = video.with_suffix(".png")
        if png == video:
            raise UserError(f"--video {video}: give an .mp4 name (a PNG is written next to it)")
        for path in (video, png):
            check_not_inside(path, "--video", skills_dir, "the skills directory")
            check_output_file(path, "--video", overwrite)
