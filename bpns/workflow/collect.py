"""Collect demonstrations into a file: the first step of the pipeline (``bpns demos``,
``bpns run``). Checking that they replay exactly is a data check
(:func:`bpns.data.demos.check_replay`)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from bpns.atomic import require_free_space
from bpns.data.datasets import TASK_INDEX, TASK_SEED, min_demo_bytes, write_demonstrations
from bpns.data.demo_attempts import demo_noise_of
from bpns.data.demos import Progress, collect_attempts, no_progress
from bpns.env.environment import Environment
from bpns.env.worlds import NOMINAL_WORLD, WorldDistribution


# -- demonstrations -----------------------------------------------------------------------
@dataclass(frozen=True)
class DemosWritten:
    path: Path
    env_name: str
    num_written: int
    failed: tuple[int, ...]  # task indices the demonstrator failed on
    seconds: float
    why: tuple[str, ...] = ()  # for each failed task: why (DemoAttempt.explain)
    noise: float = 0.0  # DART noise scale the demonstrations were collected with
    worlds: str = "nominal"  # the label of the worlds they were collected in

    def lines(self) -> list[str]:
        noisy = f" (DART noise {self.noise:g})" if self.noise else ""
        where = f" in {self.worlds} worlds" if self.worlds != "nominal" else ""
        tried = self.num_written + len(self.failed)
        out = [
            f"wrote {self.num_written} demonstrations of {self.env_name}{noisy}{where} to "
            f"{self.path} in {self.seconds:.1f} s: {self.num_written}/{tried} tasks succeeded"
            + (f"; the demonstrator failed on tasks {list(self.failed)}" if self.failed else "")
        ]
        for index, why in zip(self.failed, self.why, strict=False):
            out.append(f"  task {index}: {why}")
        return out


def collect_demos(
    env: Environment,
    num: int,
    seed: int,
    out: Path,
    workers: int = 1,
    progress: Progress = no_progress,
    debug: bool = False,
    noise: float | None = None,
    worlds: WorldDistribution = NOMINAL_WORLD,
) -> DemosWritten:
    """Run the scripted demonstrator on train tasks 0..num-1 and save the successes; say
    why each failure failed (with ``debug``: its traceback and last abstract states).
    ``noise``: DART noise scale (:class:`bpns.data.demo_attempts.ActionNoise`); None: the
    environment's declared one. ``worlds``: task ``i`` is demonstrated in the physics
    ``worlds.draw(i)``, stored with it (``physics``) so that replay is exact. Raises
    :class:`bpns.atomic.NotEnoughSpaceError`, before collecting any, when ``num``
    demonstrations cannot fit on ``out``'s disk."""
    # a lower bound per demonstration: more than the disk holds is certain not to fit
    needed = num * min_demo_bytes(env, env.task(0, seed, True))
    require_free_space(out, needed, f"{num} demonstrations")

    failed: list[int] = []
    why: list[str] = []
    t0 = time.perf_counter()
    noise = demo_noise_of(env) if noise is None else noise

    def successful():
        for index, attempt in progress(
            collect_attempts(env.name, num, seed, workers, noise=noise, worlds=worlds),
            num,
            f"demos {env.name}",
            "task",
        ):
            if attempt.demo is None:
                failed.append(index)
                why.append(attempt.explain(debug))
            elif worlds.nominal:
                yield attempt.demo, {TASK_INDEX: index}
            else:
                yield attempt.demo, {TASK_INDEX: index, "physics": worlds.draw(index).to_json()}

    root: dict[str, str | int] = {TASK_SEED: seed}
    if not worlds.nominal:
        root["worlds"] = worlds.to_json()
    n = write_demonstrations(out, env, successful(), root)
    return DemosWritten(
        out,
        env.name,
        n,
        tuple(failed),
        time.perf_counter() - t0,
        tuple(why),
        noise,
        worlds.label(),
    )
