"""Tiny pure-numpy environments with hand-written skills, for the planning tests.

ToyStickButton (1D): a robot on a line can only reach x in [0, REACH]; buttons beyond
that must be pressed with the tip of a stick. Where the robot grips the stick (chosen by
the PickStick sampler) decides how far the tip reaches, so a bad grip only shows up one
step later, when PressWithStick gets stuck at the reach limit: refinement must backtrack.
PressDirect on a far button is the shortest abstract plan but is never refinable.

ToyLights: lights toggled on and off; symbolic only, for search-heavy tests.

Also: hand-made propositional STRIPS problems (nullary atoms) and brute-force reference
values (h*, h+) for the heuristic and search tests.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Hashable, Iterable, Sequence

import numpy as np

from bpns.env.environment import Capabilities
from bpns.planning.strips import GroundProblem
from bpns.structs import (
    GroundAtom,
    GroundOperator,
    LiftedAtom,
    Object,
    Predicate,
    Skill,
    State,
    STRIPSOperator,
    Task,
    Type,
    Variable,
)

REACH = 5.0
SPEED = 0.5
TOL = 0.1

ROBOT = Type("robot", ("x", "holding"))
STICK = Type("stick", ("x", "length", "held", "offset"))
BUTTON = Type("button", ("x", "pressed"))

HAND_EMPTY = Predicate("HandEmpty", (ROBOT,), lambda s, o: s.get(o[0], "holding") < 0.5)
HOLDING = Predicate(
    "Holding",
    (ROBOT, STICK),
    lambda s, o: s.get(o[0], "holding") > 0.5 and s.get(o[1], "held") > 0.5,
)
PRESSED = Predicate("Pressed", (BUTTON,), lambda s, o: s.get(o[0], "pressed") > 0.5)

_R, _S, _B = Variable("?r", ROBOT), Variable("?s", STICK), Variable("?b", BUTTON)
PRESS_DIRECT = STRIPSOperator(
    "PressDirect",
    (_R, _B),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,))}),
    frozenset({LiftedAtom(PRESSED, (_B,))}),
    frozenset(),
)
PICK_STICK = STRIPSOperator(
    "PickStick",
    (_R, _S),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,))}),
    frozenset({LiftedAtom(HOLDING, (_R, _S))}),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,))}),
)
PRESS_WITH_STICK = STRIPSOperator(
    "PressWithStick",
    (_R, _S, _B),
    frozenset({LiftedAtom(HOLDING, (_R, _S))}),
    frozenset({LiftedAtom(PRESSED, (_B,))}),
    frozenset(),
)
PLACE_STICK = STRIPSOperator(
    "PlaceStick",
    (_R, _S),
    frozenset({LiftedAtom(HOLDING, (_R, _S))}),
    frozenset({LiftedAtom(HAND_EMPTY, (_R,))}),
    frozenset({LiftedAtom(HOLDING, (_R, _S))}),
)


class ToyStickButton:
    """Environment protocol implementation; action = (dx, grip) in [-1, 1]^2."""

    name = "toy_stick_button"
    contact_settle_steps = 1
    capabilities = Capabilities()

    @property
    def types(self) -> frozenset[Type]:
        return frozenset({ROBOT, STICK, BUTTON})

    @property
    def predicates(self) -> frozenset[Predicate]:
        return frozenset({HAND_EMPTY, HOLDING, PRESSED})

    @property
    def contact_predicates(self) -> frozenset[Predicate]:
        return frozenset({HAND_EMPTY, HOLDING, PRESSED})

    @property
    def goal_predicates(self) -> frozenset[Predicate]:
        return frozenset({PRESSED})

    @property
    def action_low(self) -> np.ndarray:
        return np.array([-1.0, -1.0])

    @property
    def action_high(self) -> np.ndarray:
        return np.array([1.0, 1.0])

    def train_tasks(self, n: int, seed: int) -> list[Task]:
        rng = np.random.default_rng(seed)
        return [make_task(list(rng.uniform(0.5, 8.5, size=rng.integers(1, 3)))) for _ in range(n)]

    def eval_tasks(self, n: int, seed: int) -> list[Task]:
        return self.train_tasks(n, seed + 1)

    def task(self, index: int, seed: int, train: bool) -> Task:
        rng = np.random.default_rng([seed, index, int(train)])
        return make_task(list(rng.uniform(0.5, 8.5, size=rng.integers(1, 3))))

    def check_action(self, action: np.ndarray) -> np.ndarray:
        action = np.asarray(action, dtype=np.float64)
        if action.shape != (2,) or not np.isfinite(action).all():
            raise ValueError(f"bad action {action!r}")
        return np.clip(action, self.action_low, self.action_high)

    def demonstrator(self, task: Task, rng: np.random.Generator):
        raise NotImplementedError("the planning tests need no demonstrations")

    def render(self, states, camera: str, width: int, height: int):
        return iter(np.zeros((height, width, 3), dtype=np.uint8) for _ in states)

    def scene(self, states):
        return None  # no 3D scene to show

    def simulate(self, state: State, action: np.ndarray) -> State:
        data = {o: v.copy() for o, v in state.data.items()}
        robot = next(o for o in data if o.type == ROBOT)
        stick = next(o for o in data if o.type == STICK)
        r, s = data[robot], data[stick]
        dx, grip = float(action[0]), float(action[1])
        r[0] = min(max(r[0] + SPEED * dx, 0.0), REACH)
        if r[1] > 0.5:
            s[0] = r[0] - s[3]
        if grip > 0.5 and r[1] < 0.5 and s[0] <= r[0] <= s[0] + s[1]:
            r[1], s[2], s[3] = 1.0, 1.0, r[0] - s[0]
        elif grip < -0.5 and r[1] > 0.5:
            r[1], s[2] = 0.0, 0.0
        tip = s[0] + s[1]
        for o, v in data.items():
            if o.type == BUTTON:
                touching = abs(tip - v[0]) < TOL if r[1] > 0.5 else abs(r[0] - v[0]) < TOL
                if touching:
                    v[1] = 1.0
        return State(data)

    def save_world(self, world: Hashable) -> str:
        return ""

    def load_world(self, text: str) -> Hashable:
        return None

    def state_from_flat(self, world: Hashable, flat: np.ndarray, like: State) -> State:
        out, k = {}, 0
        for o in like.objects:
            out[o] = np.asarray(flat[k : k + o.type.dim], dtype=np.float64).copy()
            k += o.type.dim
        return State(out)


class SlowEnv(ToyStickButton):
    """Same dynamics, but every simulation step sleeps (for timeout tests)."""

    def __init__(self, delay: float) -> None:
        self.delay = delay

    def simulate(self, state: State, action: np.ndarray) -> State:
        time.sleep(self.delay)
        return super().simulate(state, action)


def fell_off(state: State) -> bool:
    robot = next(o for o in state.objects if o.type == ROBOT)
    return state.get(robot, "x") >= REACH


class CliffEnv(ToyStickButton):
    """The track ends at the robot's reach: a robot that gets there has fallen off, from
    where no goal can be reached (a declared dead end)."""

    capabilities = Capabilities(dead_end=fell_off)


def objects(n_buttons: int) -> tuple[Object, Object, list[Object]]:
    return (
        Object("robot", ROBOT),
        Object("stick", STICK),
        [Object(f"button{i}", BUTTON) for i in range(n_buttons)],
    )


def make_task(
    button_xs: Sequence[float],
    pressed: Sequence[bool] | None = None,
    horizon: int = 1000,
    stick_x: float = 1.0,
) -> Task:
    """Robot at 0, a 4-long stick lying on [stick_x, stick_x + 4]; goal: all buttons pressed."""
    robot, stick, buttons = objects(len(button_xs))
    pressed = pressed or [False] * len(button_xs)
    data = {robot: np.array([0.0, 0.0]), stick: np.array([stick_x, 4.0, 0.0, 0.0])}
    for b, x, p in zip(buttons, button_xs, pressed, strict=True):
        data[b] = np.array([float(x), float(p)])
    return Task(State(data), frozenset(GroundAtom(PRESSED, (b,)) for b in buttons), horizon)


def _toward(x: float, goal: float) -> float:
    return float(np.clip((goal - x) / SPEED, -1.0, 1.0))


def press_direct_policy(state: State, objs: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    return np.array([_toward(state.get(objs[0], "x"), subgoal[0]), 0.0])


def press_direct_sampler(
    state: State, objs: Sequence[Object], rng: np.random.Generator
) -> np.ndarray:
    g = state.vec(objs).copy()
    g[0] = state.get(objs[1], "x")  # robot x := button x
    return g


def pick_policy(state: State, objs: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    x = state.get(objs[0], "x")
    near = abs(subgoal[0] - x) <= SPEED
    return np.array([_toward(x, subgoal[0]), 1.0 if near else 0.0])


class PickSampler:
    """Grip point uniform along the stick (or always ``good`` if given); the first
    ``bad_first`` draws grip far back, too far for the tip to reach a far button."""

    def __init__(self, bad_first: int = 0, good: float | None = None) -> None:
        self.bad_first = bad_first
        self.good = good
        self.calls = 0

    def __call__(
        self, state: State, objs: Sequence[Object], rng: np.random.Generator
    ) -> np.ndarray:
        self.calls += 1
        g = state.vec(objs).copy()
        sx, length = state.get(objs[1], "x"), state.get(objs[1], "length")
        if self.calls <= self.bad_first:
            offset = 3.5
        else:
            offset = self.good if self.good is not None else rng.uniform(0.0, length)
        g[0] = sx + offset
        return g


def press_stick_policy(state: State, objs: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    return np.array([_toward(state.get(objs[0], "x"), subgoal[0]), 0.0])


def press_stick_sampler(
    state: State, objs: Sequence[Object], rng: np.random.Generator
) -> np.ndarray:
    g = state.vec(objs).copy()
    bx = state.get(objs[2], "x")
    g[0] = bx - state.get(objs[1], "length") + state.get(objs[1], "offset")  # tip on button
    return g


def place_policy(state: State, objs: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    return np.array([0.0, -1.0])


def place_sampler(state: State, objs: Sequence[Object], rng: np.random.Generator) -> np.ndarray:
    return state.vec(objs).copy()


def skills(
    pick_bad_first: int = 0,
    pick_good: float | None = None,
    press_direct_policy_fn=None,
    press_direct_sampler_fn=None,
) -> list[Skill]:
    """Oracle skills; the optional arguments swap in misbehaving pieces."""
    return [
        Skill(
            PRESS_DIRECT,
            press_direct_policy_fn or press_direct_policy,
            press_direct_sampler_fn or press_direct_sampler,
        ),
        Skill(PICK_STICK, pick_policy, PickSampler(pick_bad_first, pick_good)),
        Skill(PRESS_WITH_STICK, press_stick_policy, press_stick_sampler),
        Skill(PLACE_STICK, place_policy, place_sampler),
    ]


# ---------------------------------------------------------------- ToyLights (symbolic)

LIGHT = Type("light", ("on", "index"))
ON = Predicate("On", (LIGHT,), lambda s, o: s.get(o[0], "on") > 0.5)
OFF = Predicate("Off", (LIGHT,), lambda s, o: s.get(o[0], "on") < 0.5)
_L = Variable("?l", LIGHT)
TURN_ON = STRIPSOperator(
    "TurnOn",
    (_L,),
    frozenset({LiftedAtom(OFF, (_L,))}),
    frozenset({LiftedAtom(ON, (_L,))}),
    frozenset({LiftedAtom(OFF, (_L,))}),
)
TURN_OFF = STRIPSOperator(
    "TurnOff",
    (_L,),
    frozenset({LiftedAtom(ON, (_L,))}),
    frozenset({LiftedAtom(OFF, (_L,))}),
    frozenset({LiftedAtom(ON, (_L,))}),
)


class ToyLights:
    """Action i > 0.5 toggles light i (index feature); one action per light."""

    name = "toy_lights"
    contact_settle_steps = 1
    capabilities = Capabilities()

    def __init__(self, n: int) -> None:
        self.n = n

    types = property(lambda self: frozenset({LIGHT}))
    predicates = property(lambda self: frozenset({ON, OFF}))
    contact_predicates = property(lambda self: frozenset({ON, OFF}))
    goal_predicates = property(lambda self: frozenset({ON, OFF}))
    action_low = property(lambda self: np.zeros(self.n))
    action_high = property(lambda self: np.ones(self.n))

    def train_tasks(self, n: int, seed: int) -> list[Task]:
        return []

    eval_tasks = train_tasks

    def task(self, index: int, seed: int, train: bool) -> Task:
        return lights_task(self.n, frozenset())

    def check_action(self, action: np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(action, dtype=np.float64), 0.0, 1.0)

    def demonstrator(self, task: Task, rng: np.random.Generator):
        raise NotImplementedError("the planning tests need no demonstrations")

    def render(self, states, camera: str, width: int, height: int):
        return iter(np.zeros((height, width, 3), dtype=np.uint8) for _ in states)

    def scene(self, states):
        return None  # no 3D scene to show

    def simulate(self, state: State, action: np.ndarray) -> State:
        data = {}
        for o, v in state.data.items():
            v = v.copy()
            if action[int(v[1])] > 0.5:
                v[0] = 1.0 - v[0]
            data[o] = v
        return State(data)

    def save_world(self, world: Hashable) -> str:
        return ""

    def load_world(self, text: str) -> Hashable:
        return None

    def state_from_flat(self, world: Hashable, flat: np.ndarray, like: State) -> State:
        return like


def lights(n: int) -> list[Object]:
    return [Object(f"light{i:02d}", LIGHT) for i in range(n)]


def lights_task(n: int, goal: frozenset[GroundAtom], horizon: int = 1000) -> Task:
    return Task(
        State({o: np.array([0.0, float(i)]) for i, o in enumerate(lights(n))}), goal, horizon
    )


def _toggle_policy(state: State, objs: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
    a = np.zeros(int(max(state.get(o, "index") for o in state.objects)) + 1)
    a[int(state.get(objs[0], "index"))] = 1.0
    return a


def _noop_sampler(state: State, objs: Sequence[Object], rng: np.random.Generator) -> np.ndarray:
    return state.vec(objs).copy()


def light_skills() -> list[Skill]:
    return [
        Skill(TURN_ON, _toggle_policy, _noop_sampler),
        Skill(TURN_OFF, _toggle_policy, _noop_sampler),
    ]


# ------------------------------------------------- propositional problems (nullary atoms)


def atom(name: str) -> GroundAtom:
    """A nullary ground atom (a proposition)."""
    return GroundAtom(Predicate(name, (), lambda s, o: False), ())


def op(
    name: str, pre: Iterable[str] = (), add: Iterable[str] = (), delete: Iterable[str] = ()
) -> GroundOperator:
    def lifted(xs: Iterable[str]) -> frozenset[LiftedAtom]:
        return frozenset(LiftedAtom(atom(x).predicate, ()) for x in xs)

    return STRIPSOperator(name, (), lifted(pre), lifted(add), lifted(delete)).ground(())


def problem(
    ops: Sequence[GroundOperator], init: Iterable[str], goal: Iterable[str]
) -> GroundProblem:
    return GroundProblem.from_ground_operators(
        ops, {atom(x) for x in init}, {atom(x) for x in goal}
    )


def optimal_cost(p: GroundProblem, start: int) -> float:
    """h*: breadth-first search over real states (unit costs)."""
    seen, queue = {start}, deque([(start, 0)])
    while queue:
        s, d = queue.popleft()
        if p.is_goal(s):
            return float(d)
        for _, t in p.successors(s):
            if t not in seen:
                seen.add(t)
                queue.append((t, d + 1))
    return math.inf


def relaxed_optimal_cost(p: GroundProblem, start: int) -> float:
    """h+: breadth-first search over delete-relaxed states (atoms only accumulate)."""
    seen, queue = {start}, deque([(start, 0)])
    while queue:
        s, d = queue.popleft()
        if p.is_goal(s):
            return float(d)
        for i, pre in enumerate(p.pre):
            if s & pre == pre:
                t = s | p.add[i]
                if t not in seen:
                    seen.add(t)
                    queue.append((t, d + 1))
    return math.inf


def reachable_states(p: GroundProblem) -> list[int]:
    seen, queue = {p.init}, deque([p.init])
    while queue:
        s = queue.popleft()
        for _, t in p.successors(s):
            if t not in seen:
                seen.add(t)
                queue.append(t)
    return sorted(seen)


def random_problem(rng: np.random.Generator, n_atoms: int = 6, n_ops: int = 9) -> GroundProblem:
    names = [f"p{i}" for i in range(n_atoms)]

    def pick(lo: int, hi: int) -> list[str]:
        return list(rng.choice(names, size=int(rng.integers(lo, hi + 1)), replace=False))

    ops = [op(f"o{i}", pick(0, 2), pick(1, 2), pick(0, 2)) for i in range(n_ops)]
    return problem(ops, pick(1, 2), pick(1, 3))
