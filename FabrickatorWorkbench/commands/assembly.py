"""Assembly: step through the build in the 3D view."""

from __future__ import annotations

import FreeCADGui as Gui

from FabrickatorWorkbench.commands.base import Command, no_task_dialog, selected_fabrication
from FabrickatorWorkbench.commands.brushes import remember_panel
from FabrickatorWorkbench.taskpanels.assembly import AssemblyPanel


class Assembly(Command):
    NAME = "Fabrickator_Assembly"
    ICON = "Assembly"
    MENU = "&Assembly"
    TIP = ("Step through the build bottom-up, layer by layer: the next bricks in blue, "
           "printed parts with their ID when they are inserted")

    def IsActive(self):
        fab = selected_fabrication()
        return Gui.ActiveDocument is not None and no_task_dialog() and fab is not None and fab.Steps > 0

    def run(self):
        open_assembly(selected_fabrication())


def open_assembly(fab):
    """Open the assembly panel for ``fab``; the panel."""
    panel = AssemblyPanel(fab)
    Gui.Control.showDialog(panel)
    remember_panel(fab, panel)
    return panel
