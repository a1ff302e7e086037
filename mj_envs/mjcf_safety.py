"""Refuse MJCF text that would make MuJoCo read files: scenes come from demo files too.

A task's scene is stored as MJCF text inside each demonstration file, and MuJoCo opens
whatever an ``<include>`` or a ``file=`` attribute names, relative to the working
directory. Every scene a domain builds is procedural (assets/panda.xml has no meshes or
texture files), so untrusted text may reference no file at all, except names listed in
``allowed_files`` (in-memory assets a domain would pass to ``MjModel.from_xml_string``).
Document type declarations are refused too (entity expansion).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Collection

from bpns.errors import BpnsError

MAX_MJCF_CHARS = 1 << 24
# compiler directories and every attribute that names a file (mesh, hfield, skin,
# texture and its cube faces fileright/fileleft/..., model, include)
_DIR_ATTRIBUTES = frozenset({"assetdir", "meshdir", "texturedir"})


class UnsafeMjcfError(BpnsError, ValueError):
    """MJCF text that includes or references files outside what the domain ships."""


def check_mjcf(xml: str, allowed_files: Collection[str] = ()) -> None:
    """Raise :class:`UnsafeMjcfError` if ``xml`` is too large, declares a DTD or
    entities, ``<include>``s anything or references a file not in ``allowed_files``."""
    if len(xml) > MAX_MJCF_CHARS:
        raise UnsafeMjcfError(f"MJCF text longer than {MAX_MJCF_CHARS} characters")
    if "<!DOCTYPE" in xml.upper() or "<!ENTITY" in xml.upper():
        raise UnsafeMjcfError("MJCF with a document type or entity declaration")
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as err:
        raise UnsafeMjcfError(f"MJCF is not well-formed XML: {err}") from None
    for element in root.iter():
        if element.tag == "include":
            raise UnsafeMjcfError(
                f"MJCF <include file={element.get('file')!r}> is not allowed in a stored scene"
            )
        for name, value in element.attrib.items():
            if name in _DIR_ATTRIBUTES or (name.startswith("file") and value not in allowed_files):
                raise UnsafeMjcfError(
                    f"MJCF <{element.tag} {name}={value!r}> references a file the domain "
                    "does not ship"
                )
