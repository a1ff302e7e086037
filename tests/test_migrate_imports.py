"""``scripts/migrate_imports.py`` rewrites code written against the flat ``bpns`` layout
into the packages, and leaves code already in the new layout alone."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def migrate_imports():
    spec = importlib.util.spec_from_file_location(
        "migrate_imports", ROOT / "scripts" / "migrate_imports.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


OLD = """from bpns.datasets import load_demonstrations
from bpns.execution import SkillExecutor
from bpns.failures import FailureReason
from bpns.evaluation import evaluate
import bpns.evaluation as evaluation
from bpns import dataset_checks as checks
from bpns import reporting
from bpns import atomic
monkeypatch.setattr("bpns.registry.make_environment", fake)
executor = bpns.execution.SkillExecutor(env, task, config)
see bpns/rollout_files.py and :mod:`bpns.environment`; the `bpns.environments` group
"""
NEW = """from bpns.data.datasets import load_demonstrations
from bpns.execution.executor import SkillExecutor
from bpns.execution.failures import FailureReason
from bpns.evaluation.evaluate import evaluate
import bpns.evaluation.evaluate as evaluation
from bpns.data import dataset_checks as checks
from bpns.evaluation import reporting
from bpns import atomic
monkeypatch.setattr("bpns.env.registry.make_environment", fake)
executor = bpns.execution.executor.SkillExecutor(env, task, config)
see bpns/evaluation/rollout_files.py and :mod:`bpns.env.environment`; the `bpns.environments` group
"""


def test_old_module_paths_are_rewritten_to_the_packages(migrate_imports):
    assert migrate_imports.migrate(OLD) == NEW


def test_code_already_in_the_new_layout_is_left_alone(migrate_imports):
    assert migrate_imports.migrate(NEW) == NEW
    packages = 'units = {"bpns.execution", "bpns.evaluation"}  # `bpns.execution` holds\n'
    assert migrate_imports.migrate(packages) == packages
    assert migrate_imports.migrate("from bpns.execution import video\n") == (
        "from bpns.execution import video\n"
    )


def test_every_new_module_path_imports(migrate_imports):
    for new in migrate_imports.MOVED.values():
        importlib.import_module(f"bpns.{new}")


def test_files_are_rewritten_in_place_and_a_second_run_changes_nothing(
    migrate_imports, tmp_path, capsys
):
    plugin = tmp_path / "plugin"
    plugin.mkdir()
    (plugin / "env.py").write_text("from bpns.environment import Capabilities\n")
    (plugin / "notes.txt").write_text("bpns.environment\n")  # not a source file: kept
    assert migrate_imports.main([str(plugin)]) == 0
    assert (plugin / "env.py").read_text() == "from bpns.env.environment import Capabilities\n"
    assert (plugin / "notes.txt").read_text() == "bpns.environment\n"
    assert capsys.readouterr().out.splitlines() == [str(plugin / "env.py")]
    assert migrate_imports.main([str(plugin)]) == 0
    assert capsys.readouterr().out == ""
    assert migrate_imports.main([str(tmp_path / "missing")]) == 2
    assert "no such file or directory" in capsys.readouterr().err


REGROUPED_OLD = """from bpns.learning.mlp import MLPParams
from bpns.learning import gnn_artifacts
from bpns.approaches.baselines import GNN_BC
import bpns.learning.pddl
see bpns/learning/baselines.py
"""
REGROUPED_NEW = """from bpns.nets.mlp import MLPParams
from bpns.baselines import files as gnn_artifacts
from bpns.baselines.approaches import GNN_BC
import bpns.learning.artifacts.pddl
see bpns/baselines/learn.py
"""


def test_paths_from_the_second_regrouping_are_rewritten(migrate_imports):
    assert migrate_imports.migrate(REGROUPED_OLD) == REGROUPED_NEW
    assert migrate_imports.migrate(REGROUPED_NEW) == REGROUPED_NEW
    for new in migrate_imports.REGROUPED.values():
        importlib.import_module(new)
