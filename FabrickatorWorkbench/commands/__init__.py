"""Toolbar and menu commands, one module each.

:func:`register` adds them to FreeCAD (GUI only) and returns their names in
toolbar order.  Every command checks that Fabrickator's packages can be
imported, wraps its change to the document in one undo transaction
(aborted, with the reason in the Report view, when it fails) and is
enabled only when it applies.
"""

from __future__ import annotations

import FreeCADGui as Gui

from FabrickatorWorkbench.commands import (assembly, brushes, calibration, export, layout, legofy,
                                           load, report, suggest, watch)


def register() -> list[str]:
    """Add every command to FreeCADGui; the names in toolbar order."""
    commands = [legofy.Legofy(), layout.Layout(), brushes.HighResBrush(), suggest.SuggestRegions(),
                brushes.MergeBrush(),
                brushes.SplitBrush(), load.AddLoad(), export.Export(), assembly.Assembly(),
                report.Report(), watch.WatchFolder(), calibration.CalibrationStrip()]
    for command in commands:
        Gui.addCommand(command.NAME, command)
    return [c.NAME for c in commands]
