"""GUI test of the force check (issue 14): Add load puts 20 kg on the bridge over the nose of
the example HMD, the Stress display mode draws the failing bricks white, the Report lists
them with why, and a click selects one.  Screenshots: tests/gui/artifacts/stress*.png."""

from __future__ import annotations

import unittest

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

from TestFabrickatorGui import ARTIFACTS, GuiTestCase, ROOT, answer_modal, fab, fit, settle

HMD = ROOT / "examples" / "build" / "hmd.step"
#: The bridge over the nose cut of examples/hmd.py (model mm): thin, and above nothing.
NOSE_BRIDGE = (-16.0, 2.0, 31.0, 16.0, 30.0, 34.0)
#: What the test puts on it, g.
HEAVY_G = 20000.0


#: Background of the stress pictures: grey, so that the white (failing) bricks show.
BACKGROUND = "#5c6370"


def screenshot(name: str):
    """The 3D view saved as tests/gui/artifacts/NAME.png on a grey background."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    settle()
    Gui.activeDocument().activeView().saveImage(str(path), 800, 600, BACKGROUND)
    return path


def click(tree, row) -> list:
    """Click ``row`` of ``tree`` as a user would; the names selected afterwards."""
    tree.scrollToItem(row)
    rect = tree.visualItemRect(row)
    for kind in (QtCore.QEvent.MouseButtonPress, QtCore.QEvent.MouseButtonRelease):
        event = QtGui.QMouseEvent(kind, QtCore.QPointF(rect.center()), QtCore.Qt.LeftButton,
                                  QtCore.Qt.LeftButton if kind == QtCore.QEvent.MouseButtonPress
                                  else QtCore.Qt.NoButton, QtCore.Qt.NoModifier)
        QtGui.QApplication.sendEvent(tree.viewport(), event)
    settle(0.2)
    return [o.Name for o in Gui.Selection.getSelection()]


class TestStress(GuiTestCase):
    @unittest.skipUnless(HMD.is_file(), "examples/build/hmd.step is missing: run make examples/build/hmd.step")
    def test_heavy_load_shows_failing_bricks_white_and_the_report_selects_them(self):
        import Part

        from FabrickatorWorkbench.commands import load as load_command
        from FabrickatorWorkbench.viewproviders import stress

        source = self.doc.addObject("Part::Feature", "HMD")
        source.Shape = Part.read(str(HMD))
        f = fab().make_fabrication(source, slice_print_times=False)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertTrue(f.Stands, f.Forces)
        self.assertEqual(f.ViewObject.DisplayMode, "Normal")
        self.assertEqual(sorted(f.ViewObject.listDisplayModes()), ["Normal", "Stress"])
        fit()

        # Add load with a solid selected (a weight modelled on the nose bridge): its box
        weight = self.doc.addObject("Part::Feature", "Weight")
        lo, hi = NOSE_BRIDGE[:3], NOSE_BRIDGE[3:]
        weight.Shape = Part.makeBox(*(h - l for l, h in zip(lo, hi)), App.Vector(*lo))
        self.doc.recompute()
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(self.doc.Name, weight.Name)

        def mass(dialog):
            dialog.setDoubleValue(HEAVY_G)
            dialog.accept()

        answer_modal(mass, "FabrickatorLoadMass", timeout_s=60)
        Gui.runCommand("Fabrickator_AddLoad")
        settle(0.5)
        loads = fab().loads(f)
        self.assertEqual([x.Mass for x in loads], [HEAVY_G])
        self.assertEqual(tuple(round(v, 6) for v in (loads[0].Shape.BoundBox.XMin,
                                                     loads[0].Shape.BoundBox.ZMax)), (-16.0, 34.0))
        weight.ViewObject.Visibility = False
        self.assertEqual(self.doc.UndoNames[0], "Add load")
        force = fab().report(f)["stability"]["force"]
        self.assertFalse(force["stable"])
        self.assertFalse(f.Stands)
        self.assertGreater(f.FailingBricks, 0)
        failing = set(force["failing_bricks"])

        # the Stress display mode: failing bricks white, the least loaded dark
        f.ViewObject.DisplayMode = "Stress"
        settle(0.5)
        util = {int(k): (float("inf") if v is None else v) for k, v in force["utilisation"].items()}
        lego = [b for b in fab().bricks(f) if b.Kind == "lego"]
        for b in lego:
            self.assertTrue(b.ViewObject.OverrideMaterial, b.Label)
            shown = tuple(round(c, 3) for c in b.ViewObject.ShapeMaterial.DiffuseColor[:3])
            self.assertEqual(shown, tuple(round(c, 3) for c in stress.colour(util[b.BrickId])),
                             b.Label)
        self.assertTrue(any(b.BrickId in failing for b in lego))
        calm = min(lego, key=lambda b: util[b.BrickId])
        self.assertLess(sum(calm.ViewObject.ShapeMaterial.DiffuseColor[:3]), 1.0)
        loads[0].ViewObject.Visibility = False
        fit()
        shot = screenshot("stress")
        self.assertGreater(shot.stat().st_size, 0)
        # from the open face side: the nose bridge with the load (blue) on it
        loads[0].ViewObject.Visibility = True
        Gui.activeDocument().activeView().setViewDirection((0.45, 1.0, -0.55))
        Gui.SendMsgToActiveView("ViewFit")
        screenshot("stress_nose")

        # the Report lists every failing brick with why; a click selects it
        seen = {}

        def report(dialog):
            seen["text"] = dialog.findChild(QtGui.QTextBrowser).toPlainText()
            tree = dialog.findChild(QtGui.QTreeWidget, "FabrickatorReportItems")
            rows = [tree.topLevelItem(n) for n in range(tree.topLevelItemCount())]
            seen["rows"] = [(r.text(0), r.text(1)) for r in rows]
            fails = [r for r in rows if r.text(0).startswith("Fails:")]
            seen["selected"] = click(tree, fails[0])
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            dialog.grab().save(str(ARTIFACTS / "stress_report_dialog.png"))
            seen["view"] = screenshot("stress_failing_brick_selected")
            dialog.reject()

        answer_modal(report, "FabrickatorReportDialog", timeout_s=60)
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Report")
        settle()
        self.assertIn("does not stand on a table", seen["text"])
        self.assertIn("Failing bricks.", seen["text"])
        rows = [r for r in seen["rows"] if r[0].startswith("Fails:")]
        self.assertEqual(len(rows), len(force["failures"]))
        first = force["failures"][0]
        self.assertIn(f"layer {first['layer']}, cell {first['cell'][0]}, {first['cell'][1]}", rows[0][0])
        self.assertEqual(rows[0][1], first["why"])
        if first.get("printed_part"):
            wanted = [p.Name for p in fab().printed_parts(f) if p.PartId == first["printed_part"]]
        else:
            wanted = [b.Name for b in fab().bricks(f) if b.BrickId == first["brick"]]
        self.assertEqual(seen["selected"], wanted)

        # Normal gives the bricks their LEGO colours back
        f.ViewObject.DisplayMode = "Normal"
        settle()
        self.assertFalse(any(b.ViewObject.OverrideMaterial for b in lego))

        # a load that touches no brick fails: the document stays as it was
        names = sorted(o.Name for o in self.doc.Objects)
        report_json = f.ReportJson
        self.assertIsNone(load_command.add_load(f, (500, 500, 500, 510, 510, 510), 100))
        self.assertEqual(sorted(o.Name for o in self.doc.Objects), names)
        self.assertEqual(f.ReportJson, report_json)
        self.assertEqual(fab().loads(f), loads)


class TestStressReopens(GuiTestCase):
    def test_a_document_saved_in_the_stress_mode_reopens_in_it(self):
        import sys

        sys.path.insert(0, str(ROOT / "tests" / "app"))
        from TestFabrickatorForces import TIP, l_shape

        from FabrickatorWorkbench.viewproviders import stress

        from FabrickatorWorkbench.commands.load import load_target

        f = fab().make_fabrication(l_shape(self.doc), slice_print_times=False)
        f.Ground = "baseplate"
        self.doc.recompute()
        # where Add load puts a load: the selected bricks, else the top layer
        plate = [b for b in fab().bricks(f) if b.Cell[2] == 3]
        self.assertEqual(load_target(f, plate), plate)
        self.assertEqual(load_target(f, [f]), plate)
        fab().make_load(self.doc, f, TIP, 1000)
        self.doc.recompute()
        self.assertFalse(f.Stands, f.Forces)
        f.ViewObject.DisplayMode = "Stress"
        settle()
        path = str(self.tmp / "stress.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        settle()
        f = fab().fabrications(self.doc)[0]
        self.assertEqual(f.ViewObject.DisplayMode, "Stress")
        self.assertEqual([type(x.ViewObject.Proxy).__name__ for x in fab().loads(f)],
                         ["ViewProviderLoad"])
        util = {int(k): (float("inf") if v is None else v)
                for k, v in fab().report(f)["stability"]["force"]["utilisation"].items()}
        for b in fab().bricks(f):
            self.assertTrue(b.ViewObject.OverrideMaterial, b.Label)
            shown = tuple(round(c, 3) for c in b.ViewObject.ShapeMaterial.DiffuseColor[:3])
            self.assertEqual(shown, tuple(round(c, 3) for c in stress.colour(util[b.BrickId])))
        f.ViewObject.DisplayMode = "Normal"
        settle()
        self.assertFalse(any(b.ViewObject.OverrideMaterial for b in fab().bricks(f)))
