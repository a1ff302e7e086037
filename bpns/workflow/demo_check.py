"""``bpns check-env NAME --demo``: the demonstrator and the oracle skills on a few tasks.

The contract checks (:mod:`bpns.workflow.contract`) ask whether an environment keeps its
promises; a task author also wants to know, while writing a demonstrator, on which tasks
it fails and in which phase. This runs the scripted demonstrator on the first train and
eval tasks, and plans with the environment's hand-written skills (where it declares any)
on the first eval tasks, one line each: solved, or what failed and why (the failing phase
a :class:`mj_envs.oracles.phases.PhasedDemonstrator` names, the goal atoms still missing
at the horizon, the planner's failure reason and what it tried).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from bpns.approaches.bilevel import oracle_skills, planning_explanation
from bpns.data.demo_attempts import attempt_demonstration
from bpns.env.environment import Environment
from bpns.inspect.explain import explanation_lines
from bpns.planning.bilevel import plan
from bpns.planning.config import planning_config_for

EXPLANATION_LINES = 4  # of a failed plan's explanation, shown under its line


@dataclass(frozen=True)
class DemoCheckRow:
    """One task's outcome: who ran it (``demonstrator`` or ``oracle``), on which task."""

    who: str
    stream: str  # "train" or "eval"
    index: int
    solved: bool
    detail: str  # "solved in N steps", or why not (possibly several lines)

    def lines(self) -> list[str]:
        head, *rest = self.detail.splitlines() or [""]
        verdict = "ok" if self.solved else "FAILED"
        return [f"{verdict:6s} {self.who}, {self.stream} task {self.index}: {head}"] + [
            f"         {line}" for line in rest
        ]


@dataclass(frozen=True)
class DemoCheckReport:
    rows: tuple[DemoCheckRow, ...]

    @property
    def failed(self) -> int:
        return sum(not r.solved for r in self.rows)

    def lines(self) -> list[str]:
        out = [line for row in self.rows for line in row.lines()]
        n = len(self.rows)
        out.append(f"{n - self.failed}/{n} demonstrations and oracle plans succeeded")
        return out


def check_demonstrations(
    env: Environment, n_tasks: int = 3, seed: int = 0, timeout: float = 30.0
) -> DemoCheckReport:
    """The demonstrator on train and eval tasks ``0..n_tasks-1`` (of ``seed``'s streams),
    then the oracle skills through the planner on the same eval tasks (``timeout``
    seconds each) where the environment declares them."""
    rows = [
        _demonstrate(env, stream, i, seed) for stream in ("train", "eval") for i in range(n_tasks)
    ]
    if env.capabilities.has_oracle_skills:
        rows += [_plan_with_oracle(env, i, seed, timeout) for i in range(n_tasks)]
    return DemoCheckReport(tuple(rows))


def _demonstrate(env: Environment, stream: str, index: int, seed: int) -> DemoCheckRow:
    task = env.task(index, seed, stream == "train")
    attempt = attempt_demonstration(env, task, [seed, index])
    return DemoCheckRow("demonstrator", stream, index, attempt.solved, attempt.explain())


def _plan_with_oracle(env: Environment, index: int, seed: int, timeout: float) -> DemoCheckRow:
    task = env.task(index, seed, False)
    config = planning_config_for(env, timeout=timeout)
    t0 = time.perf_counter()
    result = plan(task, oracle_skills(env), env, config, np.random.default_rng([seed, index]))
    seconds = time.perf_counter() - t0
    if result.success:
        steps = 0 if result.skeleton is None else len(result.skeleton.operators)
        detail = f"planned {steps} steps ({len(result.actions)} actions) in {seconds:.1f} s"
        return DemoCheckRow("oracle", "eval", index, True, detail)
    why = explanation_lines(planning_explanation(result.stats))[:EXPLANATION_LINES]
    detail = "\n".join([f"no plan: {result.reason} after {seconds:.1f} s", *why])
    return DemoCheckRow("oracle", "eval", index, False, detail)
