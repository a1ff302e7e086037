"""Broken plugins (issue 24): an installed entry point whose module is missing, does not
parse or raises is reported by name as one ``bpns: error:`` line, and presets (which
take every installed plugin) skip it with one warning line."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.cli_probe import run_cli

PLUGINS = {
    "gone": "no_such_module_h24:Env",
    "unparsable": "h24_unparsable:Env",
    "raising": "h24_raising:Env",
}
# builds, but lacks the contract's declarations (capabilities, contact_settle_steps)
UNDECLARED = {"undeclared": "h24_undeclared:Env"}


@pytest.fixture
def broken_plugins(tmp_path, monkeypatch):
    """A distribution declaring four broken environments and one broken approach."""
    (tmp_path / "h24_unparsable.py").write_text("def (:\n")
    (tmp_path / "h24_raising.py").write_text(
        "class Env:\n    def __init__(self):\n        raise RuntimeError('needs a GPU')\n"
    )
    (tmp_path / "h24_undeclared.py").write_text("class Env:\n    name = 'undeclared'\n")
    info = tmp_path / "h24_broken-0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: h24-broken\nVersion: 0\n")
    declared = {**PLUGINS, **UNDECLARED}
    lines = ["[bpns.environments]", *(f"{n} = {v}" for n, v in declared.items())]
    lines += ["[bpns.approaches]", "broken-approach = no_such_module_h24:ENTRY"]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


@pytest.mark.parametrize(
    "name, error",
    [
        ("gone", "ModuleNotFoundError: No module named 'no_such_module_h24'"),
        ("unparsable", "SyntaxError: invalid syntax"),
        ("raising", "RuntimeError: needs a GPU"),
    ],
)
@pytest.mark.parametrize(
    "command",
    [
        ["check-env", "{name}"],
        ["demos", "--env", "{name}", "-n", "1", "--out", "{w}/d.h5"],
        ["eval", "--env", "{name}", "--approach", "oracle", "-n", "1"],
        ["experiment", "--env", "{name}", "--out", "{w}/sweep"],
    ],
    ids=lambda c: c[0] if isinstance(c, list) else c,
)
def test_a_broken_environment_plugin_is_one_error_line_naming_it(
    broken_plugins, tmp_path, capsys, name, error, command
):
    argv = [a.format(name=name, w=tmp_path / "w") for a in command]
    code, err = run_cli(argv, capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert line.startswith(
        f"bpns: error: environment plugin {name!r} (entry point {name} = {PLUGINS[name]}) "
        f"cannot be loaded: {error}"
    )
    assert not (tmp_path / "w").exists()


def test_a_broken_approach_plugin_is_one_error_line_naming_it(broken_plugins, capsys):
    code, err = run_cli(["eval", "--env", "cover", "--approach", "broken-approach"], capsys)
    assert code == 2
    assert err.strip() == (
        "bpns: error: approach plugin 'broken-approach' (entry point broken-approach = "
        "no_such_module_h24:ENTRY) cannot be loaded: ModuleNotFoundError: No module named "
        "'no_such_module_h24'"
    )


def _bpns(argv, plugins_dir):
    """A fresh ``bpns`` process with the plugins installed (presets list the plugins
    installed when bpns is imported)."""
    path = os.pathsep.join([str(plugins_dir), *sys.path])
    return subprocess.run(
        [sys.executable, "-m", "bpns.cli", *argv],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": path},
        check=False,
    )


def test_presets_skip_each_broken_plugin_with_one_warning(broken_plugins, tmp_path):
    proc = _bpns(
        ["experiment", "--preset", "smoke", "--dry-run", "--out", str(tmp_path / "s")],
        broken_plugins,
    )
    assert proc.returncode == 0, proc.stderr
    warnings = proc.stderr.strip().splitlines()
    assert len(warnings) == 4 and all(w.startswith("bpns: warning: ") for w in warnings)
    assert sorted(w.split("'")[1] for w in warnings) == sorted({**PLUGINS, **UNDECLARED})
    assert all(w.endswith("; the sweep skips it") for w in warnings)
    assert "demos/cover-seed0" in proc.stdout
    assert not any(f"/{n}-" in proc.stdout for n in {**PLUGINS, **UNDECLARED})


def test_an_environment_lacking_the_contracts_declarations_named_is_one_error_line(
    broken_plugins, tmp_path, capsys
):
    argv = ["experiment", "--env", "undeclared", "--out", str(tmp_path / "w")]
    code, err = run_cli(argv, capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert line.startswith("bpns: error: environment 'undeclared' lacks capabilities")
    assert not (tmp_path / "w").exists()


def test_presets_skip_a_broken_approach_plugin_with_one_warning(broken_plugins, tmp_path):
    argv = ["experiment", "--preset", "paper", "--env", "cover", "--seeds", "0"]
    argv += ["--demos", "4", "--dry-run", "--out", str(tmp_path / "s")]
    proc = _bpns(argv, broken_plugins)
    assert proc.returncode == 0, proc.stderr
    (warning,) = proc.stderr.strip().splitlines()
    assert warning.startswith("bpns: warning: approach plugin 'broken-approach'")
    assert "eval/cover-bpns-n4-seed0" in proc.stdout
    assert "broken-approach" not in proc.stdout


def test_a_preset_skips_an_environment_that_does_not_load_in_time(monkeypatch, tmp_path, capsys):
    import time

    from bpns.cli import experiment
    from bpns.env import registry

    real = registry.make_environment
    for name in registry.environment_names():  # imported once: later loads are quick
        real(name)

    def slow(name):
        if name == "coffee":  # e.g. a plugin whose import blocks on a network drive
            time.sleep(5.0)
        return real(name)

    monkeypatch.setattr(registry, "make_environment", slow)
    monkeypatch.setattr(experiment, "PLUGIN_LOAD_SECONDS", 1.5)
    argv = ["experiment", "--preset", "smoke", "--dry-run", "--out", str(tmp_path / "s")]
    code, err = run_cli(argv, capsys)
    assert code == 0, err
    (warning,) = [line for line in err.splitlines() if "coffee" in line]
    assert warning == (
        "bpns: warning: environment plugin 'coffee' did not load within 1.5 s; the sweep "
        "skips it (name it with --env to wait for it)"
    )


def test_waiting_for_a_call_returns_its_value_or_raises_its_error_or_times_out():
    from bpns.cli.experiment import _within

    assert _within(5.0, abs, -3) == 3
    with pytest.raises(ValueError, match="bad"):
        _within(5.0, _raise, ValueError("bad"))
    with pytest.raises(TimeoutError, match="did not return within 0.2 s"):
        import time

        _within(0.2, time.sleep, 2.0)


def _raise(err: Exception) -> None:
    raise err
