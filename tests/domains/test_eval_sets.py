"""The domains' ``large`` eval sets and ``--objects`` counts (issue 38): eval tasks hold
the counts asked for, train tasks never change, and counts equal to a domain's own draw
exactly its own tasks (so the paper set is untouched)."""

from __future__ import annotations

import numpy as np
import pytest

import mj_envs  # noqa: F401  (selects the GL backend before mujoco loads)
from bpns.env.environment import eval_environment, eval_set_of
from bpns.env.object_counts import ObjectCountError, ObjectCounts
from bpns.env.registry import make_environment
from bpns.structs import Task

# domain -> (the kind its counts name, its own eval counts, the large set's)
DOMAINS = {
    "cover": ("block", "block=2", (3, 4)),
    "stick_button": ("button", "button=3:4", (5, 8)),
    "coffee": ("cup", "cup=2:3", (4, 6)),
    "doors": ("grid", "grid=2:3", (5, 6)),
    "doors_paper": ("grid", "grid=5", (5, 6)),
}
N_TASKS = {"doors": 3, "doors_paper": 3}  # large floor plans take longer to build


def _n(name: str) -> int:
    return N_TASKS.get(name, 6)


def _same(a: Task, b: Task) -> bool:
    return (
        a.init.sim.world.xml == b.init.sim.world.xml
        and np.array_equal(a.init.sim.flat, b.init.sim.flat)
        and a.goal == b.goal
        and a.horizon == b.horizon
    )


def _count(task: Task, kind: str) -> int:
    if kind == "grid":  # the plan's side: rooms are named room<i>_<j>
        cells = [o.name[4:].split("_") for o in task.init.objects if o.type.name == "room"]
        return max(max(int(i), int(j)) for i, j in cells) + 1
    return sum(o.type.name == kind for o in task.init.objects)


@pytest.mark.parametrize("name", list(DOMAINS))
def test_large_eval_tasks_hold_the_counts_and_train_tasks_are_unchanged(name):
    kind, _, (lo, hi) = DOMAINS[name]
    env = make_environment(name)
    large = eval_environment(env, "large")
    counts = [_count(large.task(i, 0, False), kind) for i in range(_n(name))]
    if kind == "grid" and name == "doors_paper":  # a random connected part of the map
        assert all(c <= hi for c in counts) and max(counts) > 5
    else:
        assert all(lo <= c <= hi for c in counts), counts
    assert all(_same(large.task(i, 0, True), env.task(i, 0, True)) for i in range(2))
    assert large.max_objects[kind if kind != "grid" else "room"] >= max(
        counts if kind != "grid" else [c * c for c in counts]
    )


@pytest.mark.parametrize("name", list(DOMAINS))
def test_a_domains_own_counts_draw_exactly_its_paper_tasks(name):
    _, own, _ = DOMAINS[name]
    env = make_environment(name)
    same = eval_environment(env, objects=ObjectCounts.parse(own))
    assert same is not env  # a copy carrying the counts, drawing by them
    assert all(_same(same.task(i, 0, False), env.task(i, 0, False)) for i in range(_n(name)))
    assert eval_environment(env, "paper") is env


@pytest.mark.parametrize("name", ["stick_button", "coffee", "cover"])
def test_the_largest_count_is_placed_without_overlap(name):
    kind, _, _ = DOMAINS[name]
    env = make_environment(name)
    most = env.capabilities.object_limits[kind][1]
    big = eval_environment(env, objects=ObjectCounts.of({kind: most}))
    for i in range(3):
        task = big.task(i, 1, False)
        assert _count(task, kind) == most
        objs = [o for o in task.init.objects if o.type.name == kind]
        xy = np.array([[task.init.get(o, "x"), task.init.get(o, "y")] for o in objs])
        gaps = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
        assert gaps[~np.eye(len(objs), dtype=bool)].min() > 0.05


@pytest.mark.parametrize("name", list(DOMAINS))
def test_a_count_beyond_what_the_scene_holds_is_one_clear_error(name):
    kind, _, _ = DOMAINS[name]
    env = make_environment(name)
    with pytest.raises(ObjectCountError, match=rf"{kind}=99: {name} scenes hold"):
        eval_set_of(env, objects=ObjectCounts.of({kind: 99}))
