"""The core structs: types and objects key dicts across processes; states group objects."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys

import numpy as np
import pytest

from bpns.structs import Object, State, Type

BLOCK = Type("block", ("x", "y"))
TARGET = Type("target", ("x",))


def test_a_type_and_an_object_key_a_dict_in_a_process_with_other_string_hashes():
    table = {BLOCK: 1, Object("b0", BLOCK): 2}
    code = (
        "import pickle, sys\n"
        "from bpns.structs import Object, Type\n"
        "t = pickle.loads(sys.stdin.buffer.read())\n"
        "block = Type('block', ('x', 'y'))\n"
        "print(t[block], t[Object('b0', block)], block.feature_index('y'))\n"
    )
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    out = subprocess.run(
        [sys.executable, "-c", code],
        input=pickle.dumps(table),
        capture_output=True,
        env=env,
        check=True,
    )
    assert out.stdout.decode().split() == ["1", "2", "1"]


def test_an_unknown_feature_names_the_type_and_its_features():
    with pytest.raises(KeyError, match=r"type 'block' has no feature 'z'.*\('x', 'y'\)"):
        BLOCK.feature_index("z")


def test_objects_of_type_are_sorted_and_a_missing_type_has_none():
    b1, b0, t = Object("b1", BLOCK), Object("b0", BLOCK), Object("t", TARGET)
    state = State({b1: np.zeros(2), t: np.zeros(1), b0: np.ones(2)})
    assert state.objects_of_type(BLOCK) == (b0, b1)
    assert state.objects_of_type(TARGET) == (t,)
    assert state.objects_of_type(Type("other", ())) == ()
    assert state.get(b0, "y") == 1.0


def test_types_compare_and_order_by_name_and_features_only():
    assert Type("block", ("x", "y")) == BLOCK and hash(Type("block", ("x", "y"))) == hash(BLOCK)
    assert Type("block", ("x",)) != BLOCK
    assert sorted([TARGET, BLOCK]) == [BLOCK, TARGET]


def test_a_types_angles_must_be_features_and_survive_pickling():
    with pytest.raises(ValueError, match=r"angles \['yaw'\] are not among its features"):
        Type("robot", ("x",), angles=("yaw",))
    robot = Type("robot", ("x", "yaw"), angles=("yaw",))
    assert robot.angle_indices == (1,)
    back = pickle.loads(pickle.dumps(robot))
    assert back == robot and back.angles == ("yaw",) and hash(back) == hash(robot)
    assert robot != Type("robot", ("x", "yaw"))
