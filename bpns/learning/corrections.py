"""Corrections on the states the learned skills reach in perturbed worlds (DAgger).

Behaviour cloning learns the states the demonstrator visits. A cloned skill acting in a
world that differs from its demonstrations (latency, friction, mass, noise) soon leaves
them, and the network's answer there is an extrapolation (docs/WORLDS.md: Coffee's hot
pick under a step of latency climbs to the ceiling). DAgger (Ross et al., 2011) asks an
expert what it would have done on the states the *learner* reaches, and learns those too.

A correction rollout replays one demonstration with the learned skills: in a world drawn
for the demonstration's task, each of its segments' learned skill (its operator bound as
in the demonstration) runs towards the segment's final scope, one after another, and the
expert is asked on every state the learner acts on; its command is the label. The
rollout ends where a skill fails or after the last segment. Only the policies are
retrained (operators and samplers stay as learned): each correction is a one-step row
(scope, subgoal, command) added to its skill's policy data, each network retrained with
the seed it had.

Experts (``CorrectionConfig.expert``):

- ``oracle``: the environment's hand-written skills, functions of the state and the
  subgoal; per segment the one whose operator does what the segment did
  (:func:`oracle_step`), towards the segment's final state over its objects.
- ``demonstrator``: the scripted demonstrator of the task, seeded as when it was
  demonstrated, following the learner's states. A demonstrator that is a queue of phases
  goes on asking for a phase the learner cut short (Coffee's "rise to travel height"
  after the cloned arm went on diagonally towards the grasp), so its labels there
  contradict its own demonstrations: measured worse (docs/WORLDS.md).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from bpns.env.abstraction import abstract
from bpns.env.environment import Environment, perturbed
from bpns.env.registry import make_environment
from bpns.env.worlds import WorldDistribution
from bpns.execution.executor import Executed, RolloutConfig, SkillExecutor, completion_test
from bpns.learning.jobs import policy_data
from bpns.learning.operators import SkillDataset, applicable_bindings, learn_operators
from bpns.learning.partition import partition_segments
from bpns.learning.pipeline import LearnedSkills, policy_seed
from bpns.learning.policies import LearnedPolicy, ScopeDims, train_policy
from bpns.learning.sharing import shared_data
from bpns.pools import make_pool, surviving_map
from bpns.structs import Object, Segment, Skill, State

KEEP = ("best", "last")  # which policies corrections keep (CorrectionConfig.keep)
EXPERTS = ("oracle", "demonstrator")
_WORLD_STREAM = 0xC0EC7  # separates the correction worlds' draws from the evaluation's


@dataclass(frozen=True)
class CorrectionConfig:
    """How corrections are collected and how often.

    ``worlds``: the physics each rollout is drawn from (by the demonstration's task
    index, as ``bpns eval --perturb`` draws a task's, from a stream of its own:
    :attr:`rollout_worlds`). ``rounds``: collect, retrain,
    collect again with the retrained skills (the corrections of every round are kept).
    ``expert``: who labels (module docstring). ``expert_mix``: the probability that a
    step executes the expert's command instead of the learner's (DAgger's beta; the
    label is recorded either way). ``horizon_scale``: a skill's learned horizon times
    this in the world (as ``ExecutionConfig.horizon_scale``). ``seed``: the mixing.
    ``relabel``: the demonstrations' own states are labelled by the oracle too, so that
    every label of a segment it can do comes from one expert (its commands differ from
    the demonstrator's on the demonstrator's own states; measured better, docs/WORLDS.md);
    None: so with the oracle as the expert (:attr:`relabels`)."""

    worlds: WorldDistribution
    rounds: int = 1
    expert: str = "oracle"
    expert_mix: float = 0.0
    horizon_scale: float = 2.0
    seed: int = 0
    relabel: bool | None = None
    keep: str = "best"

    def __post_init__(self) -> None:
        if not isinstance(self.rounds, int) or self.rounds < 1:
            raise ValueError(f"rounds must be a whole number >= 1, got {self.rounds!r}")
        if self.expert not in EXPERTS:
            raise ValueError(f"expert must be one of {', '.join(EXPERTS)}, got {self.expert!r}")
        if not 0.0 <= self.expert_mix <= 1.0:
            raise ValueError(f"expert_mix must be in [0, 1], got {self.expert_mix}")
        if not 0.0 < self.horizon_scale < math.inf:
            raise ValueError(f"horizon_scale must be finite and > 0, got {self.horizon_scale}")
        if self.relabel and self.expert != "oracle":
            raise ValueError("relabel needs the oracle as the expert")
        if self.keep not in KEEP:
            raise ValueError(f"keep must be one of {', '.join(KEEP)}, got {self.keep!r}")

    @property
    def relabels(self) -> bool:
        """Whether the oracle labels the demonstrations' own states too."""
        return self.expert == "oracle" if self.relabel is None else self.relabel

    @property
    def rollout_worlds(self) -> WorldDistribution:
        """``worlds`` with a stream of its own: task ``i`` of the evaluation, drawn with
        ``worlds``' seed, never meets the very world demonstration ``i`` was corrected in."""
        seed = np.random.SeedSequence([self.worlds.seed or 0, self.seed, _WORLD_STREAM])
        return dataclasses.replace(self.worlds, seed=int(seed.generate_state(1)[0]))

    def to_json(self) -> dict[str, object]:
        return {
            "worlds": self.worlds.label(),
            "rounds": self.rounds,
            "expert": self.expert,
            "expert_mix": self.expert_mix,
            "horizon_scale": self.horizon_scale,
            "seed": self.seed,
            "relabel": self.relabels,
            "keep": self.keep,
        }


@dataclass(frozen=True)
class DemoOrigin:
    """Where a demonstration's task came from: ``env.task(index, seed, True)``, its
    demonstrator seeded ``[seed, index]`` (``bpns.data.datasets.task_origins``)."""

    seed: int
    index: int


@dataclass(frozen=True, eq=False)
class OracleStep:
    """The hand-written skill (by its index) doing what a segment did, bound to its
    objects, towards the segment's final state over them."""

    skill: int
    objects: tuple[Object, ...]
    subgoal: np.ndarray


@dataclass(frozen=True, eq=False)
class PlannedStep:
    """One segment of a demonstration as a correction rollout executes it: the learned
    skill (by index; None when its group was dropped), its objects in the operator's
    order, the subgoal over its policy's scope, and the oracle for it (None: none)."""

    skill: int | None
    objects: tuple[Object, ...]
    subgoal: np.ndarray
    oracle: OracleStep | None


@dataclass(frozen=True, eq=False)
class Correction:
    """One labelled state: skill ``skill``'s scope there, the subgoal it was executing
    towards, and the expert's command."""

    skill: int
    scope: np.ndarray
    subgoal: np.ndarray
    command: np.ndarray


@dataclass(frozen=True)
class RolloutSummary:
    """How one correction rollout ended: segments completed of those it had, and
    ``"done"`` or the failure (a ``FailureReason`` value) of ``failed_skill``."""

    completed: int
    segments: int
    ended: str
    corrections: int
    failed_skill: str | None = None


@dataclass(frozen=True, eq=False)
class RoundReport:
    """One round: its rollouts' summaries and how many corrections each skill got."""

    rollouts: tuple[RolloutSummary, ...]
    corrections: tuple[tuple[str, int], ...]
    seconds: float = 0.0  # collecting and retraining
    retrained: bool = True  # False: the check replaying the last round's policies
    kept: bool = False  # the policies these rollouts replayed are the ones kept

    @property
    def completed(self) -> int:
        return sum(r.completed == r.segments for r in self.rollouts)

    def line(self, number: int) -> str:
        failed = Counter(f"{r.failed_skill} ({r.ended})" for r in self.rollouts if r.failed_skill)
        worst = ", ".join(f"{name} {n}" for name, n in failed.most_common(3)) or "none"
        total = sum(n for _, n in self.corrections)
        kept = "; the policies it replayed are kept" if self.kept else ""
        if not self.retrained:
            return (
                f"corrections check: {self.completed}/{len(self.rollouts)} rollouts of the "
                f"last round's policies completed every segment; failed most: {worst}{kept}; "
                f"{self.seconds:.1f} s"
            )
        return (
            f"corrections round {number}: {self.completed}/{len(self.rollouts)} rollouts "
            f"completed every segment; failed most: {worst}; {total} corrections{kept}; "
            f"{self.seconds:.1f} s"
        )

    def to_json(self) -> dict[str, object]:
        return {
            "rollouts": len(self.rollouts),
            "completed": self.completed,
            "failed": dict(
                Counter(f"{r.failed_skill}:{r.ended}" for r in self.rollouts if r.failed_skill)
            ),
            "corrections": dict(self.corrections),
            "seconds": round(self.seconds, 1),
            "retrained": self.retrained,
            "kept": self.kept,
        }


# -- what each rollout executes ----------------------------------------------------------
def skill_datasets(skills: LearnedSkills) -> list[SkillDataset]:
    """The operators' datasets as learning built them, from the segments the skills
    carry (skills learned in this process), checked against the skills' operators."""
    config = skills.config
    if not skills.segments:
        raise ValueError("the skills carry no segments: learn them in this process first")
    groups = partition_segments([seg for segs in skills.segments for seg in segs])
    datasets = learn_operators(
        groups, config.min_segment_fraction, config.anchor_parameters, config.index_names
    )
    got = [d.operator.name for d in datasets]
    want = [s.operator.name for s in skills.skills]
    if got != want:
        raise ValueError(f"the segments give the operators {got}, the skills have {want}")
    return datasets


def oracle_step(
    oracle: Sequence[Skill], segment: Segment, objects: Sequence[Object]
) -> OracleStep | None:
    """The hand-written skill that does what ``segment`` did: among the ground operators
    applicable in its initial atoms, the one whose add effects overlap the segment's
    most (those with no effect the segment lacks first), towards the segment's final
    state over its objects (hand-written subgoals are absolute scope vectors). None
    when no operator adds any of the segment's effects."""
    achieved = segment.add_effects
    best: tuple[tuple[int, int, int], int, tuple[Object, ...]] | None = None
    for index, skill in enumerate(oracle):
        for binding in applicable_bindings(skill.operator, segment.init_atoms, objects):
            adds = skill.operator.ground(binding).add_effects
            shared = len(adds & achieved)
            if not shared:
                continue
            score = (int(adds <= achieved), shared, -len(adds - achieved))
            if best is None or score > best[0]:
                best = (score, index, binding)
    if best is None:
        return None
    _, index, binding = best
    return OracleStep(index, binding, segment.states[-1].vec(binding))


def rollout_steps(
    skills: LearnedSkills,
    datasets: Sequence[SkillDataset],
    oracle: Sequence[Skill] | None,
) -> list[tuple[PlannedStep, ...]]:
    """Per demonstration (the skills' segments), the steps its rollout executes."""
    owner: dict[int, tuple[int, tuple[Object, ...]]] = {}
    for k, dataset in enumerate(datasets):
        for seg, binding in zip(dataset.segments, dataset.bindings, strict=True):
            owner[id(seg)] = (k, binding)
    out = []
    for segments in skills.segments:
        steps = []
        for seg in segments:
            k, objects = owner.get(id(seg), (None, ()))
            policy = None if k is None else skills.skills[k].policy
            scope = policy.dims.scope(objects) if isinstance(policy, LearnedPolicy) else objects
            expert = None
            if oracle is not None:
                expert = oracle_step(oracle, seg, seg.states[0].objects)
            steps.append(PlannedStep(k, tuple(objects), seg.states[-1].vec(scope), expert))
        out.append(tuple(steps))
    return out


# -- a rollout ----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _OracleCommand:
    """A hand-written policy bound to its objects and subgoal: a function of the state."""

    skill: Skill
    step: OracleStep

    def __call__(self, state: State) -> np.ndarray:
        return self.skill.policy(state, self.step.objects, self.step.subgoal)


class _Labeller:
    """A learned policy that asks the expert on every state it acts on, records the
    command as a correction, and executes the learner's action (or, with probability
    ``mix``, the expert's). An expert that raises (a demonstrator giving up) is asked
    no more; the learner goes on."""

    def __init__(
        self,
        env: Environment,
        skill: int,
        learner: LearnedPolicy,
        mix: float,
        rng: np.random.Generator,
        out: list[Correction],
    ) -> None:
        self.env, self.skill, self.learner = env, skill, learner
        self.mix, self.rng, self.out = mix, rng, out
        self.expert: Callable[[State], np.ndarray] | None = None

    def __call__(self, obs: State, objects: Sequence[Object], subgoal: np.ndarray) -> np.ndarray:
        if self.expert is not None:
            try:
                command = np.asarray(self.env.check_action(self.expert(obs)), np.float64)
            except Exception:  # noqa: BLE001  the expert gave up here: no more labels
                self.expert = None
            else:
                scope = obs.vec(self.learner.dims.scope(objects))
                self.out.append(Correction(self.skill, scope, np.asarray(subgoal), command))
                if self.mix > 0.0 and self.rng.random() < self.mix:
                    return command
        return self.learner(obs, objects, subgoal)


@dataclass(frozen=True, eq=False)
class RolloutJob:
    """Everything one rollout needs, picklable for a worker process. ``measure_only``:
    the learned policies act alone and nobody labels (the keep-best check measures the
    policies; asking the expert there would cost its every command and teach nothing)."""

    env_name: str
    skills: tuple[Skill, ...]
    predicates: frozenset
    origin: DemoOrigin
    steps: tuple[PlannedStep, ...]
    config: CorrectionConfig
    measure_only: bool = False


_ENVIRONMENTS: dict[str, Environment] = {}
_ORACLES: dict[str, tuple[Skill, ...]] = {}  # per process, by environment name


def run_rollout(
    job: RolloutJob, env: Environment | None = None
) -> tuple[list[Correction], RolloutSummary]:
    """One correction rollout (module docstring); ``env`` defaults to the registered one
    of ``job.env_name`` (made once per process)."""
    if env is None:
        env = _ENVIRONMENTS.get(job.env_name) or _ENVIRONMENTS.setdefault(
            job.env_name, make_environment(job.env_name)
        )
    config, origin = job.config, job.origin
    world = perturbed(env, config.rollout_worlds.draw(origin.index))
    task = world.task(origin.index, origin.seed, True)
    demonstrator = None
    oracle: tuple[Skill, ...] = ()
    if job.measure_only:  # nobody labels
        pass
    elif config.expert == "demonstrator":
        demonstrator = env.demonstrator(task, np.random.default_rng([origin.seed, origin.index]))
    else:  # made once per process: every rollout asks the same hand-written skills
        oracle = _ORACLES.get(env.name) or _ORACLES.setdefault(env.name, hand_written(env))
    rng = np.random.default_rng([config.seed, origin.seed, origin.index])
    executor = SkillExecutor(world, task, RolloutConfig(horizon_scale=config.horizon_scale))
    out: list[Correction] = []
    state, used, completed = task.init, 0, 0
    demonstrator_alive = True
    for step in job.steps:
        skill = None if step.skill is None else job.skills[step.skill]
        if skill is None:
            return out, RolloutSummary(completed, len(job.steps), "no skill", len(out))
        labeller = None  # a given skill (the environment's own policy) acts as it is
        if isinstance(skill.policy, LearnedPolicy) and not job.measure_only:
            labeller = _Labeller(world, step.skill, skill.policy, config.expert_mix, rng, out)
            if demonstrator is not None and demonstrator_alive:
                labeller.expert = demonstrator
            elif step.oracle is not None and oracle:
                labeller.expert = _OracleCommand(oracle[step.oracle.skill], step.oracle)
        acting = skill if labeller is None else dataclasses.replace(skill, policy=labeller)
        ground = skill.operator.ground(step.objects)
        test = completion_test(ground, ground.apply(abstract(state, job.predicates)))
        result = executor.execute(acting, step.objects, step.subgoal, state, test, used)
        if labeller is not None:
            demonstrator_alive = demonstrator_alive and labeller.expert is not None
        if not isinstance(result, Executed):
            summary = RolloutSummary(completed, len(job.steps), result.value, len(out), skill.name)
            return out, summary
        state, used = result.states[-1], used + len(result.actions)
        completed += 1
    return out, RolloutSummary(completed, len(job.steps), "done", len(out))


def hand_written(env: Environment) -> tuple[Skill, ...]:
    """The environment's hand-written skills (``Capabilities.oracle_skills``)."""
    make = env.capabilities.oracle_skills
    if make is None:
        raise ValueError(
            f"environment {env.name!r} declares no oracle skills to label corrections: "
            "label with its demonstrator instead"
        )
    return tuple(make())


# -- rounds ---------------------------------------------------------------------------------
def collect_corrections(
    env: Environment,
    skills: LearnedSkills,
    steps: Sequence[tuple[PlannedStep, ...]],
    origins: Sequence[DemoOrigin],
    config: CorrectionConfig,
    workers: int = 1,
    measure_only: bool = False,
) -> Iterator[tuple[list[Correction], RolloutSummary]]:
    """One rollout per demonstration the skills were learned from (``origins`` and its
    :func:`rollout_steps` in the same order), in ``workers`` processes, yielded in order
    (``measure_only``: :class:`RolloutJob`'s)."""
    if not len(origins) == len(steps) == len(skills.segments):
        raise ValueError(f"{len(origins)} task origins for {len(skills.segments)} demonstrations")
    jobs = (
        RolloutJob(env.name, skills.skills, skills.predicates, origin, s, config, measure_only)
        for origin, s in zip(origins, steps, strict=True)
    )
    if workers <= 1:
        yield from (run_rollout(job, env) for job in jobs)
        return
    yield from surviving_map(
        lambda k: make_pool(k or workers), run_rollout, jobs, 4 * workers, _worker_died
    )


def _worker_died(job: RolloutJob) -> tuple[list[Correction], RolloutSummary]:
    """A rollout whose worker died, also when it ran alone: no segment counted done."""
    return [], RolloutSummary(0, len(job.steps), "worker_died", 0)


DemoStates = Callable[[int], Sequence[State]]  # demonstration i's states, with simulator


def oracle_labels(
    env: Environment,
    skills: LearnedSkills,
    steps: Sequence[tuple[PlannedStep, ...]],
    oracle: Sequence[Skill],
    demo_states: DemoStates | None = None,
) -> dict[int, np.ndarray]:
    """``id(segment)`` -> the oracle's command on each of its states (checked and
    clipped as the demonstrator's were), for every segment of the skills'
    demonstrations whose step has an oracle (:func:`rollout_steps`).

    Learning reads features only; an oracle policy may need the scene itself (Doors'
    base path planner reads the world's walls). ``demo_states(i)`` gives demonstration
    i's states with their simulator state: a segment whose states it reproduces
    feature for feature is labelled on those."""
    out: dict[int, np.ndarray] = {}
    for i, (segments, planned) in enumerate(zip(skills.segments, steps, strict=True)):
        full = None if demo_states is None else demo_states(i)
        offset = 0
        for seg, step in zip(segments, planned, strict=True):
            states = _with_simulator(seg, full, offset)
            offset += len(seg.actions)
            if step.oracle is None:
                continue
            policy, where = oracle[step.oracle.skill].policy, step.oracle
            commands = [
                env.check_action(policy(s, where.objects, where.subgoal)) for s in states[:-1]
            ]
            out[id(seg)] = np.asarray(commands, np.float64).reshape(seg.actions.shape)
    return out


def _with_simulator(seg: Segment, full: Sequence[State] | None, offset: int) -> Sequence[State]:
    """``seg``'s states as ``full[offset:]`` has them (with simulator state) when those
    are the same features, else as learning read them."""
    if full is None:
        return seg.states
    mine = full[offset : offset + len(seg.states)]
    same = len(mine) == len(seg.states) and all(
        a.data.keys() == b.data.keys() and all(np.array_equal(a.data[o], b.data[o]) for o in a.data)
        for a, b in zip(mine, seg.states, strict=True)
    )
    return mine if same else seg.states


def retrain_policies(
    skills: LearnedSkills,
    datasets: Sequence[SkillDataset],
    corrections: Sequence[Correction],
    relabelled: dict[int, np.ndarray] | None = None,
) -> LearnedSkills:
    """``skills`` with every learned policy that has corrections retrained on its own
    data plus them (each a one-step row: its scope, then the subgoal as the row's end),
    with the seed and the scope dimensions it was trained with; the others keep their
    networks. ``relabelled``: labels replacing a segment's own (:func:`oracle_labels`);
    a policy with any of them is retrained too."""
    config = skills.config
    relabelled = relabelled or {}
    by_skill: dict[int, list[Correction]] = {}
    for c in corrections:
        by_skill.setdefault(c.skill, []).append(c)
    new: list[Skill] = []
    for k, (skill, dataset) in enumerate(zip(skills.skills, datasets, strict=True)):
        rows, old = by_skill.get(k, []), skill.policy
        shared = shared_data(datasets, k) if config.share_effect_data else None
        own = dataset.segments if shared is None else shared.segments
        relabel = [relabelled.get(id(seg)) for seg in own]
        if not isinstance(old, LearnedPolicy) or not (rows or any(r is not None for r in relabel)):
            new.append(skill)
            continue
        scopes, dims, actions = policy_data(dataset, shared, config)
        if not _same_dims(dims, old.dims):
            raise ValueError(f"{skill.name}: its segments give other scope dimensions")
        actions = [a if r is None else r for a, r in zip(actions, relabel, strict=True)]
        policy = train_policy(
            [*scopes, *(np.stack([c.scope, c.subgoal]) for c in rows)],
            [*actions, *(c.command[None, :] for c in rows)],
            old.dims,
            config.policy,
            policy_seed(config.seed, k),
            config.use_subgoals,
            config.near_goal_scale,
            config.linear_policy_base,
        )
        new.append(dataclasses.replace(skill, policy=policy))
    return dataclasses.replace(skills, skills=tuple(new))


def _same_dims(a: ScopeDims, b: ScopeDims) -> bool:
    return (
        a.size == b.size
        and np.array_equal(a.state_dims, b.state_dims)
        and np.array_equal(a.subgoal_dims, b.subgoal_dims)
        and np.array_equal(a.angles, b.angles)
    )


def improve_with_corrections(
    env: Environment,
    skills: LearnedSkills,
    origins: Sequence[DemoOrigin],
    config: CorrectionConfig,
    workers: int = 1,
    report: Callable[[str], None] | None = None,
    demo_states: DemoStates | None = None,
) -> tuple[LearnedSkills, tuple[RoundReport, ...]]:
    """``config.rounds`` rounds of: a correction rollout per demonstration with the
    current skills, then every policy retrained on its data and all corrections so far
    with the seeds learning drew. ``demo_states``: the demonstrations' states with their
    simulator state, for an oracle that relabels them (:func:`oracle_labels`).

    Each round's rollouts measure the policies they replay: how many demonstrations
    they carry through every segment in a perturbed world. With ``config.keep`` "best"
    the last round's policies are replayed once more (a check, not retrained on), and
    the policies that completed the most rollouts are kept, the later on a tie (DAgger
    returns the best of its iterates: in Stick Button and Doors a round's retraining
    made the replays worse, 224 -> 145 and 240 -> 168 of 250). The returned reports end
    with the check's, and the one that measured the kept policies says so."""
    datasets = skill_datasets(skills)
    oracle = hand_written(env) if config.expert == "oracle" else None
    steps = rollout_steps(skills, datasets, oracle)  # the same every round
    relabelled = None
    if config.relabels and oracle is not None:
        relabelled = oracle_labels(env, skills, steps, oracle, demo_states)
    say = report or (lambda message: None)
    corrections: list[Correction] = []
    reports: list[RoundReport] = []
    replayed: list[LearnedSkills] = []  # the policies each report's rollouts replayed
    current = skills
    for number in range(1, config.rounds + 1):
        t0 = time.perf_counter()
        summaries = []
        for rows, summary in collect_corrections(env, current, steps, origins, config, workers):
            corrections.extend(rows)
            summaries.append(summary)
        replayed.append(current)
        current = retrain_policies(skills, datasets, corrections, relabelled)
        counts = Counter(c.skill for c in corrections)
        names = tuple((skills.skills[k].name, counts[k]) for k in sorted(counts))
        reports.append(RoundReport(tuple(summaries), names, time.perf_counter() - t0))
        say(reports[-1].line(number))
    if config.keep == "last":
        return current, tuple(reports)
    t0 = time.perf_counter()
    check = [
        s
        for _, s in collect_corrections(
            env, current, steps, origins, config, workers, measure_only=True
        )
    ]
    reports.append(RoundReport(tuple(check), (), time.perf_counter() - t0, retrained=False))
    replayed.append(current)
    best = max(range(len(reports)), key=lambda i: (reports[i].completed, i))
    reports[best] = dataclasses.replace(reports[best], kept=True)
    last = reports[-1]
    which = f"round {best}'s" if best else "the demonstrations' own (no round's)"
    say(
        f"corrections check: {last.completed}/{len(last.rollouts)} rollouts of the last "
        f"round's policies completed every segment; kept {which} policies "
        f"({reports[best].completed} completed); {last.seconds:.1f} s"
    )
    return replayed[best], tuple(reports)
