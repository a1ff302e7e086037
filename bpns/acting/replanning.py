"""Bilevel planning in the model, execution in the world, repair on divergence.

:class:`ClosedLoopPlanner` plans from the world's observed state in the model
(:func:`bpns.planning.plan`), then executes the plan step by step in the world
(:class:`bpns.acting.world.WorldRun`). At each skill boundary the monitor
(:mod:`bpns.acting.monitor`) checks the atoms the rest of the plan needs; a skill that
fails in the world, or loses such an atom while it runs, or a boundary that lacks one, is
a divergence. A divergence is repaired from the world's current state: first the rest of
the same abstract plan, from the last step whose needed atoms hold (refinement only, no
search), then a new bilevel plan, and when the abstract search finds none, a plan whose
first step finishes a skill the world stopped midway (``ExecutionConfig.resume_stopped``),
and when there is still none, the same again after the environment's back-off motion
(``ExecutionConfig.back_off``); at most ``max_replans`` times, within the task's deadline.
Where the world's features left the model's prediction by more than ``rerefine_atol`` at
a boundary, the rest of the plan is checked again from where things really are: kept as
it is when its subgoals still reach the goal in the model from there (one rollout per
step), else refined again (new subgoals, same abstract plan).

A step whose world start state is bit-identical to the model's, under the very same
physics and at full speed (``world_speed`` 1), takes over the model's segment instead of
simulating it again: ``f`` is deterministic, so the world would reproduce it exactly
(with a nominal world and model, closed-loop execution costs nothing).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.acting.monitor import (
    atoms_text,
    kept_atoms,
    necessary_atoms,
    released_atoms,
    repair_point,
)
from bpns.acting.prediction import InFlightPredictor
from bpns.acting.world import WorldRun
from bpns.env.abstraction import abstract
from bpns.env.environment import Environment, adopt_state
from bpns.execution.executor import (
    CompletionTest,
    Executed,
    ExecutionTimeout,
    RolloutConfig,
    SkillExecutor,
    completion_test,
)
from bpns.execution.failures import FailureReason
from bpns.execution.rollouts import Rollout
from bpns.planning.bilevel import PlanningStats, PlanResult, plan
from bpns.planning.config import PlanningConfig
from bpns.planning.refinement import RefinementResult, refine
from bpns.planning.search import AbstractPlan
from bpns.structs import GroundAtom, GroundOperator, Skill, State, Task


@dataclass(frozen=True, eq=False)
class PlannedStep:
    """One refined step: the skill, its ground operator and subgoal, and the model's
    segment (``states[0]`` its start, then the state after each of ``actions``)."""

    skill: Skill
    op: GroundOperator
    subgoal: np.ndarray
    test: CompletionTest
    actions: tuple[np.ndarray, ...]
    states: tuple[State, ...]


def planned_steps(
    skills: Sequence[Skill],
    operators: Sequence[GroundOperator],
    tests: Sequence[CompletionTest],
    result: PlanResult | RefinementResult,
) -> list[PlannedStep]:
    """The steps of a successful plan or refinement, with their model segments."""
    starts = (*result.step_starts, len(result.actions))
    return [
        PlannedStep(
            skill,
            op,
            subgoal,
            test,
            tuple(result.actions[a:b]),
            tuple(result.states[a : b + 1]),
        )
        for skill, op, subgoal, test, a, b in zip(
            skills, operators, result.subgoals, tests, starts[:-1], starts[1:], strict=True
        )
    ]


@dataclass
class ClosedLoopStats:
    """What the closed loop cost, summed over every plan it made."""

    nodes_created: int = 0
    abstract_plans: int = 0
    samples: int = 0
    model_steps: int = 0  # control steps simulated in the model (planning)
    replans: int = 0  # divergences repaired
    rerefinements: int = 0  # boundaries where the rest was refined again (deviation)
    furthest: Rollout | None = field(default=None, repr=False)
    explanation: dict | None = field(default=None, repr=False)


@dataclass(frozen=True, eq=False)
class ClosedLoopResult:
    success: bool
    reason: FailureReason | None
    world: WorldRun
    stats: ClosedLoopStats
    skeleton: tuple[str, ...] = ()  # the ground skills executed, in order


class ClosedLoopPlanner:
    """Plans with ``skills`` in ``model`` (the planner's simulator) and executes in the
    world a :class:`WorldRun` carries; see the module docstring."""

    def __init__(
        self,
        skills: Sequence[Skill],
        model: Environment,
        config: PlanningConfig,
        execution: ExecutionConfig,
        explain: Callable[[PlanningStats], dict] | None = None,
    ) -> None:
        self.by_operator = {s.operator: s for s in skills}
        self.skills = list(skills)
        self.model = model
        self.config = config
        self.execution = execution
        self.explain = explain  # PlanningStats -> JSON explanation of a failed plan

    # -- planning in the model ------------------------------------------------------
    def _model_task(self, world: WorldRun) -> Task:
        task = world.task
        return Task(adopt_state(self.model, world.state), task.goal, task.horizon - world.used)

    def _plan(
        self,
        world: WorldRun,
        rng: np.random.Generator,
        deadline: float,
        stats: ClosedLoopStats,
        resume_from: frozenset[GroundAtom] | None = None,
        tried: Sequence[tuple[GroundOperator, ...]] = (),
    ) -> list[PlannedStep] | FailureReason:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return FailureReason.TIMEOUT
        config = dataclasses.replace(self.config, timeout=remaining)
        result = plan(
            self._model_task(world),
            self.skills,
            self.model,
            config,
            rng,
            resume_from=resume_from,
            tried=tried,
        )
        s = result.stats
        stats.nodes_created += s.nodes_created
        stats.abstract_plans += s.abstract_plans_tried
        stats.samples += s.samples_drawn
        stats.model_steps += s.sim_steps
        if not result.success:
            if result.furthest is not None and stats.furthest is None:
                stats.furthest = result.furthest
            resumed = resume_from is not None
            if self.explain is not None and (stats.explanation is None or resumed):
                stats.explanation = self.explain(s)  # a resumption's attempts say more
            return result.reason or FailureReason.REFINEMENT_FAILED
        skeleton = result.skeleton
        assert skeleton is not None
        tests = [
            _test(op, after)
            for op, after in zip(skeleton.operators, skeleton.atoms[1:], strict=True)
        ]
        return planned_steps(result.skills, skeleton.operators, tests, result)

    def _refine_rest(
        self,
        world: WorldRun,
        operators: Sequence[GroundOperator],
        rng: np.random.Generator,
        deadline: float,
        stats: ClosedLoopStats,
    ) -> list[PlannedStep] | None:
        """The same abstract plan ``operators`` refined again from the world's state."""
        task = self._model_task(world)
        atoms = [abstract(task.init, self.model.predicates)]
        for op in operators:
            if not op.applicable(atoms[-1]):
                return None
            atoms.append(op.apply(atoms[-1]))
        skeleton = AbstractPlan(tuple(operators), tuple(atoms), float(len(operators)))
        skills = [self.by_operator[op.operator] for op in operators]
        remaining = deadline - time.monotonic()
        if remaining <= 0:  # the task's time is up: its timeout, not a planning config error
            raise ExecutionTimeout
        config = dataclasses.replace(self.config, timeout=remaining)
        try:
            ref = refine(skeleton, skills, task, self.model, config, rng, deadline)
        except ExecutionTimeout:
            return None
        stats.samples += ref.stats.samples
        stats.model_steps += ref.stats.sim_steps
        if not ref.success:
            return None
        tests = [_test(op, after) for op, after in zip(operators, atoms[1:], strict=True)]
        return planned_steps(skills, operators, tests, ref)

    def _reuse_rest(
        self,
        world: WorldRun,
        rest: Sequence[PlannedStep],
        deadline: float,
        stats: ClosedLoopStats,
    ) -> list[PlannedStep] | None:
        """The rest of the plan with its subgoals kept, simulated again in the model from
        the world's state: one rollout per step, no sampling. The cheap repair of a world
        that deviated a little (a Coffee task re-refined at every boundary spent its 60 s
        on fresh samples); None when a step no longer reaches its expected atoms or the
        goal is missed, and the rest is refined again from scratch. Once the simulation
        rejoins the old prediction (a step starts within ``rerefine_atol`` of where the
        old plan expected it: the test that calls this at all) the old plan's remaining
        segments stand as they are: checking them again at every boundary cost each task
        the square of its plan length in rollouts. So do they beyond
        ``execution.check_ahead`` steps (each is checked at its own boundary). The task's deadline
        passing meanwhile is its timeout (:class:`ExecutionTimeout`, as in the world)."""
        task = self._model_task(world)
        executor = SkillExecutor(self.model, task, RolloutConfig.of(self.config), deadline)
        state, used, out = task.init, 0, []
        try:
            ahead = self.execution.check_ahead
            for k, step in enumerate(rest):
                if k > 0 and (
                    (ahead is not None and k >= ahead) or not self._deviated(state, step.states[0])
                ):
                    out.extend(rest[k:])  # checked enough, or rejoined the prediction
                    return out
                done = executor.execute(
                    step.skill, step.op.objects, step.subgoal, state, step.test, used
                )
                if not isinstance(done, Executed):
                    return None
                segment = (state, *done.states)
                out.append(
                    PlannedStep(
                        step.skill, step.op, step.subgoal, step.test, tuple(done.actions), segment
                    )
                )
                state, used = done.states[-1], used + len(done.actions)
        finally:
            stats.model_steps += executor.sim_steps
        if not task.goal_holds(abstract(state, self.model.goal_predicates)):
            return None
        return out

    # -- the loop -------------------------------------------------------------------
    def run(self, world: WorldRun, rng: np.random.Generator, deadline: float) -> ClosedLoopResult:
        if self.execution.predict_latency:
            steps = self.execution.latency_learn_steps
            world.predict_with(InFlightPredictor(self.model, learn_steps=steps))
        stats = ClosedLoopStats()
        executed: list[str] = []
        try:
            return self._loop(world, rng, deadline, stats, executed)
        except ExecutionTimeout:
            return ClosedLoopResult(False, FailureReason.TIMEOUT, world, stats, tuple(executed))

    def _loop(
        self,
        world: WorldRun,
        rng: np.random.Generator,
        deadline: float,
        stats: ClosedLoopStats,
        executed: list[str],
    ) -> ClosedLoopResult:
        def failed(reason: FailureReason) -> ClosedLoopResult:
            return ClosedLoopResult(False, reason, world, stats, tuple(executed))

        steps = self._plan(world, rng, deadline, stats)
        if isinstance(steps, FailureReason):
            return failed(steps)
        needed = necessary_atoms([s.op for s in steps], world.task.goal)
        seen = set(world.atoms())  # every atom the world showed at a boundary
        i = 0
        while not world.goal_holds():
            problem = None
            if i >= len(steps):
                problem = ("diverged", "the plan ended but the goal does not hold")
            else:
                problem = self._execute(world, steps[i], needed[i + 1])
                executed.append(str(steps[i].op))
                atoms = world.atoms()
                seen |= atoms
                missing = needed[i + 1] - atoms
                if problem is None and missing:
                    problem = ("diverged", f"expected {atoms_text(missing)} did not hold")
            if problem is None:
                i += 1
                if i < len(steps) and self._deviated(world.state, steps[i - 1].states[-1]):
                    self._slow_down(world, "the world left the model's prediction")
                    rest = self._reuse_rest(world, steps[i:], deadline, stats)
                    text = "kept the subgoals of the last {n} steps: they still reach the goal"
                    if rest is None:
                        rest = self._refine_rest(
                            world, [s.op for s in steps[i:]], rng, deadline, stats
                        )
                        text = "refined the last {n} steps again"
                    if rest is not None:
                        stats.rerefinements += 1
                        world.event("rerefined", text.format(n=len(rest)))
                        steps, i = steps[:i] + rest, i
                continue
            stats.replans += 1
            kind, text = problem
            self._slow_down(world, "the world diverged from the plan")
            world.event(kind, f"replan {stats.replans}: {text}")
            if world.used >= world.task.horizon:  # no step left to act: nothing to plan for
                return failed(FailureReason.TASK_HORIZON)
            if stats.replans > self.execution.max_replans:
                return failed(FailureReason.REPLAN_BUDGET)
            repaired = self._repair(world, steps, needed, frozenset(seen), rng, deadline, stats)
            if self._backs_off(world, repaired):
                world.event(
                    "backed_off",
                    f"replan {stats.replans} found no plan ({repaired}) from "
                    f"{{{atoms_text(world.atoms())}}}: backing off",
                )
                world.back_off()
                seen |= world.atoms()
                repaired = self._repair(world, steps, needed, frozenset(seen), rng, deadline, stats)
            if isinstance(repaired, FailureReason):
                world.event(
                    "replan_failed",
                    f"replan {stats.replans} found no plan: {repaired}, "
                    f"from {{{atoms_text(world.atoms())}}}",
                )
                return failed(repaired)
            steps, i = repaired, 0
            needed = necessary_atoms([s.op for s in steps], world.task.goal)
        return ClosedLoopResult(True, None, world, stats, tuple(executed))

    def _execute(
        self, world: WorldRun, step: PlannedStep, needed_after: frozenset[GroundAtom]
    ) -> tuple[str, str] | None:
        """Step ``step`` in the world; None when it reached its expected atoms."""
        start = step.states[0]
        if (
            world.speed == 1.0  # a slowed world does not reproduce the model
            and world.state.sim is not None
            and start.sim is not None
            and world.state.sim.world is start.sim.world
            and np.array_equal(world.state.sim.flat, start.sim.flat)
        ):
            world.reuse(step.op, step.subgoal, step.actions, step.states[1:])
            return None
        keep: tuple[GroundAtom, ...] = ()
        releases: tuple[GroundAtom, ...] = ()
        atoms = world.atoms()
        if self.execution.watch_atoms:
            keep = kept_atoms(
                step.op, atoms, needed_after, self.model.contact_predicates, step.states
            )
        if self.execution.watch_releases:
            releases = released_atoms(step.op, atoms, self.model.contact_predicates, step.states)
        reason = world.execute(step.skill, step.op, step.subgoal, step.test, keep, releases)
        if reason is None:
            return None
        if reason is FailureReason.ATOM_LOST:
            lost = [a for a in (*keep, *releases) if not a.holds(world.state)]
            return (
                "atom_lost",
                f"{atoms_text(lost) or 'an atom'} stopped holding during {step.op}",
            )
        return ("skill_failed", f"{step.op} failed in the world: {reason}")

    def _backs_off(self, world: WorldRun, repaired: list[PlannedStep] | FailureReason) -> bool:
        """Back off before giving up? Only when no plan was found (not when time ran
        out) and the environment declares a back-off (``ExecutionConfig.back_off``)."""
        return (
            isinstance(repaired, FailureReason)
            and repaired in (FailureReason.REFINEMENT_FAILED, FailureReason.NO_ABSTRACT_PLAN)
            and self.execution.back_off
            and world.env.capabilities.back_off is not None
            and world.used < world.task.horizon
        )

    def _slow_down(self, world: WorldRun, why: str) -> None:
        """With ``slow_from="deviation"``: the first deviation slows every later skill."""
        if not self.execution.slows_on_deviation or world.speed != 1.0:
            return
        limits = self.execution.world_limits(RolloutConfig.of(self.config), slowed=True)
        world.slow_down(limits, f"{why}: skills slowed to {limits.speed:g} of their speed")

    def _deviated(self, world_state: State, model_state: State) -> bool:
        atol = self.execution.rerefine_atol
        if atol is None:
            return False
        for obj, value in world_state.data.items():
            other = model_state.data.get(obj)
            if other is None or other.shape != value.shape:
                return True
            if np.max(np.abs(value - other), initial=0.0) > atol:
                return True
        return False

    def _repair(
        self,
        world: WorldRun,
        steps: list[PlannedStep],
        needed: Sequence[frozenset[GroundAtom]],
        seen: frozenset[GroundAtom],
        rng: np.random.Generator,
        deadline: float,
        stats: ClosedLoopStats,
    ) -> list[PlannedStep] | FailureReason:
        """The rest of the same abstract plan from where it still applies, else a new plan,
        else (no abstract plan at all) one that first finishes a skill stopped midway. The
        new plans pass over the rest already refined in vain from this state (``tried``):
        refined again from the same state, it would cost as many samples again."""
        tried: tuple[tuple[GroundOperator, ...], ...] = ()
        j = repair_point(needed, world.atoms())
        if j is not None and j < len(steps):
            ops = [s.op for s in steps[j:]]
            rest = self._refine_rest(world, ops, rng, deadline, stats)
            if rest is not None:
                world.event(
                    "replanned",
                    f"replan {stats.replans}: the plan's last {len(rest)} steps refined again",
                )
                return rest
            tried = (tuple(ops),)
        new = self._plan(world, rng, deadline, stats, tried=tried)
        if new is FailureReason.NO_ABSTRACT_PLAN and self.execution.resume_stopped:
            new = self._plan(world, rng, deadline, stats, resume_from=seen, tried=tried)
            if not isinstance(new, FailureReason) and not new[0].op.applicable(world.atoms()):
                world.event(
                    "replanned",
                    f"replan {stats.replans}: a new plan of {len(new)} steps that first "
                    f"finishes {new[0].op}, stopped midway",
                )
                return new
        if not isinstance(new, FailureReason):
            world.event("replanned", f"replan {stats.replans}: a new plan of {len(new)} steps")
        return new


def _test(op: GroundOperator, after: frozenset[GroundAtom]) -> CompletionTest:
    return completion_test(op, after)


def world_run(
    env: Environment,
    task: Task,
    config: PlanningConfig,
    deadline: float,
    execution: ExecutionConfig | None = None,
) -> WorldRun:
    """A :class:`WorldRun` of ``task`` in ``env`` with ``config``'s skill limits, each
    skill's horizon scaled by ``execution.horizon_scale``."""
    limits = RolloutConfig.of(config)
    if execution is not None:
        limits = execution.world_limits(limits)
    return WorldRun(env, task, limits, deadline)
