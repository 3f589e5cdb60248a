"""Add load: a mass (a phone, a lens, a battery) resting on the bricks, and the force check
run with it (issue 14)."""

from __future__ import annotations

import FreeCADGui as Gui
from PySide import QtGui

from FabrickatorWorkbench import bridge, log, make
from FabrickatorWorkbench.commands.base import (Command, no_task_dialog, recompute_or_fail,
                                                selected_fabrication, transaction)
from FabrickatorWorkbench.objects.tree import BRICK_ROLE, role

#: Mass the dialog offers first, g: about a phone in a headset.
DEFAULT_GRAMS = 170.0


class AddLoad(Command):
    NAME = "Fabrickator_AddLoad"
    ICON = "Load"
    MENU = "Add &load"
    TIP = ("Put a mass on the selected bricks, printed part or solid (its bounding box), or on "
           "the top layer when only the Fabrication is selected, and check that the build "
           "carries it (the Stress display mode shows how hard each brick works)")

    def IsActive(self):
        return selected_fabrication() is not None and no_task_dialog()

    def run(self):
        fab = selected_fabrication()
        where = load_target(fab, Gui.Selection.getSelection())
        grams = ask_grams()
        if grams:
            add_load(fab, where, grams)


def load_target(fab, selection):
    """Where a new load of ``fab`` goes (``where`` of :func:`make.make_load`): the selected
    bricks of ``fab`` and the bricks of its selected printed parts, else a selected solid
    that is not Fabrickator's (its bounding box), else the bricks of the top layer."""
    bricks = make.bricks(fab)
    by_id = {int(b.BrickId): b for b in bricks}
    chosen = []
    for obj in selection:
        if role(obj) == BRICK_ROLE and make.fabrication_of(obj) == fab:
            chosen.append(obj)
        elif role(obj) == "PrintedPart" and make.fabrication_of(obj) == fab:
            chosen += [by_id[int(i)] for i in obj.BrickIds if int(i) in by_id]
    if chosen:
        return chosen
    for obj in selection:
        if role(obj) is None and bridge.source_kind(obj) == "shape":
            return obj
    top = max(b.Cell[2] + b.Size[2] for b in bricks)
    return [b for b in bricks if b.Cell[2] + b.Size[2] == top]


def add_load(fab, where, grams: float):
    """Add a load of ``grams`` at ``where`` to ``fab`` and recompute, in one undo transaction;
    the Load, or None when it failed (then the document is as it was and the Report view
    says why)."""
    doc = fab.Document
    name = None
    with transaction(doc, "Add load"):
        made = make.make_load(doc, fab, where, grams)
        name = made.Name
        recompute_or_fail(fab)
        log.message(f"{fab.Label}: {made.Label}: {fab.Forces}")
    return doc.getObject(name) if name is not None else None


def ask_grams() -> float:
    """The mass of the new load in g, asked in a dialog (0 when cancelled)."""
    dialog = QtGui.QInputDialog(Gui.getMainWindow())
    dialog.setObjectName("FabrickatorLoadMass")
    dialog.setWindowTitle("Add load")
    dialog.setLabelText("Mass resting on the bricks (g):")
    dialog.setInputMode(QtGui.QInputDialog.DoubleInput)
    dialog.setDoubleRange(0.1, 1e6)
    dialog.setDoubleDecimals(1)
    dialog.setDoubleValue(DEFAULT_GRAMS)
    return float(dialog.doubleValue()) if dialog.exec_() else 0.0
