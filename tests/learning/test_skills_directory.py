"""Saving and loading learned skills; the readable listing."""

import dataclasses
import json
import os
import re
import stat

import numpy as np
import pytest

from bpns.learning.artifacts.skills_dir import ArtifactError, describe, load_skills, save_skills
from bpns.learning.pipeline import learn_skills
from bpns.structs import Predicate, Type
from tests import toy_learning as toy

B0 = toy.blocks(2)[0]
T0 = toy.targets(2)[0]
R = toy.ROBOT_OBJ


@pytest.fixture(scope="module")
def skills():
    return toy.learned_toy_skills()


def _load(path, predicates=toy.PREDICATES, types=toy.TYPES):
    return load_skills(path, predicates, types)


def test_round_trip_gives_identical_outputs(skills, tmp_path):
    path = save_skills(skills, tmp_path / "skills")
    back = _load(path)
    assert back.operators == skills.operators
    assert back.config == skills.config
    assert back.stats == skills.stats
    assert back.predicates == skills.predicates
    state = toy.make_state(4.1, [4.0, 7.5], [2.0, 9.0], held=0)
    for orig, loaded in zip(skills.skills, back.skills, strict=True):
        assert loaded.horizon == orig.horizon is not None
        objs = (B0, R) if len(orig.operator.parameters) == 2 else (B0, R, T0)
        goal = orig.sampler(state, objs, np.random.default_rng(0))
        np.testing.assert_array_equal(goal, loaded.sampler(state, objs, np.random.default_rng(0)))
        np.testing.assert_array_equal(
            orig.policy(state, objs, goal), loaded.policy(state, objs, goal)
        )


def test_operators_are_stored_as_readable_json(skills, tmp_path):
    path = save_skills(skills, tmp_path / "skills")
    index = json.loads((path / "skills.json").read_text())
    op1 = next(e for e in index["skills"] if e["name"] == "Covers_HandEmpty")
    assert op1["parameters"] == [["?block0", "block"], ["?robot0", "robot"], ["?target0", "target"]]
    assert ["Covers", ["?block0", "?target0"]] in op1["add_effects"]
    assert {p["name"] for p in index["predicates"]} == {"Covers", "HandEmpty", "Holding"}


def test_loading_without_a_predicate_names_it(skills, tmp_path):
    path = save_skills(skills, tmp_path / "skills")
    with pytest.raises(ArtifactError, match="predicate 'Covers'"):
        _load(path, predicates=toy.PREDICATES - {toy.COVERS})


def test_loading_with_a_different_predicate_signature_fails(skills, tmp_path):
    path = save_skills(skills, tmp_path / "skills")
    other = Predicate("Covers", (toy.BLOCK, toy.BLOCK), lambda s, o: False)
    with pytest.raises(ArtifactError, match="Covers"):
        _load(path, predicates=(toy.PREDICATES - {toy.COVERS}) | {other})


def test_loading_with_missing_or_changed_types_fails(skills, tmp_path):
    path = save_skills(skills, tmp_path / "skills")
    with pytest.raises(ArtifactError, match="type 'target'"):
        _load(path, types=toy.TYPES - {toy.TARGET})
    changed = Type("target", ("x", "width"))
    with pytest.raises(ArtifactError, match="features"):
        _load(path, types=(toy.TYPES - {toy.TARGET}) | {changed})


def test_saving_is_atomic_and_refuses_to_overwrite_by_default(skills, tmp_path):
    path = save_skills(skills, tmp_path / "skills")
    with pytest.raises(FileExistsError):
        save_skills(skills, path)
    renamed = dataclasses.replace(skills, skills=skills.skills[:1])
    save_skills(renamed, path, overwrite=True)
    assert [s.name for s in _load(path).skills] == ["Holding"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["skills"]  # no temporaries left


def test_saved_directory_has_ordinary_permissions(skills, tmp_path):
    umask = os.umask(0)
    os.umask(umask)
    path = save_skills(skills, tmp_path / "skills")
    assert stat.S_IMODE(path.stat().st_mode) == 0o777 & ~umask


def test_failed_save_leaves_nothing_behind(skills, tmp_path):
    broken = dataclasses.replace(skills.skills[0], policy=lambda s, o, g: g)
    bad = dataclasses.replace(skills, skills=(broken,))
    with pytest.raises(TypeError):
        save_skills(bad, tmp_path / "skills")
    assert list(tmp_path.iterdir()) == []


def test_not_a_skills_directory(tmp_path):
    with pytest.raises(ArtifactError, match="not a skills directory"):
        _load(tmp_path)


def test_no_subgoal_skills_round_trip(tmp_path):
    config = toy.fast_config(steps=10, use_subgoals=False)
    result = learn_skills(toy.demos(3, seed=0), toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    back = _load(save_skills(result, tmp_path / "s"))
    state = toy.make_state(1.0, [3.0, 7.5], [5.0, 9.0])
    goal = back.skills[0].sampler(state, (B0, R), np.random.default_rng(0))
    np.testing.assert_array_equal(goal, state.vec((B0, R)))
    text = describe(back)
    assert "no subgoals" in text
    legend = text.split("What the annotations mean:\n")[1].splitlines()
    assert any(line.split()[:2] == ["no", "subgoals"] for line in legend)
    assert not any("starts with" in line for line in legend)  # not printed, not explained


def test_skills_with_correlated_subgoal_noise_round_trip(tmp_path):
    config = toy.fast_config(steps=50, correlated_subgoal_noise=True)
    result = learn_skills(toy.demos(6, seed=0), toy.PREDICATES, toy.CONTACT_PREDICATES, config)
    pick = result.skill("Holding")
    assert pick.sampler.correlation is not None
    back = _load(save_skills(result, tmp_path / "s"))
    assert back.config.correlated_subgoal_noise
    state = toy.make_state(1.0, [3.0, 7.5], [5.0, 9.0])
    a = pick.sampler(state, (B0, R), np.random.default_rng(2))
    b = back.skill("Holding").sampler(state, (B0, R), np.random.default_rng(2))
    np.testing.assert_array_equal(a, b)


def test_describe_lists_every_operator(skills):
    text = describe(skills)
    assert text.startswith("2 skills learned from 30 demonstrations")
    assert "Holding(?block0:block, ?robot0:robot)    [60 segments, horizon " in text
    assert "add: Covers(?block0, ?target0), HandEmpty(?robot0)" in text
    # the pick takes the block's place as given and names the range it was shown
    assert re.search(r"starts with: \?block0\.x in \[[-0-9.e]+, [-0-9.e]+\]", text)
    legend = text.split("What the annotations mean:\n")[1]
    assert [line.split()[0] for line in legend.splitlines()] == ["segments", "horizon", "starts"]


def test_skills_saved_with_index_names_before_readable_names_still_load(skills, tmp_path):
    """A directory from before readable names: Op<k> names, weights in Op<k>.*.npz and
    no order keys in skills.json."""
    indexed = dataclasses.replace(
        skills,
        skills=tuple(
            dataclasses.replace(
                s, operator=dataclasses.replace(s.operator, name=f"Op{k}", order_key=None)
            )
            for k, s in enumerate(skills.skills)
        ),
    )
    path = save_skills(indexed, tmp_path / "old")
    index = json.loads((path / "skills.json").read_text())
    for entry in index["skills"]:
        del entry["order_key"]
    (path / "skills.json").write_text(json.dumps(index))
    assert (path / "Op0.policy.npz").is_file()
    back = _load(path)
    assert [s.name for s in back.skills] == ["Op0", "Op1"]
    assert [s.operator.sort_name for s in back.skills] == ["Op0", "Op1"]
    # the readable names' order keys are the old names: planning orders them alike
    assert [s.operator.sort_name for s in skills.skills] == ["Op0", "Op1"]
