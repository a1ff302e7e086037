"""Find approaches by name through the ``bpns.approaches`` entry-point group.

Like environments (:mod:`bpns.env.registry`), an approach is declared in package metadata,
e.g. ``[project.entry-points."bpns.approaches"] bpns = "bpns.approaches.bilevel:BPNS"``
naming an :class:`~bpns.approaches.base.ApproachEntry`. A new approach (a baseline in
this repository or in a plugin package) adds its entry point; nothing here changes,
and evaluation workers find it by name in any process.
"""

from __future__ import annotations

from importlib.metadata import entry_points

from bpns.approaches.base import ApproachEntry
from bpns.env.registry import PluginError, load_plugin
from bpns.errors import BpnsError

GROUP = "bpns.approaches"


class UnknownApproachError(BpnsError, KeyError):
    def __str__(self) -> str:
        return str(self.args[0])


def approach_names() -> list[str]:
    """Every installed approach's name, sorted."""
    return sorted({ep.name for ep in entry_points(group=GROUP)})


def get_approach(name: str) -> ApproachEntry:
    matches = [ep for ep in entry_points(group=GROUP) if ep.name == name]
    if not matches:
        known = ", ".join(approach_names()) or "none installed"
        raise UnknownApproachError(f"unknown approach {name!r}; known: {known}")
    entry = load_plugin(matches[0], "approach", lambda loaded: loaded)
    if not isinstance(entry, ApproachEntry) or entry.name != name:
        raise PluginError(
            f"approach plugin {name!r} (entry point {name} = {matches[0].value}) must name "
            f"an ApproachEntry called {name!r}, got {type(entry).__name__}"
        )
    return entry
