"""Every step a user runs, as typed library functions: collect demonstrations
(:mod:`.collect`), learn skills (:mod:`.learn`), evaluate approaches (:mod:`.evaluate`),
report the results (:mod:`.report`) and check an environment's contract
(:mod:`.contract`). The ``bpns`` commands only parse arguments, call these and print what
they return; each step raises :class:`bpns.errors.BpnsError` subclasses for what it
refuses and takes a progress callback instead of printing."""

from bpns.workflow.collect import DemosWritten, collect_demos
from bpns.workflow.learn import CannotLearnError, LearnedRun, baselines_needed, learn_to_directory

__all__ = [
    "CannotLearnError",
    "DemosWritten",
    "LearnedRun",
    "baselines_needed",
    "collect_demos",
    "learn_to_directory",
]
