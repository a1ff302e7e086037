"""What scripted demonstrators and oracle skills share: the phase runner, motion primitives
and the helpers that write STRIPS operators."""
