"""View providers: icons, colours, double-click to edit.  Used by the GUI only, yet
importable in ``freecadcmd`` (FreeCAD's GUI modules are imported inside the methods
the GUI calls).

Bricks are ``App::Link`` objects whose look comes from their prototype, so
they need no view provider of their own.  :func:`attach_missing` gives an
object made without the GUI (in ``freecadcmd``, or a document saved there)
its view provider when the GUI shows it.  View providers know nothing of
the objects' modules: what they need of their object they ask its proxy.
"""

from __future__ import annotations

from FabrickatorWorkbench.viewproviders.base import ICONS, icon
from FabrickatorWorkbench.viewproviders.fabrication import ViewProviderFabrication
from FabrickatorWorkbench.viewproviders.load import ViewProviderLoad
from FabrickatorWorkbench.viewproviders.printed_part import ViewProviderPrintedPart
from FabrickatorWorkbench.viewproviders.region import ViewProviderRegion

#: The view provider of each Fabrickator role (the objects' ``FabrickatorRole``).
BY_ROLE = {"Fabrication": ViewProviderFabrication, "PrintedPart": ViewProviderPrintedPart,
           "HighResRegion": ViewProviderRegion, "Load": ViewProviderLoad}

__all__ = ["ICONS", "icon", "attach_missing", "BY_ROLE"]


def attach_missing(obj) -> None:
    """Attach Fabrickator's view provider to ``obj`` unless it has one (no-op without
    a view object, i.e. without the GUI)."""
    view = getattr(obj, "ViewObject", None)
    if view is None:
        return
    kind = BY_ROLE.get(getattr(obj, "FabrickatorRole", None))
    if kind is not None and getattr(view, "Proxy", None) is None:
        kind(view)
