"""View provider of a PrintedPart: printed colour, its icon."""

from __future__ import annotations

from FabrickatorWorkbench.viewproviders.base import ViewProvider

#: Colour of printed parts (a light, PLA-like orange).
PRINTED_COLOUR = (0.96, 0.62, 0.26)


class ViewProviderPrintedPart(ViewProvider):
    """A printed part, shown as its exact solid in the printed colour."""

    ICON = "PrintedPart"

    def __init__(self, vobj):
        super().__init__(vobj)
        vobj.ShapeColor = PRINTED_COLOUR
