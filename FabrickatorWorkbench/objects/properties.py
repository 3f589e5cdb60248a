"""Idempotent property set-up for proxies and plain objects.

A proxy adds its properties in one method called from ``__init__`` and from
``onDocumentRestored`` (on restore ``__init__`` is not called), so a file
saved by an older version gains the new properties when opened.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import FreeCAD as App

from FabrickatorWorkbench.viewproviders import attach_missing

#: Editor modes of FreeCAD's property editor.
NORMAL, READ_ONLY, HIDDEN = 0, 1, 2


@dataclass(frozen=True)
class Prop:
    """One property: FreeCAD type, name, group, tool tip, default, editor mode.

    ``default`` may be a function of no arguments, called when the property is
    added (a default that lives in another table, read only then).
    """

    type: str
    name: str
    group: str
    doc: str
    default: Any = None
    mode: int = NORMAL


def ensure(obj, props) -> list[str]:
    """Add the missing ``props`` to ``obj`` (with their defaults), move the present ones
    into their group (a file from an older version may have them elsewhere) and set
    every editor mode; returns the names added."""
    added = []
    existing = set(obj.PropertiesList)
    for p in props:
        if p.name not in existing:
            obj.addProperty(p.type, p.name, p.group, p.doc)
            default = p.default() if callable(p.default) else p.default
            if default is not None:
                setattr(obj, p.name, default)
            added.append(p.name)
        elif obj.getGroupOfProperty(p.name) != p.group:
            obj.setGroupOfProperty(p.name, p.group)
        if p.mode != NORMAL:
            obj.setEditorMode(p.name, p.mode)
    return added


class Stateless:
    """Base of object proxies that keep nothing of their own: everything lives in the
    object's properties, so nothing is serialised."""

    def dumps(self):
        return None

    def loads(self, state):
        return None

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None


class FeatureProxy(Stateless):
    """Base of the FeaturePython proxies: the subclass's ``PROPERTIES`` are added
    on creation and again on restore (``__init__`` is not called then), and a
    restored object gets its view provider when the GUI is up."""

    PROPERTIES: tuple = ()

    def __init__(self, obj):
        obj.Proxy = self
        self.ensure_properties(obj)

    def ensure_properties(self, obj) -> None:
        """Add what is missing (idempotent)."""
        ensure(obj, self.PROPERTIES)

    def onDocumentRestored(self, obj):
        self.ensure_properties(obj)
        if App.GuiUp:
            attach_missing(obj)
