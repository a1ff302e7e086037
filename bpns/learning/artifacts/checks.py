"""Checks on an untrusted skills directory, made before anything in it is trusted.

A skills directory may be hand-edited, damaged or hostile. Files are opened only when
they are regular files inside the directory (no ``..``, absolute paths or symlinks out
of it; a FIFO is refused without blocking), read with a size cap, and ``skills.json``
is refused if nested deeper than any valid index before it is parsed. Its schema is
checked field by field. ``.npz`` members are inspected from their zip and ``.npy``
headers (name, dtype, declared shape) before any is decompressed, and only expected
keys are loaded. Loaded networks are checked against their declared scope dimensions
and for finiteness. Every check raises ``ValueError`` naming the problem; the loader
turns it into ``ArtifactError``.
"""

from __future__ import annotations

import dataclasses
import errno
import io
import json
import math
import os
import re
import stat
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bpns.nets.layers import check_layers

MAX_INDEX_BYTES = 1 << 22
MAX_INDEX_DEPTH = 8  # a valid index nests 5 deep (skills/entry/atoms/atom/args)
MAX_NPZ_BYTES = 1 << 28
MAX_ARRAY_BYTES = 1 << 26
MAX_LAYERS = 64

_NET_KEY = r"(input_mean|input_std|output_mean|output_std|input_low|input_high|[wb]\d{1,2})"
_DIMS_KEY = r"dims/(size|state_dims|subgoal_dims|num_objects|objects|angles)"
_BASE_KEY = r"linear/([wb]0|input_low|input_high)"
POLICY_KEYS = re.compile(rf"{_DIMS_KEY}|net/{_NET_KEY}|{_BASE_KEY}|use_subgoals|near_scale")
SAMPLER_KEYS = re.compile(
    rf"{_DIMS_KEY}|(generator|classifier)/{_NET_KEY}|{_BASE_KEY}|max_tries|novelty/(dims|low|high)|noise/chol"
)
INTEGER_KEYS = re.compile(rf"{_DIMS_KEY}|max_tries|use_subgoals|novelty/dims")


# ------------------------------------------------------------------------------ files


def confined_file(directory: Path, name: Any) -> Path:
    """``directory / name`` if ``name`` is a plain file name whose real path stays
    inside ``directory``; ValueError otherwise."""
    if not isinstance(name, str) or not name or "\x00" in name:
        raise ValueError(f"file name {name!r} is not a non-empty string")
    if os.path.isabs(name) or any(part in ("", ".", "..") for part in re.split(r"[/\\]", name)):
        raise ValueError(f"file name {name!r} leaves the skills directory")
    root = directory.resolve()
    path = (directory / name).resolve()
    if path.parent != root:
        raise ValueError(f"file {name!r} resolves to {path}, outside {root}")
    return path


def read_regular_file(path: Path, max_bytes: int) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``max_bytes``; opened
    non-blocking, so a FIFO or device is refused instead of hanging."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise ValueError(f"{path.name}: cannot be opened ({os.strerror(err.errno)})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ValueError(f"{path.name}: not a regular file")
        if info.st_size > max_bytes:
            raise ValueError(f"{path.name}: {info.st_size} bytes, over the limit of {max_bytes}")
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > max_bytes:  # grew while being read
                raise ValueError(f"{path.name}: over the limit of {max_bytes} bytes")
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as err:
        if err.errno == errno.EAGAIN:
            raise ValueError(f"{path.name}: not readable without blocking") from None
        raise
    finally:
        os.close(fd)


# ------------------------------------------------------------------------------ index


def nesting_depth(text: str) -> int:
    """Deepest bracket nesting of JSON ``text``, ignoring brackets inside strings."""
    stripped = re.sub(r'"(?:[^"\\]|\\.)*"', '""', text)
    depth = deepest = 0
    for bracket in re.findall(r"[\[\]{}]", stripped):
        depth += 1 if bracket in "[{" else -1
        deepest = max(deepest, depth)
    return deepest


def parse_index(data: bytes) -> Any:
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError("not UTF-8 text") from None
    if nesting_depth(text) > MAX_INDEX_DEPTH:
        raise ValueError(f"nested deeper than {MAX_INDEX_DEPTH} levels")
    try:
        return json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as err:
        raise ValueError(f"not valid JSON ({err})") from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"not strict JSON ({name})")


def _short(x: Any) -> str:
    text = repr(x)
    return text if len(text) <= 80 else text[:77] + "..."


def _is_int(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _is_number(x: Any) -> bool:
    return (_is_int(x) or isinstance(x, float)) and math.isfinite(x)


def _is_str_list(x: Any) -> bool:
    return isinstance(x, list) and all(isinstance(s, str) for s in x)


def _require(ok: bool, what: str) -> None:
    if not ok:
        raise ValueError(what)


def _atoms_ok(x: Any) -> bool:
    return isinstance(x, list) and all(
        isinstance(a, list) and len(a) == 2 and isinstance(a[0], str) and _is_str_list(a[1])
        for a in x
    )


# The keys ``save_skills`` writes: a hand-edited index with one missing or one more is
# refused (an unknown key would be silently ignored, a typo'd one silently defaulted).
INDEX_KEYS = frozenset(
    {"format", "version", "env", "types", "predicates", "config", "stats", "skills"}
)
_SKILL_KEYS = frozenset(
    {"name", "parameters", "preconditions", "add_effects", "delete_effects", "horizon"}
)
LEARNED_SKILL_KEYS = _SKILL_KEYS | {"policy", "sampler"}
GIVEN_SKILL_KEYS = _SKILL_KEYS | {"policy", "sampler", "given", "binding"}
OPTIONAL_SKILL_KEYS = frozenset({"order_key"})  # absent in directories of Op<k>-named skills


def check_keys(
    entry: Mapping[str, Any], required: frozenset[str], optional: frozenset[str], where: str
) -> None:
    """ValueError naming the first key ``entry`` lacks, or the first it has beyond
    ``required`` and ``optional``."""
    missing = sorted(required - entry.keys())
    if missing:
        raise ValueError(f"{where} lacks the key {missing[0]!r}")
    unknown = sorted(entry.keys() - required - optional)
    if unknown:
        raise ValueError(f"{where} has the unknown key {unknown[0]!r}")


def check_index_schema(index: Mapping[str, Any]) -> None:
    """Types of every field of a (format-checked) skills index; ValueError naming the
    first wrong one."""
    check_keys(index, INDEX_KEYS, frozenset(), "the index")
    _require(index.get("env") is None or isinstance(index["env"], str), "'env' is not a string")
    for key, inner in (("types", "features"), ("predicates", "types")):
        entries = index.get(key)
        _require(isinstance(entries, list), f"{key!r} is not a list")
        for e in entries:
            _require(
                isinstance(e, dict)
                and isinstance(e.get("name"), str)
                and _is_str_list(e.get(inner)),
                f"{key!r} entry {_short(e)} is not {{'name': str, {inner!r}: [str]}}",
            )
    _require(isinstance(index.get("config"), dict), "'config' is not an object")
    _require(index.get("stats") is None or isinstance(index["stats"], dict), "bad 'stats'")
    skills = index.get("skills")
    _require(isinstance(skills, list), "'skills' is not a list")
    names = []
    for e in skills:
        _require(isinstance(e, dict) and isinstance(e.get("name"), str), f"bad skill {_short(e)}")
        name = e["name"]
        names.append(name)
        required = GIVEN_SKILL_KEYS if e.get("given") is not None else LEARNED_SKILL_KEYS
        check_keys(e, required, OPTIONAL_SKILL_KEYS, f"skill {name}")
        params = e.get("parameters")
        _require(
            isinstance(params, list)
            and all(isinstance(p, list) and len(p) == 2 and _is_str_list(p) for p in params),
            f"skill {name}: 'parameters' is not a list of [name, type]",
        )
        _require(len({p[0] for p in params}) == len(params), f"skill {name}: repeated parameter")
        for key in ("preconditions", "add_effects", "delete_effects"):
            _require(_atoms_ok(e.get(key)), f"skill {name}: {key!r} is not a list of atoms")
            for _, args in e[key]:
                _require(
                    all(a in {p[0] for p in params} for a in args),
                    f"skill {name}: {key!r} names an unknown parameter",
                )
        if e.get("given") is not None:  # an environment's given skill: no weights
            _require(isinstance(e["given"], str), f"skill {name}: 'given' is not a name")
            binding = e.get("binding")
            _require(
                isinstance(binding, list)
                and all(_is_int(i) and 0 <= i < len(params) for i in binding)
                and len(set(binding)) == len(binding),
                f"skill {name}: 'binding' does not name distinct parameters of the skill",
            )
            _require(
                e.get("policy") is None and e.get("sampler") is None,
                f"skill {name}: a given skill has no weight files",
            )
        else:
            _require(isinstance(e.get("policy"), str), f"skill {name}: 'policy' is not a file name")
            _require(
                "sampler" in e and (e["sampler"] is None or isinstance(e["sampler"], str)),
                f"skill {name}: 'sampler' is not a file name or null",
            )
        horizon = e.get("horizon")
        _require(
            horizon is None or (_is_int(horizon) and horizon >= 1),
            f"skill {name}: horizon must be an integer >= 1 or null, got {horizon!r}",
        )
    duplicates = sorted({n for n in names if names.count(n) > 1})
    _require(not duplicates, f"two skills share the operator name {duplicates}")


def check_json_fields(
    values: Mapping[str, Any], cls: type, where: str, complete: bool = True
) -> None:
    """Each value whose key is a field of dataclass ``cls`` has a JSON type its
    annotation admits (int, float, bool, tuple of int, optional ones, or an object),
    and no key is another (a setting mistyped by hand would be ignored). With
    ``complete`` every field must be there (one removed by hand would be silently
    defaulted); without, a field may be missing (a format version saved before it
    existed)."""
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(values.keys() - fields)
    if unknown:
        raise ValueError(f"{where} has the unknown key {unknown[0]!r}")
    missing = sorted(fields - values.keys())
    if complete and missing:
        raise ValueError(f"{where} lacks the key {missing[0]!r}")
    for f in dataclasses.fields(cls):
        if f.name not in values:
            continue
        v, ann = values[f.name], str(f.type)
        optional = ann.endswith("| None")
        base = ann.replace("| None", "").strip()
        if v is None:
            _require(optional, f"{where}.{f.name} may not be null")
        elif base == "int":
            _require(_is_int(v), f"{where}.{f.name} is not an integer")
        elif base == "float":
            _require(_is_number(v), f"{where}.{f.name} is not a finite number")
        elif base == "bool":
            _require(isinstance(v, bool), f"{where}.{f.name} is not a boolean")
        elif base.startswith("tuple[int"):
            _require(isinstance(v, list) and all(_is_int(x) for x in v), f"{where}.{f.name}")
        elif base.startswith("tuple[") or base == "str":
            pass  # checked where they are used
        else:
            _require(isinstance(v, dict), f"{where}.{f.name} is not an object")


# -------------------------------------------------------------------------------- npz


def read_npz(path: Path, allowed: re.Pattern[str]) -> dict[str, np.ndarray]:
    """The arrays of a regular ``.npz`` file inside the size limits, keys matching
    ``allowed``, each checked from its headers before it is decompressed."""
    raw = read_regular_file(path, MAX_NPZ_BYTES)
    if not raw:
        raise ValueError(f"{path.name}: empty file")
    out: dict[str, np.ndarray] = {}
    with zipfile.ZipFile(io.BytesIO(raw)) as archive:
        for info in archive.infolist():
            key = info.filename[:-4] if info.filename.endswith(".npy") else None
            if key is None or not allowed.fullmatch(key):
                raise ValueError(f"{path.name}: unexpected member {info.filename!r}")
            if key in out:
                raise ValueError(f"{path.name}: member {info.filename!r} appears twice")
            if info.file_size > MAX_ARRAY_BYTES:
                raise ValueError(
                    f"{path.name}: {key!r} declares {info.file_size} bytes, over the limit"
                )
            with archive.open(info) as member:
                out[key] = _read_npy(member, f"{path.name}: {key!r}")
            if INTEGER_KEYS.fullmatch(key) and out[key].dtype.kind not in "biu":
                raise ValueError(f"{path.name}: {key!r} must hold integers, not {out[key].dtype}")
            rank = _rank(key)
            if out[key].ndim != rank:
                raise ValueError(
                    f"{path.name}: {key!r} has shape {out[key].shape}, expected {rank} dimensions"
                )
    return out


def _rank(key: str) -> int:
    """How many dimensions the array saved under ``key`` has."""
    last = key.rsplit("/", 1)[-1]
    if re.fullmatch(r"w\d+", last) or last == "chol":
        return 2
    if last in ("size", "num_objects", "max_tries", "use_subgoals", "near_scale"):
        return 0
    return 1


def _read_npy(member: Any, where: str) -> np.ndarray:
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
    else:
        raise ValueError(f"{where}: unsupported .npy version {version}")
    if dtype.hasobject or dtype.kind not in "biuf" or dtype.fields is not None:
        raise ValueError(f"{where}: dtype {dtype} is not plain numbers")
    if len(shape) > 2 or math.prod(shape) * dtype.itemsize > MAX_ARRAY_BYTES:
        raise ValueError(f"{where}: declared shape {shape} is beyond the limits")
    count = math.prod(shape)
    data = member.read(count * dtype.itemsize)
    if len(data) != count * dtype.itemsize:
        raise ValueError(f"{where}: truncated")
    array = np.frombuffer(data, dtype=dtype, count=count)
    return array.reshape(shape, order="F" if fortran else "C").copy()


# ----------------------------------------------------------------------- loaded skills


def check_scope_dims(dims: Any, scope_size: int, where: str) -> None:
    """A :class:`ScopeDims` against the size its operator's scope objects give."""
    _require(dims.size == scope_size, f"{where}: scope size {dims.size}, operator's {scope_size}")
    for name in ("state_dims", "subgoal_dims", "angles"):
        d = np.asarray(getattr(dims, name))
        _require(
            d.ndim == 1 and np.all((d >= 0) & (d < scope_size)) and len(np.unique(d)) == len(d),
            f"{where}: {name} {d.tolist()} out of range for a scope of {scope_size}",
        )


def check_network(
    params: Any, input_dim: int, raw_output_dim: Callable[[int], bool], where: str
) -> None:
    """An :class:`MLPParams`: chained layer shapes, input/output statistics of matching
    length, positive input std, an ordered input box and finite numbers throughout."""
    ws, bs = params.weights, params.biases
    _require(0 < len(ws) <= MAX_LAYERS, f"{where}: {len(ws)} layers")
    width = check_layers(params.layers, input_dim, where)
    _require(raw_output_dim(width), f"{where}: {width} outputs do not fit the network's role")
    for name in ("input_mean", "input_std", "input_low", "input_high"):
        a = getattr(params, name)
        _require(a is None or a.shape == (input_dim,), f"{where}: {name} has the wrong shape")
    _require(bool(np.all(params.input_std > 0)), f"{where}: input_std must be positive")
    n_out = params.output_mean.shape
    _require(n_out == params.output_std.shape and len(n_out) == 1, f"{where}: output stats shapes")
    arrays = [*ws, *bs, params.input_mean, params.input_std, params.output_mean, params.output_std]
    arrays += [a for a in (params.input_low, params.input_high) if a is not None]
    _require(all(np.all(np.isfinite(a)) for a in arrays), f"{where}: weights hold NaN or inf")
    with np.errstate(all="ignore"):  # inference folds the statistics into the weights
        inv_std = 1.0 / params.input_std
        folded = [ws[0] * inv_std[:, None], (params.input_mean * inv_std) @ ws[0]]
        if params.output_std.shape == (ws[-1].shape[1],):
            folded += [ws[-1] * params.output_std, bs[-1] * params.output_std]
    _require(all(np.all(np.isfinite(a)) for a in folded), f"{where}: weights overflow at inference")
    if params.input_low is not None:
        _require(bool(np.all(params.input_low <= params.input_high)), f"{where}: input box")


def check_skill_arrays(policy: Any, sampler: Any, scope_size: int, name: str) -> None:
    """A loaded policy and (learned) sampler against the operator's scope size."""
    dims = policy.dims
    check_scope_dims(dims, scope_size, f"{name} policy")
    ns, ng = dims.input_width, len(dims.subgoal_dims)
    if policy.near_scale is not None:
        _require(0 < policy.near_scale < math.inf, f"{name} policy: near_scale")
    n_in = ns + (ng * (2 if policy.near_scale is not None else 1) if policy.use_subgoals else 0)
    check_network(policy.params, n_in, lambda n: n >= 1, f"{name} policy")
    _require(
        policy.params.output_mean.shape == (policy.params.raw_output_dim,),
        f"{name} policy: output stats shape",
    )
    _check_base(getattr(policy, "base", None), n_in, policy.params.raw_output_dim, f"{name} policy")
    if sampler is None:
        return
    sdims = sampler.dims
    check_scope_dims(sdims, scope_size, f"{name} sampler")
    ns, ng = sdims.input_width, len(sdims.subgoal_dims)
    _require(1 <= sampler.max_tries <= 1_000_000, f"{name} sampler: max_tries")
    check_network(sampler.generator_params, ns, lambda n: n == 2 * ng, f"{name} generator")
    _require(sampler.generator_params.output_mean.shape == (ng,), f"{name} generator: output stats")
    if sampler.classifier_params is not None:
        check_network(sampler.classifier_params, ns + ng, lambda n: n == 1, f"{name} classifier")
    _check_base(getattr(sampler, "base", None), ns, ng, f"{name} sampler")
    _check_novelty(sampler.novelty, ns, f"{name} sampler")


def _check_novelty(novelty: Any, ns: int, where: str) -> None:
    """A loaded :class:`bpns.learning.samplers.Novelty` (or None) against the state dims."""
    if novelty is None:
        return
    d = novelty.dims
    ok = d.ndim == 1 and bool(np.all((d >= 0) & (d < ns))) and len(np.unique(d)) == len(d)
    _require(ok, f"{where}: novelty dims {d.tolist()} out of range for {ns} state dims")
    shapes = novelty.low.shape == d.shape == novelty.high.shape
    _require(shapes, f"{where}: novelty bounds need one value per dim ({d.size})")
    finite = np.isfinite(novelty.low).all() and np.isfinite(novelty.high).all()
    _require(bool(finite) and bool(np.all(novelty.low <= novelty.high)), f"{where}: novelty bounds")


def _check_base(base: Any, n_in: int, n_out: int, where: str) -> None:
    """A loaded :class:`bpns.nets.linear.LinearBase` (or None) against its network."""
    if base is None:
        return
    _require(
        base.weight.shape == (n_in, n_out)
        and base.bias.shape == (n_out,)
        and base.low.shape == base.high.shape == (n_in,),
        f"{where}: linear base of shape {base.weight.shape}, {base.bias.shape}; "
        f"expected ({n_in}, {n_out}), ({n_out},)",
    )
    _require(
        all(bool(np.isfinite(a).all()) for a in (base.weight, base.bias))
        and not np.isnan(base.low).any()
        and not np.isnan(base.high).any()
        and bool(np.all(base.low <= base.high)),
        f"{where}: linear base is not finite or its input box is empty",
    )
