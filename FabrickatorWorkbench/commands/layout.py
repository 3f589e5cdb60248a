"""Layout: lay the selected Fabrication out again with another brick set, seed or clearance."""

from __future__ import annotations

import FreeCADGui as Gui

from FabrickatorWorkbench import log
from FabrickatorWorkbench.commands.base import (Command, recompute_or_fail, selected_fabrication,
                                                transaction)


class Layout(Command):
    NAME = "Fabrickator_Layout"
    ICON = "Layout"
    MENU = "Lay &out"
    TIP = ("Lay the selected Fabrication out again: brick set, seed (another arrangement), "
           "clearance, scale")

    def IsActive(self):
        return selected_fabrication(computed=False) is not None

    def run(self):
        fab = selected_fabrication(computed=False)
        dialog = LayoutDialog(fab)
        if dialog.exec_():
            apply_layout(fab, dialog.values())


def apply_layout(fab, values: dict) -> bool:
    """Set the layout parameters ``values`` (property name -> value) and recompute, as one
    transaction; True when the new layout computed (else the document is unchanged)."""
    done = False
    with transaction(fab.Document, "Lay out"):
        for name, value in values.items():
            setattr(fab, name, value)
        recompute_or_fail(fab)
        log.message(f"{fab.Label}: {fab.Status}")
        done = True
    return done


class LayoutDialog:
    """A small dialog with the layout parameters of a Fabrication."""

    def __init__(self, fab):
        from PySide import QtGui

        self.dialog = QtGui.QDialog(Gui.getMainWindow())
        self.dialog.setObjectName("FabrickatorLayoutDialog")
        self.dialog.setWindowTitle(f"Lay out {fab.Label}")
        form = QtGui.QFormLayout(self.dialog)
        self.brick_set = QtGui.QLineEdit(fab.BrickSet)
        self.brick_set.setToolTip("all, plates, bricks, design numbers (3001,3024) or plate2x4 ...; "
                                  "must contain the 1x1 plate 3024")
        self.seed = QtGui.QSpinBox()
        self.seed.setRange(0, 2 ** 31 - 1)
        self.seed.setValue(int(fab.Seed))
        self.clearance = QtGui.QDoubleSpinBox()
        self.clearance.setRange(0.0, 1.0)
        self.clearance.setDecimals(3)
        self.clearance.setSingleStep(0.01)
        self.clearance.setSuffix(" mm")
        self.clearance.setValue(float(fab.Clearance.Value))
        self.scale = QtGui.QDoubleSpinBox()
        self.scale.setRange(0.001, 1000.0)
        self.scale.setDecimals(3)
        self.scale.setValue(float(fab.Scale))
        form.addRow("Brick set", self.brick_set)
        form.addRow("Seed", self.seed)
        form.addRow("Clearance", self.clearance)
        form.addRow("Scale", self.scale)
        buttons = QtGui.QDialogButtonBox(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)
        buttons.accepted.connect(self.dialog.accept)
        buttons.rejected.connect(self.dialog.reject)
        form.addRow(buttons)

    def exec_(self) -> bool:
        return bool(self.dialog.exec_())

    def values(self) -> dict:
        """The dialog's values as Fabrication property values."""
        return {"BrickSet": self.brick_set.text().strip(), "Seed": self.seed.value(),
                "Clearance": self.clearance.value(), "Scale": self.scale.value()}
