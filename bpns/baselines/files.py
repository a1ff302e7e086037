"""Save and load the GNN baselines' models as single ``.npz`` files.

A model file holds its weights and, under the key ``meta.json``, a JSON text: format,
version, kind (``gnn-meta`` or ``gnn-bc``), the graph vocabulary by name, and for the
metacontroller the operators it scores (name and parameter types), plus the training
config and statistics for people. Files are written atomically and read with
``allow_pickle=False``. Loading binds names to the environment's types and predicates
(and to the given skills' operators) and checks every array: a damaged file, a missing
key, a wrong shape or a non-finite weight is one :class:`ArtifactError` naming the file.

Conventional places inside a skills directory: ``gnn_meta.npz``, ``gnn_bc.npz``.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bpns.atomic import atomic_path
from bpns.baselines.gnn import GNNParams
from bpns.baselines.gnn_bc import GNNPolicy
from bpns.baselines.gnn_meta import GNNMetacontroller
from bpns.baselines.graphs import GraphVocabulary
from bpns.learning.artifacts.skills_dir import ArtifactError
from bpns.structs import Predicate, STRIPSOperator, Type

FORMAT = "bpns-gnn"
VERSION = 1
META_KEY = "meta.json"
KIND_META = "gnn-meta"
KIND_BC = "gnn-bc"
META_FILE = "gnn_meta.npz"
BC_FILE = "gnn_bc.npz"


def _save(path: str | os.PathLike, kind: str, info: Mapping[str, Any], params: GNNParams) -> Path:
    header = {"format": FORMAT, "version": VERSION, "kind": kind, **info}
    arrays = {**params.to_arrays(), META_KEY: np.array(json.dumps(header))}
    target = Path(path)
    with atomic_path(target, ".npz") as tmp:
        with open(tmp, "wb") as f:  # a file object: np.savez must not append ".npz"
            np.savez(f, **arrays)
    return target


def save_metacontroller(
    meta: GNNMetacontroller, path: str | os.PathLike, extra: Mapping[str, Any] | None = None
) -> Path:
    """Write ``meta`` to ``path`` atomically; ``extra`` (JSON-able) is kept for people."""
    return _save(path, KIND_META, {**meta.to_json(), "info": dict(extra or {})}, meta.params)


def save_bc_policy(
    policy: GNNPolicy, path: str | os.PathLike, extra: Mapping[str, Any] | None = None
) -> Path:
    return _save(path, KIND_BC, {**policy.to_json(), "info": dict(extra or {})}, policy.params)


def _read(path: str | os.PathLike, kind: str) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    p = Path(path)
    if not p.is_file():
        raise ArtifactError(f"{p}: no such model file")
    try:
        with np.load(p, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        header = json.loads(str(arrays.pop(META_KEY)))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as err:
        raise ArtifactError(f"{p}: damaged model file ({type(err).__name__}: {err})") from None
    if (
        not isinstance(header, dict)
        or header.get("format") != FORMAT
        or header.get("version") != VERSION
        or header.get("kind") != kind
    ):
        got = (
            {k: header.get(k) for k in ("format", "version", "kind")}
            if isinstance(header, dict)
            else header
        )
        raise ArtifactError(
            f"{p}: not a {kind} model (got {got}; expected format {FORMAT!r} version "
            f"{VERSION} kind {kind!r})"
        )
    return header, arrays


def _params(p: Path, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray], types, preds):
    try:
        vocab = GraphVocabulary.from_json(header["vocabulary"], types, preds)
        params = GNNParams.from_arrays(arrays)
        params.check(vocab)
    except ArtifactError:
        raise
    except (KeyError, TypeError, ValueError, IndexError) as err:
        raise ArtifactError(f"{p}: damaged model file ({type(err).__name__}: {err})") from None
    return vocab, params


def load_metacontroller(
    path: str | os.PathLike,
    operators: Sequence[STRIPSOperator],
    predicates: Iterable[Predicate],
    types: Iterable[Type],
) -> GNNMetacontroller:
    """Load a metacontroller saved by :func:`save_metacontroller`, binding its operators
    by name to ``operators`` (e.g. the skills directory's) with the same parameter types."""
    p = Path(path)
    header, arrays = _read(p, KIND_META)
    vocab, params = _params(p, header, arrays, types, predicates)
    by_name = {op.name: op for op in operators}
    bound = []
    try:
        for entry in header["operators"]:
            op = by_name.get(entry["name"])
            if op is None or [v.type.name for v in op.parameters] != list(entry["parameters"]):
                raise ArtifactError(
                    f"{p}: the metacontroller scores operator {entry['name']}"
                    f"{tuple(entry['parameters'])}, which the given skills do not have "
                    f"(they have {sorted(by_name)})"
                )
            bound.append(op)
        return GNNMetacontroller(vocab, bound, params)
    except ArtifactError:
        raise
    except (KeyError, TypeError, ValueError) as err:
        raise ArtifactError(f"{p}: damaged model file ({type(err).__name__}: {err})") from None


def load_bc_policy(
    path: str | os.PathLike, predicates: Iterable[Predicate], types: Iterable[Type]
) -> GNNPolicy:
    p = Path(path)
    header, arrays = _read(p, KIND_BC)
    vocab, params = _params(p, header, arrays, types, predicates)
    if header.get("action_dim") != params.global_out_dim:
        raise ArtifactError(
            f"{p}: header says action_dim {header.get('action_dim')}, the network outputs "
            f"{params.global_out_dim}"
        )
    return GNNPolicy(vocab, params)


def saved_info(path: str | os.PathLike, kind: str) -> dict[str, Any]:
    """The ``info`` a model was saved with (training config and statistics)."""
    header, _ = _read(path, kind)
    return dict(header.get("info") or {})
