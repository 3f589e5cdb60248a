"""Calibration strip: print test studs and sockets to find this printer's stud and socket fit."""

from __future__ import annotations

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

from FabrickatorWorkbench import make
from FabrickatorWorkbench.commands.base import Command, transaction
from FabrickatorWorkbench.commands.export import ask_folder


class CalibrationStrip(Command):
    NAME = "Fabrickator_CalibrationStrip"
    ICON = "CalibrationStrip"
    MENU = "&Calibration strip"
    TIP = ("Write a printable strip of test studs and sockets in steps of 0.05 mm around the "
           "preferences' Stud fit and Socket fit (STL, 3MF and how to read it) into a folder, "
           "and show it; the first value that clamps real LEGO is your printer's fit")

    def run(self, folder: str | None = None):
        """Ask for a folder (unless ``folder`` is given) and write and show the strip there."""
        folder = folder or ask_folder("Write the calibration strip to a folder")
        if folder:
            show_calibration_strip(folder)


def show_calibration_strip(folder: str, doc=None):
    """Write the strip into ``folder`` and add it to ``doc`` (the active document, or a new
    one) as one undo step, with a wait cursor; the new object, or None when it failed
    (the Report view says why and the document is unchanged)."""
    doc = doc or App.ActiveDocument or App.newDocument("CalibrationStrip")
    made = []
    QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
    try:
        with transaction(doc, "Calibration strip"):
            made.append(make.make_calibration_strip(folder, doc))
    finally:
        QtGui.QApplication.restoreOverrideCursor()
    if not made:
        return None
    strip = made[0]
    strip.ViewObject.ShapeColor = (0.95, 0.55, 0.15)
    Gui.Selection.clearSelection()
    Gui.Selection.addSelection(strip)
    view = Gui.ActiveDocument.ActiveView if Gui.ActiveDocument else None
    if view is not None and hasattr(view, "viewIsometric"):
        view.viewIsometric()
        Gui.SendMsgToActiveView("ViewSelection")
    return strip
