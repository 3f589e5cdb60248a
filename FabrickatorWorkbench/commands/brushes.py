"""The brushes: open the brush panel in high-res, merge or split mode."""

from __future__ import annotations

import FreeCADGui as Gui

from FabrickatorWorkbench.commands.base import Command, no_task_dialog, selected_fabrication
from FabrickatorWorkbench.taskpanels.brush import BrushPanel


class _Brush(Command):
    MODE = ""

    def IsActive(self):
        return (Gui.ActiveDocument is not None and no_task_dialog()
                and selected_fabrication() is not None)

    def run(self):
        open_brush(selected_fabrication(), self.MODE)


def open_brush(fab, mode: str):
    """Open the brush panel for ``fab`` in ``mode``; the panel."""
    panel = BrushPanel(fab, mode)
    Gui.Control.showDialog(panel)
    remember_panel(fab, panel)
    return panel


def remember_panel(fab, panel) -> None:
    """Let the Fabrication's view provider know its open panel (macros and tests reach it
    as ``fab.ViewObject.Proxy.panel``)."""
    proxy = getattr(fab.ViewObject, "Proxy", None)
    if proxy is not None:
        proxy.panel = panel


class HighResBrush(_Brush):
    NAME = "Fabrickator_HighResBrush"
    ICON = "HighResBrush"
    MENU = "&High-res brush"
    TIP = ("Paint bricks (or pick faces of the part, or a region solid) that must be printed "
           "exactly: they become printed parts")
    MODE = "high-res"


class MergeBrush(_Brush):
    NAME = "Fabrickator_MergeBrush"
    ICON = "MergeBrush"
    MENU = "&Merge brush"
    TIP = "Paint printed bricks whose printed parts should become one part"
    MODE = "merge"


class SplitBrush(_Brush):
    NAME = "Fabrickator_SplitBrush"
    ICON = "SplitBrush"
    MENU = "&Split brush"
    TIP = "Paint printed bricks that should be printed as parts of their own"
    MODE = "split"
