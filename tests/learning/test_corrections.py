"""Corrections (DAgger): who labels a segment, what retraining keeps, and the whole loop in
a perturbed Cover world."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
import torch

from bpns.env.abstraction import abstract
from bpns.env.worlds import parse_world
from bpns.learning.config import learning_config_for
from bpns.learning.corrections import (
    Correction,
    CorrectionConfig,
    DemoOrigin,
    hand_written,
    improve_with_corrections,
    oracle_labels,
    oracle_step,
    retrain_policies,
    rollout_steps,
    skill_datasets,
)
from bpns.learning.pipeline import learn_skills
from bpns.learning.policies import LearnedPolicy
from bpns.structs import GroundAtom, LiftedAtom, Segment, Skill, State, STRIPSOperator, Variable
from tests import toy_learning as toy

# -- which hand-written skill labels a segment -----------------------------------------


_R, _B, _T = Variable("?r", toy.ROBOT), Variable("?b", toy.BLOCK), Variable("?t", toy.TARGET)


def _atom(predicate, *variables: Variable) -> LiftedAtom:
    return LiftedAtom(predicate, variables)


def _operator(name: str, pre, add, delete=()) -> STRIPSOperator:
    r, b, t = _R, _B, _T
    params = tuple(v for v in (r, b, t) if any(v in a.variables for a in (*pre, *add, *delete)))
    return STRIPSOperator(name, params, frozenset(pre), frozenset(add), frozenset(delete))


def _still(state: State, objects, subgoal: np.ndarray) -> np.ndarray:
    return np.zeros(2)


def _nowhere(state: State, objects, rng: np.random.Generator) -> np.ndarray:
    return np.zeros(1)


def _skill(op: STRIPSOperator) -> Skill:
    return Skill(op, policy=_still, sampler=_nowhere)


def test_the_oracle_for_a_segment_does_what_it_did_and_nothing_it_did_not():
    empty, holding = _atom(toy.HAND_EMPTY, _R), _atom(toy.HOLDING, _R, _B)
    covers = _atom(toy.COVERS, _B, _T)
    pick = _operator("Pick", [empty], [holding], [empty])
    # adds Holding too, but also something the segment did not do: second choice
    grab_and_cover = _operator("GrabCover", [empty], [holding, covers])
    place = _operator("Place", [holding], [covers])
    robot, (block,) = toy.ROBOT_OBJ, toy.blocks(1)
    before = toy.make_state(0.0, [1.0], [3.0])
    after = toy.make_state(1.0, [1.0], [3.0], held=0)
    segment = Segment(
        (before, after),
        np.zeros((1, 2)),
        frozenset(abstract(before, toy.PREDICATES)),
        frozenset(abstract(after, toy.PREDICATES)),
    )
    assert GroundAtom(toy.HOLDING, (robot, block)) in segment.add_effects
    oracle = [_skill(place), _skill(grab_and_cover), _skill(pick)]
    step = oracle_step(oracle, segment, before.objects)
    assert step is not None and oracle[step.skill].operator.name == "Pick"
    assert step.objects == (robot, block)
    np.testing.assert_array_equal(step.subgoal, after.vec([robot, block]))
    # nothing adds what the segment did: no expert for it
    assert oracle_step([_skill(place)], segment, before.objects) is None


# -- retraining ----------------------------------------------------------------------------


def test_retraining_without_corrections_keeps_every_network():
    skills = toy.learned_toy_skills()
    datasets = skill_datasets(skills)
    again = retrain_policies(skills, datasets, [])
    assert all(a.policy is b.policy for a, b in zip(again.skills, skills.skills, strict=True))


def test_a_retrained_policy_answers_the_expert_where_it_was_corrected():
    """Corrections at states no demonstration visited move the policy there towards the
    expert's command; skills without corrections keep their networks."""
    skills = toy.learned_toy_skills()
    datasets = skill_datasets(skills)
    k = next(i for i, s in enumerate(skills.skills) if s.operator.name.startswith("Holding"))
    skill, objects = skills.skills[k], datasets[k].bindings[0]
    seg = datasets[k].segments[0]
    scope = skill.policy.dims.scope(objects)
    subgoal = seg.states[-1].vec(scope)
    # the robot far beyond anything demonstrated
    far = State({**seg.states[0].data, objects[0]: np.array([toy.WORLD + 5.0, 0.0])})
    command = np.array([-toy.SPEED, 0.0])
    before = skill.policy(far, objects, subgoal)
    rows = [Correction(k, far.vec(scope), subgoal, command) for _ in range(400)]
    torch.set_num_threads(1)
    again = retrain_policies(skills, datasets, rows)
    after = again.skills[k].policy(far, objects, subgoal)
    assert abs(after[0] - command[0]) < abs(before[0] - command[0])
    assert abs(after[0] - command[0]) < 0.1
    others = [i for i in range(len(skills.skills)) if i != k]
    assert all(again.skills[i].policy is skills.skills[i].policy for i in others)


def test_correction_settings_are_checked():
    worlds = parse_world(["latency=1"])
    with pytest.raises(ValueError, match="rounds"):
        CorrectionConfig(worlds, rounds=0)
    with pytest.raises(ValueError, match="expert must be one of"):
        CorrectionConfig(worlds, expert="teacher")
    with pytest.raises(ValueError, match="expert_mix"):
        CorrectionConfig(worlds, expert_mix=1.5)
    with pytest.raises(ValueError, match="horizon_scale"):
        CorrectionConfig(worlds, horizon_scale=float("nan"))


# -- the loop in physics -------------------------------------------------------------------


@functools.cache
def _cover_skills(cover_env_name: str = "cover"):
    from bpns.data.demos import run_demonstrator
    from bpns.env.registry import make_environment

    env = make_environment(cover_env_name)
    origins = [DemoOrigin(7, i) for i in range(3)]
    demos = [
        run_demonstrator(env, env.task(o.index, o.seed, True), [o.seed, o.index]) for o in origins
    ]
    net = toy.MLPConfig(num_steps=300, batch_size=128)
    config = dataclasses.replace(
        learning_config_for(env), policy=net, generator=net, classifier=net
    )
    torch.set_num_threads(1)
    skills = learn_skills(demos, env.predicates, env.contact_predicates, config)
    return env, skills, origins


def test_with_the_oracle_acting_every_rollout_completes_its_demonstration():
    """The oracle chosen for each segment, acting towards the segment's final state in
    a world with a step of latency, takes the task through every segment: the labels
    are what the subgoal asks for."""
    env, skills, origins = _cover_skills()
    config = CorrectionConfig(parse_world(["latency=1"]), rounds=1, expert_mix=1.0, keep="last")
    _, (report,) = improve_with_corrections(env, skills, origins, config)
    assert report.completed == len(origins)
    assert all(r.corrections > 0 for r in report.rollouts)


def test_corrections_retrain_the_policies_of_the_skills_they_label():
    env, skills, origins = _cover_skills()
    config = CorrectionConfig(parse_world(["latency=1"]), rounds=1, relabel=False, keep="last")
    lines: list[str] = []
    improved, (report,) = improve_with_corrections(
        env, skills, origins, config, report=lines.append
    )
    labelled = {name for name, n in report.corrections if n > 0}
    assert labelled, "the learned skills acted, so the oracle was asked"
    for old, new in zip(skills.skills, improved.skills, strict=True):
        assert (old.policy is not new.policy) == (old.name in labelled)
        assert old.sampler is new.sampler and old.operator == new.operator
    assert lines and lines[0].startswith("corrections round 1:")
    assert len(report.rollouts) == len(origins)


def test_relabelling_gives_the_demonstrations_the_oracles_commands():
    """`relabel`: every segment an oracle skill can do gets the oracle's commands on its
    own states (in bounds, one per action), and the policies learn those instead."""
    env, skills, _ = _cover_skills()
    oracle = hand_written(env)
    labels = oracle_labels(
        env, skills, rollout_steps(skills, skill_datasets(skills), oracle), oracle
    )
    segments = [seg for segs in skills.segments for seg in segs]
    assert labels and set(labels) <= {id(seg) for seg in segments}
    for seg in segments:
        if id(seg) in labels:
            got = labels[id(seg)]
            assert got.shape == seg.actions.shape
            assert (got >= env.action_low).all() and (got <= env.action_high).all()
    datasets = skill_datasets(skills)
    again = retrain_policies(skills, datasets, [], labels)
    assert any(a.policy is not b.policy for a, b in zip(again.skills, skills.skills, strict=True))
    worlds = parse_world(["latency=1"])
    with pytest.raises(ValueError, match="relabel needs the oracle"):
        CorrectionConfig(worlds, expert="demonstrator", relabel=True)
    # by default the oracle relabels; the demonstrator, which labelled them, does not
    assert CorrectionConfig(worlds).relabels and CorrectionConfig(worlds).to_json()["relabel"]
    assert not CorrectionConfig(worlds, expert="demonstrator").relabels
    assert not CorrectionConfig(worlds, relabel=False).relabels


@functools.cache
def _doors_skills():
    """Doors skills learned, as `bpns learn` learns them, from states without their
    simulator; the demonstrations themselves keep it."""
    from bpns.data.demos import run_demonstrator
    from bpns.env.registry import make_environment
    from bpns.learning.given import given_skills_of

    env = make_environment("doors")
    origins = [DemoOrigin(7, i) for i in range(3)]
    demos = [
        run_demonstrator(env, env.task(o.index, o.seed, True), [o.seed, o.index]) for o in origins
    ]
    bare = [dataclasses.replace(d, states=tuple(State(s.data) for s in d.states)) for d in demos]
    net = toy.MLPConfig(num_steps=100, batch_size=128)
    config = dataclasses.replace(
        learning_config_for(env), policy=net, generator=net, classifier=net
    )
    torch.set_num_threads(1)
    given = given_skills_of(env)
    skills = learn_skills(bare, env.predicates, env.contact_predicates, config, given=given)
    return env, skills, origins, demos


def test_doors_corrections_relabel_on_the_scene_and_go_on_past_given_skills():
    """Doors' oracle plans the base's path in the scene's walls: it relabels the
    demonstrations' states with their simulator state (learning read features only),
    and a rollout goes on past the environment's given skill (moving through a door)."""
    from bpns.learning.given import given_skills_of

    env, skills, origins, demos = _doors_skills()
    assert given_skills_of(env), "Doors declares a given skill"
    oracle = hand_written(env)
    steps = rollout_steps(skills, skill_datasets(skills), oracle)
    with pytest.raises(AttributeError):  # the scene is not in a features-only state
        oracle_labels(env, skills, steps, oracle)
    labels = oracle_labels(env, skills, steps, oracle, lambda i: demos[i].states)
    segments = [seg for segs in skills.segments for seg in segs]
    assert labels and all(
        labels[id(s)].shape == s.actions.shape for s in segments if id(s) in labels
    )
    config = CorrectionConfig(
        parse_world(["action_noise=0.001"]), rounds=1, expert_mix=1.0, keep="last"
    )
    _, (report,) = improve_with_corrections(
        env, skills, origins, config, demo_states=lambda i: demos[i].states
    )
    # a rollout goes on past a given skill's step (before, every rollout ended at one)
    given = [
        next(
            k
            for k, p in enumerate(plan)
            if not isinstance(skills.skills[p.skill].policy, LearnedPolicy)
        )
        for plan in steps
    ]
    assert any(r.completed > g for r, g in zip(report.rollouts, given, strict=True))


def test_corrections_keep_the_policies_whose_replays_completed_the_most():
    """keep="best": the last round's policies are replayed once more, and the policies
    (the plain ones included) that carried the most demonstrations through every segment
    are returned; the report that measured them says so."""
    env, skills, origins = _cover_skills()
    config = CorrectionConfig(parse_world(["latency=1"]), rounds=1, relabel=False)
    lines: list[str] = []
    improved, reports = improve_with_corrections(env, skills, origins, config, report=lines.append)
    first, check = reports
    assert first.retrained and not check.retrained and check.corrections == ()
    # the check measures the policies alone: the expert is not asked there
    assert all(r.corrections == 0 for r in check.rollouts)
    assert any(r.corrections > 0 for r in first.rollouts)
    assert [r.kept for r in reports].count(True) == 1
    kept_plain = first.kept  # its rollouts replayed the plain policies
    assert (first.completed > check.completed) == kept_plain
    same = all(a.policy is b.policy for a, b in zip(improved.skills, skills.skills, strict=True))
    assert same == kept_plain
    assert lines[-1].startswith("corrections check: ") and "kept" in lines[-1]
    assert check.to_json()["retrained"] is False
    with pytest.raises(ValueError, match="keep must be one of"):
        CorrectionConfig(parse_world(["latency=1"]), keep="first")
