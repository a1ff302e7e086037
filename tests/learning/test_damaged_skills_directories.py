"""Damaged, hostile or inconsistent skills directories give one ArtifactError."""

from __future__ import annotations

import io
import json
import os
import shutil
import zipfile

import numpy as np
import pytest

from bpns.learning.artifacts.skills_dir import ArtifactError, load_skills, save_skills
from tests import toy_learning as toy


@pytest.fixture(scope="module")
def saved_skills(tmp_path_factory):
    return save_skills(toy.learned_toy_skills(), tmp_path_factory.mktemp("skills") / "skills")


@pytest.fixture
def skills_copy(saved_skills, tmp_path):
    path = tmp_path / "skills"
    shutil.copytree(saved_skills, path)
    return path


def _edit_index(path, edit):
    index = json.loads((path / "skills.json").read_text())
    edit(index)
    (path / "skills.json").write_text(json.dumps(index))


def _edit_npz(path, edit, name="Holding.policy.npz"):
    with np.load(path / name) as data:
        arrays = {k: data[k] for k in data.files}
    edit(arrays)
    np.savez(path / name, **arrays)


def _set(key, value, name="Holding.policy.npz"):
    def mutate(path):
        _edit_npz(path, lambda a: a.__setitem__(key, value(a[key])), name)

    return mutate


def _index(edit):
    return lambda path: _edit_index(path, edit)


def _deep_nesting(path):
    (path / "skills.json").write_text("[" * 100_000 + "]" * 100_000)


def _fifo_weights(path):
    os.unlink(path / "Holding.policy.npz")
    os.mkfifo(path / "Holding.policy.npz")


def _empty_weights(path):
    (path / "Holding.policy.npz").write_bytes(b"")


def _symlink_escape(path):
    outside = path.parent / "outside.npz"
    shutil.copy(path / "Holding.policy.npz", outside)
    os.unlink(path / "Holding.policy.npz")
    os.symlink(outside, path / "Holding.policy.npz")


def _dotdot_path(path):
    shutil.copy(path / "Holding.policy.npz", path.parent / "elsewhere.npz")
    _edit_index(path, lambda i: i["skills"][0].__setitem__("policy", "../elsewhere.npz"))


def _absolute_path(path):
    absolute = str((path / "Holding.policy.npz").resolve())
    _edit_index(path, lambda i: i["skills"][0].__setitem__("policy", absolute))


def _huge_declared_member(path):
    """An allowed key whose .npy header declares a 4 GiB array (tiny on disk)."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (2**29,)}
    )
    with zipfile.ZipFile(path / "Holding.policy.npz", "a") as z:
        z.writestr("net/w9.npy", header.getvalue() + b"\0" * 64)


def _extra_member(path):
    with zipfile.ZipFile(path / "Holding.policy.npz", "a") as z:
        z.writestr("payload.npy", b"\x93NUMPY")


def _duplicate_operator(path):
    _edit_index(path, lambda i: i["skills"].append(dict(i["skills"][0])))


CASES = [
    (_deep_nesting, r"nested deeper than"),
    (_fifo_weights, r"not a regular file"),
    (_empty_weights, r"empty file"),
    (_symlink_escape, r"outside"),
    (_dotdot_path, r"leaves the skills directory"),
    (_absolute_path, r"leaves the skills directory"),
    (_huge_declared_member, r"declared shape \(536870912,\) is beyond the limits"),
    (_extra_member, r"unexpected member 'payload.npy'"),
    (_duplicate_operator, r"two skills share the operator name \['Holding'\]"),
    (_index(lambda i: i["skills"][0].__setitem__("horizon", 0)), r"horizon must be"),
    (_index(lambda i: i["skills"][0].__setitem__("horizon", "x")), r"horizon must be"),
    (_index(lambda i: i["types"][0].__setitem__("features", 3)), r"'types' entry"),
    (_index(lambda i: i["skills"][0].__setitem__("policy", 7)), r"'policy' is not a file"),
    (_index(lambda i: i["config"].__setitem__("seed", "zero")), r"config.seed"),
    (_index(lambda i: i["config"]["policy"].__setitem__("input_margin", "x")), r"input_margin"),
    (_index(lambda i: i.__setitem__("skills", {"a": 1})), r"'skills' is not a list"),
    (_set("net/w1", lambda w: w[:, :-1]), r"Holding.policy.npz: net: layer 1 has shapes"),
    # the first layer: numpy's broadcast error named no layer (probe of issue 41)
    (_set("net/w0", lambda w: w[:, :-1]), r"Holding.policy.npz: net: layer 0 has shapes"),
    (_set("net/w0", lambda w: w * np.nan), r"Holding policy: weights hold NaN or inf"),
    (
        _set("generator/b0", lambda b: b + np.inf, "Holding.sampler.npz"),
        r"Holding generator: weights",
    ),
    (_set("dims/state_dims", lambda d: d + 100), r"state_dims .* out of range"),
    (_set("dims/size", lambda s: s + 1), r"scope size"),
    (_set("net/input_std", lambda s: -s), r"input_std must be positive"),
    # edited by hand: a key missing or one more than save_skills writes, an array missing
    (_index(lambda i: i["skills"][0].pop("horizon")), r"skill Holding lacks the key 'horizon'"),
    (_index(lambda i: i["skills"][0].__setitem__("horizn", 5)), r"unknown key 'horizn'"),
    (_index(lambda i: i.__setitem__("note", "mine")), r"the index has the unknown key 'note'"),
    (_index(lambda i: i.pop("predicates")), r"the index lacks the key 'predicates'"),
    (_index(lambda i: i["config"].pop("settle_steps")), r"config lacks the key 'settle_steps'"),
    (
        _index(lambda i: i["config"]["policy"].pop("num_steps")),
        r"config network lacks the key 'num_steps'",
    ),
    (
        lambda path: shutil.copy(path / "Holding.policy.npz", path / "Bogus.policy.npz"),
        r"Bogus.policy.npz is the weights of no skill in skills.json",
    ),
    (
        _index(lambda i: i["config"].__setitem__("refuse_novel_start", False)),
        r"config has the unknown key 'refuse_novel_start'",
    ),
    (
        _index(lambda i: i["config"]["policy"].__setitem__("hiden_sizes", [8])),
        r"config network has the unknown key 'hiden_sizes'",
    ),
    (
        lambda path: _edit_npz(path, lambda a: a.pop("net/w2")),
        r"Holding.policy.npz lacks the array 'net/w2'",
    ),
]


@pytest.mark.parametrize("mutate, message", CASES, ids=[str(i) for i in range(len(CASES))])
def test_damaged_skills_directory_gives_one_artifact_error(skills_copy, mutate, message):
    mutate(skills_copy)
    with pytest.raises(ArtifactError, match=message):
        load_skills(skills_copy, toy.PREDICATES, toy.TYPES)


def test_index_that_is_a_fifo_does_not_hang(skills_copy):
    os.unlink(skills_copy / "skills.json")
    os.mkfifo(skills_copy / "skills.json")
    with pytest.raises(ArtifactError, match="not a regular file"):
        load_skills(skills_copy, toy.PREDICATES, toy.TYPES)


def test_symlink_inside_the_directory_is_allowed(skills_copy):
    os.rename(skills_copy / "Holding.policy.npz", skills_copy / "Op0.policy.real.npz")
    os.symlink("Op0.policy.real.npz", skills_copy / "Holding.policy.npz")
    assert len(load_skills(skills_copy, toy.PREDICATES, toy.TYPES).skills) == 2


def test_a_version_1_directory_lacking_a_setting_added_since_still_loads(skills_copy):
    def older(index):  # saved before the config recorded every setting
        index["version"] = 1
        index["config"].pop("correlated_subgoal_noise")
        index["config"]["policy"].pop("input_margin")

    _edit_index(skills_copy, older)
    learned = load_skills(skills_copy, toy.PREDICATES, toy.TYPES)
    assert len(learned.skills) == 2
    assert learned.config.correlated_subgoal_noise is False
