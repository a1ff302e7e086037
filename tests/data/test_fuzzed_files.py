"""Property-based fuzzing of demo files and skills directories (hypothesis).

Start from a small valid file or directory, apply a few random mutations (attributes,
datasets, shapes, dtypes, values, names, index fields, .npz members, raw bytes), load:
the result must be finite data or the library's own error (DatasetError /
ArtifactError), never another exception, a hang or a NaN.

CI runs 200 derandomized examples per target. For a longer random run:

    HYPOTHESIS_PROFILE=long .venv/bin/python -m pytest -q tests/data/test_fuzzed_files.py

(``long``: 3000 examples each; ``HYPOTHESIS_MAX_EXAMPLES=N`` overrides the count.)
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
import tempfile
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from bpns.data.datasets import DatasetError, load_demonstrations
from bpns.learning.artifacts.skills_dir import ArtifactError, load_skills, save_skills
from bpns.learning.policies import LearnedPolicy
from bpns.learning.samplers import LearnedSampler
from tests import toy_learning as toy

settings.register_profile(
    "ci",
    max_examples=200,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
settings.register_profile(
    "long",
    max_examples=3000,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
PROFILE = settings.get_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
if "HYPOTHESIS_MAX_EXAMPLES" in os.environ:
    PROFILE = settings(PROFILE, max_examples=int(os.environ["HYPOTHESIS_MAX_EXAMPLES"]))
HANG_SECONDS = 60


class Hang(Exception):
    pass


@contextlib.contextmanager
def no_hang():
    """Fail an example that takes longer than HANG_SECONDS (a FIFO read, a huge loop)."""

    def alarm(signum, frame):
        raise Hang(f"loading took over {HANG_SECONDS} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(HANG_SECONDS)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


# ------------------------------------------------------------------------ values

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=12),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=12,
)

dtypes = st.sampled_from(
    [np.float64, np.float32, np.float16, np.int64, np.int8, np.uint8, np.bool_, np.complex64]
)
special_floats = st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -1e308, 0.0, 2.0**63])


@st.composite
def arrays(draw, max_dims=3):
    dtype = draw(dtypes)
    shape = draw(hnp.array_shapes(min_dims=0, max_dims=max_dims, min_side=0, max_side=6))
    return draw(hnp.arrays(dtype, shape, elements=None))


attr_values = (
    st.integers(-(2**63), 2**63 - 1)
    | st.floats()
    | st.text(max_size=40)
    | st.binary(max_size=20)
    | json_values.map(json.dumps)
    | arrays(max_dims=1)
)


# --------------------------------------------------------------------- demo files


def _datasets(f: h5py.File) -> list[str]:
    out: list[str] = []
    f.visititems(lambda name, obj: out.append(name) if isinstance(obj, h5py.Dataset) else None)
    return out


@st.composite
def h5_mutation(draw):
    kind = draw(
        st.sampled_from(
            ["attr", "attr", "dataset", "dataset", "value", "rename", "delete", "add", "world"]
        )
    )
    return kind, draw(st.integers(0, 10**6)), draw(attr_values), draw(arrays())


def _apply_h5(f: h5py.File, mutation) -> None:
    kind, pick, attr_value, array = mutation
    groups = ["/", "data", "data/demo_0", "data/demo_1"]
    names = _datasets(f)
    if kind == "attr":
        where = groups[pick % len(groups)]
        keys = ["env", "format", "num_demos", "world", "goal", "objects", "horizon", "x"]
        if where in f:
            with contextlib.suppress(ValueError, TypeError):  # h5py refuses e.g. NUL in text
                f[where].attrs[keys[pick // 7 % len(keys)]] = attr_value
    elif kind == "dataset" and names:
        name = names[pick % len(names)]
        del f[name]
        f[name] = array
    elif kind == "value" and names:
        name = names[pick % len(names)]
        data = np.array(f[name])
        if data.dtype.kind in "biu":
            data = data.astype(np.float64)
        if data.size and data.dtype.kind in "fc":
            flat = data.reshape(-1)
            flat[pick % flat.size] = [np.nan, np.inf, -np.inf, 1e300][pick % 4]
            del f[name]
            f[name] = flat.reshape(data.shape)
    elif kind == "rename" and "data/demo_1" in f:
        new = ["demo_x", "demo_-1", "demo_01", "demo_7", "Demo_1", "demo_1_"][pick % 6]
        f["data"].move("demo_1", new)
    elif kind == "delete":
        victims = names + ["data/demo_0/features", "data/demo_1", "data"]
        victim = victims[pick % len(victims)]
        if victim in f:
            del f[victim]
    elif kind == "add" and "data" in f and isinstance(f["data"], h5py.Group):
        target = ["data", "data/demo_0", "data/demo_0/features"][pick % 3]
        if target in f and isinstance(f[target], h5py.Group):
            name = ["demo_9", "extra", "robot", "states"][pick % 4]
            if name not in f[target]:
                f[target][name] = array
    elif kind == "world" and "data/demo_0" in f and "world" in f["data/demo_0"].attrs:
        g = f["data/demo_0"]
        xml = str(g.attrs["world"])
        cut = pick % max(1, len(xml))
        edits = [
            xml[:cut],
            xml.replace("<worldbody>", '<include file="/etc/hostname"/><worldbody>', 1),
            xml.replace("<asset>", '<asset><texture name="t" file="/etc/hostname"/>', 1),
            xml[:cut] + "<" + xml[cut:],
        ]
        g.attrs["world"] = edits[pick % len(edits)]


def _check_demos_finite(demos) -> None:
    for demo in demos:
        assert np.all(np.isfinite(demo.actions))
        for s in demo.states:
            assert np.all(np.isfinite(s.sim.flat))
            assert all(np.all(np.isfinite(v)) for v in s.data.values())


@PROFILE
@given(mutations=st.lists(h5_mutation(), min_size=1, max_size=3))
def test_fuzzed_demo_files_load_finite_or_raise_dataset_error(
    cover_demo_file, cover_env, mutations
):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "demos.h5"
        shutil.copy(cover_demo_file, path)
        with h5py.File(path, "a") as f:
            for m in mutations:
                _apply_h5(f, m)
        with no_hang():
            try:
                demos = load_demonstrations(path, cover_env)
            except DatasetError:
                event("refused with DatasetError")
                return
        event("loaded")
        _check_demos_finite(demos)


# --------------------------------------------------------------- skills directories


@pytest.fixture(scope="module")
def toy_skills_dir(tmp_path_factory):
    return save_skills(toy.learned_toy_skills(), tmp_path_factory.mktemp("fuzz") / "skills")


def _leaves(value, path=()):
    yield path
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _leaves(v, (*path, i))


def _set_at(root, path, value):
    if not path:
        return value
    node = root
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return root


_DELETE = object()


@st.composite
def skills_mutation(draw):
    kind = draw(st.sampled_from(["index", "index", "npz", "npz", "npz_add", "bytes"]))
    return (
        kind,
        draw(st.integers(0, 10**6)),
        draw(json_values | st.just(_DELETE)),
        draw(arrays() | special_floats),
        draw(st.binary(max_size=64)),
    )


def _apply_skills(directory: Path, mutation) -> None:
    kind, pick, json_value, array, raw = mutation
    files = sorted(p.name for p in directory.iterdir())
    if kind == "index":
        index_path = directory / "skills.json"
        try:
            index = json.loads(index_path.read_text())
        except (ValueError, OSError):
            return
        paths = list(_leaves(index))
        path = paths[pick % len(paths)]
        if not path and json_value is _DELETE:
            return
        index = _set_at(index, path, json_value)
        index_path.write_text(json.dumps(index))
    elif kind in ("npz", "npz_add"):
        npzs = [f for f in files if f.endswith(".npz")]
        if not npzs:
            return
        target = directory / npzs[pick % len(npzs)]
        try:
            with np.load(target) as data:
                arrays_ = {k: data[k] for k in data.files}
        except (ValueError, OSError, zipfile.BadZipFile, EOFError):
            return
        keys = sorted(arrays_)
        key = keys[pick % len(keys)] if keys else "x"
        if kind == "npz_add":
            key = ["extra", "net/w7", "dims/size", "classifier/w0"][pick % 4]
        if isinstance(array, float):  # poke one value
            if key in arrays_ and arrays_[key].size:
                a = arrays_[key].astype(np.float64)
                a.reshape(-1)[pick % a.size] = array
                arrays_[key] = a
        elif pick % 5 == 0:
            arrays_.pop(key, None)
        else:
            arrays_[key] = array
        buffer = io.BytesIO()
        np.savez(buffer, **arrays_)
        target.write_bytes(buffer.getvalue())
    elif kind == "bytes":
        target = directory / files[pick % len(files)]
        data = target.read_bytes()
        cut = pick % (len(data) + 1)
        target.write_bytes([data[:cut], data[:cut] + raw + data[cut + len(raw) :], raw][pick % 3])


def _check_skills_finite(skills) -> None:
    for skill in skills.skills:
        assert skill.horizon is None or skill.horizon >= 1
        nets = []
        if isinstance(skill.policy, LearnedPolicy):
            nets.append(skill.policy.params)
        if isinstance(skill.sampler, LearnedSampler):
            nets.append(skill.sampler.generator_params)
            if skill.sampler.classifier_params is not None:
                nets.append(skill.sampler.classifier_params)
        for params in nets:
            for key, a in params.to_arrays().items():
                assert np.all(np.isfinite(a)), key


@PROFILE
@given(mutations=st.lists(skills_mutation(), min_size=1, max_size=3))
def test_fuzzed_skills_directories_load_finite_or_raise_artifact_error(toy_skills_dir, mutations):
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp) / "skills"
        shutil.copytree(toy_skills_dir, directory)
        for m in mutations:
            _apply_skills(directory, m)
        with no_hang():
            try:
                skills = load_skills(directory, toy.PREDICATES, toy.TYPES)
            except ArtifactError:
                event("refused with ArtifactError")
                return
        event("loaded")
        _check_skills_finite(skills)
