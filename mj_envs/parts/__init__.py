"""Reusable scene parts: a latching push button, free rigid objects and their placement."""
