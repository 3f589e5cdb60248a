"""View provider of a Fabrication: its icon, its groups as children; double-click opens
the brush panel; two display modes, Normal (LEGO colours) and Stress (the force check's
utilisation of every brick, :mod:`.stress`).

The view provider sits below the commands and task panels: it opens the brush
panel by running the brush command (:data:`EDIT_COMMAND`, by name) on its
Fabrication, and deleting a Fabrication asks the Fabrication's proxy to remove
what it made.
"""

from __future__ import annotations

from FabrickatorWorkbench import log
from FabrickatorWorkbench.viewproviders import stress
from FabrickatorWorkbench.viewproviders.base import ViewProvider

#: The command a double-click (edit mode 0) runs on the Fabrication: the high-res brush.
EDIT_COMMAND = "Fabrickator_HighResBrush"


class ViewProviderFabrication(ViewProvider):
    """Fabrication in the tree and the 3D view."""

    ICON = "Fabrication"

    #: The task panel open on this Fabrication, if any (the commands set it).
    panel = None
    #: The layout preview of the last recompute
    #: (:class:`~FabrickatorWorkbench.viewproviders.layout_preview.LayoutPreview`), if any.
    last_preview = None
    #: The print times being sliced after the last recompute
    #: (:class:`~FabrickatorWorkbench.objects.later_slices.LaterSlice`), if any.
    later_slice = None

    def attach(self, vobj):
        super().attach(vobj)
        from pivy import coin

        for mode in stress.MODES:
            vobj.addDisplayMode(coin.SoGroup(), mode)

    def getDisplayModes(self, vobj):
        return list(stress.MODES)

    def getDefaultDisplayMode(self):
        return stress.NORMAL

    def setDisplayMode(self, mode):
        return mode

    def onChanged(self, vobj, prop):
        """Switching the display mode recolours the bricks."""
        if prop == "DisplayMode":
            on = vobj.DisplayMode == stress.STRESS
            if not stress.apply(vobj.Object, on) and on and getattr(vobj.Object, "LayoutJson", ""):
                log.message(f"{vobj.Object.Label}: no force check in this result yet: recompute "
                            f"it to see the Stress colours")

    def updateData(self, obj, prop):
        """A new result in the Stress mode gets its stress colours."""
        view = getattr(obj, "ViewObject", None)
        if prop == "ReportJson" and view is not None and view.DisplayMode == stress.STRESS:
            stress.apply(obj, True)

    def claimChildren(self):
        return list(self.Object.Contents) if hasattr(self.Object, "Contents") else []

    def setEdit(self, vobj, mode=0):
        """Open the brush panel on the Fabrication (mode 0); True when it opened."""
        if mode != 0:
            return None
        import FreeCADGui as Gui

        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(vobj.Object)
        Gui.runCommand(EDIT_COMMAND)
        return bool(Gui.Control.activeDialog())

    def unsetEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        import FreeCADGui as Gui

        Gui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj):
        import FreeCADGui as Gui

        if Gui.Control.activeDialog():
            return False
        vobj.Document.setEdit(vobj.Object.Name, 0)
        return True

    def onDelete(self, vobj, subelements):
        """Deleting a Fabrication deletes what it made (bricks, groups, printed parts)."""
        remove = getattr(getattr(vobj.Object, "Proxy", None), "remove_owned", None)
        if remove is not None:
            remove(vobj.Object)
        return True
