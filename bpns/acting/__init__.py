"""Acting in a world that differs from the planner's model: closed-loop execution.

The approaches plan (or choose skills) in the *model*; :mod:`.world` executes what they
decided in the *world*, re-querying the skill's policy on the world's observation every
control step; :mod:`.monitor` compares the world's abstract state with what the rest of
the plan needs, at every skill boundary and while a skill runs; :mod:`.replanning`
repairs the plan from the observed world state when they disagree (the rest of the same
abstract plan first, then a new plan), within a replan budget and the task's timeout.
:class:`.config.ExecutionConfig` says how.
"""
