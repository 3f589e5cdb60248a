"""View providers: icons, colours, double-click to edit.  GUI only.

Bricks are ``App::Link`` objects whose look comes from their prototype, so
they need no view provider of their own.  :func:`attach_missing` gives an
object made without the GUI (in ``freecadcmd``, or a document saved there)
its view provider when the GUI shows it.
"""

from __future__ import annotations

import os

#: Folder of the SVG icons.
ICONS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                     "resources", "icons")


def icon(name: str) -> str:
    """Path of the icon ``name`` (without .svg)."""
    return os.path.join(ICONS, f"{name}.svg")


def attach_missing(obj) -> None:
    """Attach Fabrickator's view provider to ``obj`` unless it has one (GUI only)."""
    view = getattr(obj, "ViewObject", None)
    if view is None:
        return
    from FabrickatorWorkbench.viewproviders import fabrication, printed_part, region

    kind = {"Fabrication": fabrication.ViewProviderFabrication,
            "PrintedPart": printed_part.ViewProviderPrintedPart,
            "HighResRegion": region.ViewProviderRegion}.get(getattr(obj, "FabrickatorRole", None))
    if kind is not None and getattr(view, "Proxy", None) is None:
        kind(view)
