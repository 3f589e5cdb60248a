"""View provider of a Fabrication: its icon; double-click opens the brush panel."""

from __future__ import annotations

import FreeCADGui as Gui

from FabrickatorWorkbench.viewproviders.base import ViewProvider


class ViewProviderFabrication(ViewProvider):
    """Fabrication in the tree and the 3D view."""

    ICON = "Fabrication"

    #: The task panel open on this Fabrication, if any.
    panel = None

    def claimChildren(self):
        return list(self.Object.Contents) if hasattr(self.Object, "Contents") else []

    def setEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        from FabrickatorWorkbench.commands.brushes import remember_panel
        from FabrickatorWorkbench.taskpanels.brush import BrushPanel
        panel = BrushPanel(vobj.Object, "high-res")
        Gui.Control.showDialog(panel)
        remember_panel(vobj.Object, panel)
        return True

    def unsetEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        Gui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj):
        if Gui.Control.activeDialog():
            return False
        vobj.Document.setEdit(vobj.Object.Name, 0)
        return True

    def onDelete(self, vobj, subelements):
        """Deleting a Fabrication deletes what it made (bricks, groups, printed parts)."""
        from FabrickatorWorkbench.make import remove_owned
        remove_owned(vobj.Object)
        return True
