"""Planning parameters, passed explicitly (no global config).

The paper's ablations are just configs: ``Samples=1`` is ``PlanningConfig(n_samples=1)``
and ``AbstractPlans=1`` is ``PlanningConfig(n_abstract=1)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bpns.env.environment import Environment

HEURISTICS = ("lmcut", "hff", "hadd", "hmax")
SEARCHES = ("astar", "gbfs", "ucs")


@dataclass(frozen=True)
class PlanningConfig:
    """Parameters of bilevel planning (paper Alg. 1 and appendix B).

    n_abstract:        N_abstract, abstract plans (skeletons) tried before giving up.
    n_samples:         N_samples, subgoal samples per skeleton step before backtracking.
    timeout:           wall-clock seconds for the whole ``plan`` call (paper: 300).
    heuristic:         delete-relaxation heuristic guiding the abstract search.
    search:            "astar" (g+h), "gbfs" (h) or "ucs" (g, heuristic unused).
    max_skill_horizon: H_skill, most actions one skill may take for one subgoal.
    stuck_steps:       a rollout fails after this many consecutive steps in which every
                       feature stayed within ``stuck_atol`` of where it stood when the
                       world last stopped moving (saves waiting out H_skill).
    stuck_atol:        absolute tolerance of the "going nowhere" test, in the features'
                       own units: above the contact jitter of a resting scene and the
                       chatter of an arm held at its reach limit (0.6 mm per step).
    max_plan_length:   most ground skills in one abstract plan.
    max_state_repeats: times an abstract state may recur on one abstract plan: 0 is a
                       strictly acyclic search; 1 admits plans whose loops change only what
                       the predicates do not see (Coffee declares it: twisting a pot by its
                       knob and letting go returns to the same abstract state). Such plans
                       are longer, so A* reaches them only after the acyclic ones.
    nogood_atol:       remember refuted steps and skeleton suffixes and refute a new
                       arrival from a state whose features all lie within this tolerance
                       of a refuted one (see ``bpns.planning.nogoods``); None is the
                       paper's plain chronological backtracking.
    set_aside_after:   set a skeleton aside once one of its steps has failed every one of
                       its ``n_samples`` samples from this many different arrivals (states
                       the steps before it left), and refine the next skeleton; skeletons
                       set aside are refined again, without the limit, once the search
                       has no other skeleton left. Backtracking otherwise tries every
                       combination of the earlier steps' samples before it gives up on a
                       step that fails whatever they do. None: never (the paper's).
    reuse_prefixes:    start refining a skeleton after the deepest prefix an earlier
                       skeleton of the same call already refined (same steps, same
                       expected abstract states) instead of simulating it again.
    demote_refuted:    once a ground step has failed every sample from an arrival and no
                       step adding the same atoms has succeeded, operators that add exactly
                       those atoms cost this much more in the abstract search, which
                       restarts (skeletons already tried are not tried again): skeletons
                       that achieve the atoms another way come first, none is dropped
                       (see ``bpns.planning.nogoods.RefutedAchievers``). None: unit costs
                       throughout (the paper's).
    end_on_contact_change: end a skill at the first change of a contact-related atom (as
                       segmentation does): success if the expected atoms hold then, else
                       an immediate sample failure instead of waiting out H_skill.
    end_at_dead_end:   end a rollout at once, as a failed sample, in a state the
                       environment declares a dead end (``Capabilities.dead_end``: no goal
                       is reachable from it any more, e.g. Coffee's spilled coffee) instead
                       of waiting out H_skill. False: every rollout runs on (the paper's).
    """

    n_abstract: int = 8
    n_samples: int = 10
    timeout: float = 300.0
    heuristic: str = "lmcut"
    search: str = "astar"
    max_skill_horizon: int = 200
    stuck_steps: int = 10
    stuck_atol: float = 1e-3
    max_plan_length: int = 100
    max_state_repeats: int = 0
    end_on_contact_change: bool = False
    end_at_dead_end: bool = True
    nogood_atol: float | None = 5e-3
    set_aside_after: int | None = 3
    reuse_prefixes: bool = True
    demote_refuted: float | None = None

    def __post_init__(self) -> None:
        if self.heuristic not in HEURISTICS:
            raise ValueError(f"heuristic must be one of {HEURISTICS}, got {self.heuristic!r}")
        if self.search not in SEARCHES:
            raise ValueError(f"search must be one of {SEARCHES}, got {self.search!r}")
        for name in (
            "n_abstract",
            "n_samples",
            "max_skill_horizon",
            "stuck_steps",
            "max_plan_length",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not 0 < self.timeout < math.inf:  # results.json is strict JSON: no Infinity
            raise ValueError(f"timeout must be a finite number of seconds > 0, got {self.timeout}")
        if self.nogood_atol is not None and not 0 <= self.nogood_atol < math.inf:
            raise ValueError(f"nogood_atol must be >= 0 or None, got {self.nogood_atol}")
        if self.set_aside_after is not None and self.set_aside_after < 1:
            raise ValueError(f"set_aside_after must be >= 1 or None, got {self.set_aside_after}")
        if self.demote_refuted is not None and not 0 < self.demote_refuted < math.inf:
            raise ValueError(
                f"demote_refuted must be a finite cost > 0 or None, got {self.demote_refuted}"
            )
        if self.max_state_repeats < 0:
            raise ValueError(f"max_state_repeats must be >= 0, got {self.max_state_repeats}")
        if not 0 <= self.stuck_atol < math.inf:
            raise ValueError(f"stuck_atol must be >= 0, got {self.stuck_atol}")


def planning_config_for(env: Environment, **overrides: object) -> PlanningConfig:
    """The environment's declared planning defaults (``capabilities.planning_defaults``,
    e.g. the paper's N_abstract=1000 for Stick Button) with ``overrides`` (those not
    None) on top: the one source of a domain's planning settings."""
    fields = dict(env.capabilities.planning_defaults)
    fields.update({k: v for k, v in overrides.items() if v is not None})
    return PlanningConfig(**fields)
