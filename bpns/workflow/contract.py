"""Check that an environment keeps the contract bpns relies on (``bpns check-env``).

Each check exercises one promise of :class:`bpns.env.environment.Environment` the way the
rest of bpns uses it (seeded task streams, workers that rebuild environments by name and
receive pickled tasks, exact re-simulation, predicates evaluated on every state, saved
demonstrations that replay) and reports a broken promise as one :class:`Violation`.
A check that cannot run (no Gymnasium id) leaves a note instead.
"""

from __future__ import annotations

import itertools
import pickle
import tempfile
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np

from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demo_attempts import attempt_demonstration
from bpns.data.demos import replay
from bpns.env.environment import Environment, declaration_problem
from bpns.env.registry import GROUP
from bpns.learning.config import learning_config_for
from bpns.planning.config import planning_config_for
from bpns.structs import Demonstration, Object, Predicate, State, Task


@dataclass(frozen=True)
class Violation:
    """One broken promise: which check, and what is wrong, in one line."""

    check: str
    message: str

    def __str__(self) -> str:
        return f"{self.check}: {self.message}"


@dataclass(frozen=True)
class ContractConfig:
    n_tasks: int = 3  # tasks per stream sampled and checked
    seed: int = 0
    n_demos: int = 2  # train tasks the demonstrator must solve (and whose demos replay)
    rollout_steps: int = 10  # random-action steps for the determinism and predicate checks
    gym: bool = True  # run Gymnasium's check_env on the environment's Gym ids
    only: frozenset[str] | None = None  # run only the checks of these names


@dataclass
class ContractReport:
    violations: list[Violation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    checks: list[str] = field(default_factory=list)  # the checks that ran


def check_environment(env: Environment, n_tasks: int = 3, seed: int = 0, **kw) -> list[Violation]:
    """The contract violations of ``env`` (empty when it keeps the contract)."""
    return run_checks(env, ContractConfig(n_tasks=n_tasks, seed=seed, **kw)).violations


def run_checks(env: Environment, config: ContractConfig = ContractConfig()) -> ContractReport:
    report = ContractReport()
    ctx = _Context(env, config, report)
    for name, check in CHECKS:
        if config.only is not None and name not in config.only:
            continue
        report.checks.append(name)
        try:
            check(ctx)
        except Exception as err:  # noqa: BLE001  (a crashing check is a violation, named)
            ctx.fail(name, f"raised {type(err).__name__}: {err}")
    return report


@dataclass
class _Context:
    env: Environment
    config: ContractConfig
    report: ContractReport
    tasks: list[Task] = field(default_factory=list)
    demos: list[Demonstration] = field(default_factory=list)

    def task_list(self) -> list[Task]:
        """The first train tasks (sampled here when the tasks check did not run)."""
        if not self.tasks:
            self.tasks = self.env.train_tasks(self.config.n_tasks, self.config.seed)
        return self.tasks

    def fail(self, check: str, message: str) -> None:
        self.report.violations.append(Violation(check, message))


# -- helpers -------------------------------------------------------------------------------
def _same_state(a: State, b: State) -> str | None:
    """None if ``a`` and ``b`` are bit-identical (features and simulator state), else why."""
    if set(a.data) != set(b.data):
        return "different objects"
    for obj in a.data:
        if not np.array_equal(a.data[obj], b.data[obj]):
            return f"features of {obj.name} differ"
    if (a.sim is None) != (b.sim is None):
        return "one has a simulator state, the other not"
    if a.sim is not None and not np.array_equal(a.sim.flat, b.sim.flat):
        return "simulator states differ"
    return None


def _same_task(a: Task, b: Task) -> str | None:
    if a.goal != b.goal:
        return "goals differ"
    if a.horizon != b.horizon:
        return "horizons differ"
    return _same_state(a.init, b.init)


def _random_actions(env: Environment, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    low, high = np.asarray(env.action_low), np.asarray(env.action_high)
    return rng.uniform(low, high, size=(n, len(low)))


def _rollout(env: Environment, state: State, actions: np.ndarray) -> list[State]:
    states = [state]
    for a in actions:
        states.append(env.simulate(states[-1], a))
    return states


def _groundings(pred: Predicate, objects: Sequence[Object]) -> list[tuple[Object, ...]]:
    pools = [[o for o in objects if o.type == t] for t in pred.types]
    return [c for c in itertools.product(*pools) if len(set(c)) == len(c)]


# -- the checks ------------------------------------------------------------------------------
def check_name(ctx: _Context) -> None:
    cls = type(ctx.env)
    target = f"{cls.__module__}:{cls.__qualname__}"
    names = [ep.name for ep in entry_points(group=GROUP) if ep.value.replace(" ", "") == target]
    if not names:
        ctx.fail("name", f"{target} is not registered under the {GROUP!r} entry points")
    elif ctx.env.name not in names:
        ctx.fail(
            "name",
            f"name {ctx.env.name!r} differs from its entry-point name {names[0]!r} "
            "(workers rebuild environments by name)",
        )


def check_tasks(ctx: _Context) -> None:
    env, n, seed = ctx.env, ctx.config.n_tasks, ctx.config.seed
    for train, stream in ((True, "train"), (False, "eval")):
        sample = env.train_tasks if train else env.eval_tasks
        first, again = sample(n, seed), sample(n, seed)
        if len(first) != n:
            ctx.fail("tasks", f"{stream}_tasks({n}, {seed}) returned {len(first)} tasks")
            continue
        for i, (a, b) in enumerate(zip(first, again, strict=True)):
            if why := _same_task(a, b):
                ctx.fail("tasks", f"{stream} task {i} differs between two samplings: {why}")
                return
        alone = env.task(n - 1, seed, train)
        if why := _same_task(alone, first[-1]):
            ctx.fail(
                "tasks",
                f"task({n - 1}, {seed}, train={train}) differs from the {stream} stream's "
                f"task {n - 1}: {why} (tasks must not depend on other indices)",
            )
        if train:
            ctx.tasks = first
    if _same_task(env.task(0, seed, True), env.task(0, seed, False)) is None:
        ctx.fail("tasks", "train and eval streams give the same task 0 for one seed")


def check_goal_predicates(ctx: _Context) -> None:
    env = ctx.env
    if problem := declaration_problem(env):
        ctx.fail("declarations", problem)
        return
    for what, make in (("planning", planning_config_for), ("learning", learning_config_for)):
        try:
            make(env)
        except (TypeError, ValueError) as err:
            ctx.fail("declarations", f"the declared {what} defaults are not valid: {err}")
    preds = frozenset(env.predicates)
    if extra := frozenset(env.contact_predicates) - preds:
        ctx.fail("declarations", f"contact_predicates not in predicates: {_names(extra)}")
    if extra := frozenset(env.goal_predicates) - preds:
        ctx.fail("declarations", f"goal_predicates not in predicates: {_names(extra)}")
    goal_preds = frozenset(env.goal_predicates)
    for i, task in enumerate(ctx.task_list()):
        if missing := {a.predicate for a in task.goal} - goal_preds:
            ctx.fail("declarations", f"task {i}'s goal uses {_names(missing)}, not goal predicates")
            return


def check_classifiers(ctx: _Context) -> None:
    for pred in sorted(ctx.env.predicates, key=str):
        fn = pred.classifier
        where = getattr(fn, "__qualname__", type(fn).__qualname__)
        try:
            pickle.loads(pickle.dumps(pred))
        except Exception as err:  # noqa: BLE001
            ctx.fail(
                "classifiers",
                f"{pred.name}'s classifier {where} does not pickle ({type(err).__name__}); "
                "tasks go to worker processes: use a module-level function",
            )


def check_pickle(ctx: _Context) -> None:
    for i, task in enumerate(ctx.task_list()):
        try:
            back = pickle.loads(pickle.dumps(task))
        except Exception as err:  # noqa: BLE001
            ctx.fail("pickle", f"task {i} does not pickle: {type(err).__name__}: {err}")
            return
        if why := _same_task(task, back):
            ctx.fail("pickle", f"task {i} changes in a pickle round trip: {why}")
            return


def check_simulate(ctx: _Context) -> None:
    env, cfg = ctx.env, ctx.config
    init = ctx.task_list()[0].init
    actions = _random_actions(env, cfg.rollout_steps, cfg.seed)
    one, two = _rollout(env, init, actions), _rollout(env, init, actions)
    for k, (a, b) in enumerate(zip(one, two, strict=True)):
        if why := _same_state(a, b):
            ctx.fail("simulate", f"not deterministic: step {k} of two identical rollouts: {why}")
            return
    mid = len(one) // 2
    resumed = _rollout(env, pickle.loads(pickle.dumps(one[mid])), actions[mid:])
    if why := _same_state(resumed[-1], one[-1]):
        ctx.fail("simulate", f"stepping on from an unpickled state diverges: {why}")
    bad = {
        "an action of the wrong shape": np.zeros(len(env.action_low) + 1),
        "a NaN action": np.full(len(env.action_low), np.nan),
    }
    for what, action in bad.items():
        try:
            env.simulate(init, action)
        except ValueError:
            continue
        except Exception as err:  # noqa: BLE001
            ctx.fail("simulate", f"{what} raised {type(err).__name__}, not ValueError")
            continue
        ctx.fail("simulate", f"{what} was accepted; it must raise ValueError")
    ctx.rollout = one  # type: ignore[attr-defined]


def check_predicates(ctx: _Context) -> None:
    states = getattr(ctx, "rollout", None) or [t.init for t in ctx.task_list()]
    for pred in sorted(ctx.env.predicates, key=str):
        for k, state in enumerate(states):
            for objs in _groundings(pred, state.objects):
                try:
                    value = pred.classifier(state, objs)
                except Exception as err:  # noqa: BLE001
                    ctx.fail(
                        "predicates",
                        f"{pred.name}{_args(objs)} raised {type(err).__name__}: {err} "
                        f"on rollout state {k}",
                    )
                    break
                if not isinstance(value, bool | np.bool_):
                    ctx.fail(
                        "predicates",
                        f"{pred.name}{_args(objs)} returned {type(value).__name__}, not bool",
                    )
                    break
            else:
                continue
            break


def check_demonstrator(ctx: _Context) -> None:
    env, cfg = ctx.env, ctx.config
    for i in range(cfg.n_demos):
        task = env.task(i, cfg.seed, True)
        attempt = attempt_demonstration(env, task, [cfg.seed, i])
        if attempt.demo is None:
            ctx.fail("demonstrator", f"train task {i} not solved: {attempt.explain()}")
        else:
            ctx.demos.append(attempt.demo)


def check_replay(ctx: _Context) -> None:
    if not ctx.demos and "demonstrator" not in ctx.report.checks:
        cfg = ctx.config
        for i in range(cfg.n_demos):
            demo = attempt_demonstration(ctx.env, ctx.env.task(i, cfg.seed, True), [cfg.seed, i])
            ctx.demos += [demo.demo] if demo.demo is not None else []
    if not ctx.demos:
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "demos.h5"
        save_demonstrations(path, ctx.env, ctx.demos)
        loaded = load_demonstrations(path, ctx.env)
    for i, demo in enumerate(loaded):
        r = replay(ctx.env, demo, i)
        if not r.exact or not r.goal_reached:
            ctx.fail(
                "replay",
                f"saved demo {i} does not replay exactly (max state diff {r.max_state_diff:.3g}, "
                f"feature diff {r.max_feature_diff:.3g}, goal reached {r.goal_reached})",
            )


def check_gym(ctx: _Context) -> None:
    if not ctx.config.gym:
        ctx.report.notes.append("gym: skipped (disabled)")
        return
    import gymnasium as gym  # lazy: ~0.1 s to import, and only this check needs it
    from gymnasium.utils.env_checker import check_env  # lazy, as gymnasium above

    ids = [
        id_
        for id_, spec in gym.registry.items()
        if (spec.kwargs or {}).get("env_name") == ctx.env.name
    ]
    if not ids:
        ctx.report.notes.append(
            f"gym: skipped, no Gymnasium id names {ctx.env.name!r} "
            "(is the environment's package imported?)"
        )
        return
    for id_ in ids:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                gym_env = gym.make(id_, disable_env_checker=True)
                try:
                    check_env(gym_env.unwrapped, skip_render_check=True)
                finally:
                    gym_env.close()
            except Exception as err:  # noqa: BLE001
                ctx.fail("gym", f"{id_} fails Gymnasium's check_env: {type(err).__name__}: {err}")


def _names(preds) -> str:
    return ", ".join(sorted(map(str, preds)))


def _args(objs: Sequence[Object]) -> str:
    return "(" + ", ".join(o.name for o in objs) + ")"


CHECKS: tuple[tuple[str, Callable[[_Context], None]], ...] = (
    ("name", check_name),
    ("tasks", check_tasks),
    ("declarations", check_goal_predicates),
    ("classifiers", check_classifiers),
    ("pickle", check_pickle),
    ("simulate", check_simulate),
    ("predicates", check_predicates),
    ("demonstrator", check_demonstrator),
    ("replay", check_replay),
    ("gym", check_gym),
)
