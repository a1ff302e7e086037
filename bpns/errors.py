"""The one root of every error the library raises on purpose.

``except BpnsError`` catches whatever bpns (and ``mj_envs``, ``ik``) report about bad
input, bad files or an environment breaking its contract; the ``bpns`` command line
catches it once and prints it as one ``bpns: error: ...`` line. Each error class also
keeps the builtin base it always had (``ValueError``, ``KeyError`` ...), so code that
caught those keeps working. This module imports nothing, so every module may use it.
"""

from __future__ import annotations


class BpnsError(Exception):
    """Something bpns refuses or cannot do, said in one sentence (``str(err)``)."""

    def __str__(self) -> str:
        # KeyError's str() quotes its message; a bpns error reads as written
        return str(self.args[0]) if len(self.args) == 1 else super().__str__()
