"""Optional extras: a command that needs one that is not installed says which pip
command installs it, in one line."""

from __future__ import annotations

import importlib
from types import ModuleType

from bpns.errors import BpnsError

EXTRAS = {"rerun": "viz", "pyarrow": "lerobot", "pandas": "lerobot"}


class ExtraMissingError(BpnsError, ImportError):
    """A command needs an optional extra that is not installed."""


def require(module: str, what: str) -> ModuleType:
    """``module`` imported, or :class:`ExtraMissingError` naming the pip command that
    installs the extra it belongs to (``what`` says what needs it)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        extra = EXTRAS[module]
        raise ExtraMissingError(
            f"{what} needs the optional extra [{extra}]: pip install 'bpns[{extra}]'"
        ) from None
