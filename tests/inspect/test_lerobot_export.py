"""``bpns export --format lerobot``: a LeRobot v3 dataset that Rerun's LeRobot reader
loads back with the HDF5 file's frames, actions, states, task texts and camera video."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pyarrow.parquet as pq
import pytest
from rerun.experimental import LeRobotReader

from bpns.cli import main
from tests.cli_probe import error_line


def _episodes(path) -> list[dict]:
    """Per demo group of an HDF5 file: actions, features (sorted objects), flat states, goal."""
    out = []
    with h5py.File(path) as f:
        for k in range(int(f.attrs["num_demos"])):
            g = f[f"data/demo_{k}"]
            names = sorted(g["features"])
            state = np.concatenate([g["features"][n][()] for n in names], axis=1)
            goal = " and ".join(
                sorted(f"{p}({', '.join(args)})" for p, args in json.loads(g.attrs["goal"]))
            )
            out.append(
                {"actions": g["actions"][()], "state": state, "sim": g["states"][()], "goal": goal}
            )
    return out


def _reader_columns(root, episode: int) -> dict[str, list]:
    """Every temporal component Rerun's LeRobot reader yields for ``episode``."""
    columns: dict[str, list] = {}
    for chunk in LeRobotReader(root).stream(episode).to_chunks():
        batch = chunk.to_record_batch()
        if "frame_index" not in batch.schema.names:
            continue
        for name in batch.schema.names:
            if ":" in name:
                key = f"{chunk.entity_path.lstrip('/')}|{name}"
                columns.setdefault(key, []).extend(batch.column(name).to_pylist())
    return columns


@pytest.mark.parametrize("source", ["demos", "rollouts"])
def test_an_exported_dataset_reads_back_with_the_files_frames(
    source, cover_demo_file, oracle_rollouts, tmp_path
):
    path = cover_demo_file if source == "demos" else oracle_rollouts[("stick_button", "solved")]
    out = tmp_path / "dataset"
    argv = ["export", str(path), "--format", "lerobot", "--out", str(out)]
    assert main([*argv, "--width", "96", "--height", "72"]) == 0
    episodes = _episodes(path)
    reader = LeRobotReader(out)
    assert reader.version == "v3" and reader.episodes() == list(range(len(episodes)))
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["total_frames"] == sum(len(e["actions"]) for e in episodes)
    camera = "observation.images.overview"
    for k, e in enumerate(episodes):
        n = len(e["actions"])
        columns = _reader_columns(out, k)
        action = np.array([v for v in columns["action|Scalars:scalars"]])
        state = np.array([v for v in columns["observation.state|Scalars:scalars"]])
        sim = np.array([v for v in columns["observation.sim_state|Scalars:scalars"]])
        assert len(action) == len(state) == n
        np.testing.assert_array_equal(action, e["actions"].astype(np.float32))
        np.testing.assert_array_equal(state, e["state"][:n].astype(np.float32))
        np.testing.assert_array_equal(sim[:, : e["sim"].shape[1]], e["sim"][:n])
        assert {t[0] for t in columns["task|TextDocument:text"]} == {e["goal"]}
        assert len(columns[f"{camera}|VideoStream:sample"]) == n
    frames = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    assert frames.num_rows == info["total_frames"]
    assert frames.column("index").to_pylist() == list(range(frames.num_rows))
    if source == "rollouts":
        assert frames.column("next.success").to_pylist()[-1] is True


def test_export_refuses_an_existing_dataset_without_overwrite(cover_demo_file, tmp_path, capsys):
    out = tmp_path / "dataset"
    argv = ["export", str(cover_demo_file), "--out", str(out), "--no-videos"]
    assert main(argv) == 0
    assert "exists; pass --overwrite" in error_line(argv, capsys)
    assert main([*argv, "--overwrite"]) == 0
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    other = ["export", str(cover_demo_file), "--out", str(tmp_path / "other"), "--overwrite"]
    assert "is not a dataset" in error_line(other, capsys)
    assert (tmp_path / "other" / "notes.txt").read_text() == "mine"
