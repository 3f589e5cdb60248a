"""Undo and redo through FreeCAD's own Std_Undo / Std_Redo after the workbench's commands,
in the GUI (FreeCAD 0.20 and 1.x): the document exactly as before each command after
Undo, exactly as after it after Redo, and the 3D view still drawing."""

from __future__ import annotations

import sys
from pathlib import Path

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtGui

from TestFabrickatorGui import GuiTestCase, answer_modal, fab, screenshot, settle

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "app"))
from TestFabrickatorApp import padded_body  # noqa: E402
from TestFabrickatorUndo import state  # noqa: E402


class TestUndoInTheGui(GuiTestCase):
    def undo_redo(self, before: dict, after: dict, what: str) -> None:
        """Std_Undo then Std_Redo, twice, checking the document against ``before``/``after``."""
        for _ in range(2):
            Gui.runCommand("Std_Undo")
            settle(0.2)
            self.assertEqual(state(self.doc), before, f"undo {what}")
            Gui.runCommand("Std_Redo")
            settle(0.2)
            self.assertEqual(state(self.doc), after, f"redo {what}")

    def test_commands_undo_and_redo_with_std_undo(self):
        body, _, _ = padded_body(self.doc, 40.0, 24.0, 19.2)
        before = state(self.doc)
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(body)
        Gui.runCommand("Fabrickator_Legofy")
        settle()
        f = fab().fabrications(self.doc)[0]
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        legofied = state(self.doc)
        self.undo_redo(before, legofied, "Legofy")
        f = fab().fabrications(self.doc)[0]

        def handler(dialog):
            dialog.findChild(QtGui.QSpinBox).setValue(5)
            dialog.accept()

        answer_modal(handler, "FabrickatorLayoutDialog")
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Layout")
        settle()
        self.assertEqual(f.Seed, 5)
        relaid = state(self.doc)
        self.assertNotEqual(relaid, legofied)
        self.undo_redo(legofied, relaid, "Lay out")

        brick = next(b for b in fab().bricks(f) if b.Kind == "lego")
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(brick)
        self.doc.openTransaction("High-res brush")
        fab().mark_high_res(f, bricks=[brick])
        self.doc.recompute()
        self.doc.commitTransaction()
        brushed = state(self.doc)
        self.assertEqual(len(fab().printed_parts(f)), 1)
        self.undo_redo(relaid, brushed, "High-res brush")
        Gui.SendMsgToActiveView("ViewFit")
        settle(0.3)
        screenshot("undo_redo_brushed")
        for _ in range(3):
            Gui.runCommand("Std_Undo")
            settle(0.2)
        self.assertEqual(state(self.doc), before)
        self.assertEqual(App.ActiveDocument.Name, self.doc.Name)
