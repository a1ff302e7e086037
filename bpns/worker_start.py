"""Loaded by the forkserver before it starts any worker (see :func:`bpns.pools.worker_context`).

A worker whose start is still under way when its pool is shut down (Ctrl-C or SIGTERM
during ``bpns demos --workers 2``) finds the pool's semaphore already removed and cannot
begin. That is the expected end of a worker nobody wants any more, yet the forkserver
printed it as a ``FileNotFoundError`` traceback under the command's ``bpns: terminated``
line. Workers inherit this module's ``sys.excepthook``, which stays silent for exactly
that case and prints every other exception as before.
"""

from __future__ import annotations

import sys
from types import TracebackType

_DEFAULT_HOOK = sys.excepthook


def _pool_gone(kind: type[BaseException], tb: TracebackType | None) -> bool:
    """Whether the exception is a semaphore that vanished while a worker unpickled it."""
    if not issubclass(kind, FileNotFoundError) or tb is None:
        return False
    while tb.tb_next is not None:
        tb = tb.tb_next
    code = tb.tb_frame.f_code
    return code.co_name == "__setstate__" and code.co_filename.endswith("synchronize.py")


def _quiet_when_the_pool_is_gone(
    kind: type[BaseException], value: BaseException, tb: TracebackType | None
) -> None:
    if not _pool_gone(kind, tb):
        _DEFAULT_HOOK(kind, value, tb)


sys.excepthook = _quiet_when_the_pool_is_gone
