"""Drawer: a worked example of a bpns task package with an articulated part (README.md)."""
