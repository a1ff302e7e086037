"""Checks on untrusted HDF5 demonstration content, made before anything is trusted.

A demo file may be hand-edited, damaged or hostile. Everything read from it is checked
here: member names and link kinds (no external or soft links, no external or virtual
datasets, which would read other files), attribute types, dataset ranks, dtypes and
column counts, a size limit checked on the *declared* shape before a single byte is
read, and finiteness. Each check raises ``ValueError`` with a message naming what is
wrong; :mod:`bpns.data.datasets` adds the file and demo and turns it into ``DatasetError``.
"""

from __future__ import annotations

import json
import re
from typing import Any

import h5py
import numpy as np

# Far above any demonstration (1000 steps x 200 flat-state numbers is 1.6 MB), far below
# what would exhaust memory.
MAX_ARRAY_BYTES = 1 << 28
MAX_ROWS = 1_000_000
MAX_JSON_CHARS = 1 << 20
DEMO_NAME = re.compile(r"demo_(0|[1-9][0-9]{0,17})")


def demo_index(name: str) -> int:
    """The index of a ``demo_<int>`` group name; ValueError for any other name."""
    match = DEMO_NAME.fullmatch(name)
    if match is None:
        raise ValueError(f"group /data/{name!r} is not named demo_<int>")
    return int(match.group(1))


def demo_names(data: h5py.Group) -> list[str]:
    """Names of the demo groups under ``/data`` in index order; every member must be a
    group (a hard link, not a link into another file) named ``demo_<int>``."""
    names = list(data)
    for name in names:
        demo_index(name)
        link = data.get(name, getlink=True)
        if not isinstance(link, h5py.HardLink):
            raise ValueError(f"/data/{name} is a {type(link).__name__}, not a stored group")
        # the object's header only (opening ~10^3 groups as h5py objects costs ~0.1 s)
        if h5py.h5o.get_info(data.id, name.encode()).type != h5py.h5o.TYPE_GROUP:
            raise ValueError(f"/data/{name} is not a group")
    return sorted(names, key=demo_index)


def member(group: h5py.Group, name: str, kind: type) -> Any:
    """``group[name]`` if it is a hard-linked ``kind`` (h5py.Group or h5py.Dataset)."""
    link = group.get(name, getlink=True)  # one lookup: a demo has ~10 members
    if link is None:
        raise ValueError(f"{name!r} is missing")
    if not isinstance(link, h5py.HardLink):
        raise ValueError(f"{name!r} is a {type(link).__name__}, not stored in this file")
    obj = group[name]
    if not isinstance(obj, kind):
        raise ValueError(f"{name!r} is not an HDF5 {kind.__name__.lower()}")
    return obj


def read_matrix(group: h5py.Group, name: str, columns: int) -> np.ndarray:
    """A finite float64 (rows, ``columns``) array, refused on its declared shape and
    dtype before it is read if it could not be one or would be too large."""
    ds = member(group, name, h5py.Dataset)
    if ds.external or ds.is_virtual:
        raise ValueError(f"{name!r} refers to data outside this file")
    dtype, shape = ds.dtype, ds.shape  # h5py properties: each access asks the library
    if dtype.kind not in "fiu" or dtype.itemsize > 8:
        raise ValueError(f"{name!r} has dtype {dtype}, expected real numbers")
    if len(shape) != 2:
        raise ValueError(f"{name!r} has shape {shape}, expected (steps, {columns})")
    rows, cols = shape
    if cols != columns:
        raise ValueError(f"{name!r} has {cols} columns, the environment needs {columns}")
    if rows > MAX_ROWS or rows * cols * 8 > MAX_ARRAY_BYTES:
        raise ValueError(
            f"{name!r} declares shape {shape}: beyond the size limit of "
            f"{MAX_ROWS} rows and {MAX_ARRAY_BYTES} bytes"
        )
    out = np.asarray(ds[()], dtype=np.float64)
    bad = ~np.isfinite(out)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise ValueError(f"{name!r} holds NaN or inf (first at step {row})")
    return out


def text_attr(group: h5py.Group, name: str) -> str:
    """A scalar string attribute."""
    if name not in group.attrs:
        raise ValueError(f"attribute {name!r} is missing")
    value = group.attrs[name]
    if isinstance(value, bytes):
        try:
            value = value.decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"attribute {name!r} is not UTF-8 text") from None
    if not isinstance(value, str):
        raise ValueError(f"attribute {name!r} is not a string")
    return value


def int_attr(group: h5py.Group, name: str, low: int, high: int) -> int:
    """A scalar integer attribute in [low, high]."""
    if name not in group.attrs:
        raise ValueError(f"attribute {name!r} is missing")
    value = group.attrs[name]
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise ValueError(f"attribute {name!r} is not an integer")
    if not low <= int(value) <= high:
        raise ValueError(f"attribute {name!r} = {int(value)} is outside [{low}, {high}]")
    return int(value)


def json_attr(group: h5py.Group, name: str) -> Any:
    text = text_attr(group, name)
    if len(text) > MAX_JSON_CHARS:
        raise ValueError(f"attribute {name!r} is longer than {MAX_JSON_CHARS} characters")
    try:
        return json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        raise ValueError(f"attribute {name!r} is not valid JSON") from None


def parse_objects(value: Any) -> list[tuple[str, str]]:
    """The ``objects`` attribute: a list of distinct [name, type name] string pairs."""
    if not isinstance(value, list) or not all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(s, str) for s in p) for p in value
    ):
        raise ValueError("attribute 'objects' is not a list of [name, type] strings")
    names = [p[0] for p in value]
    if len(set(names)) != len(names):
        raise ValueError("attribute 'objects' names an object twice")
    return [(p[0], p[1]) for p in value]


def parse_goal(value: Any) -> list[tuple[str, list[str]]]:
    """The ``goal`` attribute: a list of [predicate name, [object names]]."""
    if not isinstance(value, list) or not all(
        isinstance(a, list)
        and len(a) == 2
        and isinstance(a[0], str)
        and isinstance(a[1], list)
        and all(isinstance(o, str) for o in a[1])
        for a in value
    ):
        raise ValueError("attribute 'goal' is not a list of [predicate, [objects]]")
    return [(a[0], list(a[1])) for a in value]


def root_text_attr(f: h5py.File, name: str) -> str | None:
    """A top-level string attribute, or None if it is absent or not a string."""
    try:
        return text_attr(f, name)
    except ValueError:
        return None
