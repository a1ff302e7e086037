"""MJCF from untrusted files may not make MuJoCo open files."""

from __future__ import annotations

import pytest

from mj_envs.mjcf_safety import MAX_MJCF_CHARS, UnsafeMjcfError, check_mjcf
from mj_envs.world import MjcfError, World

PLAIN = '<mujoco><worldbody><geom type="sphere" size="0.1"/></worldbody></mujoco>'


@pytest.mark.parametrize(
    "xml, message",
    [
        ('<mujoco><include file="/etc/passwd"/></mujoco>', "<include file='/etc/passwd'>"),
        ('<mujoco><asset><mesh name="m" file="a.stl"/></asset></mujoco>', "<mesh file="),
        ('<mujoco><asset><hfield name="h" file="h.png"/></asset></mujoco>', "<hfield file="),
        ('<mujoco><asset><texture name="t" fileright="r.png"/></asset></mujoco>', "fileright"),
        ('<mujoco><compiler meshdir="/etc"/></mujoco>', "meshdir"),
        ('<!DOCTYPE m [<!ENTITY e "x">]><mujoco/>', "entity declaration"),
        ("<mujoco><worldbody>", "not well-formed"),
    ],
)
def test_file_references_and_entities_are_refused(xml, message):
    with pytest.raises(UnsafeMjcfError, match=message):
        check_mjcf(xml)


def test_oversized_text_is_refused_before_parsing():
    with pytest.raises(UnsafeMjcfError, match="longer than"):
        check_mjcf(" " * (MAX_MJCF_CHARS + 1))


def test_procedural_scene_and_declared_assets_pass():
    check_mjcf(PLAIN)
    check_mjcf('<mujoco><asset><mesh name="m" file="m.stl"/></asset></mujoco>', {"m.stl"})


def test_world_refuses_an_include_before_mujoco_opens_it(tmp_path):
    secret = tmp_path / "secret.xml"
    secret.write_text(PLAIN)
    with pytest.raises(UnsafeMjcfError):
        World.from_xml(f'<mujoco><include file="{secret}"/></mujoco>')
    with pytest.raises(MjcfError):
        World.from_xml('<mujoco><worldbody><geom type="nonsense"/></worldbody></mujoco>')
