"""Rerun recordings of eval rollouts and demonstrations, read back with Rerun's reader:
the bodies' poses at every step are MuJoCo's forward kinematics of the file's states,
every ground atom's timeline is its classifier's truth, the features are the states',
and the skills, events and the planner's attempts are there."""

from __future__ import annotations

import json
import shutil

import h5py
import mujoco
import numpy as np
import pytest

from bpns.cli import main
from bpns.env.abstraction import ground_atoms
from bpns.env.registry import make_environment
from bpns.evaluation.rollout_files import RolloutsFile
from tests.inspect.conftest import DOMAINS, OUTCOMES
from tests.inspect.rrd import Recording


def _view(argv: list[str]) -> None:
    assert main(["view", *argv]) == 0


def _forward_kinematics(xml: str, flats: np.ndarray) -> tuple[mujoco.MjModel, np.ndarray]:
    """Every body's world position per flat state, computed here from the MJCF alone."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    out = np.empty((len(flats), model.nbody, 3))
    for t, flat in enumerate(flats):
        mujoco.mj_setState(model, data, flat, mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_kinematics(model, data)
        out[t] = data.xpos
    return model, out


@pytest.mark.parametrize("outcome", OUTCOMES)
@pytest.mark.parametrize("domain", DOMAINS)
def test_a_rollout_recording_holds_its_bodies_atoms_skills_and_states(
    oracle_rollouts, tmp_path, domain, outcome
):
    rollouts = oracle_rollouts[(domain, outcome)]
    out = tmp_path / "task0.rrd"
    _view([str(rollouts), "--task", "0", "--out", str(out)])
    rec = Recording(out)
    with h5py.File(rollouts) as f:
        g = f["data/demo_0"]
        flats, xml = g["states"][()], str(g.attrs["world"])
        features = {name: g["features"][name][()] for name in g["features"]}
    steps = len(flats)

    # bodies: each one's pose at every step, equal to the states' forward kinematics
    model, xpos = _forward_kinematics(xml, flats)
    bodies = rec.children("world", "bodies")
    visible = {
        model.body(model.geom_bodyid[g]).name
        for g in range(model.ngeom)
        if model.geom_group[g] < 3 and model.geom_rgba[g][3] > 0
    }
    assert visible <= bodies and "panda/hand" in bodies
    for body in bodies:
        at, translation = rec.series(("world", "bodies", body), "Transform3D:translation")
        assert list(at) == list(range(steps))
        expected = xpos[:, model.body(body).id].astype(np.float32)
        np.testing.assert_array_equal(np.array([t[0] for t in translation], np.float32), expected)
    geoms = [c for b in bodies for c in rec.children("world", "bodies", b)]
    kinds = {
        comp.split(":")[0]
        for b in bodies
        for g in rec.children("world", "bodies", b)
        for comp in rec.components(("world", "bodies", b, g))
        if ":" in comp
    }
    assert len(geoms) >= len(bodies) and {"Mesh3D", "Boxes3D"} <= kinds

    # every ground atom's truth at every step; the features are the file's
    env = make_environment(domain)
    file = RolloutsFile.read(rollouts)
    demo = file.demonstration(env, file.rows[0])
    atoms = ground_atoms(demo.states[0].objects, env.predicates)
    labels = {f"{a.predicate.name}({', '.join(o.name for o in a.objects)})": a for a in atoms}
    assert rec.children("atoms") == set(labels)
    for label, atom in labels.items():
        at, values = rec.series(("atoms", label), "Scalars:scalars")
        truth = [float(atom.predicate.classifier(s, atom.objects)) for s in demo.states]
        assert list(at) == list(range(steps)) and [v[0] for v in values] == truth
    for name, matrix in features.items():
        _, values = rec.series(("features", name), "Scalars:scalars")
        np.testing.assert_array_equal(np.array(values), matrix)

    # the skills executed, each as it started and how it ended, and the outcome
    _, log = rec.series(("plan", "log"), "TextLog:text")
    log = [line[0] for line in log]
    row = file.rows[0]
    for k, step in enumerate(row.steps):
        assert f"{k + 1}/{len(row.steps)} {step.label}: {step.outcome}" in log
    assert log[-1].endswith("solved" if row.solved else f"failed: {row.reason}")
    at, skill = rec.series(("plan", "skill"), "Scalars:scalars")
    assert len(at) == steps and skill[-1][0] == len(row.steps)
    attempts = rec.static_values(("planner", "attempts"), "TextDocument:text")
    if outcome == "failed":
        assert not row.solved and "abstract plans tried" in attempts[0][0]
    else:
        assert row.solved and attempts == []


def test_a_recording_shows_the_monitors_events_where_the_rollout_has_them(
    oracle_rollouts, tmp_path
):
    rollouts = tmp_path / "rollouts.h5"
    shutil.copy(oracle_rollouts[("cover", "failed")], rollouts)
    events = [
        {"at": 5, "kind": "diverged", "text": "expected Holding(block0) did not hold"},
        {"at": 9, "kind": "replanned", "text": "replan 1: 2 skills from the observed state"},
    ]
    with h5py.File(rollouts, "a") as f:
        f["data/demo_0"].attrs["events"] = json.dumps(events)
    out = tmp_path / "events.rrd"
    _view([str(rollouts), "--task", "0", "--out", str(out)])
    at, texts = Recording(out).series(("events",), "TextLog:text")
    assert list(at) == [5, 9]
    assert [t[0] for t in texts] == [f"{e['kind']}: {e['text']}" for e in events]


def test_a_demonstration_recording_carries_camera_images_at_every_step(
    cover_demo_file, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    _view([str(cover_demo_file), "--demo", "1", "--images", "--width", "64", "--height", "48"])
    assert (tmp_path / "demo_1.rrd").is_file()  # the default name, in the working directory
    out = tmp_path / "demo1.rrd"
    _view([str(cover_demo_file), "--demo", "1", "--out", str(out), "--camera", "front", "top"])
    rec = Recording(out)
    with h5py.File(cover_demo_file) as f:
        steps = len(f["data/demo_1/states"])
    for camera in ("front", "top"):
        at, blobs = rec.series(("cameras", camera), "EncodedImage:blob")
        assert list(at) == list(range(steps)) and all(len(b[0]) > 100 for b in blobs)
    assert rec.children("plan") == {"skill"}  # a demonstration has no skills to show
    assert "HandEmpty(robot)" in rec.children("atoms")


@pytest.mark.parametrize("free, message", [(4096, "No space left on device"), (10**12, "stopped")])
def test_a_recording_rerun_cannot_write_is_one_error_line_and_no_file(
    oracle_rollouts, tmp_path, monkeypatch, capsys, free, message
):
    # rerun reports a writer that died (a full disk: probe of issue 41) only as a
    # RuntimeError; the command says why in one line and leaves no partial file
    import rerun as rr

    from bpns import atomic

    def dead_writer(self, *args, **kwargs):
        raise RuntimeError("File-writer thread shut down prematurely")

    monkeypatch.setattr(rr.RecordingStream, "flush", dead_writer)
    monkeypatch.setattr(
        atomic.shutil, "disk_usage", lambda path: shutil._ntuple_diskusage(1, 1, free)
    )
    out = tmp_path / "task0.rrd"
    code = main(
        ["view", str(oracle_rollouts[("cover", "solved")]), "--task", "0"] + ["--out", str(out)]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("bpns: error: cannot write")
    assert message in err[0]
    assert list(tmp_path.iterdir()) == []
