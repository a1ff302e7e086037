"""The layering the architecture promises (docs/ARCHITECTURE.md), checked on the source.

* No import cycles among the project's modules, counting imports inside functions too
  (a lazy import that closes a cycle still ties the modules together).
* ``bpns``'s packages (env, data, learning, execution, planning, approaches,
  evaluation, ...) import each other in one direction, and the environment contract
  (``bpns.env``) depends on nothing but the core structs.
* ``bpns`` is environment-agnostic: it imports nothing from ``mj_envs``, ``ik`` or
  ``mujoco``, and no ``bpns`` module names a domain.
* Inside a domain package, the demonstrator and the oracle skills depend on the
  environment side (rules, scene, behaviours), never the reverse.
* Every exception class the project defines derives from ``bpns.errors.BpnsError``,
  so one ``except BpnsError`` catches whatever it raises on purpose.

The domains are the registry's (the ``bpns.environments`` entry points), not a list here.
"""

from __future__ import annotations

import ast
import builtins
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from bpns.env.registry import GROUP, environment_names

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("bpns", "ik", "mj_envs")
DOMAINS = tuple(environment_names())  # every registered environment, plugins included


def _domain_packages() -> list[str]:
    """The packages under ``mj_envs.domains`` that registered environments live in."""
    modules = (ep.value.split(":")[0] for ep in entry_points(group=GROUP))
    return sorted({m.rpartition(".")[0] for m in modules if m.startswith("mj_envs.domains.")})


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for f in (ROOT / pkg).rglob("*.py"):
            name = ".".join(f.relative_to(ROOT).with_suffix("").parts)
            mods[name.removesuffix(".__init__")] = f
    return mods


def _imports(name: str, path: Path) -> set[str]:
    """Every module name ``path`` imports, at any depth (relative imports resolved)."""
    tree = ast.parse(path.read_text())
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return out


def _project_edges() -> dict[str, set[str]]:
    mods = _modules()

    def resolve(target: str) -> str | None:
        while target and target not in mods:
            target = target.rpartition(".")[0]
        return target or None

    edges: dict[str, set[str]] = {}
    for name, path in mods.items():
        targets = {resolve(t) for t in _imports(name, path)}
        # a module importing its own package (or the package its parent) is not a cycle
        edges[name] = {t for t in targets if t and t != name and not name.startswith(t + ".")}
    return edges


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        x = stack.pop()
                        on_stack.discard(x)
                        comp.append(x)
                        if x == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
            elif w not in index:
                index[w] = low[w] = counter
                counter += 1
                stack.append(w)
                on_stack.add(w)
                work.append((w, iter(sorted(edges.get(w, ())))))
            elif w in on_stack:
                low[v] = min(low[v], index[w])
    return out


def test_no_module_imports_another_in_a_cycle_even_lazily():
    assert _cycles(_project_edges()) == []


def _bpns_package_edges() -> dict[str, set[str]]:
    """Imports between ``bpns``'s packages and top-level modules (``bpns.env``,
    ``bpns.structs`` ...): module edges collapsed into the unit each module belongs to."""

    def unit(module: str) -> str | None:
        parts = module.split(".")
        return ".".join(parts[:2]) if parts[0] == "bpns" and len(parts) > 1 else None

    edges: dict[str, set[str]] = {}
    for name, targets in _project_edges().items():
        if (u := unit(name)) is not None:
            edges.setdefault(u, set()).update(
                t for t in map(unit, targets) if t is not None and t != u
            )
    return edges


def test_bpns_packages_import_each_other_in_one_direction():
    edges = _bpns_package_edges()
    assert {"bpns.env", "bpns.data", "bpns.execution", "bpns.evaluation"} <= set(edges)
    assert _cycles(edges) == []


def test_the_environment_contract_depends_on_nothing_but_the_core_structs():
    assert _bpns_package_edges()["bpns.env"] == {"bpns.structs", "bpns.errors"}


def test_cycle_finder_finds_a_planted_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_bpns_imports_no_simulator_robot_or_domain_code():
    for name, path in _modules().items():
        if not name.startswith("bpns"):
            continue
        bad = {t for t in _imports(name, path) if t.split(".")[0] in ("mj_envs", "ik", "mujoco")}
        assert not bad, f"{name} imports {sorted(bad)}"
        # a domain's name as a string in code (not prose in a docstring) means a branch on it
        named = {
            node.value
            for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Constant) and node.value in DOMAINS
        }
        assert not named, f"{name} names the domains {sorted(named)}"


def test_every_domain_package_is_registered():
    on_disk = {
        f"mj_envs.domains.{p.name}"
        for p in (ROOT / "mj_envs" / "domains").iterdir()
        if (p / "__init__.py").exists()
    }
    assert on_disk and on_disk == set(_domain_packages())


@pytest.mark.parametrize("pkg", _domain_packages())
def test_domain_environment_side_never_imports_its_oracles(pkg):
    edges = _project_edges()
    oracles = {f"{pkg}.demonstrator", f"{pkg}.skills"}
    sides = [m for m in edges if m.startswith(pkg + ".") and m not in oracles | {f"{pkg}.env"}]
    assert f"{pkg}.rules" in sides
    for side in sides:
        assert not edges[side] & oracles, f"{side} imports an oracle module"
    assert f"{pkg}.env" not in edges[f"{pkg}.demonstrator"] | edges[f"{pkg}.skills"]


def test_shared_machinery_imports_no_domain():
    for name, targets in _project_edges().items():
        if name.startswith(("mj_envs.robots", "mj_envs.parts", "mj_envs.oracles")) or name in (
            "mj_envs.base",
            "mj_envs.world",
            "mj_envs.scene",
        ):
            assert not {t for t in targets if t.startswith("mj_envs.domains")}, name


def _class_bases() -> dict[str, set[str]]:
    """Every class the project defines (by name) and the names of its bases, across
    all its definitions (``errors.BpnsError`` counts as ``BpnsError``)."""
    bases: dict[str, set[str]] = {}
    for path in _modules().values():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                names = {ast.unparse(b).rpartition(".")[2] for b in node.bases}
                bases.setdefault(node.name, set()).update(names)
    return bases


def _derives(name: str, bases: dict[str, set[str]], root: type | str) -> bool:
    """Whether class ``name`` derives from ``root``: a builtin class (any builtin
    subclass of it counts) or the name of a project class."""
    builtin = getattr(builtins, name, None)
    if isinstance(root, type) and isinstance(builtin, type) and issubclass(builtin, root):
        return True
    if name == root:
        return True
    return any(_derives(b, bases, root) for b in bases.get(name, ()) if b != name)


def test_every_exception_class_derives_from_bpns_error():
    bases = _class_bases()
    # errors are Exceptions; a KeyboardInterrupt subclass (the CLI's Terminated: SIGTERM
    # unwinding as Ctrl-C does) is a stop, not an error
    exceptions = {n for n in bases if n != "BpnsError" and _derives(n, bases, Exception)}
    # the walk finds the exceptions the planner, the skills and the CLI raise
    assert {"SearchTimeout", "NoSubgoal", "UserError"} <= exceptions
    outside = sorted(n for n in exceptions if not _derives(n, bases, "BpnsError"))
    assert outside == [], f"exception classes not deriving from BpnsError: {outside}"


def test_exception_check_flags_an_exception_outside_bpns_error():
    bases = {"BpnsError": {"Exception"}, "Kept": {"BpnsError", "ValueError"}, "Stray": {"KeyError"}}
    assert _derives("Stray", bases, BaseException) and _derives("Kept", bases, BaseException)
    assert _derives("Kept", bases, "BpnsError") and not _derives("Stray", bases, "BpnsError")
