"""View provider of a HighResRegion: a transparent red volume."""

from __future__ import annotations

from FabrickatorWorkbench.viewproviders.base import ViewProvider

#: Colour and transparency (percent) of region volumes.
REGION_COLOUR = (0.9, 0.22, 0.27)
REGION_TRANSPARENCY = 75


class ViewProviderRegion(ViewProvider):
    """A high-res region."""

    ICON = "HighResRegion"

    def __init__(self, vobj):
        super().__init__(vobj)
        vobj.ShapeColor = REGION_COLOUR
        vobj.Transparency = REGION_TRANSPARENCY
