"""How a plan made in the model meets the world (``bpns eval --execution``)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from bpns.errors import BpnsError
from bpns.execution.executor import RolloutConfig

MODES = ("closed-loop", "open-loop")
SLOW_FROM = ("start", "deviation")  # when a world_speed below 1 takes effect


class ExecutionConfigError(BpnsError, ValueError):
    """A setting of :class:`ExecutionConfig` out of its range."""


@dataclass(frozen=True)
class ExecutionConfig:
    """closed_loop:   execute skill by skill in the world, each policy re-queried every
                      control step on the world's observation, monitored, and replan on
                      divergence (False: replay the model's plan open loop, as the paper).
    max_replans:      divergences tolerated per task before it fails (``replan_budget``).
    rerefine_atol:    at a skill boundary where the world's features left the model's
                      prediction by more than this (feature units: metres, radians), the
                      rest of the plan is refined again from the world's state, so later
                      subgoals fit where things really are; None: only on a divergence.
    check_ahead:      at such a boundary, how many steps of the rest are simulated again
                      in the model from the world's state (their subgoals kept when they
                      still reach their expected atoms); the later steps keep the old
                      prediction until their own boundary checks them. None: the whole
                      rest, and it must still reach the goal. Checking the whole rest at
                      every boundary costs a plan of n steps about n^2 / 2 step rollouts.
    watch_atoms:      end a skill the moment an atom the rest of the plan needs (and the
                      model's rollout kept) stops holding for the environment's
                      ``contact_settle_steps``, instead of at its horizon.
    watch_releases:   also end a skill the moment a contact precondition it deletes (a
                      grip it lets go of at the end) stops holding before its add effects
                      all hold, when the model's own rollout of the step kept it until
                      then (a handle slipping out of the fingers before the door opened):
                      without it the skill runs on to its horizon on nothing.
    horizon_scale:    a skill executing in the world may take this many times its own
                      horizon (still capped by the planner's ``max_skill_horizon``). The
                      horizon learned from demonstrations cuts refinement short in the
                      model, where a slow sample is cheap to abandon; in the world,
                      abandoning a skill that is still moving (a softer arm, a delayed
                      command) costs a replan from a state the plan never expected.
                      A skill that stops moving still ends at once (``stuck``).
    world_speed:      a skill executing in the world applies this fraction of each
                      commanded motion (the environment's ``motion_dims``; the fingers as
                      commanded). A cloned policy's law is a gain on the distance to its
                      subgoal; a command that arrives late overshoots by that gain, so a
                      slower arm stays stable under more latency. The skill's horizon in
                      the world grows by 1 / world_speed with it. Refinement in the model
                      moves at full speed; 1.0: as commanded.
    resume_stopped:   when a replan finds no abstract plan from the world's state, plan
                      again letting the first step be an operator that lacks only
                      preconditions it deletes itself: a skill the world stopped midway
                      (a hand that reached the doorway but not the handle) leaves a state
                      no demonstration shows, from which the learned operators offer no
                      way on; refinement in the model checks that the skill finishes.
    back_off:         when a replan finds no plan at all, run the environment's declared
                      back-off motion in the world (``Capabilities.back_off``: e.g. the
                      fingers opened, the hand raised and returned to where the task began)
                      and plan once more from there, once per divergence. A failed skill
                      can leave the robot where no learned skill starts well (the hand
                      on the table beside a dropped stick); demonstrations start from
                      poses like the one it backs off to.
    predict_latency:  skills executing in the world see their observation advanced, in
                      the model, by the commands the world has not applied yet; the
                      world's latency is identified from the task's first control steps
                      (:class:`bpns.acting.prediction.InFlightPredictor`). A command
                      computed from a state ``d`` steps stale overshoots; this is the
                      state it will meet.
    latency_learn_steps: the control steps of a task the latency is identified from
                      (until then nothing is predicted).
    slow_from:        when ``world_speed`` takes effect: from the task's ``start``, or from
                      the first ``deviation`` (a skill boundary where the world's features
                      left the model's prediction by more than ``rerefine_atol``, or a
                      divergence): until the world shows it differs from the model, the
                      skills run as demonstrated and refined.
    """

    closed_loop: bool = True
    max_replans: int = 10
    rerefine_atol: float | None = 0.01
    check_ahead: int | None = None
    watch_atoms: bool = True
    watch_releases: bool = False
    horizon_scale: float = 2.0
    world_speed: float = 1.0
    slow_from: str = SLOW_FROM[0]
    resume_stopped: bool = True
    back_off: bool = True
    predict_latency: bool = False
    latency_learn_steps: int = 20

    def __post_init__(self) -> None:
        if isinstance(self.max_replans, bool) or not isinstance(self.max_replans, int):
            raise ExecutionConfigError(
                f"max_replans must be a whole number, got {self.max_replans!r}"
            )
        if self.max_replans < 0:
            raise ExecutionConfigError(f"max_replans must be >= 0, got {self.max_replans}")
        atol = self.rerefine_atol
        if atol is not None and not (0.0 < atol < math.inf):
            raise ExecutionConfigError(f"rerefine_atol must be finite and > 0, got {atol}")
        ahead = self.check_ahead
        if ahead is not None and (isinstance(ahead, bool) or not isinstance(ahead, int)):
            raise ExecutionConfigError(f"check_ahead must be a whole number, got {ahead!r}")
        if ahead is not None and ahead < 1:
            raise ExecutionConfigError(f"check_ahead must be >= 1 or None, got {ahead}")
        if not (1.0 <= self.horizon_scale < math.inf):
            raise ExecutionConfigError(
                f"horizon_scale must be finite and >= 1, got {self.horizon_scale}"
            )
        if not (0.0 < self.world_speed <= 1.0):
            raise ExecutionConfigError(f"world_speed must be in (0, 1], got {self.world_speed}")
        steps = self.latency_learn_steps
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise ExecutionConfigError(
                f"latency_learn_steps must be a whole number >= 1, got {steps!r}"
            )
        if self.slow_from not in SLOW_FROM:
            raise ExecutionConfigError(
                f"slow_from must be one of {', '.join(SLOW_FROM)}, got {self.slow_from!r}"
            )

    @property
    def starting_speed(self) -> float:
        """The world speed a task starts with (full speed when it waits for a deviation)."""
        return self.world_speed if self.slow_from == "start" else 1.0

    @property
    def slows_on_deviation(self) -> bool:
        return self.world_speed < 1.0 and self.slow_from == "deviation"

    def world_limits(self, limits: RolloutConfig, slowed: bool | None = None) -> RolloutConfig:
        """``limits`` (the planner's, for the model) as a skill executing in the world
        gets them: its motion times ``world_speed`` and its horizon times
        ``horizon_scale / world_speed``, capped at the planner's ``max_skill_horizon /
        world_speed`` (a skill slowed to half its speed needs twice the steps to cover the
        same ground). The task's own horizon stays as it is. ``slowed``: at the slowed
        speed or at full speed (default: as ``slow_from`` starts a task)."""
        if slowed is None:
            speed = self.starting_speed
        else:
            speed = self.world_speed if slowed else 1.0
        return dataclasses.replace(
            limits,
            horizon_scale=self.horizon_scale / speed,
            max_skill_horizon=math.ceil(limits.max_skill_horizon / speed),
            speed=speed,
        )

    @property
    def mode(self) -> str:
        return MODES[0] if self.closed_loop else MODES[1]

    @classmethod
    def of_mode(cls, mode: str, **fields: object) -> ExecutionConfig:
        if mode not in MODES:
            raise ExecutionConfigError(f"unknown execution {mode!r}; known: {', '.join(MODES)}")
        return cls(closed_loop=mode == MODES[0], **fields)  # type: ignore[arg-type]


OPEN_LOOP = ExecutionConfig(closed_loop=False)
CLOSED_LOOP = ExecutionConfig()
