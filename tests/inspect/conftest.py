"""Tiny evaluations to inspect: the oracle on one Cover and one Stick Button task,
solved under nominal physics and failed with frictionless finger pads (one abstract
plan, one sample per step: the pick touches, the place cannot hold). Seconds each."""

from __future__ import annotations

from pathlib import Path

import pytest

from bpns.cli import main

DOMAINS = ("cover", "stick_button")
OUTCOMES = ("solved", "failed")


def evaluate_oracle(env: str, out: Path, failed: bool, extra: tuple[str, ...] = ()) -> Path:
    argv = ["eval", "--env", env, "--approach", "oracle", "-n", "1", "--workers", "1"]
    argv += ["--timeout", "60", "--seed", "7", "--out", str(out), "--report-videos", "none"]
    if failed:
        argv += ["--perturb", "friction_scale=0", "--n-abstract", "1", "--n-samples", "1"]
    code = main([*argv, *extra])
    assert code == (1 if failed else 0)
    return out


class _Evaluations(dict):
    """(domain, solved|failed) -> the evaluation's rollouts file, evaluated when first
    asked for (once per session)."""

    def __init__(self, root: Path) -> None:
        super().__init__()
        self.root = root

    def __missing__(self, key: tuple[str, str]) -> Path:
        env, outcome = key
        d = evaluate_oracle(env, self.root / f"{env}_{outcome}", outcome == "failed")
        self[key] = d / "rollouts_oracle.h5"
        return self[key]


@pytest.fixture(scope="session")
def oracle_rollouts(tmp_path_factory) -> dict[tuple[str, str], Path]:
    return _Evaluations(tmp_path_factory.mktemp("inspect_evals"))
