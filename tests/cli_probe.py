"""Running a ``bpns`` command in-process and reading its one error line (for the
hardening tests)."""

from __future__ import annotations

from bpns.cli import main


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    """(exit status, stderr) of ``bpns ARGV``; argparse's own exits count as statuses."""
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    return code, capsys.readouterr().err


def error_line(argv: list[str], capsys, usage: bool = False) -> str:
    """The ``bpns: error:`` line of ``bpns ARGV``, asserting exit status 2 and that the
    line is all it printed (``usage``: argparse's usage lines may precede it)."""
    code, err = run_cli(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    if not usage:
        assert len(lines) == 1, err
        assert lines[0].startswith("bpns: error: "), err
    return lines[-1]
