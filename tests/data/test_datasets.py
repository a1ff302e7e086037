"""HDF5 demonstrations: exact replay after a round trip, clear errors on bad files."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from bpns.data.datasets import DatasetError, load_demonstrations, save_demonstrations
from bpns.data.demos import replay
from bpns.structs import State


def test_saved_demos_replay_exactly_from_their_first_state(tmp_path, cover_env, cover_demos):
    path = tmp_path / "demos.h5"
    assert save_demonstrations(path, cover_env, cover_demos) == len(cover_demos)
    loaded = load_demonstrations(path, cover_env)
    assert len(loaded) == len(cover_demos)
    for i, (orig, back) in enumerate(zip(cover_demos, loaded, strict=True)):
        assert np.array_equal(orig.actions, back.actions)
        assert back.task.goal == orig.task.goal
        report = replay(cover_env, back, i)
        assert report.max_state_diff == 0.0 and report.max_feature_diff == 0.0
        assert report.goal_reached


def test_features_only_loading_gives_the_same_demos_without_simulator_states(
    tmp_path, cover_env, cover_demos
):
    path = tmp_path / "demos.h5"
    save_demonstrations(path, cover_env, cover_demos)
    full = load_demonstrations(path, cover_env)
    light = load_demonstrations(path, cover_env, features_only=True)
    for a, b in zip(full, light, strict=True):
        assert np.array_equal(a.actions, b.actions) and a.task.goal == b.task.goal
        assert a.task.horizon == b.task.horizon and len(a.states) == len(b.states)
        assert all(sa.allclose(sb) for sa, sb in zip(a.states, b.states, strict=True))
        assert all(s.sim is not None for s in a.states) and all(s.sim is None for s in b.states)


def test_loaded_states_list_their_objects_sorted_as_a_fresh_state_does(
    tmp_path, cover_env, cover_demos
):
    path = tmp_path / "demos.h5"
    save_demonstrations(path, cover_env, cover_demos)
    for demo in load_demonstrations(path, cover_env, features_only=True):
        for state in demo.states:
            # loading fills the objects cache once per demo: it must equal what the
            # property computes from the data
            assert state.objects == tuple(sorted(state.data)) == State(state.data).objects
            assert list(state.data) == list(state.objects)


def test_corrupt_file_gives_one_clear_error(tmp_path, cover_env):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"this is not hdf5" * 10)
    with pytest.raises(DatasetError, match="corrupt or truncated"):
        load_demonstrations(bad, cover_env)


def test_truncated_file_gives_one_clear_error(tmp_path, cover_env, cover_demos):
    path = tmp_path / "demos.h5"
    save_demonstrations(path, cover_env, cover_demos[:1])
    data = path.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError):
        load_demonstrations(cut, cover_env)


def test_missing_file_and_foreign_hdf5_are_reported(tmp_path, cover_env):
    with pytest.raises(DatasetError, match="no such"):
        load_demonstrations(tmp_path / "nope.h5", cover_env)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    with pytest.raises(DatasetError, match="not a bpns demonstration file .it has no format"):
        load_demonstrations(other, cover_env)
    with h5py.File(other, "a") as f:
        f.attrs["format"] = "bpns-demos-0"
    with pytest.raises(DatasetError, match="its format is 'bpns-demos-0'; expected format"):
        load_demonstrations(other, cover_env)


def test_failed_write_leaves_no_half_written_file(tmp_path, cover_env, cover_demos):
    path = tmp_path / "out.h5"

    def exploding():
        yield cover_demos[0]
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        save_demonstrations(path, cover_env, exploding())
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []
