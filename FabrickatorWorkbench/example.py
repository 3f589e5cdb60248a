"""The bundled example, opened in FreeCAD: ``make gui`` runs this file in FreeCAD.

:func:`open_example` imports the HMD-like example (examples/hmd.py, built by
``make`` into examples/build/hmd.step), legofies it with its two lens
mounts marked high-res, and shows the result in the Fabrickator workbench.
Run as a file by FreeCAD (``freecad FabrickatorWorkbench/example.py``), it
does that as soon as the main window is up.
"""

from __future__ import annotations

import os

import FreeCAD as App
import Part

import FabrickatorWorkbench as fab
from FabrickatorWorkbench import log

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STEP = os.path.join(ROOT, "examples", "build", "hmd.step")
#: The two lens mounts of the example (model mm), the regions that must be exact.
LENS_MOUNTS = ((-54, 25, 25.5, -9, 36, 70.5), (9, 25, 25.5, 54, 36, 70.5))


def open_example(path: str = STEP):
    """A new document with the example's Fabrication computed; the Fabrication."""
    if not os.path.exists(path):
        log.error(f"{path} is missing: run `make examples/build/hmd.step` in {ROOT}")
        return None
    doc = App.newDocument("HMD_example")
    source = doc.addObject("Part::Feature", "HMD")
    source.Label = "HMD body"
    source.Shape = Part.read(path)
    f = fab.make_fabrication(source)
    for n, box in enumerate(LENS_MOUNTS, 1):
        fab.mark_high_res(f, box=box, label=f"Lens mount {n}")
    doc.recompute()
    if App.GuiUp:
        import FreeCADGui as Gui

        Gui.activateWorkbench("FabrickatorWorkbench")
        source.ViewObject.Visibility = False
        for region in f.Regions:
            region.ViewObject.Visibility = False
        Gui.ActiveDocument.ActiveView.viewIsometric()
        Gui.SendMsgToActiveView("ViewFit")
        Gui.Selection.addSelection(f)
    log.message(f"example: {f.Label}: {f.Status}. Try the High-res brush, Assembly and Report "
                f"commands on the Fabrickator toolbar")
    return f


def open_when_the_window_is_up() -> None:
    """Open the example half a second from now, once FreeCAD's main window is up (GUI only)."""
    from PySide import QtCore

    from FabrickatorWorkbench import example

    QtCore.QTimer.singleShot(500, example.open_example)


if __name__ != "FabrickatorWorkbench.example" and App.GuiUp:
    open_when_the_window_is_up()
