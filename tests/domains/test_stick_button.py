"""Stick Button in physics: latching buttons, reach, holder collisions, oracle, replay."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from bpns.approaches.bilevel import oracle_skills
from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demos import replay, run_demonstrator
from bpns.env.abstraction import abstract
from bpns.env.registry import make_environment as make_env
from bpns.planning.bilevel import plan
from bpns.planning.config import planning_config_for
from bpns.structs import Object, State, Task
from mj_envs.domains.stick_button.behaviours import (
    FINGER_REACH,
    GRASP_MIN,
    SAFE_Z,
    grasp_point,
    move_action,
    stick_in_hand,
)
from mj_envs.domains.stick_button.rules import BUTTON, GRASPED, PRESSED, STICK_HEIGHT
from mj_envs.domains.stick_button.skills import APPROACH_CLEARANCE
from mj_envs.parts.button import CAP_RADIUS, LATCH_DEPTH, PRESSED_RGBA
from mj_envs.robots.panda import FINGERTIP_DROP


@pytest.fixture(scope="module")
def env():
    return make_env("stick_button")


def _obj(state: State, name: str) -> Object:
    return next(o for o in state.objects if o.name == name)


def _is_far(state: State, button: Object) -> bool:
    return float(np.hypot(*state.data[button][:2])) > FINGER_REACH


def _task_with(env, train: bool, want: Callable[[Task], bool]) -> Task:
    """The first task of the seed-0 stream with a wanted property (deterministic)."""
    for i in range(50):
        task = env.task(i, 0, train)
        if want(task):
            return task
    raise AssertionError("no such task in the first 50")


def _has(task: Task, far: bool) -> bool:
    s = task.init
    return any(_is_far(s, b) == far for b in s.objects_of_type(BUTTON))


def _button(task: Task, far: bool) -> Object:
    s = task.init
    return next(b for b in s.objects_of_type(BUTTON) if _is_far(s, b) == far)


def _drive(env, s: State, goal: np.ndarray, grip: float, steps: int, until=None) -> list[State]:
    """Proportional moves toward ``goal``; returns every state visited."""
    robot = _obj(s, "robot")
    out = []
    for _ in range(steps):
        s = env.simulate(s, move_action(s, robot, goal, grip))
        out.append(s)
        if until is not None and until(s):
            break
    return out


def _travel(world_state: State, button: Object) -> float:
    world = world_state.sim.world
    world.load(world_state.sim.flat)
    return float(world.data.qpos[world.model.joint(f"{button.name}_cap_joint").qposadr[0]])


def _pads_on(state: State, geom_prefix: str) -> set[str]:
    """Finger geoms in MuJoCo's contact list with geoms whose name starts with a prefix."""
    world = state.sim.world
    world.load(state.sim.flat)
    m, d = world.model, world.data
    fingers = {
        m.geom(f"panda/{n}").id: n
        for n in ("left_pad", "right_pad", "left_finger_col", "right_finger_col")
    }
    out = set()
    for c in d.contact[: d.ncon]:
        a, b = int(c.geom1), int(c.geom2)
        for f, o in ((a, b), (b, a)):
            if f in fingers and (m.geom(o).name or "").startswith(geom_prefix) and c.dist <= 0:
                out.add(fingers[f])
    return out


def _above_button(env, s: State, button: Object, clearance: float) -> list[State]:
    """Closed fingers to the travel height, over the cap, then down to just above it."""
    bx, by, top = s.data[button][:3]
    states = _drive(env, s, np.array([bx, by, SAFE_Z]), -1.0, 60)
    return states + _drive(
        env, states[-1], np.array([bx, by, top + clearance + FINGERTIP_DROP]), -1.0, 40
    )


def test_pressed_flips_when_the_cap_passes_the_latch_depth_and_stays_latched(env):
    task = _task_with(env, True, lambda t: _has(t, far=False))
    button = _button(task, far=False)
    s = _above_button(env, task.init, button, APPROACH_CLEARANCE)[-1]
    assert not PRESSED.holds(s, (button,))
    pushed = []
    for _ in range(30):  # push down 3 mm per step until the joint reads Pressed
        s = env.simulate(s, np.array([0.0, 0.0, -0.003, -1.0]))
        pushed.append(s)
        if PRESSED.holds(s, (button,)):
            break
    travels = [_travel(x, button) for x in pushed]
    flags = [PRESSED.holds(x, (button,)) for x in pushed]
    assert flags[-1] and not any(flags[:-1])
    assert travels[-1] >= LATCH_DEPTH > max(travels[:-1])  # the reading decides
    # lift the hand away and wait: the latch holds the cap down, and it is drawn green
    bx, by = s.data[button][:2]
    after = _drive(env, s, np.array([bx, by, SAFE_Z]), -1.0, 30)
    assert all(PRESSED.holds(x, (button,)) for x in after)
    assert min(_travel(x, button) for x in after) >= LATCH_DEPTH
    world = after[-1].sim.world
    world.load(after[-1].sim.flat)
    env.decorate(world)
    cap = world.model.geom(f"{button.name}_cap_geom").id
    assert np.allclose(world.model.geom_rgba[cap], PRESSED_RGBA)


def test_a_button_pushed_short_of_the_latch_depth_springs_back_unpressed(env):
    task = _task_with(env, True, lambda t: _has(t, far=False))
    button = _button(task, far=False)
    s = _above_button(env, task.init, button, APPROACH_CLEARANCE)[-1]
    for _ in range(30):
        s = env.simulate(s, np.array([0.0, 0.0, -0.002, -1.0]))
        if _travel(s, button) > LATCH_DEPTH / 2:
            break
    assert LATCH_DEPTH / 2 < _travel(s, button) < LATCH_DEPTH
    bx, by = s.data[button][:2]
    after = _drive(env, s, np.array([bx, by, SAFE_Z]), -1.0, 20)
    assert not any(PRESSED.holds(x, (button,)) for x in after)
    assert _travel(after[-1], button) < 0.001


def test_the_fingertips_cannot_reach_a_far_button(env):
    task = _task_with(env, True, lambda t: _has(t, far=True))
    button = _button(task, far=True)
    bx, by, top = task.init.data[button][:3]
    states = _above_button(env, task.init, button, -0.01)  # aim 1 cm into the cap
    states += _drive(env, states[-1], np.array([bx, by, top]), -1.0, 60)
    robot = _obj(task.init, "robot")
    gaps = [np.hypot(x.get(robot, "x") - bx, x.get(robot, "y") - by) for x in states]
    assert not any(PRESSED.holds(x, (button,)) for x in states)
    assert min(gaps) > CAP_RADIUS + 0.03  # the arm is stretched out well short of the cap
    assert _travel(states[-1], button) < 0.001


def _grasp_attempt(env, task: Task, offset: float) -> list[State]:
    """Open, go above the stick ``offset`` from its back end, descend, close, lift."""
    s = task.init
    stick = _obj(s, "stick")
    goal = grasp_point(s, stick, offset)
    states = _drive(env, s, np.array([goal[0], goal[1], SAFE_Z]), 1.0, 60)
    states += _drive(env, states[-1], goal, 1.0, 40)
    for _ in range(15):
        states.append(env.simulate(states[-1], move_action(states[-1], _obj(s, "robot"), goal, -1)))
    states += _drive(env, states[-1], np.array([goal[0], goal[1], SAFE_Z]), -1.0, 40)
    return states


def test_grasping_over_the_holder_collides_and_along_the_free_part_succeeds(env):
    task = env.task(0, 0, True)
    robot, stick = _obj(task.init, "robot"), _obj(task.init, "stick")
    grasped = (robot, stick)

    blocked = _grasp_attempt(env, task, offset=0.06)  # the back 12 cm lie in the holder
    assert not any(GRASPED.holds(x, grasped) for x in blocked)
    lowest = min(blocked, key=lambda x: x.get(robot, "z"))
    assert lowest.get(robot, "z") - FINGERTIP_DROP > STICK_HEIGHT  # fingers stopped on top
    assert _pads_on(lowest, "holder")  # ... of the holder's walls (contact list)
    assert blocked[-1].get(stick, "z") < STICK_HEIGHT  # the stick never left the table

    held = _grasp_attempt(env, task, offset=GRASP_MIN + 0.02)
    flags = [GRASPED.holds(x, grasped) for x in held]
    assert flags[-1] and any(flags) and not flags[0]
    first = flags.index(True)
    assert _pads_on(held[first], "stick") >= {"left_pad", "right_pad"}
    assert held[-1].get(stick, "z") > SAFE_Z - 0.03  # lifted by friction alone


def test_train_tasks_have_one_or_two_buttons_and_eval_tasks_three_or_four(env):
    counts = {True: set(), False: set()}
    far = set()
    for train in (True, False):
        for i in range(12):
            task = env.task(i, 3, train)
            buttons = task.init.objects_of_type(BUTTON)
            counts[train].add(len(buttons))
            assert task.goal == {a for a in task.goal if a.predicate == PRESSED}
            assert {a.objects[0] for a in task.goal} == set(buttons)
            far |= {_is_far(task.init, b) for b in buttons}
    assert counts[True] == {1, 2} and counts[False] == {3, 4}
    assert far == {True, False}
    assert env.contact_predicates == {GRASPED, PRESSED}


def test_every_task_starts_with_the_hand_above_no_button(env):
    """No button is sampled under the home gripper (the learned skills start from there)."""
    for train in (True, False):
        for i in range(40):
            atoms = abstract(env.task(i, 0, train).init, env.predicates)
            assert any(a.predicate.name == "AboveNoButton" for a in atoms), (train, i)


@pytest.fixture(scope="module")
def demos(env):
    tasks = [
        _task_with(env, True, lambda t: _has(t, far=True)),
        _task_with(env, False, lambda t: _has(t, far=True) and _has(t, far=False)),
    ]
    return [run_demonstrator(env, task, seed=[9, k]) for k, task in enumerate(tasks)]


def test_the_demonstrator_presses_near_buttons_by_hand_and_far_ones_with_the_stick(env, demos):
    for demo in demos:
        assert demo is not None, "the oracle must solve these seeded tasks"
        final = demo.states[-1]
        assert demo.task.goal <= abstract(final, env.goal_predicates)
        robot, stick = _obj(final, "robot"), _obj(final, "stick")
        assert GRASPED.holds(final, (robot, stick))  # a far button needed the stick
    assert any(len(d.task.goal) >= 3 for d in demos)


def test_a_saved_demo_replays_bit_exactly(tmp_path, env, demos):
    path = tmp_path / "demos.h5"
    save_demonstrations(path, env, demos)
    for i, demo in enumerate(load_demonstrations(path, env)):
        report = replay(env, demo, i)
        assert report.max_state_diff == 0.0 and report.max_feature_diff == 0.0
        assert report.goal_reached


def test_oracle_skills_solve_an_eval_task_needing_hand_and_stick_through_the_planner(env):
    task = _task_with(
        env,
        False,
        lambda t: _has(t, far=True) and _has(t, far=False) and len(t.goal) == 3,
    )
    # the domain's declared planning defaults (N_abstract=1000) with few samples per step:
    # oracle samplers seldom need a second try
    config = planning_config_for(env, n_samples=1, timeout=60.0, max_skill_horizon=150)
    result = plan(task, oracle_skills(env), env, config, np.random.default_rng(0))
    assert result.success, result.reason
    names = [op.name for op in result.skeleton.operators]
    assert any(n.startswith("RobotPress") for n in names)
    assert any(n.startswith("StickPress") for n in names)
    state = task.init
    for action in result.actions:  # f is exact: the returned actions solve the task
        state = env.simulate(state, action)
    assert task.goal <= abstract(state, env.goal_predicates)


def _backed_off(env, task: Task, failed_at: State):
    """A WorldRun from ``failed_at`` (where a failed skill left the world) after the
    environment's back-off: whether it got there, the run; its actions replay exactly."""
    from bpns.acting.world import BACK_OFF, WorldRun
    from bpns.execution.executor import RolloutConfig

    run = WorldRun(env, task, RolloutConfig(), None)
    run.state = failed_at
    done = run.back_off()
    (step,) = run.rollout().steps
    assert step.operator == BACK_OFF
    s = failed_at
    for action in run.action_array():
        s = env.simulate(s, action)
    assert np.array_equal(s.sim.flat, run.state.sim.flat)
    return done, run


def test_the_back_off_lets_go_and_returns_the_hand_to_its_start_when_nothing_is_held(env):
    # a closed loop's last resort: the hand closed on nothing above the holder (a failed
    # pick) opens and ends where the task began (what every demonstration starts from);
    # the motion runs in physics through WorldRun and replays exactly
    from mj_envs.oracles.motions import OPEN_FINGERS

    task = env.task(0, 0, True)
    robot, stick = _obj(task.init, "robot"), _obj(task.init, "stick")
    missed = _grasp_attempt(env, task, offset=0.06)[-1]  # fingers shut on the holder walls
    assert not GRASPED.holds(missed, (robot, stick)) and missed.get(robot, "fingers") < 0.01
    done, run = _backed_off(env, task, missed)
    end = run.state
    assert done and run.rollout().steps[0].outcome == "reached"
    assert end.get(robot, "fingers") >= OPEN_FINGERS - 0.002
    start_hand = task.init.data[robot][:3]
    assert np.all(np.abs(end.data[robot][:3] - start_hand) <= 0.02)
    assert end.get(stick, "z") < STICK_HEIGHT  # the stick stayed on the table


def test_the_back_off_keeps_a_held_stick_and_only_rises_to_the_travel_height(env):
    # a stick press stopped at its horizon with the stick still in hand: letting go would
    # drop it where no plan picks it again; rising with it is where a second press starts
    task = env.task(0, 0, True)
    robot, stick = _obj(task.init, "robot"), _obj(task.init, "stick")
    attempt = _grasp_attempt(env, task, offset=GRASP_MIN + 0.02)
    low = next(x for x in attempt if GRASPED.holds(x, (robot, stick)))  # just closed on it
    assert low.get(robot, "z") < SAFE_Z - 0.05
    done, run = _backed_off(env, task, low)
    end = run.state
    assert done and GRASPED.holds(end, (robot, stick))
    assert abs(end.get(robot, "z") - SAFE_Z) <= 0.02
    assert np.all(np.abs(end.data[robot][:2] - low.data[robot][:2]) <= 0.02)  # straight up
    assert end.get(stick, "z") > SAFE_Z - 0.05  # carried up with the hand


def test_a_stick_between_the_fingers_is_in_hand_though_no_pad_touches_it(env):
    task = env.task(0, 0, True)
    robot, stick = _obj(task.init, "robot"), _obj(task.init, "stick")
    held = _grasp_attempt(env, task, offset=GRASP_MIN + 0.02)
    grasped = [GRASPED.holds(x, (robot, stick)) for x in held]
    assert all(stick_in_hand(x) for x, g in zip(held, grasped, strict=True) if g)
    closing = held[grasped.index(True) - 1]  # closing round it, the pads not on it yet
    assert not grasped[grasped.index(True) - 1] and stick_in_hand(closing)
    assert not stick_in_hand(task.init)  # the hand far above it
    shut = _grasp_attempt(env, task, offset=0.06)[-1]  # closed on the holder's walls
    assert shut.get(robot, "fingers") < 0.01 and not stick_in_hand(shut)


def test_the_back_off_closes_again_on_a_stick_still_between_the_fingers(env):
    # under latency a press can shake one pad off the stick while the hand still lifts
    # it: the grasped reading drops, and a back-off that let go dropped the stick
    task = env.task(0, 0, True)
    robot, stick = _obj(task.init, "robot"), _obj(task.init, "stick")
    held = _grasp_attempt(env, task, offset=GRASP_MIN + 0.02)
    grasped = [GRASPED.holds(x, (robot, stick)) for x in held]
    loose = held[grasped.index(True) - 1]
    assert not GRASPED.holds(loose, (robot, stick)) and stick_in_hand(loose)
    done, run = _backed_off(env, task, loose)
    end = run.state
    assert done and GRASPED.holds(end, (robot, stick))
    assert abs(end.get(robot, "z") - SAFE_Z) <= 0.02
    assert end.get(stick, "z") > SAFE_Z - 0.05  # carried up with the hand
