"""Stack: a worked example of a bpns task package (see docs/NEW_TASK.md)."""
