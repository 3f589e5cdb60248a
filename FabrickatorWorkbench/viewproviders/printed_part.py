"""View provider of a PrintedPart: printed colour, its icon."""

from __future__ import annotations

from FabrickatorWorkbench.viewproviders.base import ViewProvider


class ViewProviderPrintedPart(ViewProvider):
    """A printed part, shown as its exact solid in the printed colour."""

    ICON = "PrintedPart"

    def __init__(self, vobj):
        super().__init__(vobj)
        from FabrickatorWorkbench.objects.tree import PRINTED_COLOUR
        vobj.ShapeColor = PRINTED_COLOUR
