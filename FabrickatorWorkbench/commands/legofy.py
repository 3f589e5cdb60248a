"""Legofy: turn the selected solids or meshes, or a model file, into Fabrications."""

from __future__ import annotations

import os

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtGui

from FabrickatorWorkbench import bridge, log, make
from FabrickatorWorkbench.commands.base import Command, file_dialog, recompute_or_fail, transaction

#: File types the open dialog offers.
FILTER = "Models (*.step *.stp *.brep *.iges *.igs *.stl *.obj *.ply *.3mf *.FCStd *.fcstd);;All files (*)"


class Legofy(Command):
    NAME = "Fabrickator_Legofy"
    ICON = "Legofy"
    MENU = "&Legofy"
    TIP = ("Build the selected solid or mesh from LEGO bricks (a parametric Fabrication); "
           "with nothing selected, pick a model file")

    def run(self):
        sources = sources_in_selection()
        if sources:
            legofy_objects(sources)
            return
        path = ask_model_file()
        if path:
            legofy_path(path)


def sources_in_selection() -> list:
    """Selected objects that have a solid or a mesh and are not Fabrickator's own."""
    return [o for o in Gui.Selection.getSelection()
            if bridge.source_kind(o) is not None and not hasattr(o, "FabrickatorRole")]


def legofy_objects(sources) -> list:
    """Make and compute one Fabrication per source, in one transaction; the Fabrications."""
    doc = sources[0].Document
    made = []
    with transaction(doc, "Legofy"):
        for source in sources:
            made.append(make.make_fabrication(source))
        recompute_or_fail(*made)
        for fab in made:
            log.message(f"{fab.Label}: {fab.Status}")
    return [f for f in made if doc.getObject(f.Name) is not None and f.Status.startswith("ok")]


def legofy_path(path: str):
    """Import the model file at ``path`` into the active (or a new) document and legofy it."""
    doc = App.ActiveDocument or App.newDocument(os.path.splitext(os.path.basename(path))[0])
    fab = None
    with transaction(doc, "Legofy"):
        _, fab = make.legofy_file(path, doc)
        recompute_or_fail(fab)
        log.message(f"{fab.Label}: {fab.Status}")
    if fab is not None and doc.getObject(fab.Name) is not None:
        Gui.SendMsgToActiveView("ViewFit")
        return fab
    return None


def ask_model_file() -> str:
    """A model file chosen in a dialog ('' when cancelled)."""
    dialog = file_dialog("Legofy a model file", "FabrickatorOpenModel")
    dialog.setNameFilter(FILTER)
    dialog.setFileMode(QtGui.QFileDialog.ExistingFile)
    chosen = dialog.selectedFiles() if dialog.exec_() else []
    return chosen[0] if chosen else ""
