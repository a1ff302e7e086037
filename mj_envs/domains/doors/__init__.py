"""Doors: a Panda on a mobile base crosses rooms through latched doors (paper App. A)."""
