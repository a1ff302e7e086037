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
    "learned": "learning.learned",
    "pddl": "learning.pddl",
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
    package, module = MOVED[name].split(".")
    if module != name and not alias:
        alias = f" as {name}"  # the name the code below uses
    return f"{indent}from bpns.{package} import {module}{alias}"


def migrate(text: str) -> str:
    """``text`` with every old bpns module path replaced by its new one."""
    text = _DOTTED.sub(lambda m: "bpns." + MOVED[m.group(1)], text)
    text = _OLD_PACKAGE_NAME.sub(lambda m: "bpns." + MOVED[m.group(1)], text)
    text = _IMPORT_STATEMENT.sub(lambda m: m.group(1) + "bpns." + MOVED[m.group(2)], text)
    text = _PATH.sub(lambda m: "bpns/" + MOVED[m.group(1)].replace(".", "/") + ".py", text)
    return _FROM_BPNS.sub(_from_bpns, text)


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
