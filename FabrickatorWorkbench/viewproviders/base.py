"""Common view provider behaviour: an icon, nothing serialised."""

from __future__ import annotations

from FabrickatorWorkbench.objects.properties import Stateless
from FabrickatorWorkbench.viewproviders import icon


class ViewProvider(Stateless):
    """Base of Fabrickator's Python view providers."""

    ICON = "Fabrickator"

    def __init__(self, vobj):
        vobj.Proxy = self
        self.Object = vobj.Object

    def attach(self, vobj):
        self.Object = vobj.Object

    def getIcon(self):
        return icon(self.ICON)
