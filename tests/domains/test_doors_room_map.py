"""Doors on the paper's floor plans (issue 38): connected rooms of a 5x5 map with random
connectivity, solid walls where there is no door, and today's full grids unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from bpns.env.abstraction import abstract
from bpns.structs import GroundAtom
from mj_envs.domains.doors.env import DoorsEnv, DoorsPaperEnv
from mj_envs.domains.doors.motion import scene_boxes
from mj_envs.domains.doors.rules import DOOR, DOORS_SHARE_ROOM, ROOM, door_in_room
from mj_envs.domains.doors.scene import NEIGHBOURS, RoomMap, sample_plan, sample_room_map


def _plans(spec: RoomMap, n: int = 60):
    return [sample_room_map(np.random.default_rng([3, i]), spec) for i in range(n)]


def test_room_maps_have_the_papers_room_counts_and_every_room_is_reachable():
    plans = _plans(RoomMap())
    counts = [len(p.rooms()) for p in plans]
    assert min(counts) >= 4 and max(counts) <= 25
    assert len(set(counts)) > 8  # the count varies over the range
    for p in plans:
        for room in p.rooms():
            p.doors_between(p.start_room, room)  # raises if unreachable
        assert p.start_room != p.goal_room
        assert p.rows <= 5 and p.cols <= 5


def test_doors_join_adjacent_existing_rooms_and_not_every_shared_wall_has_one():
    plans = _plans(RoomMap())
    missing = 0
    for p in plans:
        cells = set(p.rooms())
        for d in p.doors:
            assert d.a in cells and d.b in cells
            assert abs(d.a[0] - d.b[0]) + abs(d.a[1] - d.b[1]) == 1
        shared = {
            frozenset((c, (c[0] + di, c[1] + dj)))
            for c in cells
            for di, dj in NEIGHBOURS
            if (c[0] + di, c[1] + dj) in cells
        }
        doors = {frozenset((d.a, d.b)) for d in p.doors}
        assert doors <= shared and len(doors) >= len(cells) - 1  # a spanning tree at least
        missing += len(shared - doors)
    assert missing > 0  # random connectivity: some shared walls are solid


def test_a_door_fraction_of_one_puts_a_door_in_every_shared_wall():
    for p in _plans(RoomMap(rooms=(6, 12), door_fraction=1.0), 20):
        cells = set(p.rooms())
        shared = sum(
            1 for c in cells for di, dj in ((1, 0), (0, 1)) if (c[0] + di, c[1] + dj) in cells
        )
        assert len(p.doors) == shared


def test_a_shared_wall_without_a_door_is_a_solid_wall_the_base_planner_avoids():
    env = DoorsPaperEnv()
    layout = next(
        lay
        for i in range(40)
        if len((lay := env.sample_layout(np.random.default_rng([5, 1, i]), False)).objects) > 12
    )
    task = env.make_task(layout)
    world = task.init.sim.world
    names = [world.model.geom(g).name for g in range(world.model.ngeom)]
    solid = [n for n in names if n.startswith("wall_") and not n.startswith("wall_door")]
    assert solid  # the outline and the walls without a door
    boxes = scene_boxes(world.model, frozenset())
    assert len(boxes.centres) >= len(solid)


def test_paper_tasks_start_in_one_room_with_the_goal_in_another():
    env = DoorsPaperEnv()
    for task in env.eval_tasks(3, seed=0):
        atoms = abstract(task.init, env.predicates)
        in_room = [a for a in atoms if a.predicate.name == "InRoom"]
        assert len(in_room) == 1  # the settled robot stands in exactly one room
        assert not task.goal_holds(atoms)
        assert task.horizon >= 1500
    assert env.max_objects == {"robot": 1, "door": 40, "room": 25}


def test_todays_full_grids_are_unchanged_by_the_room_map_option():
    rng_a, rng_b = np.random.default_rng(9), np.random.default_rng(9)
    assert sample_plan(rng_a, (2, 3)) == sample_plan(rng_b, (2, 3))
    plan = sample_plan(np.random.default_rng(9), (2, 3))
    assert plan.cells is None and len(plan.rooms()) == plan.rows * plan.cols
    assert DoorsEnv().room_map is None


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"size": 1}, "size must lie in 2..8"),
        ({"rooms": (1, 4)}, "room counts"),
        ({"rooms": (4, 30)}, "room counts"),
        ({"door_fraction": float("nan")}, "door_fraction"),
        ({"door_fraction": 1.5}, "door_fraction"),
    ],
)
def test_bad_room_map_parameters_are_refused_naming_the_value(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RoomMap(**kwargs)


def test_doors_share_a_room_exactly_when_one_room_holds_both_on_every_map():
    env = DoorsPaperEnv()
    states = [task.init for task in env.train_tasks(3, seed=5)]
    for state in [*states, states[0]]:  # back to the first: nothing carried over
        doors = state.objects_of_type(DOOR)
        rooms = state.objects_of_type(ROOM)
        atoms = abstract(state, [DOORS_SHARE_ROOM])
        for d1 in doors:
            for d2 in doors:
                shared = d1 != d2 and any(
                    door_in_room(state, d1, r) and door_in_room(state, d2, r) for r in rooms
                )
                assert (GroundAtom(DOORS_SHARE_ROOM, (d1, d2)) in atoms) == shared
        assert atoms  # a map with two doors in a room
