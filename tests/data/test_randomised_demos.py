"""Demonstrations collected under randomised physics (`bpns demos --perturb`): each task
in its own drawn world, the world stored with it, replay exact in it and only in it."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from bpns.data.datasets import (
    DatasetError,
    iter_demonstrations,
    load_demonstrations,
    read_attributes,
    task_origins,
)
from bpns.data.demos import check_replay, demo_physics, replay
from bpns.env.worlds import WorldDistribution, parse_world
from bpns.workflow import collect_demos
from tests.cli_probe import error_line

WORLDS = ["mass_scale=1.5:2", "latency=0,1", "seed=0"]


@pytest.fixture(scope="module")
def randomised(tmp_path_factory, cover_env):
    path = tmp_path_factory.mktemp("randomised") / "demos.h5"
    written = collect_demos(cover_env, 4, 7, path, worlds=parse_world(WORLDS))
    assert written.num_written >= 3, written.lines()
    assert "in mass_scale=1.5:2,latency=0,1 worlds" in written.lines()[0]
    return path, [i for i in range(4) if i not in written.failed]


def test_each_demonstration_records_the_world_drawn_for_its_task(randomised):
    path, tasks = randomised
    worlds = parse_world(WORLDS)
    root, _ = read_attributes(path)
    assert WorldDistribution.from_json(root["worlds"]) == worlds
    physics = demo_physics(path)
    assert physics == [worlds.draw(i) for i in tasks]
    assert all(1.5 <= p.mass_scale <= 2 for p in physics)


def test_each_demonstration_records_the_task_it_solved(randomised, cover_env):
    """The seed and index of its task: the task and its demonstrator can be made again
    (corrections ask that demonstrator, or the oracle, about other states)."""
    path, tasks = randomised
    origins = task_origins(path)
    assert origins == [(7, i) for i in tasks]
    for (seed, index), demo in zip(origins, load_demonstrations(path, cover_env), strict=True):
        init = cover_env.task(index, seed, True).init
        np.testing.assert_array_equal(init.vec(init.objects), demo.states[0].vec(init.objects))


def test_a_file_without_task_origins_says_how_to_get_them(tmp_path, cover_env, cover_demos):
    from bpns.data.datasets import save_demonstrations

    path = tmp_path / "plain.h5"
    save_demonstrations(path, cover_env, cover_demos[:1])
    with pytest.raises(DatasetError, match="collect them again with `bpns demos`"):
        task_origins(path)


def test_randomised_demonstrations_replay_exactly_in_their_own_worlds(randomised, cover_env):
    check = check_replay(cover_env, randomised[0])
    assert check.ok, check.lines()
    assert all(r.max_state_diff == 0.0 for r in check.reports)


def test_the_stored_world_matters_nominal_physics_does_not_reproduce_them(
    randomised, tmp_path, cover_env
):
    stripped = tmp_path / "stripped.h5"
    stripped.write_bytes(randomised[0].read_bytes())
    with h5py.File(stripped, "r+") as f:
        for name in f["data"]:
            del f["data"][name].attrs["physics"]
    assert all(p.nominal for p in demo_physics(stripped))
    latency = [p.latency for p in demo_physics(randomised[0])]
    assert 0 in latency and 1 in latency  # both cases below are met
    for i in range(len(latency)):
        if latency[i]:  # a latency queue is part of the state: it does not even load
            with pytest.raises(DatasetError, match="flat simulator state has shape"):
                list(iter_demonstrations(stripped, cover_env, [i]))
            continue
        (demo,) = iter_demonstrations(stripped, cover_env, [i])
        assert not replay(cover_env, demo, i).exact  # heavier objects than nominal


def test_learning_reads_randomised_demonstrations_like_any_other(randomised, cover_env):
    (first, *_) = load_demonstrations(randomised[0], cover_env, features_only=True)
    assert first.states[0].sim is None and len(first.actions) > 0


def test_a_tampered_physics_record_is_one_error_naming_the_demonstration(
    randomised, tmp_path, cover_env
):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(randomised[0].read_bytes())
    with h5py.File(bad, "r+") as f:
        f["data/demo_1"].attrs["physics"] = "{not json"
    with pytest.raises(DatasetError, match="demo_1 has an unusable 'physics' record"):
        demo_physics(bad)
    with pytest.raises(DatasetError, match="demo_1 is damaged: its 'physics' record"):
        load_demonstrations(bad, cover_env)


def test_nominal_demonstrations_carry_no_physics_records(tmp_path, cover_env):
    path = tmp_path / "plain.h5"
    collect_demos(cover_env, 1, 7, path)
    root, per_demo = read_attributes(path)
    assert "worlds" not in root and "physics" not in per_demo[0]
    assert demo_physics(path)[0].nominal
    assert np.isfinite(load_demonstrations(path, cover_env)[0].actions).all()


@pytest.mark.parametrize(
    "perturb, message",
    [
        (["modrate"], "--perturb"),
        (["mass_scale=nan"], "--perturb"),
        (["latency=-1"], "--perturb"),
    ],
)
def test_bad_demo_worlds_are_one_error_line_before_any_work(perturb, message, tmp_path, capsys):
    out = tmp_path / "d.h5"
    argv = ["demos", "--env", "cover", "-n", "1", "--out", str(out), "--perturb", *perturb]
    assert error_line(argv, capsys).startswith(f"bpns: error: {message}")
    assert not out.exists()
