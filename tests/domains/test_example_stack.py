"""The worked example package (examples/bpns_stack) end to end on a few demos: demos ->
save, load and exact replay -> learned operators -> tasks solved by bilevel planning.

`make test` installs the example (`pip install -e examples/bpns_stack`); run alone, this
test installs it into the running virtual environment first.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
import torch

import mj_envs  # noqa: F401
from bpns.data.datasets import load_demonstrations, save_demonstrations
from bpns.data.demos import replay
from bpns.env.registry import environment_names, make_environment
from bpns.evaluation.evaluate import EvalSpec, evaluate
from bpns.learning import learn_skills, save_skills
from bpns.learning.config import learning_config_for
from bpns.planning.config import planning_config_for

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "bpns_stack"


def _install_example() -> None:
    if "stack" not in environment_names():
        subprocess.run(
            [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "-e", str(EXAMPLE)],
            check=True,
        )
    if str(EXAMPLE) not in sys.path:  # an editable install's .pth is read at start-up only
        sys.path.insert(0, str(EXAMPLE))


@pytest.fixture(scope="module")
def stack():
    _install_example()
    return make_environment("stack")


def test_stack_pipeline_demos_replay_learn_eval(stack, tmp_path):
    from bpns.data.demo_attempts import attempt_demonstration

    # 30 demos and 4000 gradient steps: 12 demos at 1500 steps solved 1-3 of 3 on one machine
    # and none on another (an AVX-512 Xeon): the learned place was at the edge of working,
    # where rounding decides. Here 2-3 of 5 tasks solved for two learning seeds.
    attempts = [attempt_demonstration(stack, stack.task(i, 0, True), [0, i]) for i in range(30)]
    assert all(a.solved for a in attempts), [a.explain() for a in attempts if not a.solved]
    path = tmp_path / "stack.h5"
    save_demonstrations(path, stack, [a.demo for a in attempts])
    demos = load_demonstrations(path, stack)
    assert all(replay(stack, d, i).exact for i, d in enumerate(demos))

    torch.set_num_threads(1)
    config = learning_config_for(stack)
    config = dataclasses.replace(
        config,
        policy=dataclasses.replace(config.policy, num_steps=4000),
        generator=dataclasses.replace(config.generator, num_steps=4000),
        classifier=dataclasses.replace(config.classifier, num_steps=2000),
    )
    learned = learn_skills(demos, stack.predicates, stack.contact_predicates, config)
    ops = sorted(str(op).split("\n", 1)[1] for op in learned.operators)
    assert ops == [
        "    pre: Clear(?block0), Clear(?block1), Holding(?block0)\n"
        "    add: HandEmpty(?robot0), On(?block0, ?block1)\n"
        "    del: Clear(?block1), Holding(?block0)",
        "    pre: Clear(?block0), HandEmpty(?robot0), OnTable(?block0)\n"
        "    add: Holding(?block0)\n"
        "    del: HandEmpty(?robot0), OnTable(?block0)",
    ]
    save_skills(learned, tmp_path / "skills", env_name="stack")
    spec = EvalSpec(
        "stack", "bpns", planning_config_for(stack, timeout=20.0), str(tmp_path / "skills")
    )
    report = evaluate(spec, num_tasks=5)
    assert report.num_solved >= 1, [o.reason for o in report.outcomes]
