"""The ``bpns`` command line: one sub-command per module (demos ... experiment, check-env).

One module per command, each with ``HELP``, ``configure(parser)`` and ``run(args)``;
none imports another (shared helpers live in :mod:`bpns.cli.common`, the work itself in
library modules). Every command reports bad input (missing/corrupt files, unknown
environments, bad arguments) as one ``bpns: error: ...`` line and exit status 2, never a
traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from types import ModuleType

from bpns.atomic import storage_problem
from bpns.cli import (
    check_env,
    demos,
    experiment,
    export,
    learn,
    render,
    replay,
    run,
    skills,
    view,
)
from bpns.cli import eval as eval_
from bpns.cli.common import Terminated
from bpns.errors import BpnsError

COMMANDS: dict[str, ModuleType] = {
    "demos": demos,
    "replay": replay,
    "render": render,
    "view": view,
    "export": export,
    "learn": learn,
    "skills": skills,
    "eval": eval_,
    "run": run,
    "experiment": experiment,
    "check-env": check_env,
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bpns",
        description="Bilevel planning with learned neuro-symbolic skills on a MuJoCo Panda.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, command in COMMANDS.items():
        command.configure(sub.add_parser(name, help=command.HELP, description=command.HELP))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # native libraries' own loggers (rerun's, on a full disk) would print lines beside the
    # one error line this reports; RUST_LOG set by the user still wins
    os.environ.setdefault("RUST_LOG", "off")
    with _numeric_warnings_held() as held, _terminate_unwinds():
        try:
            code = int(COMMANDS[args.command].run(args) or 0)
        except BpnsError as err:  # every error the library reports, one line
            return _error(str(err))
        except BrokenPipeError:  # e.g. `bpns skills show DIR | head` stopped reading
            return _reader_gone()
        except OSError as err:  # a full disk or read-only filesystem while writing
            problem = storage_problem(err)
            if problem is None:
                held.release()
                raise
            return _error(problem)
        except Terminated as stop:
            hint = f"; {stop}" if str(stop) else ""
            print(f"bpns: terminated{hint}", file=sys.stderr)
            return 128 + signal.SIGTERM
        except KeyboardInterrupt:
            print("bpns: interrupted", file=sys.stderr)
            return 130
        except BaseException:
            held.release()
            raise
        held.release()
        return code


@contextlib.contextmanager
def _terminate_unwinds() -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers can only be set from the main thread
        return

    def stop(signum: int, frame: object) -> None:
        raise Terminated

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class _Held:
    """RuntimeWarnings (numpy's overflow and invalid-value notes) raised by a command:
    shown after it when it ends normally, dropped when it ends in one error line, which
    must be the only thing the user sees."""

    def __init__(self, show) -> None:
        self.show = show  # the showwarning in place before
        self.records: list[tuple] = []

    def hold(self, message, category, filename, lineno, file=None, line=None) -> None:
        if issubclass(category, RuntimeWarning):
            self.records.append((message, category, filename, lineno, file, line))
        else:
            self.show(message, category, filename, lineno, file, line)

    def release(self) -> None:
        for record in self.records:
            self.show(*record)
        self.records.clear()


@contextlib.contextmanager
def _numeric_warnings_held() -> Iterator[_Held]:
    with warnings.catch_warnings():  # restores showwarning afterwards
        held = _Held(warnings.showwarning)
        warnings.showwarning = held.hold
        yield held


def _error(message: str) -> int:
    print(f"bpns: error: {message}", file=sys.stderr)
    return 2


def _reader_gone() -> int:
    """stdout's reader closed the pipe: stop quietly, as a shell tool killed by SIGPIPE
    would (exit 141), and keep Python's exit-time flush from raising again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # stdout is no file (captured)
        pass
    return 141


__all__ = ["COMMANDS", "build_parser", "main"]
