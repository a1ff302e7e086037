"""The environment contract: the protocol bpns talks through, finding an environment by
name, the perturbation spec it applies, and the abstract view of its states."""
