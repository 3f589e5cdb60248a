"""GUI test of the Report: it says in words what weak points and incomplete studs are,
lists each one, and a click selects it in the 3D view."""

from __future__ import annotations

import unittest

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

from TestFabrickatorGui import ARTIFACTS, GuiTestCase, ROOT, answer_modal, fab, fit, screenshot, settle

HMD = ROOT / "examples" / "build" / "hmd.step"
#: The two lens mounts of the example (model mm).
LENS_MOUNTS = ((-54, 25, 25.5, -9, 36, 70.5), (9, 25, 25.5, 54, 36, 70.5))


class TestReport(GuiTestCase):
    def fabrication_without_connectors(self):
        """The example HMD with its lens mounts printed and the printed part cut
        exactly (no studs or sockets: the core's --no-connectors), so the Report has weak
        points and incomplete studs to show."""
        import Part

        from FabrickatorWorkbench.objects import fabricate

        made = fabricate.request
        fabricate.request = lambda *a, **k: made(*a, **k).replace(connectors=False)
        self.addCleanup(setattr, fabricate, "request", made)
        source = self.doc.addObject("Part::Feature", "HMD")
        source.Shape = Part.read(str(HMD))
        f = fab().make_fabrication(source)
        for n, box in enumerate(LENS_MOUNTS, 1):
            fab().mark_high_res(f, box=box, label=f"Lens mount {n}")
        self.doc.recompute()
        source.ViewObject.Visibility = False
        fit()
        return f

    @unittest.skipUnless(HMD.is_file(), "examples/build/hmd.step is missing: run make examples/build/hmd.step")
    def test_report_explains_weak_points_and_incomplete_studs_and_selects_them(self):
        f = self.fabrication_without_connectors()
        doc = fab().report(f)
        st = doc["stability"]
        self.assertGreater(st["weak_points"], 0)
        self.assertGreater(st["incomplete_studs"], 0)
        seen = {}

        def click(tree, row):
            tree.scrollToItem(row)
            rect = tree.visualItemRect(row)
            for kind in (QtCore.QEvent.MouseButtonPress, QtCore.QEvent.MouseButtonRelease):
                event = QtGui.QMouseEvent(kind, QtCore.QPointF(rect.center()), QtCore.Qt.LeftButton,
                                          QtCore.Qt.LeftButton if kind == QtCore.QEvent.MouseButtonPress
                                          else QtCore.Qt.NoButton, QtCore.Qt.NoModifier)
                QtGui.QApplication.sendEvent(tree.viewport(), event)
            settle(0.2)
            return [o.Name for o in Gui.Selection.getSelection()]

        def handler(dialog):
            seen["text"] = dialog.findChild(QtGui.QTextBrowser).toPlainText()
            tree = dialog.findChild(QtGui.QTreeWidget, "FabrickatorReportItems")
            rows = [tree.topLevelItem(n) for n in range(tree.topLevelItemCount())]
            seen["rows"] = [(r.text(0), r.text(1)) for r in rows]
            weak = next(r for r in rows if r.text(0).startswith("Weak point"))
            seen["weak_selected"] = click(tree, weak)
            settle(0.3)
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            dialog.grab().save(str(ARTIFACTS / "report_dialog.png"))
            seen["view_weak"] = screenshot("report_weak_point_selected")
            studs = next(r for r in rows if r.text(0).startswith("Incomplete studs"))
            seen["studs_selected"] = click(tree, studs)
            dialog.reject()

        answer_modal(handler, "FabrickatorReportDialog", timeout_s=60)
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Report")
        settle()
        text = seen["text"]
        self.assertIn("A weak point is a brick that alone joins two parts of the build", text)
        self.assertIn("An incomplete stud is a place where a printed part meets a LEGO brick", text)
        self.assertIn("Print times.", text)
        self.assertNotIn("FABRICKATOR_", text)
        self.assertIn("LEGO bricks by design and colour", text)
        self.assertEqual(sum(r.count for r in fab().bom(f)), doc["bricks"]["lego"])
        self.assertNotIn("to buy", text)                      # no inventory: nothing to buy
        first = st["weak_point_details"][0]
        weak_rows = [r for r in seen["rows"] if r[0].startswith("Weak point")]
        self.assertEqual(len(weak_rows), st["weak_points"])
        self.assertIn(f"layer {first['layer']}, cell {first['cell'][0]}, {first['cell'][1]}", weak_rows[0][0])
        self.assertIn("is the only brick joining", weak_rows[0][1])
        brick = [b.Name for b in fab().bricks(f) if b.BrickId == first["brick"]]
        self.assertEqual(seen["weak_selected"], brick)
        stud_rows = [r for r in seen["rows"] if r[0].startswith("Incomplete studs")]
        self.assertEqual(len(stud_rows), len(st["incomplete_stud_parts"]))
        first = st["incomplete_stud_parts"][0]["part"]
        part = next(p for p in fab().printed_parts(f) if p.PartId == first)
        self.assertIn(f"printed part {part.PartId}, {len(part.IncompleteStuds)} in layer", stud_rows[0][0])
        self.assertEqual(seen["studs_selected"], [part.Name])
