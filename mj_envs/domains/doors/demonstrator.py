"""Doors' scripted demonstrator: a BFS room path, then per door MoveToDoor, OpenDoor,
MoveThroughDoor, each phase the very policy of the corresponding skill (the given skills'
motion planner included), so segments a given skill produced are that skill's."""

from __future__ import annotations

from collections import deque

import numpy as np

from bpns.structs import Object, State, Task
from mj_envs.domains.doors.rules import DOOR, ROBOT, ROOM, door_in_room, in_room_xy
from mj_envs.domains.doors.skills import (
    MoveThroughDoorPolicy,
    MoveToDoorPolicy,
    OpenDoorPolicy,
    OpenDoorSampler,
)
from mj_envs.oracles.phases import DemonstrationFailed, Phase, PhasedDemonstrator


def room_of(state: State, robot: Object) -> Object:
    xy = np.array([state.get(robot, "x"), state.get(robot, "y")])
    for r in state.objects_of_type(ROOM):
        if in_room_xy(state, r, xy):
            return r
    raise DemonstrationFailed("the robot is outside every room")


def room_path(state: State, start: Object, goal: Object) -> list[tuple[Object, Object]]:
    """Shortest (door, next room) sequence from ``start`` to ``goal`` (BFS)."""
    doors = state.objects_of_type(DOOR)
    rooms = state.objects_of_type(ROOM)
    links = {
        r: [
            (d, r2)
            for d in doors
            if door_in_room(state, d, r)
            for r2 in rooms
            if r2 != r and door_in_room(state, d, r2)
        ]
        for r in rooms
    }
    prev: dict[Object, tuple[Object, Object] | None] = {start: None}
    queue = deque([start])
    while queue:
        r = queue.popleft()
        for d, r2 in links[r]:
            if r2 not in prev:
                prev[r2] = (d, r)
                queue.append(r2)
    if goal not in prev:
        raise DemonstrationFailed(f"{goal.name} is not reachable from {start.name}")
    out = []
    r = goal
    while prev[r] is not None:
        d, before = prev[r]
        out.append((d, r))
        r = before
    return out[::-1]


class DoorsDemonstrator(PhasedDemonstrator):
    max_phase_steps = 400

    def __init__(self, task: Task) -> None:
        super().__init__()
        self.robot = task.init.objects_of_type(ROBOT)[0]
        goal = next(iter(task.goal))
        self.goal_room = goal.objects[1]
        self.rng = np.random.default_rng(0)
        self._planned = False

    def plan(self, state: State) -> list[Phase]:
        if self._planned:
            return []
        self._planned = True
        phases: list[Phase] = []
        here = room_of(state, self.robot)
        for door, to_room in room_path(state, here, self.goal_room):
            phases += self._door_phases(door, here, to_room)
            here = to_room
        return phases

    def _door_phases(self, door: Object, here: Object, to_room: Object) -> list[Phase]:
        r = self.robot
        move_to, through, opener = MoveToDoorPolicy(1), MoveThroughDoorPolicy(), OpenDoorPolicy()
        sampler = OpenDoorSampler()
        subgoal: dict[str, np.ndarray] = {}

        def go_to_door(state: State):
            if state.get(door, "touched") > 0.5:
                return None
            return move_to(state, (r, door), state.vec((r, door)))

        def open_door(state: State):
            if state.get(door, "open") >= 0.8 and state.get(door, "touched") < 0.5:
                return None
            if "rot" not in subgoal:
                subgoal["rot"] = sampler(state, (r, door), self.rng)
            return opener(state, (r, door), subgoal["rot"])

        def go_through(state: State):
            xy = np.array([state.get(r, "x"), state.get(r, "y")])
            if in_room_xy(state, to_room, xy):
                return None
            return through(state, (r, door, here, to_room), state.vec((r, door, here, to_room)))

        return [go_to_door, open_door, go_through]

    def idle_action(self, state: State) -> np.ndarray:
        return np.zeros(8)
