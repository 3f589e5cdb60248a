"""Fabrickator's user preferences, kept in FreeCAD's parameter tree.

They live under ``User parameter:BaseApp/Preferences/Mod/Fabrickator`` and
are edited on the preferences page (``resources/ui/preferences.ui``, whose
widgets save themselves there).  New Fabrications take their defaults from
here; each Fabrication then keeps its own values as properties.
"""

from __future__ import annotations

import FreeCAD as App

#: Parameter group of the preferences.
PATH = "User parameter:BaseApp/Preferences/Mod/Fabrickator"

#: name -> (type, default).  Types follow FreeCAD's parameter kinds.
DEFAULTS = {
    "BrickSet": ("String", "all"),
    "Clearance": ("Float", 0.1),
    "SlicerPath": ("String", ""),
    "SlicerProfile": ("String", ""),
    "SecondsPerBrick": ("Float", 10.0),
    "SliceOnRecompute": ("Bool", False),
}


def group():
    """The parameter group object."""
    return App.ParamGet(PATH)


def get(name: str):
    """The value of preference ``name`` (its default when unset)."""
    kind, default = DEFAULTS[name]
    return getattr(group(), f"Get{kind}")(name, default)


def set(name: str, value) -> None:  # noqa: A001 - the natural name next to get()
    """Store ``value`` for preference ``name``."""
    kind, _ = DEFAULTS[name]
    getattr(group(), f"Set{kind}")(name, value)


def values() -> dict:
    """All preferences as a dict."""
    return {name: get(name) for name in DEFAULTS}
