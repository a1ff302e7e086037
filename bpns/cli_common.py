"""Helpers shared by the ``bpns`` sub-commands: user errors, argument types, progress."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path


class UserError(Exception):
    """Bad input from the user: reported as one line, no traceback."""


def env_by_name(name: str):
    from bpns.registry import UnknownEnvironmentError, make_environment

    try:
        return make_environment(name)
    except UnknownEnvironmentError as err:
        raise UserError(str(err)) from None


def positive(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {v}")
    return v


def progress(iterable, total: int, desc: str, unit: str = "task"):
    from tqdm import tqdm

    return tqdm(
        iterable,
        total=total,
        desc=desc,
        unit=unit,
        disable=not sys.stderr.isatty() and os.environ.get("BPNS_PROGRESS") != "1",
        leave=False,
    )


def file_env(path: Path, name: str | None):
    import h5py

    if name is None:
        if not path.is_file():
            raise UserError(f"{path}: no such demonstration file")
        try:
            with h5py.File(path, "r") as f:
                name = str(f.attrs.get("env", ""))
        except OSError as err:
            raise UserError(
                f"{path}: not a readable HDF5 file (corrupt or truncated?): {err}"
            ) from None
        if not name:
            raise UserError(f"{path}: not a bpns demonstration file (no env attribute)")
    return env_by_name(name)
