"""Layout: lay the selected Fabrication out again with another brick set, seed, fit or scale."""

from __future__ import annotations

import FreeCADGui as Gui
from PySide import QtGui

from FabrickatorWorkbench import log
from FabrickatorWorkbench.commands.base import (Command, recompute_or_fail, selected_fabrication,
                                                transaction)


class Layout(Command):
    NAME = "Fabrickator_Layout"
    ICON = "Layout"
    MENU = "Lay &out"
    TIP = ("Lay the selected Fabrication out again: brick set, seed (another arrangement), "
           "stud and socket fit, scale")

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
        self.stud_fit = fit_box(float(fab.StudFit.Value), "studFit",
                                "Printed studs are 4.8 mm + this across: larger clamps tighter")
        self.socket_fit = fit_box(float(fab.SocketFit.Value), "socketFit",
                                  "Printed sockets are 4.8 mm + this between opposite walls: "
                                  "smaller clamps tighter")
        self.scale = QtGui.QDoubleSpinBox()
        self.scale.setRange(0.001, 1000.0)
        self.scale.setDecimals(3)
        self.scale.setValue(float(fab.Scale))
        form.addRow("Brick set", self.brick_set)
        form.addRow("Seed", self.seed)
        form.addRow("Stud fit", self.stud_fit)
        form.addRow("Socket fit", self.socket_fit)
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
                "StudFit": self.stud_fit.value(), "SocketFit": self.socket_fit.value(),
                "Scale": self.scale.value()}


def fit_box(value: float, name: str, tip: str):
    """A signed mm spin box for a stud or socket fit (the range Fit.check allows)."""
    box = QtGui.QDoubleSpinBox()
    box.setObjectName(name)
    box.setRange(-0.8, 0.8)
    box.setDecimals(3)
    box.setSingleStep(0.01)
    box.setSuffix(" mm")
    box.setValue(value)
    box.setToolTip(tip + "; find your printer's value with the Calibration strip")
    return box
