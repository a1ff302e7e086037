"""Stick Button: press every button, the far ones with a stick (paper App. A.3)."""
