"""docs/API.md is generated from the docstrings (scripts/make_api_reference.py) and current.

The generator runs in-process. Every public function of the motion primitives says what it
does: docs/NEW_TASK.md sends task authors to the reference instead of the source.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _generator():
    spec = importlib.util.spec_from_file_location(
        "make_api_reference", ROOT / "scripts" / "make_api_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen = _generator()


def test_docs_api_md_is_current():
    assert gen.is_current(gen.API_MD), (
        "docs/API.md is out of date: run python scripts/make_api_reference.py"
    )


def _public_functions(module_name: str) -> list[tuple[str, object]]:
    module = importlib.import_module(module_name)
    return [
        (name, obj)
        for name, obj in inspect.getmembers(module, inspect.isfunction)
        if not name.startswith("_") and obj.__module__ == module_name
    ]


@pytest.mark.parametrize(
    "module_name",
    [
        "mj_envs.oracles.motions",
        "mj_envs.oracles.phases",
        "mj_envs.parts.containers",
        "mj_envs.parts.articulated",
    ],
)
def test_every_public_function_has_a_docstring(module_name):
    functions = _public_functions(module_name)
    assert functions or module_name == "mj_envs.oracles.phases"  # phases: a class only
    missing = [name for name, obj in functions if not (inspect.getdoc(obj) or "").strip()]
    assert not missing, f"{module_name}: no docstring on {missing}"


def test_every_motion_primitive_has_an_entry():
    text = gen.render()
    for name, _ in _public_functions("mj_envs.oracles.motions"):
        assert f"### `{name}`\n\nfunction `{name}(" in text


def test_the_reference_is_deterministic_and_machine_independent():
    first = gen.render()
    assert gen.render() == first
    assert str(ROOT) not in first and " at 0x" not in first
    assert first.index("## `mj_envs.oracles.motions`") < first.index("## `mj_envs.scene`")


def test_check_flags_a_stale_file_in_one_line_and_write_repairs_it(tmp_path, capsys):
    out = tmp_path / "API.md"
    assert gen.main(["--check", "--out", str(out)]) == 1  # missing
    assert gen.main(["--out", str(out)]) == 0
    assert out.read_text() == gen.render()
    assert gen.main(["--check", "--out", str(out)]) == 0
    out.write_text(out.read_text() + "edited by hand\n")
    capsys.readouterr()
    assert gen.main(["--check", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "out of date" in err
    assert gen.write(out) is True and gen.write(out) is False
    assert sorted(p.name for p in tmp_path.iterdir()) == ["API.md"]  # no temporary left
