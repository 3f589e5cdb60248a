"""View provider of a Load: a translucent blue box, with its icon."""

from __future__ import annotations

from FabrickatorWorkbench.viewproviders.base import ViewProvider

#: Colour and transparency (percent) of a Load's box.
LOAD_COLOUR = (0.16, 0.42, 0.86)
LOAD_TRANSPARENCY = 60


class ViewProviderLoad(ViewProvider):
    """A Load: the box its mass rests in, seen through."""

    ICON = "Load"

    def __init__(self, vobj):
        super().__init__(vobj)
        vobj.ShapeColor = LOAD_COLOUR
        vobj.Transparency = LOAD_TRANSPARENCY
