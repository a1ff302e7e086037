"""The extras stay optional: the command line and the library import none of them until
a recording or an export is asked for."""

from __future__ import annotations

import subprocess
import sys


def test_the_command_line_imports_no_optional_extra():
    code = (
        "import sys, bpns, bpns.cli, bpns.workflow.report; "
        "print([m for m in ('rerun', 'pyarrow', 'pandas') if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
