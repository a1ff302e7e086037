"""Coffee in physics: handle grasps, the ±60° rule, the latching button, heat, pouring,
spills, the scripted demonstrator, exact replay and the oracle skills."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from bpns.approaches.bilevel import oracle_skills
from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demos import replay, run_demonstrator
from bpns.env.abstraction import abstract
from bpns.env.registry import make_environment as make_env
from bpns.structs import Object, State, Task
from mj_envs.base import InvalidActionError
from mj_envs.domains.coffee.behaviours import (
    SAFE_Z,
    TWIST_ABOVE,
    TWIST_TARGET,
    grasp_phases,
    handle_grasp,
    knob_wrist,
    needs_twist,
    pick_phases,
    place_phases,
    pour_phases,
    press_phases,
)
from mj_envs.domains.coffee.rules import (
    BUTTON_PRESSED,
    CUP,
    CUP_FILLED,
    HAND_EMPTY,
    HANDLE_RULE,
    HEAT_IDX,
    HOLDING,
    LATCH_DEPTH,
    NOT_ABOVE_CUP,
    POT_ABOVE_CUP,
    POT_HOT,
    POT_ON_PLATE,
    POUR_TILT,
    TWISTING,
    WRIST_LIMITS,
)


@pytest.fixture(scope="module")
def env():
    return make_env("coffee")


def _obj(state: State, name: str) -> Object:
    return next(o for o in state.objects if o.name == name)


def _task_with(env, train: bool, want: Callable[[Task], bool], seed: int = 0) -> Task:
    """The first task of a seeded stream with a wanted property (deterministic)."""
    for i in range(60):
        task = env.task(i, seed, train)
        if want(task):
            return task
    raise AssertionError("no such task in the first 60")


def _rotation(task: Task) -> float:
    return abs(task.init.get(_obj(task.init, "pot"), "rotation"))


def _run(env, state: State, phases, steps: int = 400) -> list[State]:
    """Run phase functions (the demonstrator's building blocks) until they are done."""
    out = [state]
    phases = list(phases)
    for _ in range(steps):
        while phases:
            action = phases[0](out[-1])
            if action is not None:
                break
            phases.pop(0)
        if not phases:
            return out
        out.append(env.simulate(out[-1], action))
    raise AssertionError("the phases did not finish")


def _hot_task(env, task: Task) -> Task:
    """The same scene with the pot already hot (heat preset in userdata)."""
    world = task.init.sim.world
    world.load(task.init.sim.flat)
    world.data.userdata[HEAT_IDX] = 1.0
    flat = world.save()
    return replace(task, init=env.state_from_flat(world, flat, task.init))


def _pads_on_pot(state: State) -> set[str]:
    world = state.sim.world
    world.load(state.sim.flat)
    m, d = world.model, world.data
    pads = {m.geom(f"panda/{n}").id: n for n in ("left_pad", "right_pad")}
    out = set()
    for c in d.contact[: d.ncon]:
        for p, o in ((c.geom1, c.geom2), (c.geom2, c.geom1)):
            if p in pads and c.dist <= 0 and (m.geom(o).name or "").startswith("pot_"):
                out.add(pads[p])
    return out


def test_holding_flips_when_both_pads_close_on_the_handle(env):
    task = _task_with(env, True, lambda t: _rotation(t) < np.deg2rad(40))
    s = task.init
    robot, pot = _obj(s, "robot"), _obj(s, "pot")
    states = _run(env, s, pick_phases(robot, pot))
    flags = [HOLDING.holds(x, (robot, pot)) for x in states]
    assert not flags[0] and flags[-1]
    first = flags.index(True)
    assert _pads_on_pot(states[first]) == {"left_pad", "right_pad"}  # the contact list
    assert not any(_pads_on_pot(x) for x in states[: first - 1])
    assert HAND_EMPTY.holds(states[0], (robot,)) and not HAND_EMPTY.holds(states[-1], (robot,))
    assert states[-1].get(pot, "z") > 0.1  # lifted by the fingers' contacts alone
    assert not TWISTING.holds(states[-1], (robot, pot))


def test_the_handle_cannot_be_grasped_when_turned_beyond_60_degrees(env):
    task = _task_with(env, True, lambda t: np.deg2rad(80) < _rotation(t) < np.deg2rad(110))
    s = task.init
    robot, pot = _obj(s, "robot"), _obj(s, "pot")
    # the wrist turned by the pot's rotation (as far as its range allows), the open
    # fingers either side of the bar: the close command is not obeyed
    travel, descend, close = grasp_phases(
        robot, pot, lambda x: handle_grasp(x, pot), lambda x: x.get(pot, "rotation"), "held"
    )
    states = _run(env, s, [travel])
    for _ in range(40):
        action = descend(states[-1])
        if action is None:
            break
        states.append(env.simulate(states[-1], action))
    assert np.linalg.norm(states[-1].data[robot][:3] - handle_grasp(states[-1], pot)) < 0.01
    for _ in range(20):
        states.append(env.simulate(states[-1], close(states[-1])))
    assert abs(states[-1].get(pot, "rotation")) > HANDLE_RULE
    assert not any(HOLDING.holds(x, (robot, pot)) for x in states)
    assert states[-1].get(robot, "fingers") > 0.035  # the close command was not obeyed


def test_button_pressed_latches_and_the_pot_heats_only_on_the_switched_on_plate(env):
    task = _task_with(env, True, lambda t: _rotation(t) < np.deg2rad(40))
    s = task.init
    robot, pot, plate = _obj(s, "robot"), _obj(s, "pot"), _obj(s, "plate")
    pressed = _run(env, s, press_phases(robot, plate))  # the pot is still on the table
    flags = [BUTTON_PRESSED.holds(x, (plate,)) for x in pressed]
    assert not flags[0] and flags[-1]
    world = pressed[-1].sim.world
    world.load(pressed[-1].sim.flat)
    travel = world.data.qpos[world.model.joint("button_cap_joint").qposadr[0]]
    assert travel >= LATCH_DEPTH and pressed[-1].get(robot, "z") > 0.2  # latched, hand up
    assert pressed[-1].get(pot, "heat") == 0.0  # off the plate: no heat
    placed = _run(env, pressed[-1], pick_phases(robot, pot) + place_phases(robot, pot, plate))
    assert POT_ON_PLATE.holds(placed[-1], (pot, plate))
    assert HAND_EMPTY.holds(placed[-1], (robot,))
    s = placed[-1]
    for _ in range(25):
        s = env.simulate(s, np.zeros(6))
    assert POT_HOT.holds(s, (pot,))


def test_liquid_rises_only_when_tilted_over_a_cup_and_pouring_on_the_table_spills(env):
    task = _hot_task(env, _task_with(env, True, lambda t: _rotation(t) < np.deg2rad(40)))
    s = task.init
    robot, pot = _obj(s, "robot"), _obj(s, "pot")
    cup = s.objects_of_type(CUP)[0]
    held = _run(env, s, pick_phases(robot, pot))[-1]
    phases = pour_phases(robot, pot, cup)
    over = _run(env, held, phases[:3])  # rise, carry, lower: upright over the cup
    assert POT_ABOVE_CUP.holds(over[-1], (pot, cup))
    assert all(x.get(cup, "liquid") == 0.0 for x in over)
    poured = _run(env, over[-1], phases[3:4])  # tilt until the cup holds its target
    tilts = np.array([x.get(pot, "tilt") for x in poured])
    liquid = np.array([x.get(cup, "liquid") for x in poured])
    rising = np.diff(liquid) > 0
    assert rising.any() and np.all(tilts[1:][rising] > POUR_TILT)
    assert CUP_FILLED.holds(poured[-1], (cup,))
    assert poured[-1].get(pot, "spilled") == 0.0
    assert not any(env.capabilities.dead_end(x) for x in (*over, *poured))
    # tilt back, carry it away from the cups and tilt over the table: a spill, and the
    # task has failed
    s = _run(env, poured[-1], phases[4:5])[-1]
    filled = s.get(cup, "liquid")
    goal = np.array([*(s.data[robot][:2] + np.array([0.0, 0.15])), SAFE_Z])
    for _ in range(30):
        s = env.simulate(s, np.array([*(0.5 * (goal - s.data[robot][:3])), 0.0, 0.0, -1.0]))
    assert NOT_ABOVE_CUP.holds(s, (robot, pot)) and s.get(pot, "spilled") == 0.0
    assert CUP_FILLED.holds(s, (cup,))
    for _ in range(25):
        s = env.simulate(s, np.array([0.0, 0.0, 0.0, 0.05, 0.0, -1.0]))
    assert s.get(pot, "tilt") > POUR_TILT and HOLDING.holds(s, (robot, pot))
    assert s.get(cup, "liquid") == filled
    assert s.get(pot, "spilled") == 1.0
    assert not CUP_FILLED.holds(s, (cup,))
    assert env.capabilities.dead_end(s)  # the planner's rollouts end here


def test_train_tasks_have_one_or_two_cups_and_eval_tasks_two_or_three(env):
    counts = {True: set(), False: set()}
    for train in (True, False):
        for i in range(12):
            task = env.task(i, 3, train)
            cups = task.init.objects_of_type(CUP)
            counts[train].add(len(cups))
            assert task.goal == {a for a in task.goal if a.predicate == CUP_FILLED}
            assert {a.objects[0] for a in task.goal} == set(cups)
    assert counts[True] == {1, 2} and counts[False] == {2, 3}
    assert {p.name for p in env.contact_predicates} == {
        "Holding",
        "HandEmpty",
        "CupFilled",
        "ButtonPressed",
    }
    assert env.capabilities.planning_defaults == {"n_abstract": 1000, "max_state_repeats": 1}


def test_wrist_and_tilt_actions_turn_the_hand(env):
    s = env.task(0, 0, True).init
    robot = _obj(s, "robot")
    for _ in range(10):
        s = env.simulate(s, np.array([0.0, 0.0, 0.0, 0.05, 0.08, 0.0]))
    for _ in range(10):
        s = env.simulate(s, np.zeros(6))
    assert s.get(robot, "wrist") == pytest.approx(0.8, abs=0.03)
    assert s.get(robot, "tilt") == pytest.approx(0.5, abs=0.03)


@pytest.mark.parametrize("bad", [np.full(6, np.nan), np.zeros(4), np.zeros((2, 6))])
def test_bad_actions_raise(env, bad):
    with pytest.raises(InvalidActionError):
        env.simulate(env.task(0, 0, True).init, bad)


@pytest.fixture(scope="module")
def demos(env):
    tasks = [
        _task_with(env, True, lambda t: not needs_twist(t.init, _obj(t.init, "pot"))),
        _task_with(env, False, lambda t: needs_twist(t.init, _obj(t.init, "pot"))),
        _task_with(env, False, lambda t: len(t.goal) == 3),
    ]
    return [run_demonstrator(env, task, seed=[5, k]) for k, task in enumerate(tasks)]


def test_the_demonstrator_solves_train_and_eval_tasks_including_a_twist(env, demos):
    for demo in demos:
        assert demo is not None, "the oracle must solve these seeded tasks"
        final = demo.states[-1]
        assert demo.task.goal <= abstract(final, env.goal_predicates)
        assert final.get(_obj(final, "pot"), "spilled") == 0.0
    twisted = demos[1]
    robot, pot = _obj(twisted.states[0], "robot"), _obj(twisted.states[0], "pot")
    assert any(TWISTING.holds(x, (robot, pot)) for x in twisted.states)
    assert abs(twisted.states[-1].get(pot, "rotation")) <= HANDLE_RULE


def test_the_knob_grasp_is_one_continuous_rule_per_side_within_the_wrist_range():
    """A learned grasp sampler fits one mode only if the demonstrator's grasp angle is a
    continuous function of the pot's rotation on each side (no jumps between face pairs)."""
    for side in (-1.0, 1.0):
        rotations = side * np.linspace(TWIST_ABOVE, np.deg2rad(120.0), 200)
        for target in (side * TWIST_TARGET[0], side * TWIST_TARGET[1]):
            grasps = np.array([knob_wrist(r, target) for r in rotations])
            faces = np.mod(grasps - rotations, np.pi / 2)
            assert np.allclose(np.minimum(faces, np.pi / 2 - faces), 0.0, atol=1e-9)
            assert np.max(np.abs(np.diff(grasps))) < 0.01  # no jump to another face pair
            turned = grasps + (target - rotations)
            # a quarter of the turn may slip in the fingers: still inside the limit
            slipped = turned + 0.25 * (target - rotations)
            assert np.all(np.abs(np.concatenate([grasps, slipped])) < WRIST_LIMITS[1])


def test_a_saved_demo_replays_bit_exactly(tmp_path, env, demos):
    path = tmp_path / "demos.h5"
    save_demonstrations(path, env, demos[:2])
    for i, demo in enumerate(load_demonstrations(path, env)):
        report = replay(env, demo, i)
        assert report.max_state_diff == 0.0 and report.max_feature_diff == 0.0
        assert report.goal_reached


def test_coffee_gym_env_passes_check_env():
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import mj_envs  # noqa: F401  (registers bpns/*-v0)

    genv = gym.make("bpns/Coffee-v0")
    check_env(genv.unwrapped, skip_render_check=True)
    obs, info = genv.reset(seed=0)
    assert genv.observation_space.contains(obs) and genv.action_space.shape == (6,)
    assert info["goal"]


def test_oracle_skills_solve_an_eval_task_needing_a_twist_through_the_planner(env):
    from bpns.planning.bilevel import plan
    from bpns.planning.config import planning_config_for

    task = _task_with(
        env, False, lambda t: len(t.goal) >= 2 and _rotation(t) > HANDLE_RULE + 0.2, seed=1
    )
    # the domain's declared planning defaults, with the oracle's few samples per step
    config = planning_config_for(env, n_samples=3, timeout=120.0, max_skill_horizon=250)
    result = plan(task, oracle_skills(env), env, config, np.random.default_rng(0))
    assert result.success, result.reason
    names = [op.name for op in result.skeleton.operators]
    assert names[:2] == ["Twist", "PickPotAfterTwist"]
    assert {"PlacePotOnPlate", "TurnOnPlate", "PourFromNothing", "PourFromOtherCup"} <= set(names)
    state = task.init
    for action in result.actions:  # f is exact: the returned actions solve the task
        state = env.simulate(state, action)
    assert task.goal <= abstract(state, env.goal_predicates)
