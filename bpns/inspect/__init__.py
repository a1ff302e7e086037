"""Watching and sharing rollouts: Rerun recordings (``bpns view``, ``bpns eval --rerun``),
LeRobot datasets (``bpns export``) and the offline eval report (``report.html``).

Everything here is environment-agnostic: an episode (a demonstration or an eval rollout)
is read from its HDF5 file, its symbolic timelines (ground atoms, skills, monitor events)
computed here, and its 3D scene asked of the environment (``Environment.scene``). The
optional extras (``rerun-sdk``, ``pyarrow``) are imported only by the modules that need
them, which the workflow imports when a command asks for them (:mod:`bpns.inspect.extras`).
"""
