"""Write docs/API.md, the reference of the pieces a new task is built from, from docstrings.

    python scripts/make_api_reference.py            # rewrite docs/API.md
    python scripts/make_api_reference.py --check    # exit 1 if docs/API.md is stale

One section per module in :data:`MODULES` (its docstring first), one entry per public
name defined in that module (functions, classes with their public methods, constants),
in source order: the signature (``inspect.signature``, with defaults and annotations
written as in the source) in a code span, then the docstring (``inspect.getdoc``).
Constants show their assignment and the comment beside or above it. The output depends
only on the source, so it is the same on every machine; it is written atomically.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import inspect
import io
import re
import sys
import tokenize
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parent.parent
API_MD = ROOT / "docs" / "API.md"
MODULES = (
    "mj_envs.oracles.motions",
    "mj_envs.oracles.phases",
    "mj_envs.parts.objects",
    "mj_envs.parts.button",
    "mj_envs.parts.containers",
    "mj_envs.parts.articulated",
    "mj_envs.scene",
)
COMMAND = "python scripts/make_api_reference.py"
# Sphinx roles in docstrings (:func:`x`, :data:`~a.b`) become plain code spans
_ROLE = re.compile(r":(?:func|class|meth|data|attr|mod|exc|obj):`~?([^`]+)`")
# what would make the output depend on the machine or the run
_UNSTABLE = re.compile(r" at 0x[0-9a-f]+|" + re.escape(str(ROOT)))


class _Source(str):
    """Text shown as written (no quotes) where ``inspect`` would print a repr."""

    def __repr__(self) -> str:
        return str(self)


def render() -> str:
    """The text of docs/API.md for the current source."""
    lines = [
        "# API reference",
        "",
        f"Generated from the docstrings by `{COMMAND}`; do not edit by",
        "hand (`tests/test_api_reference.py` fails when this file is stale). Units are",
        "metres, radians and seconds unless an entry says otherwise; docs/NEW_TASK.md shows",
        "how the pieces fit together.",
        "",
        *(f"* [`{name}`](#{_anchor(name)})" for name in MODULES),
        "",
    ]
    for name in MODULES:
        lines += _module_section(importlib.import_module(name))
    text = "\n".join(lines).rstrip("\n") + "\n"
    if found := _UNSTABLE.search(text):
        raise RuntimeError(f"the reference would depend on the machine: {found.group(0)!r}")
    return text


def write(path: Path = API_MD) -> bool:
    """Write the reference to ``path`` atomically; returns whether its content changed."""
    from bpns.atomic import atomic_path  # a temporary file beside ``path``, os.replace'd

    text = render()
    if path.exists() and path.read_text() == text:
        return False
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return True


def is_current(path: Path = API_MD) -> bool:
    """Whether ``path`` holds exactly what :func:`write` would write."""
    return path.exists() and path.read_text() == render()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is stale")
    parser.add_argument("--out", type=Path, default=API_MD, help="default: docs/API.md")
    args = parser.parse_args(argv)
    shown = _shown(args.out)
    if args.check:
        if is_current(args.out):
            return 0
        print(f"{shown} is out of date: run {COMMAND}", file=sys.stderr)
        return 1
    print(f"wrote {shown}" if write(args.out) else f"{shown} is up to date")
    return 0


# -- one module ---------------------------------------------------------------------------


def _module_section(module: ModuleType) -> list[str]:
    lines = [f"## `{module.__name__}`", "", *_doc(inspect.getdoc(module)), ""]
    source = inspect.getsource(module)
    comments = _comments(source)
    src_lines = source.splitlines()
    for node in ast.parse(source).body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            if _public(node.name):
                obj = getattr(module, node.name)
                if getattr(obj, "__module__", None) == module.__name__:
                    lines += _entry(obj, node)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            names = _assigned_names(node)
            if any(_public(n) for n in names):
                lines += _constant(node, names, comments, src_lines, source)
    return lines


def _entry(obj: object, node: ast.FunctionDef | ast.ClassDef) -> list[str]:
    kind = "class" if inspect.isclass(obj) else "function"
    lines = [f"### `{node.name}`", "", f"{kind} `{node.name}{_signature(obj, node)}`", ""]
    if isinstance(node, ast.ClassDef) and node.bases:
        lines += ["Bases: " + ", ".join(f"`{ast.unparse(b)}`" for b in node.bases) + ".", ""]
    lines += [*_doc(inspect.getdoc(obj)), ""]
    if inspect.isclass(obj):
        lines += _members(obj, node)
    return lines


def _members(cls: type, node: ast.ClassDef) -> list[str]:
    """Public methods, properties and plain class attributes defined in the class body."""
    fields = set(getattr(cls, "__dataclass_fields__", {}))
    lines: list[str] = []
    for item in node.body:
        if isinstance(item, ast.FunctionDef) and (_public(item.name) or item.name == "__call__"):
            raw = cls.__dict__[item.name]
            if isinstance(raw, property):
                head, doc = f"property `{cls.__name__}.{item.name}`", inspect.getdoc(raw)
            else:
                func = raw.__func__ if isinstance(raw, staticmethod | classmethod) else raw
                drop = 0 if isinstance(raw, staticmethod) else 1  # self / cls
                sig = _signature(func, item, drop=drop)
                head, doc = f"method `{cls.__name__}.{item.name}{sig}`", inspect.getdoc(func)
            lines += [f"* {head}", "", *_indent(_doc(doc)), ""]
        elif isinstance(item, ast.Assign | ast.AnnAssign):
            for name in _assigned_names(item):
                if _public(name) and name not in fields and item.value is not None:
                    value = ast.unparse(item.value)
                    lines += [f"* attribute `{cls.__name__}.{name} = {value}`", ""]
    return lines


def _constant(node, names, comments, src_lines, source) -> list[str]:
    value = ast.get_source_segment(source, node.value) if node.value is not None else None
    target = ", ".join(names)
    shown = f"{target} = {' '.join(value.split())}" if value else target
    note = comments.get(node.end_lineno) or _comment_above(node.lineno, src_lines)
    lines = [f"### `{target}`", "", f"constant `{shown}`", ""]
    return lines + ([note, ""] if note else [])


# -- signatures ---------------------------------------------------------------------------


def _signature(obj: object, node: ast.FunctionDef | ast.ClassDef, drop: int = 0) -> str:
    """``inspect.signature`` with annotations and defaults as written in the source."""
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):  # e.g. an exception class: its __init__ is a builtin
        return ""
    defaults = _source_defaults(node)
    params = []
    for p in list(sig.parameters.values())[drop:]:
        if isinstance(p.annotation, str):
            p = p.replace(annotation=_Source(p.annotation))
        if p.default is not inspect.Parameter.empty and p.name in defaults:
            p = p.replace(default=_Source(defaults[p.name]))
        params.append(p)
    ret = sig.return_annotation
    if isinstance(ret, str):
        ret = _Source(ret)
    if inspect.isclass(obj):
        ret = inspect.Signature.empty
    return str(sig.replace(parameters=params, return_annotation=ret))


def _source_defaults(node: ast.FunctionDef | ast.ClassDef) -> dict[str, str]:
    """Parameter name -> its default as written (a function's or a dataclass's fields)."""
    if isinstance(node, ast.ClassDef):
        init = next(
            (n for n in node.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"),
            None,
        )
        if init is None:  # a dataclass: field defaults are the annotated assignments
            return {
                n.target.id: ast.unparse(n.value)
                for n in node.body
                if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name) and n.value
            }
        node = init
    args = node.args
    positional = [*args.posonlyargs, *args.args]
    out = {
        a.arg: ast.unparse(d)
        for a, d in zip(
            positional[len(positional) - len(args.defaults) :], args.defaults, strict=True
        )
    }
    out.update(
        {a.arg: ast.unparse(d) for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True) if d}
    )
    return out


# -- text helpers -------------------------------------------------------------------------


def _public(name: str) -> bool:
    return not name.startswith("_")


def _assigned_names(node: ast.Assign | ast.AnnAssign) -> list[str]:
    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
    names: list[str] = []
    for t in targets:
        elts = t.elts if isinstance(t, ast.Tuple) else [t]
        names += [e.id for e in elts if isinstance(e, ast.Name)]
    return names


def _comments(source: str) -> dict[int, str]:
    """Line number -> the comment ending that line (after code), without the ``#``."""
    out: dict[int, str] = {}
    code_lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT and tok.start[0] in code_lines:
            out[tok.start[0]] = tok.string.lstrip("#").strip()
        elif tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT):
            code_lines.add(tok.start[0])
    return out


def _comment_above(lineno: int, src_lines: list[str]) -> str:
    """The block of ``#`` lines right above line ``lineno`` (1-based), joined."""
    block: list[str] = []
    i = lineno - 2
    while i >= 0 and src_lines[i].lstrip().startswith("#"):
        block.insert(0, src_lines[i].lstrip().lstrip("#").strip())
        i -= 1
    if block and block[0].startswith("--"):  # a section rule, not about this constant
        return ""
    return " ".join(block)


def _doc(doc: str | None) -> list[str]:
    if not doc:
        return ["*No docstring.*"]
    return _ROLE.sub(r"``\1``", doc).splitlines()


def _indent(lines: list[str]) -> list[str]:
    return [f"  {line}" if line else "" for line in lines]


def _anchor(module: str) -> str:
    """GitHub's heading anchor for ``## `module` ``."""
    return re.sub(r"[^a-z0-9_ -]", "", module.lower()).replace(" ", "-")


def _shown(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))  # run as a script from anywhere
    sys.exit(main())
