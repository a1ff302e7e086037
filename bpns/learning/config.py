"""Explicit, frozen configuration of the learning pipeline (no global config).

Defaults follow the paper (appendix B: 2x32 networks, Adam lr 1e-3, 1% skill filter,
100 rejection tries) with step counts cut so that learning from 1000 demonstrations
stays within about a minute or two on a 2-core CPU. Networks are trained on random
minibatches for a fixed number of gradient steps rather than full-batch "epochs": the
cost is then independent of dataset size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from bpns.nets.mlp import MLPConfig

if TYPE_CHECKING:
    from bpns.env.environment import Environment


@dataclass(frozen=True)
class LearningConfig:
    """Everything the learning pipeline needs besides demos and predicates."""

    seed: int = 0
    # Contact changes closer than this many steps are one event (see segmentation.py).
    # 1 is the paper's literal segmentation; physical environments declare their own
    # ``contact_settle_steps`` and `bpns learn` uses it.
    settle_steps: int = 1
    # Skills whose datasets hold fewer than this fraction of all segments are dropped.
    min_segment_fraction: float = 0.01
    # False gives the BPNS-NoSubgoal baseline: policies see the state only, no sampler.
    use_subgoals: bool = True
    # Add operator parameters for unaffected objects that a relation ties to the affected
    # ones in every segment (operators.anchor_parameters). False: the paper's operators.
    anchor_parameters: bool = True
    # Name learned operators Op0, Op1, ... as in the paper instead of after their
    # effects (naming.py); planning is the same either way.
    index_names: bool = False
    # Policies also see tanh(relative subgoal / this), in feature units (metres, radians):
    # resolution near the subgoal, where demonstrators switch (policies.py). None: off,
    # as in the paper; domains whose demonstrators switch declare it (learning_defaults).
    near_goal_scale: float | None = None
    # Train each skill's policy and subgoal generator also on the segments of operators
    # whose add effects include all of its own (sharing.py): variants of one motion that
    # segmentation split by what they leave behind. False: each operator's own data, as
    # in the paper.
    share_effect_data: bool = True
    # The subgoal generator's mean = a ridge-regression map of the start scope + the
    # network's residual (samplers.LinearBase). False: the network alone, as in the paper.
    linear_sampler_base: bool = True
    # Draw the subgoal's dims with the correlation their residuals had in training
    # (samplers.NoiseCorrelation): a held block and the hand holding it move together.
    # False: each dim independently, as in the paper.
    correlated_subgoal_noise: bool = False
    # The same under the policy (linear.py): commands proportional to the remaining offset,
    # which a few dozen segments do not teach a network near the goal (Cover's place
    # hovered two centimetres above the table). Off by default; domains declare it.
    linear_policy_base: bool = False
    # A sampler asked to start where its skill was never demonstrated refuses at once
    # (samplers.Novelty): a context dim (one the skill leaves as it finds it) beyond the
    # range its segments started from, widened by a tenth of the spread plus
    # ``novelty_floor`` feature units. Pressing a far button by hand, or picking Coffee's
    # pot by a handle turned away, otherwise costs 60-90 simulated steps per sample.
    # False: every draw is simulated, as in the paper.
    refuse_novel_starts: bool = True
    novelty_floor: float = 0.01
    # A scope dimension counts as "changing" when |final - initial| exceeds this in some
    # segment, and as static when its range over all the skill's states is within it.
    change_tolerance: float = 0.0
    # About 0.5 ms per step on one core: ~10 s per skill for all three networks. Inputs
    # are clipped into the training range + 10 % (mlp.input_box): a skill that ends a
    # little off the demonstrations' path (a wrist 5 deg off where every demo held it at
    # 0) must not send the next skill's networks into wild extrapolation. Coffee, 1000
    # demos, 50 eval tasks: 48 -> 50 solved, median 10.3 -> 1.6 s (docs/METHOD.md).
    policy: MLPConfig = field(
        default_factory=lambda: MLPConfig(num_steps=6000, batch_size=512, input_margin=0.1)
    )
    generator: MLPConfig = field(
        default_factory=lambda: MLPConfig(num_steps=8000, batch_size=256, input_margin=0.1)
    )
    classifier: MLPConfig = field(
        default_factory=lambda: MLPConfig(num_steps=4000, batch_size=256, input_margin=0.1)
    )
    max_rejection_tries: int = 100
    # A learned skill's horizon is this factor times its longest demonstrated segment
    # (None: no skill horizon, only the planner's max_skill_horizon).
    skill_horizon_factor: float | None = 2.0
    # Caps the wrong-binding negatives taken from one segment (chosen deterministically),
    # which keeps sampler data small in domains with many objects. None = no cap.
    max_negative_bindings_per_segment: int | None = 20

    def __post_init__(self) -> None:
        if not 0.0 <= self.min_segment_fraction <= 1.0:
            raise ValueError(
                f"min_segment_fraction must be in [0, 1], got {self.min_segment_fraction}"
            )
        if self.skill_horizon_factor is not None and not 0 < self.skill_horizon_factor < math.inf:
            raise ValueError(
                f"skill_horizon_factor must be finite and > 0, got {self.skill_horizon_factor}"
            )
        if self.settle_steps < 1:
            raise ValueError(f"settle_steps must be >= 1, got {self.settle_steps}")
        if self.max_rejection_tries < 1:
            raise ValueError(f"max_rejection_tries must be >= 1, got {self.max_rejection_tries}")
        if self.near_goal_scale is not None and not 0.0 < self.near_goal_scale < math.inf:
            raise ValueError(f"near_goal_scale must be finite and > 0, got {self.near_goal_scale}")
        if not 0.0 <= self.novelty_floor < math.inf:
            raise ValueError(f"novelty_floor must be finite and >= 0, got {self.novelty_floor}")
        if not 0.0 <= self.change_tolerance < math.inf:
            raise ValueError(f"change_tolerance must be >= 0, got {self.change_tolerance}")


def learning_config_for(env: Environment, **overrides: object) -> LearningConfig:
    """The environment's declared learning defaults with ``overrides`` (those not None)
    on top: ``settle_steps`` from its ``contact_settle_steps``, then its
    ``capabilities.learning_defaults`` (e.g. ``{"near_goal_scale": 0.01}``)."""
    fields: dict[str, object] = {"settle_steps": int(env.contact_settle_steps)}
    fields.update(env.capabilities.learning_defaults)
    fields.update({k: v for k, v in overrides.items() if v is not None})
    return LearningConfig(**fields)  # type: ignore[arg-type]
