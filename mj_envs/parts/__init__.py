"""Reusable scene parts: a latching push button, free rigid objects and their placement,
static containers (a bin, a shelf). Articulated parts, a cabinet with a sliding drawer or
a hinged door (one damped, limited joint, a bar handle, joint readings for predicates such
as DrawerOpen), are in :mod:`mj_envs.parts.articulated`. Signatures and units:
docs/API.md."""
