"""Write artifacts atomically: to a temporary sibling, then rename over the target;
replace whole directories so that a crash at any point loses neither version.

A temporary is named ``.NAME.tmp-<pid>-<host>-<random>``: a process killed while writing
(SIGKILL, power loss) cannot delete it, so the next write of the same target deletes
the temporaries of processes on this host that no longer run
(:func:`remove_stale_temporaries`). A full disk or a read-only filesystem is reported
by :func:`storage_problem` as one line; :func:`require_free_space` refuses a write that
cannot fit before it starts.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import hashlib
import os
import platform
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from bpns.errors import BpnsError

#: errors that say the filesystem cannot take the write (not that the input is bad)
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG})


class NotEnoughSpaceError(BpnsError):
    """A write refused before it starts: the filesystem has less space free than the
    write certainly needs (so no work is done only to fail at the end)."""


def storage_problem(err: BaseException, target: str | os.PathLike | None = None) -> str | None:
    """One line saying why a write (of ``target``, if known) failed, if ``err`` is the
    filesystem refusing it (a full disk, a quota, a read-only filesystem, or too little
    space to start: :class:`NotEnoughSpaceError`), else None. Writes here are atomic, so
    nothing was replaced and no partial file is left."""
    if isinstance(err, NotEnoughSpaceError):
        return str(err)
    if not isinstance(err, OSError) or err.errno not in STORAGE_ERRNOS:
        return None
    if target is None and err.filename:
        target = _target_of(err.filename)
    where = f" {target}" if target is not None else ""
    return (
        f"cannot write{where}: {os.strerror(err.errno)} (nothing was replaced; free space "
        "or pick another place and run the command again)"
    )


def nearly_full(path: str | os.PathLike) -> int | None:
    """The bytes free on the filesystem of ``path`` (a file, or a directory's entry)
    when under 1 MiB: a write that failed there ran out of space; else None. Libraries
    that report a failed write without its errno (ffmpeg, rerun) are read so."""
    try:
        free = shutil.disk_usage(Path(path).absolute().parent).free
    except OSError:
        return None
    return free if free < 1 << 20 else None


def require_free_space(path: str | os.PathLike, needed: int, what: str) -> None:
    """Raise :class:`NotEnoughSpaceError` when the filesystem of ``path`` (a directory,
    or a file in one; or their deepest existing ancestor) has fewer than ``needed``
    bytes free; ``what`` names what needs them (e.g. "50 demonstrations")."""
    path = Path(path)
    ancestor = path if path.is_dir() else path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    try:
        free = shutil.disk_usage(ancestor).free
    except OSError:
        return
    if needed > free:
        raise NotEnoughSpaceError(
            f"{path}: {what} need at least {_size(needed)}, and {ancestor} has {_size(free)} free"
        )


def _size(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB"):
        if n < 1000:
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"


def _target_of(filename: str | bytes | os.PathLike) -> str:
    """The target a temporary stands for (``dir/.NAME.tmp-...`` -> ``dir/NAME``)."""
    path = Path(os.fsdecode(filename))
    name = path.name
    if name.startswith(".") and ".tmp-" in name:
        return str(path.with_name(name[1:].split(".tmp-", 1)[0]))
    return str(path)


def _host_tag() -> str:
    return hashlib.sha1(platform.node().encode()).hexdigest()[:8]


def temporary_prefix(target: Path) -> str:
    """The name prefix of this process's temporaries for ``target``."""
    return f".{target.name}.tmp-{os.getpid()}-{_host_tag()}-"


_STARTED = time.time()  # (about) when this process started: when bpns was imported


def _older_than_this_process(path: Path) -> bool:
    try:
        return path.lstat().st_mtime < _STARTED
    except OSError:
        return False


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def remove_stale_temporaries(target: str | os.PathLike) -> list[Path]:
    """Delete the temporaries of ``target`` left by writes whose process died on this
    host (each name carries its writer's pid and host); returns what was deleted.
    Temporaries of running processes, or of other hosts, are left alone. A temporary
    named before pids were (``.NAME.tmp-<random>``) goes if it is older than this
    process: no write this process started made it."""
    target = Path(target)
    prefix, host = f".{target.name}.tmp-", _host_tag()
    removed: list[Path] = []
    try:
        entries = list(target.parent.iterdir())
    except OSError:
        return removed
    for entry in entries:
        if not entry.name.startswith(prefix):
            continue
        pid, _, rest = entry.name[len(prefix) :].partition("-")
        if not (pid.isdigit() and len(rest) > 9 and rest[8] == "-"):  # the earlier naming
            if not _older_than_this_process(entry):
                continue
        elif not rest.startswith(host + "-") or int(pid) == os.getpid() or _alive(int(pid)):
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
        removed.append(entry)
    return removed


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path next to ``target``; it replaces ``target`` only on success."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(target)
    fd, tmp = tempfile.mkstemp(
        prefix=temporary_prefix(target), suffix=suffix or target.suffix, dir=target.parent
    )
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp_path, 0o666 & ~umask)  # mkstemp creates 0600; artifacts are shared files
        os.replace(tmp_path, target)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


# --------------------------------------------------------------- directory replacement
#
# A directory cannot be renamed over a non-empty one. Where Linux offers
# renameat2(RENAME_EXCHANGE), the new and the old directory swap names in one atomic
# step. Elsewhere the old one is first renamed aside to ``.NAME.old-<ns>-<pid>``, then
# the new one into place: a crash between the two renames leaves no NAME, and
# :func:`recover_directory` (run before every replacement and by loaders that find NAME
# missing) renames the newest such leftover back. An old directory is removed only
# after it has been renamed to ``.NAME.trash-*``, so a crash while deleting it never
# leaves a half-deleted ``.old-`` copy that could be "recovered".

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap the names of ``a`` and ``b``; False where unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p]
    renameat2.argtypes += [ctypes.c_uint]
    renameat2.restype = ctypes.c_int
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.EXDEV):
        return False
    raise OSError(err, os.strerror(err), str(a), None, str(b))


def _aside(target: Path, kind: str) -> Path:
    return target.parent / f".{target.name}.{kind}-{time.time_ns()}-{os.getpid()}"


def _discard(path: Path, target: Path) -> None:
    """Delete ``path``, an old copy of ``target``: renamed to trash first."""
    trash = _aside(target, "trash")
    os.rename(path, trash)
    shutil.rmtree(trash, ignore_errors=True)


def recover_directory(target: str | os.PathLike) -> bool:
    """If ``target`` is missing but an interrupted :func:`replace_directory` left the old
    directory aside as ``.NAME.old-*``, rename the newest back; delete leftover trash.
    Returns whether something was recovered."""
    target = Path(target)
    if not target.parent.is_dir():
        return False
    prefix = f".{target.name}."
    olds, trash = [], []
    for entry in target.parent.iterdir():
        if entry.name.startswith(prefix + "old-") and entry.is_dir() and not entry.is_symlink():
            olds.append(entry)
        elif entry.name.startswith(prefix + "trash-"):
            trash.append(entry)
    for t in trash:
        shutil.rmtree(t, ignore_errors=True)
    recovered = False
    if olds and not os.path.lexists(target):
        newest = max(olds, key=lambda p: _stamp(p.name))
        inner = newest / target.name
        if [p.name for p in newest.iterdir()] == [target.name] and inner.is_dir():
            os.rename(inner, target)  # left by the earlier scheme: .NAME.old-XXXX/NAME
            os.rmdir(newest)
        else:
            os.rename(newest, target)
        olds.remove(newest)
        recovered = True
    if os.path.lexists(target):
        for old in olds:
            _discard(old, target)
    return recovered


def _stamp(name: str) -> tuple[int, str]:
    digits = name.rsplit("old-", 1)[-1].split("-")[0]
    return (int(digits) if digits.isdigit() else -1, name)


def replace_directory(new: str | os.PathLike, target: str | os.PathLike) -> None:
    """Put the complete directory ``new`` at ``target``, replacing a directory there, so
    that at every instant (and after a crash at any point, with
    :func:`recover_directory`) ``target`` or its ``.old-`` copy is complete."""
    new, target = Path(new), Path(target)
    recover_directory(target)
    if not os.path.lexists(target):
        os.rename(new, target)
        return
    if _exchange(new, target):
        _discard(new, target)  # ``new`` now names the old directory
        return
    old = _aside(target, "old")
    os.rename(target, old)
    os.rename(new, target)
    _discard(old, target)


# ------------------------------------------------------------------- staged outputs
#
# A command that writes several files into one directory (``bpns eval --out DIR``)
# writes them all under a staging directory first and puts them in place at the end
# in a burst of renames during which SIGINT and SIGTERM wait: stopped before that, the
# earlier outputs are left as they were, not some replaced and some not.

STAGED = "bpns-staged"  # the staging directory is ``ROOT/.bpns-staged.tmp-<pid>-<host>-*``


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """SIGINT and SIGTERM arriving inside wait until its end, then act as they would
    have (from the main thread; elsewhere handlers cannot be changed, nothing waits)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    wanted = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, lambda signum, frame: pending.append(signum)) for s in wanted}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(pending):
            signal.raise_signal(s)


class Staging:
    """Where to write the new files under ``roots`` (directories) so that they replace
    the old ones together (:meth:`commit`) or not at all: :meth:`path` maps a final path
    to its place in the root's staging directory; files written next to a staged one
    (a video's PNG) are staged with it. A file outside every root is staged in a
    staging directory of its own directory."""

    def __init__(self, *roots: Path | None) -> None:
        self._roots = [Path(r) for r in roots if r is not None]
        self._stages: dict[Path, Path] = {}

    def _stage(self, root: Path) -> Path:
        if root not in self._stages:
            root.mkdir(parents=True, exist_ok=True)
            remove_stale_temporaries(root / STAGED)  # of a command that was killed
            self._stages[root] = Path(
                tempfile.mkdtemp(prefix=temporary_prefix(root / STAGED), dir=root)
            )
        return self._stages[root]

    def path(self, target: Path) -> Path:
        target = Path(target)
        root = next((r for r in self._roots if target == r or r in target.parents), None)
        if root is None:
            root = target.parent
        staged = self._stage(root) / target.relative_to(root)
        staged.parent.mkdir(parents=True, exist_ok=True)
        return staged

    def commit(self) -> None:
        """Rename every staged file over its target (SIGINT and SIGTERM wait meanwhile)."""
        umask = os.umask(0)
        os.umask(umask)
        with deferred_signals():
            for root, stage in self._stages.items():
                for path in sorted(stage.rglob("*")):
                    if path.is_dir():
                        continue
                    target = root / path.relative_to(stage)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    os.chmod(path, 0o666 & ~umask)  # mkstemp made some 0600
                    os.replace(path, target)
        self.discard()

    def discard(self) -> None:
        for stage in self._stages.values():
            shutil.rmtree(stage, ignore_errors=True)
        self._stages.clear()


@contextlib.contextmanager
def staged(*roots: Path | None) -> Iterator[Staging]:
    """A :class:`Staging` committed when the block ends normally, discarded otherwise."""
    staging = Staging(*roots)
    try:
        yield staging
        staging.commit()
    finally:
        staging.discard()
