"""Which learned skill is weak, and why: closed-loop tests of each skill on held-out demos.

    python scripts/skill_diagnostics.py SKILLS DEMOS --first 900 --count 100 [--samples 5]
        [--perturb latency=2 obs_noise=0.005] [--horizon-scale 2] [--world-speed 0.6]

For every segment of the held-out demonstrations ``DEMOS[first : first + count]`` (not
used for learning when ``first`` is past ``bpns learn --limit``) that a learned skill
explains, the skill is rolled out from the segment's exact first simulator state with
the planner's own rollout (:class:`bpns.execution.executor.SkillExecutor`, the completion test
refinement uses) in three ways:

- ``demo subgoal``: the policy towards the subgoal the demonstration reached. Failures
  here are the policy's (imitation error, no recovery from a deviation).
- ``sampled``: ``--samples`` subgoals from the learned sampler, each rolled out. The
  rate is what refinement sees per sample; the gap to ``demo subgoal`` is the sampler's.
- ``steps``: simulated steps per successful rollout against the demonstrated segment's
  length (a skill that dawdles costs planning time even when it succeeds).

``--show-stuck N`` prints, for the first N sampled rollouts that end ``stuck``, the last
step's subgoal offset (subgoal - current, on the subgoal dims) and the policy's output
(with a linear base: the network's and the base's parts): why a cloned policy stopped.

``--perturb`` rolls every skill out in a world of fixed perturbed physics instead (the
``bpns eval --perturb`` names, one value each; the start state is carried into it as the
closed loop does), with each skill's horizon times ``--horizon-scale`` and its motion
times ``--world-speed`` (the world's ``ExecutionConfig``): which skill a world breaks.

Failure reasons are the planner's (``bpns.execution.failures``). Nothing is written; the table
goes to stdout. The environment is the one the skills directory records.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np

from bpns.acting.config import ExecutionConfig
from bpns.baselines.gnn_meta import label_segment
from bpns.data.datasets import iter_demonstrations
from bpns.env.environment import adopt_state, perturbed
from bpns.env.perturbations import parse_perturbation
from bpns.execution.executor import Executed, RolloutConfig, SkillExecutor, completion_test
from bpns.learning.artifacts.learned import load_learned
from bpns.learning.config import learning_config_for
from bpns.learning.segmentation import segment_demonstration
from bpns.planning.config import planning_config_for


@dataclass
class SkillTally:
    segments: int = 0
    demo_ok: int = 0
    demo_fail: Counter = field(default_factory=Counter)
    sampled: int = 0
    sampled_ok: int = 0
    sampled_fail: Counter = field(default_factory=Counter)
    steps_ok: list[int] = field(default_factory=list)
    steps_demo: list[int] = field(default_factory=list)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("skills")
    parser.add_argument("demos")
    parser.add_argument("--first", type=int, required=True, help="first held-out demo index")
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--samples", type=int, default=5, help="sampled subgoals per segment")
    parser.add_argument("--per-skill", type=int, default=40, help="segments per skill at most")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--perturb", nargs="+", default=[], metavar="NAME=VALUE", help="world physics"
    )
    parser.add_argument("--horizon-scale", type=float, default=1.0)
    parser.add_argument("--show-stuck", type=int, default=0, metavar="N")
    parser.add_argument("--world-speed", type=float, default=1.0)
    args = parser.parse_args()

    env, learned = load_learned(args.skills)
    skills = learned.skills
    operators = [s.operator for s in skills]
    settle = learning_config_for(env).settle_steps
    config = planning_config_for(env)
    world = perturbed(env, parse_perturbation(args.perturb))
    execution = ExecutionConfig(horizon_scale=args.horizon_scale, world_speed=args.world_speed)
    limits = execution.world_limits(RolloutConfig.of(config))
    rng = np.random.default_rng(args.seed)
    tallies: dict[str, SkillTally] = defaultdict(SkillTally)
    indices = range(args.first, args.first + args.count)
    shown = 0
    for demo in iter_demonstrations(args.demos, env, indices):
        executor = SkillExecutor(world, demo.task, limits)
        for seg in segment_demonstration(demo, env.predicates, env.contact_predicates, settle):
            label = label_segment(seg, operators)
            if label is None:
                continue
            k, binding = label
            skill = skills[k]
            tally = tallies[skill.name]
            if tally.segments >= args.per_skill or not hasattr(skill.policy, "dims"):
                continue  # enough of this skill, or a given (not learned) skill
            tally.segments += 1
            ground = skill.operator.ground(binding)
            test = completion_test(ground, ground.apply(seg.init_atoms))
            start = adopt_state(world, seg.states[0])
            scope = skill.policy.dims.scope(binding)
            demo_goal = seg.states[-1].vec(scope)
            tally.steps_demo.append(len(seg.actions))
            out = executor.execute(skill, binding, demo_goal, start, test)
            if isinstance(out, Executed):
                tally.demo_ok += 1
            else:
                tally.demo_fail[str(out)] += 1
            for _ in range(args.samples):
                subgoal = np.asarray(skill.sampler(seg.states[0], binding, rng), dtype=np.float64)
                tally.sampled += 1
                logged = _LoggedPolicy(skill.policy) if shown < args.show_stuck else None
                run = skill if logged is None else dataclasses.replace(skill, policy=logged)
                out = executor.execute(run, binding, subgoal, start, test)
                if logged is not None and str(out) == "stuck" and logged.last is not None:
                    shown += 1
                    rel, net, base = logged.last
                    print(f"stuck {skill.name}{tuple(o.name for o in binding)}:")
                    print(f"  subgoal - current: {np.round(rel, 3).tolist()}")
                    print(f"  network output:    {np.round(net, 3).tolist()}")
                    if base is not None:
                        print(f"  + linear base:     {np.round(base, 3).tolist()}")
                if isinstance(out, Executed):
                    tally.sampled_ok += 1
                    tally.steps_ok.append(len(out.actions))
                else:
                    tally.sampled_fail[str(out)] += 1
    where = f", world {' '.join(args.perturb)}" if args.perturb else ""
    print(
        f"{args.skills}: held-out demos {args.first}..{args.first + args.count - 1}{where}"
        f", horizon x{args.horizon_scale:g}, world speed {args.world_speed:g}"
    )
    print(
        "| skill | segments | demo subgoal | sampled | steps (sampled ok / demo) "
        "| failures (demo; sampled) |"
    )
    print("|---|---:|---:|---:|---:|---|")
    for skill in skills:
        t = tallies.get(skill.name)
        if t is None or t.segments == 0:
            continue
        steps = (
            f"{np.median(t.steps_ok):.0f} / {np.median(t.steps_demo):.0f}" if t.steps_ok else "-"
        )
        fails = "; ".join(
            ", ".join(f"{r} {n}" for r, n in sorted(c.items())) or "-"
            for c in (t.demo_fail, t.sampled_fail)
        )
        print(
            f"| {skill.name} | {t.segments} | {t.demo_ok}/{t.segments} | "
            f"{t.sampled_ok}/{t.sampled} | {steps} | {fails} |"
        )


class _LoggedPolicy:
    """A learned policy that keeps its last input offset and output parts."""

    def __init__(self, policy) -> None:
        self.policy, self.dims = policy, policy.dims
        self.last: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None

    def __call__(self, state, objects, subgoal):
        p = self.policy
        x = state.vec(p.dims.scope(objects))
        rel = subgoal[p.dims.subgoal_dims] - x[p.dims.subgoal_dims]
        out = p(state, objects, subgoal)
        base = None
        if p.base is not None and p.near_scale is None and p.use_subgoals:
            base = p.base(np.concatenate((x[p.dims.state_dims], rel)))
        self.last = (rel, out if base is None else out - base, base)
        return out


if __name__ == "__main__":
    main()
