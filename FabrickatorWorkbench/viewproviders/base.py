"""Common view provider behaviour: an icon, nothing serialised."""

from __future__ import annotations

import os

#: Folder of the SVG icons.
ICONS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                     "resources", "icons")


def icon(name: str) -> str:
    """Path of the icon ``name`` (without .svg)."""
    return os.path.join(ICONS, f"{name}.svg")


class ViewProvider:
    """Base of Fabrickator's Python view providers.  They keep nothing of their own
    (the look lives in the view object's properties), so nothing is serialised."""

    ICON = "Fabrickator"

    def __init__(self, vobj):
        vobj.Proxy = self
        self.Object = vobj.Object

    def attach(self, vobj):
        self.Object = vobj.Object

    def getIcon(self):
        return icon(self.ICON)

    def dumps(self):
        return None

    def loads(self, state):
        return None

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None
