"""View provider of a HighResRegion: a transparent red volume that clicks go through.

The region shows only while the brush panel is open (see
:mod:`FabrickatorWorkbench.objects.high_res_region`); there it lies over the
very bricks the user paints, so it cannot be picked: a click or a brush
stroke goes through it to the bricks, as through ghosts.  It is selected in
the tree.
"""

from __future__ import annotations

from FabrickatorWorkbench.viewproviders.base import ViewProvider

#: Colour and transparency (percent) of region volumes.
REGION_COLOUR = (0.9, 0.22, 0.27)
REGION_TRANSPARENCY = 75
#: Name of the pick style node that makes the region unpickable.
UNPICKABLE = "FabrickatorUnpickable"


class ViewProviderRegion(ViewProvider):
    """A high-res region."""

    ICON = "HighResRegion"

    def __init__(self, vobj):
        super().__init__(vobj)
        vobj.ShapeColor = REGION_COLOUR
        vobj.Transparency = REGION_TRANSPARENCY
        make_unpickable(vobj)

    def attach(self, vobj):
        super().attach(vobj)
        make_unpickable(vobj)


def make_unpickable(vobj) -> None:
    """Put an unpickable pick style first under ``vobj``'s root node (once)."""
    from pivy import coin

    root = vobj.RootNode
    if root.getNumChildren() and root.getChild(0).getName() == UNPICKABLE:
        return
    style = coin.SoPickStyle()
    style.setName(UNPICKABLE)
    style.style = coin.SoPickStyle.UNPICKABLE
    root.insertChild(style, 0)
