"""What scripted demonstrators and oracle skills share: the phase runner and motion primitives."""
