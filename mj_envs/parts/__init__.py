"""Reusable scene parts: a latching push button, free rigid objects and their placement,
static containers (a bin, a shelf). Signatures and units: docs/API.md."""
