"""Rewrite references to bpns modules from before their regrouping into packages.

    python scripts/migrate_imports.py PATH [PATH ...]

Rewrites, in place (atomically), every ``.py``, ``.md`` and ``.toml`` file under each
PATH (a file or a directory): dotted module paths (``from bpns.datasets import ...`` ->
``from bpns.data.datasets import ...``), file paths (``bpns/datasets.py`` ->
``bpns/data/datasets.py``) and ``from bpns import datasets``. For a branch written
against the old layout (a merge), or a plugin package that imports bpns's modules.

Running it again changes nothing: paths already in the new layout are left alone. The
two modules whose names are now packages, ``bpns.execution`` and ``bpns.evaluation``,
are rewritten only where the old module is certain (``import bpns.evaluation``,
``from bpns.evaluation import evaluate``, ``bpns.execution.SkillExecutor``); a bare
mention of either (prose, a string) is left for you. It prints each file it changed.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from bpns.atomic import atomic_path

# old module (under bpns) -> new module (under bpns); docs/ARCHITECTURE.md has the tree
MOVED = {
    "abstraction": "env.abstraction",
    "environment": "env.environment",
    "registry": "env.registry",
    "perturbations": "env.perturbations",
    "demos": "data.demos",
    "demo_attempts": "data.demo_attempts",
    "datasets": "data.datasets",
    "dataset_checks": "data.dataset_checks",
    "execution": "execution.executor",
    "rollouts": "execution.rollouts",
    "failures": "execution.failures",
    "video": "execution.video",
    "evaluation": "evaluation.evaluate",
    "rollout_files": "evaluation.rollout_files",
    "reporting": "evaluation.reporting",
    "learned": "learning.artifacts.learned",
    "pddl": "learning.artifacts.pddl",
}
# the second regrouping (one wing per concern): module paths inside packages -> new ones
REGROUPED = {
    "bpns.learning.nets": "bpns.nets.layers",
    "bpns.learning.mlp": "bpns.nets.mlp",
    "bpns.learning.linear": "bpns.nets.linear",
    "bpns.learning.gnn_meta": "bpns.baselines.gnn_meta",
    "bpns.learning.gnn_bc": "bpns.baselines.gnn_bc",
    "bpns.learning.gnn_artifacts": "bpns.baselines.files",
    "bpns.learning.gnn": "bpns.baselines.gnn",
    "bpns.learning.graphs": "bpns.baselines.graphs",
    "bpns.learning.baselines": "bpns.baselines.learn",
    "bpns.approaches.baselines": "bpns.baselines.approaches",
    "bpns.learning.artifact_checks": "bpns.learning.artifacts.checks",
    "bpns.learning.learned": "bpns.learning.artifacts.learned",
    "bpns.learning.pddl": "bpns.learning.artifacts.pddl",
}
SUFFIXES = (".py", ".md", ".toml")

# ``bpns.execution`` and ``bpns.evaluation`` are now packages, so a bare mention of either
# may be the new layout; they are rewritten only where the old module is certain: in an
# ``import`` statement, or followed by one of its names (not a new submodule's)
_PACKAGES = ("execution", "evaluation")
_SUBMODULES = "executor|rollouts|failures|video|evaluate|rollout_files|reporting"
# the submodules the old modules of the same name never defined (``evaluate`` was one)
_IMPORTED = "executor|rollouts|failures|video|rollout_files|reporting"
_PLAIN = "|".join(sorted((m for m in MOVED if m not in _PACKAGES), key=len, reverse=True))
_DOTTED = re.compile(rf"\bbpns\.({_PLAIN})(?!\w)")
_OLD_PACKAGE_NAME = re.compile(
    rf"\bbpns\.({'|'.join(_PACKAGES)})"
    rf"(?=\.(?!(?:{_SUBMODULES})\b)\w| import (?!(?:{_IMPORTED})\b))"
)
_IMPORT_STATEMENT = re.compile(rf"^(\s*import )bpns\.({'|'.join(_PACKAGES)})\b(?!\.)", re.M)
_OLD = "|".join(sorted(MOVED, key=len, reverse=True))
_PATH = re.compile(rf"\bbpns/({_OLD})\.py\b")
_FROM_BPNS = re.compile(r"^(\s*)from bpns import (\w+)( as \w+)?$", re.M)


def _from_bpns(m: re.Match[str]) -> str:
    indent, name, alias = m.group(1), m.group(2), m.group(3) or ""
    if name not in MOVED:
        return m.group(0)
    package, _, module = MOVED[name].rpartition(".")
    if module != name and not alias:
        alias = f" as {name}"  # the name the code below uses
    return f"{indent}from bpns.{package} import {module}{alias}"


_REGROUPED = re.compile(
    r"\b(" + "|".join(re.escape(m) for m in sorted(REGROUPED, key=len, reverse=True)) + r")(?!\w)"
)
_REGROUPED_PATH = re.compile(
    r"\b("
    + "|".join(re.escape(m.replace(".", "/")) for m in sorted(REGROUPED, key=len, reverse=True))
    + r")\.py\b"
)
_FROM_PACKAGE = re.compile(r"^(\s*)from (bpns\.\w+) import (\w+)( as \w+)?$", re.M)


def _from_package(m: re.Match[str]) -> str:
    indent, package, name, alias = m.group(1), m.group(2), m.group(3), m.group(4) or ""
    new = REGROUPED.get(f"{package}.{name}")
    if new is None:
        return m.group(0)
    new_package, _, module = new.rpartition(".")
    if module != name and not alias:
        alias = f" as {name}"
    return f"{indent}from {new_package} import {module}{alias}"


def _regrouped(text: str) -> str:
    text = _FROM_PACKAGE.sub(_from_package, text)
    text = _REGROUPED.sub(lambda m: REGROUPED[m.group(1)], text)
    return _REGROUPED_PATH.sub(
        lambda m: REGROUPED[m.group(1).replace("/", ".")].replace(".", "/") + ".py", text
    )


def migrate(text: str) -> str:
    """``text`` with every old bpns module path replaced by its new one."""
    text = _regrouped(text)
    text = _DOTTED.sub(lambda m: "bpns." + MOVED[m.group(1)], text)
    text = _OLD_PACKAGE_NAME.sub(lambda m: "bpns." + MOVED[m.group(1)], text)
    text = _IMPORT_STATEMENT.sub(lambda m: m.group(1) + "bpns." + MOVED[m.group(2)], text)
    text = _PATH.sub(lambda m: "bpns/" + MOVED[m.group(1)].replace(".", "/") + ".py", text)
    text = _FROM_BPNS.sub(_from_bpns, text)
    return _regrouped(text)


def _files(path: Path) -> list[Path]:
    """The source files under ``path``, this script excepted (it names the old paths)."""
    files = [path] if path.is_file() else sorted(path.rglob("*"))
    me = Path(__file__).resolve()
    return [p for p in files if p.suffix in SUFFIXES and p.is_file() and p.resolve() != me]


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    for root in map(Path, argv):
        if not root.exists():
            print(f"migrate_imports: error: {root}: no such file or directory", file=sys.stderr)
            return 2
        for path in _files(root):
            text = path.read_text()
            new = migrate(text)
            if new != text:
                mode = path.stat().st_mode
                with atomic_path(path) as tmp:
                    tmp.write_text(new)
                path.chmod(mode)  # an executable stays executable
                print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
