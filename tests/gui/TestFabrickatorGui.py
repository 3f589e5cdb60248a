"""GUI tests of the Fabrickator workbench, run inside FreeCAD under xvfb:

    QTWEBENGINE_DISABLE_SANDBOX=1 xvfb-run -a -s "-screen 0 1280x1024x24" \\
        freecad -u TMPDIR/user.cfg tests/gui/run_gui_tests.py --module-path=REPO

(``make test-gui``; ``-u`` keeps the tests off the user's preferences.)

Every command runs (modal dialogs are answered by a timer, as a user
would); the brush paints bricks through mouse events sent to the 3D view;
the assembly panel steps; FreeCAD's Plot and FEM still work after the
workbench loaded.  Screenshots go to tests/gui/artifacts/.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "tests" / "gui" / "artifacts"
COMMANDS = ["Fabrickator_Legofy", "Fabrickator_Layout", "Fabrickator_HighResBrush",
            "Fabrickator_SuggestRegions",
            "Fabrickator_MergeBrush", "Fabrickator_SplitBrush", "Fabrickator_AddLoad",
            "Fabrickator_Export",
            "Fabrickator_Assembly", "Fabrickator_Report", "Fabrickator_WatchFolder",
            "Fabrickator_CalibrationStrip"]

sys.path.insert(0, str(ROOT / "tests" / "app"))
from TestFabrickatorApp import padded_body  # noqa: E402


def fab():
    import FabrickatorWorkbench

    return FabrickatorWorkbench


def settle(seconds: float = 0.0) -> None:
    """Let Qt process events (for at least ``seconds``)."""
    end = time.monotonic() + seconds
    while True:
        QtGui.QApplication.processEvents()
        if time.monotonic() >= end:
            return
        time.sleep(0.02)


def answer_modal(handler, name: str, timeout_s: float = 30.0) -> None:
    """When the modal dialog with object name ``name`` opens, call ``handler(dialog)``
    (which must close it).  Any other modal dialog is reported and rejected.

    The polling timer is a child of the main window, so Qt keeps it (and the
    connected function) alive after this function returns.
    """
    deadline = time.monotonic() + timeout_s
    timer = QtCore.QTimer(Gui.getMainWindow())
    timer.setInterval(50)

    def poll():
        widget = QtGui.QApplication.activeModalWidget()
        if widget is not None and widget.objectName() == name:
            timer.stop()
            timer.deleteLater()
            try:
                handler(widget)
            except Exception as exc:
                sys.stderr.write(f"modal handler failed: {exc!r}\n")
                widget.reject()
            return
        if widget is not None:
            sys.stderr.write(f"unexpected modal dialog {widget.objectName()!r} "
                             f"({widget.windowTitle()!r}): rejected\n")
            widget.reject()
        if time.monotonic() > deadline:
            timer.stop()
            timer.deleteLater()

    timer.timeout.connect(poll)
    timer.start()


def choose_path(path: str):
    """A modal handler that picks ``path`` (a file, or a folder) in a file dialog and accepts."""

    def handler(dialog):
        if Path(path).is_dir():
            dialog.setDirectory(str(path))
        else:
            dialog.setDirectory(str(Path(path).parent))
            dialog.findChild(QtGui.QLineEdit, "fileNameEdit").setText(str(path))
        settle(0.2)
        dialog.accept()

    return handler


def view():
    return Gui.ActiveDocument.ActiveView


def fit() -> None:
    settle()
    view().viewIsometric()
    Gui.SendMsgToActiveView("ViewFit")
    settle()


def screenshot(name: str) -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    settle()
    view().saveImage(str(path), 800, 600, "White")
    return path


def screen_point(point) -> QtCore.QPointF:
    """Where the 3D ``point`` is in the viewport, in Qt widget coordinates."""
    x, y = view().getPointOnScreen(point)
    return QtCore.QPointF(x, view().graphicsView().viewport().height() - y)


def mouse(kind, point: QtCore.QPointF, buttons=QtCore.Qt.LeftButton) -> None:
    """Send a mouse event to the 3D view's viewport, as the window system would."""
    types = {"press": QtCore.QEvent.MouseButtonPress, "move": QtCore.QEvent.MouseMove,
             "release": QtCore.QEvent.MouseButtonRelease}
    event = QtGui.QMouseEvent(types[kind], point, QtCore.Qt.LeftButton,
                              buttons if kind != "release" else QtCore.Qt.NoButton,
                              QtCore.Qt.NoModifier)
    QtGui.QApplication.sendEvent(view().graphicsView().viewport(), event)
    settle()


def top_centre(brick):
    """A point on the top face of ``brick`` (between its studs)."""
    import Part

    box = Part.getShape(brick).BoundBox
    return App.Vector(box.XMin + 0.5, box.YMin + 0.5, box.ZMax - 1.8)


class GuiTestCase(unittest.TestCase):
    """A fresh document shown in the 3D view, closed afterwards."""

    def setUp(self):
        from FabrickatorWorkbench import preferences

        self.preferences = {name: preferences.get(name) for name in preferences.DEFAULTS
                            if preferences.is_set(name)}
        for name in preferences.DEFAULTS:
            preferences.reset(name)
        Gui.activateWorkbench("FabrickatorWorkbench")
        self.doc = App.newDocument("FabrickatorGui")
        self.doc.UndoMode = 1
        self.tmp = Path(tempfile.mkdtemp(prefix="fabrickator-gui-test-"))
        settle()

    def tearDown(self):
        from FabrickatorWorkbench import preferences

        for name in preferences.DEFAULTS:
            preferences.reset(name)
        for name, value in self.preferences.items():
            preferences.set(name, value)
        if Gui.Control.activeDialog():
            Gui.Control.closeDialog()
        App.closeDocument(self.doc.Name)
        shutil.rmtree(self.tmp, ignore_errors=True)
        settle()

    def open_example(self):
        """The bundled example fabricated in a document of its own, closed after the test
        (skipped when its STEP is missing)."""
        from FabrickatorWorkbench import example

        if not os.path.exists(example.STEP):
            self.skipTest(f"{example.STEP} is missing: run make first")
        f = example.open_example()
        self.addCleanup(App.closeDocument, f.Document.Name)
        return f

    def fabrication(self, high_res=None):
        """A padded Body legofied through the Legofy command (optionally with a high-res box)."""
        body, _, _ = padded_body(self.doc, 40.0, 24.0, 19.2)
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(body)
        Gui.runCommand("Fabrickator_Legofy")
        settle()
        f = fab().fabrications(self.doc)[0]
        if high_res is not None:
            fab().mark_high_res(f, box=high_res)
            self.doc.recompute()
        body.ViewObject.Visibility = False
        Gui.Selection.clearSelection()
        fit()
        return f


class TestWorkbench(GuiTestCase):
    def test_commands_toolbar_icons(self):
        listed = Gui.listCommands()
        for name in COMMANDS:
            self.assertIn(name, listed)
        bars = [b for b in Gui.getMainWindow().findChildren(QtGui.QToolBar)
                if b.windowTitle() == "Fabrickator" or b.objectName() == "Fabrickator"]
        self.assertTrue(bars)
        actions = [a for a in bars[0].actions() if a.text()]
        self.assertEqual(len(actions), len(COMMANDS))
        from FabrickatorWorkbench.commands import brushes, legofy, load
        for command in (legofy.Legofy(), brushes.SplitBrush(), load.AddLoad()):
            self.assertTrue(os.path.isfile(command.GetResources()["Pixmap"]))

    def test_plot_and_fem_still_work(self):
        import numpy

        import ObjectsFem
        import Plot
        from FabrickatorWorkbench import deps
        self.assertTrue(numpy.__file__.startswith(deps.site_packages()))
        figure = Plot.figure("Fabrickator check")
        Plot.plot([0, 1, 2, 3], [0, 1, 4, 9], "squares")
        settle(0.2)
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        out = ARTIFACTS / "plot.png"
        figure.fig.savefig(str(out))
        self.assertGreater(out.stat().st_size, 1000)
        mw = Gui.getMainWindow()
        mdi = mw.findChild(QtGui.QMdiArea)
        mdi.activeSubWindow().close()
        Gui.activateWorkbench("FemWorkbench")
        analysis = ObjectsFem.makeAnalysis(self.doc, "Analysis")
        Gui.Selection.addSelection(analysis)
        # FreeCAD 1.0 renamed the factory (capital X)
        make_solver = getattr(ObjectsFem, "makeSolverCalculiXCcxTools", None) or \
            ObjectsFem.makeSolverCalculixCcxTools
        solver = make_solver(self.doc)
        analysis.addObject(solver)
        self.doc.recompute()
        self.assertEqual(len(analysis.Group), 1)
        Gui.activateWorkbench("FabrickatorWorkbench")


class TestExampleAndPreferences(GuiTestCase):
    def test_bundled_example_opens_with_two_printed_lens_mounts(self):
        f = self.open_example()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual([p.PartId for p in fab().printed_parts(f)], ["P1", "P2"])
        self.assertGreater(f.Bricks, 100)
        screenshot("example")

    def test_preferences_page_saves_the_defaults(self):
        from FabrickatorWorkbench import preferences

        def handler(dialog):
            edit = dialog.findChild(QtGui.QLineEdit, "brickSet")
            edit.setText("bricks,3024")
            dialog.accept()

        answer_modal(handler, "Gui__Dialog__DlgPreferences")
        Gui.showPreferences("Fabrickator", 0)
        settle()
        try:
            self.assertEqual(preferences.get("BrickSet"), "bricks,3024")
            body, _, _ = padded_body(self.doc)
            f = fab().make_fabrication(body)
            self.assertEqual(f.BrickSet, "bricks,3024")
        finally:
            preferences.set("BrickSet", "all")

    def test_preferences_page_shows_the_fit_defaults_and_saves_a_changed_fit(self):
        from core.parts.interfaces import Fit
        from FabrickatorWorkbench import preferences

        shown = {}

        def handler(dialog):
            stud = dialog.findChild(QtGui.QDoubleSpinBox, "studFit")
            socket = dialog.findChild(QtGui.QDoubleSpinBox, "socketFit")
            shown.update(stud=stud.value(), socket=socket.value(), fileName=dialog.findChild(
                QtGui.QWidget, "slicerPath").property("fileName"))
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            dialog.grab().save(str(ARTIFACTS / "preferences.png"))
            stud.setValue(0.15)
            dialog.accept()

        answer_modal(handler, "Gui__Dialog__DlgPreferences")
        Gui.showPreferences("Fabrickator", 0)
        settle()
        self.assertEqual(shown["stud"], Fit.stud_fit)
        self.assertEqual(shown["socket"], Fit.socket_fit)
        self.assertEqual(shown["fileName"], "")
        self.assertEqual(preferences.get("StudFit"), 0.15)
        self.assertFalse(preferences.is_set("SocketFit"))   # unchanged: still follows Fit
        self.assertFalse(preferences.is_set("BrickSet"))
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.assertAlmostEqual(f.StudFit.Value, 0.15)
        self.assertAlmostEqual(f.SocketFit.Value, Fit.socket_fit)

    def test_preferences_page_searches_the_printers_and_saves_one(self):
        """The Printer preference lists the installed bundles' printers; typing part of a
        name offers those that contain it; the one chosen reaches a new Fabrication's
        request."""
        from FabrickatorWorkbench import preferences
        from FabrickatorWorkbench.objects import fabricate

        shown = {}

        def handler(dialog):
            combo = dialog.findChild(QtGui.QComboBox, "printer")
            names = [combo.itemText(i) for i in range(combo.count())]
            completer = combo.completer()
            completer.setCompletionPrefix("ender-3")
            found = [completer.completionModel().index(i, 0).data()
                     for i in range(completer.completionCount())]
            shown.update(editable=combo.isEditable(), names=names, found=found)
            combo.setEditText("Original Prusa MINI & MINI+")
            dialog.accept()

        answer_modal(handler, "Gui__Dialog__DlgPreferences")
        Gui.showPreferences("Fabrickator", 0)
        settle()
        try:
            self.assertTrue(shown["editable"])
            self.assertEqual(shown["names"][0], "")          # the default printer
            self.assertIn("Original Prusa MINI & MINI+", shown["names"])
            self.assertTrue(shown["found"])
            self.assertTrue(all("ender-3" in name.lower() for name in shown["found"]))
            self.assertEqual(preferences.get("Printer"), "Original Prusa MINI & MINI+")
            body, _, _ = padded_body(self.doc)
            f = fab().make_fabrication(body)
            self.assertEqual(fabricate.request(f, "part.stl", (), ()).printer,
                             "Original Prusa MINI & MINI+")
        finally:
            preferences.reset("Printer")


class TestCommands(GuiTestCase):
    def test_legofy_selection_is_one_undo_step(self):
        f = self.fabrication()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(type(f.ViewObject.Proxy).__name__, "ViewProviderFabrication")
        self.assertEqual(len(fab().bricks(f)), f.Bricks)
        proto = fab().bricks(f)[0].LinkedObject
        self.assertEqual(tuple(proto.ViewObject.ShapeColor[:3]), tuple(proto.Color[:3]))
        screenshot("legofy")
        self.doc.undo()
        self.assertEqual(fab().fabrications(self.doc), [])
        self.doc.redo()
        self.assertEqual(len(fab().fabrications(self.doc)), 1)

    def test_legofy_a_file(self):
        import trimesh

        path = self.tmp / "block.stl"
        block = trimesh.creation.box((24.0, 16.0, 9.6))
        block.apply_translation(-block.bounds[0])
        block.export(path)
        Gui.Selection.clearSelection()
        answer_modal(choose_path(path), "FabrickatorOpenModel")
        Gui.runCommand("Fabrickator_Legofy")
        settle()
        found = fab().fabrications(self.doc)
        self.assertEqual(len(found), 1)
        self.assertEqual(found[0].Plates, 3 * 2 * 3)
        self.assertEqual(found[0].Source.TypeId, "Mesh::Feature")

    def test_layout_dialog_sets_seed_and_brick_set(self):
        f = self.fabrication()

        def handler(dialog):
            dialog.findChild(QtGui.QSpinBox).setValue(7)
            dialog.findChild(QtGui.QLineEdit).setText("plates")
            dialog.accept()

        answer_modal(handler, "FabrickatorLayoutDialog")
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Layout")
        settle()
        self.assertEqual(f.Seed, 7)
        self.assertTrue(all(b.Size[2] == 1 for b in fab().bricks(f)))
        self.doc.undo()
        self.assertEqual(f.Seed, 0)
        self.assertEqual(f.BrickSet, "all")

    def test_layout_dialog_sets_the_stud_and_socket_fit(self):
        f = self.fabrication(high_res=(8, 8, 6.4, 16, 16, 9.6))
        part = fab().printed_parts(f)[0].Shape

        def handler(dialog):
            dialog.findChild(QtGui.QDoubleSpinBox, "studFit").setValue(0.2)
            dialog.findChild(QtGui.QDoubleSpinBox, "socketFit").setValue(0.1)
            dialog.accept()

        answer_modal(handler, "FabrickatorLayoutDialog")
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Layout")
        settle()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertAlmostEqual(f.StudFit.Value, 0.2)
        self.assertAlmostEqual(f.SocketFit.Value, 0.1)
        studs = [2 * c.Surface.Radius for c in fab().printed_parts(f)[0].Shape.Faces
                 if type(c.Surface).__name__ == "Cylinder"]
        self.assertTrue(studs)
        self.assertTrue(all(abs(d - 5.0) < 1e-6 for d in studs), studs)
        self.assertNotEqual(fab().printed_parts(f)[0].Shape.Volume, part.Volume)
        self.doc.undo()
        self.assertAlmostEqual(f.StudFit.Value, 0.05)
        self.assertAlmostEqual(f.SocketFit.Value, 0.0)

    def test_layout_dialog_with_a_bad_brick_set_changes_nothing(self):
        f = self.fabrication()
        layout = f.LayoutJson

        def handler(dialog):
            dialog.findChild(QtGui.QLineEdit).setText("3001")
            dialog.accept()

        answer_modal(handler, "FabrickatorLayoutDialog")
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Layout")
        settle()
        self.assertEqual(f.BrickSet, "all")
        self.assertEqual(f.LayoutJson, layout)
        self.assertTrue(f.Status.startswith("ok"), f.Status)

    def test_export_command_writes_the_folder(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        out = self.tmp / "export"
        out.mkdir()
        Gui.Selection.addSelection(f)
        answer_modal(choose_path(out), "FabrickatorChooseFolder")
        Gui.runCommand("Fabrickator_Export")
        settle()
        for name in ("parts/P1.stl", "parts/P1.step", "parts/plate-1.3mf", "instructions.html",
                     "report.json", "layout.json", "layout.png"):
            self.assertTrue((out / name).is_file(), name)

    def test_calibration_strip_command_writes_and_shows_the_strip(self):
        from FabrickatorWorkbench import preferences

        preferences.set("SocketFit", 0.1)
        out = self.tmp / "strip"
        out.mkdir()
        answer_modal(choose_path(out), "FabrickatorChooseFolder")
        Gui.runCommand("Fabrickator_CalibrationStrip")
        settle()
        for name in ("calibration_strip.stl", "calibration_strip.3mf", "README.txt"):
            self.assertTrue((out / name).is_file(), name)
        strips = [o for o in self.doc.Objects if getattr(o, "FabrickatorRole", "") == "CalibrationStrip"]
        self.assertEqual(len(strips), 1)
        strip = strips[0]
        # 0.10 under the smaller fit (stud 0.05) to 0.15 over the larger (socket 0.1)
        self.assertEqual([round(v, 6) for v in strip.Values],
                         [-0.05, 0.0, 0.05, 0.1, 0.15, 0.2, 0.25])
        self.assertTrue(strip.ViewObject.Visibility)
        self.assertEqual(Gui.Selection.getSelection(), [strip])
        Gui.Selection.clearSelection()
        screenshot("calibration_strip")
        self.doc.undo()
        self.assertEqual([o for o in self.doc.Objects
                          if getattr(o, "FabrickatorRole", "") == "CalibrationStrip"], [])

    def test_calibration_strip_command_into_a_file_says_why_and_adds_nothing(self):
        blocker = self.tmp / "a_file"
        blocker.write_text("")
        from FabrickatorWorkbench.commands.calibration import CalibrationStrip

        CalibrationStrip().run(str(blocker))
        settle()
        self.assertEqual(self.doc.Objects, [])

    def test_report_command_shows_the_numbers(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        seen = {}

        def handler(dialog):
            seen["text"] = dialog.findChild(QtGui.QTextBrowser).toPlainText()
            dialog.reject()

        answer_modal(handler, "FabrickatorReportDialog")
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Report")
        settle()
        self.assertIn(f"{f.Bricks} bricks", seen["text"])
        self.assertIn("P1", seen["text"])
        self.assertIn("speed-up", seen["text"])

    def test_watch_folder_legofies_new_and_changed_files(self):
        import trimesh

        folder = self.tmp / "watched"
        folder.mkdir()
        answer_modal(choose_path(folder), "FabrickatorChooseFolder")
        Gui.runCommand("Fabrickator_WatchFolder")
        from FabrickatorWorkbench.commands.watch import running_watcher
        watcher = running_watcher()
        self.assertIsNotNone(watcher)
        try:
            block = trimesh.creation.box((24.0, 16.0, 9.6))
            block.apply_translation(-block.bounds[0])
            block.export(folder / "part.stl")
            deadline = time.monotonic() + 15
            while not fab().fabrications(self.doc) and time.monotonic() < deadline:
                settle(0.1)
            found = fab().fabrications(self.doc)
            self.assertEqual(len(found), 1)
            self.assertEqual(found[0].Plates, 18)
            longer = trimesh.creation.box((40.0, 16.0, 9.6))
            longer.apply_translation(-longer.bounds[0])
            time.sleep(0.05)
            longer.export(folder / "part.stl")
            deadline = time.monotonic() + 15
            while found[0].Plates == 18 and time.monotonic() < deadline:
                settle(0.1)
            self.assertEqual(found[0].Plates, 30)
            self.assertEqual(len(fab().fabrications(self.doc)), 1)
            self.assertIn("changes", fab().report(found[0]))
        finally:
            watcher.stop()
        self.assertIsNone(running_watcher())


class TestBrush(GuiTestCase):
    def open_brush(self, f, mode="high-res"):
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(f)
        Gui.runCommand({"high-res": "Fabrickator_HighResBrush", "merge": "Fabrickator_MergeBrush",
                        "split": "Fabrickator_SplitBrush"}[mode])
        settle()
        panel = f.ViewObject.Proxy.panel
        self.assertIsNotNone(panel)
        return panel

    def test_dragging_paints_bricks_and_ok_prints_them(self):
        f = self.fabrication()
        panel = self.open_brush(f)
        top = [b for b in fab().bricks(f) if b.Cell[2] + b.Size[2] == 6]
        self.assertGreaterEqual(len(top), 2)
        mouse("press", screen_point(top_centre(top[0])))
        mouse("move", screen_point(top_centre(top[1])))
        mouse("release", screen_point(top_centre(top[1])))
        painted = {b.Name for b in panel.painted_bricks()}
        self.assertIn(top[0].Name, painted)
        self.assertIn(top[1].Name, painted)
        settle(0.4)
        preview = panel.preview.Name
        self.assertGreater(panel.preview.Shape.Volume, 0.0)
        self.assertFalse(top[0].Visibility)
        screenshot("brush_preview")
        panel.accept()
        settle()
        parts = fab().printed_parts(f)
        self.assertGreaterEqual(len(parts), 1)
        printed = {b.Name for b in fab().bricks(f) if b.Kind == "printed"}
        self.assertTrue(printed)
        self.assertIsNone(self.doc.getObject(preview))
        screenshot("brush_applied")
        self.doc.undo()
        self.assertEqual(fab().printed_parts(f), [])

    def test_double_click_opens_the_brush_panel(self):
        """The view provider edits its Fabrication through the high-res brush command."""
        f = self.fabrication()
        self.assertTrue(f.ViewObject.Proxy.doubleClicked(f.ViewObject))
        settle()
        panel = f.ViewObject.Proxy.panel
        self.assertIsNotNone(panel)
        self.assertEqual(panel.mode, "high-res")
        self.assertIsNotNone(Gui.Control.activeDialog())
        panel.reject()
        settle()
        self.assertFalse(Gui.Control.activeDialog())
        self.assertIsNone(Gui.ActiveDocument.getInEdit())

    def test_radius_paints_neighbours_and_cancel_changes_nothing(self):
        f = self.fabrication()
        before = (f.LayoutJson, len(self.doc.Objects))
        panel = self.open_brush(f)
        panel.form.radius.setValue(1.5)
        brick = fab().bricks(f)[-1]
        point = screen_point(top_centre(brick))
        mouse("press", point)
        mouse("release", point)
        self.assertGreater(len(panel.painted), 1)
        panel.reject()
        settle()
        self.assertEqual((f.LayoutJson, len(self.doc.Objects)), before)
        self.assertTrue(all(b.Visibility for b in fab().bricks(f)))
        self.assertEqual(list(f.Regions), [])

    def test_picking_a_face_of_the_source(self):
        f = self.fabrication()
        f.Source.ViewObject.Visibility = True
        for b in fab().bricks(f):
            b.Visibility = False
        panel = self.open_brush(f)
        panel.form.pickFaces.setChecked(True)
        top = [n for n, face in enumerate(f.Source.Shape.Faces, 1)
               if abs(face.normalAt(0, 0).z - 1) < 1e-9][0]
        centre = f.Source.Shape.Faces[top - 1].CenterOfMass
        mouse("press", screen_point(centre))
        mouse("release", screen_point(centre))
        self.assertEqual(panel.faces, [(f.Source.Name, f"Face{top}")])
        panel.accept()
        settle()
        self.assertEqual([r.Mode for r in f.Regions], ["Faces"])
        self.assertGreaterEqual(len(fab().printed_parts(f)), 1)

    def test_split_brush_records_the_edit(self):
        f = self.fabrication(high_res=(0, 0, 9.6, 16, 24, 19.2))
        self.assertGreaterEqual(len(fab().printed_parts(f)), 1)
        panel = self.open_brush(f, "split")
        part = fab().printed_parts(f)[0]
        centre = part.Shape.BoundBox.Center
        point = screen_point(App.Vector(centre.x, centre.y, part.Shape.BoundBox.ZMax - 1.8))
        mouse("press", point)
        mouse("release", point)
        self.assertTrue(panel.painted)
        panel.accept()
        settle()
        self.assertIn('"split"', f.PartEdits)


class TestAssembly(GuiTestCase):
    def test_steps_hide_later_bricks_and_highlight_the_next(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Assembly")
        settle()
        panel = f.ViewObject.Proxy.panel
        self.assertEqual(panel.current, 1)
        lego = [b for b in fab().bricks(f) if b.Kind == "lego"]
        part = fab().printed_parts(f)[0]

        def check(step):
            for b in lego:
                self.assertEqual(bool(b.Visibility), b.Step <= step, (b.Label, b.Step, step))
                self.assertEqual(bool(b.ViewObject.OverrideMaterial), b.Step == step)
            self.assertEqual(bool(part.Visibility), part.Step <= step)

        check(1)
        panel.form.next.click()
        check(2)
        panel.form.previous.click()
        check(1)
        panel.form.slider.setValue(part.Step)
        check(part.Step)
        self.assertIn(part.PartId, panel.form.info.text())
        self.assertIsNotNone(panel.labels)
        screenshot("assembly_printed_part_step")
        panel.form.last.click()
        check(f.Steps)
        panel.reject()
        settle()
        self.assertTrue(all(b.Visibility for b in lego))
        self.assertTrue(part.Visibility)
        self.assertFalse(any(b.ViewObject.OverrideMaterial for b in lego))


    def test_a_prop_shows_in_the_steps_it_stands(self):
        """The L on a table is built on a prop under its arm (the app tests say why): the
        panel draws it from its step on, and says where to stand it."""
        from TestFabrickatorForces import l_shape

        source = l_shape(self.doc)
        f = fab().make_fabrication(source, slice_print_times=False)
        self.doc.recompute()
        settle()
        source.ViewObject.Visibility = False
        fit()
        _, props = fab().step_notes(f)
        self.assertTrue(props)
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Assembly")
        settle()
        panel = f.ViewObject.Proxy.panel
        graph = Gui.ActiveDocument.ActiveView.getSceneGraph()

        def drawn() -> bool:
            return any(graph.getChild(n).getName() == "FabrickatorAssemblyProps"
                       for n in range(graph.getNumChildren()))

        step = props[0]["step"]
        panel.go(step - 1)
        self.assertFalse(drawn())
        self.assertNotIn("Prop:", panel.form.info.text())
        panel.go(step)
        self.assertTrue(drawn())
        self.assertIn("Prop: before step", panel.form.info.text())
        screenshot("assembly_prop_step")
        panel.reject()
        settle()
        self.assertFalse(drawn())


class TestIteration(GuiTestCase):
    def test_pad_edit_highlights_changed_bricks_and_ghosts_removed_ones(self):
        f = self.fabrication()
        body, sketch, pad = (self.doc.getObject(n) for n in ("Body", "Sketch", "Pad"))
        colour = {b.BrickId: tuple(b.LinkedObject.ViewObject.ShapeColor[:3]) for b in fab().bricks(f)}
        pad.Length = 28.8
        sketch.setDatum("Length", App.Units.Quantity("32 mm"))
        self.doc.recompute()
        settle()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        changes = fab().report(f)["changes"]
        bricks = fab().bricks(f)
        changed = [b for b in bricks if b.Changed]
        unchanged = [b for b in bricks if not b.Changed]
        self.assertEqual({b.BrickId for b in changed}, {e["id"] for e in changes["add"]})
        self.assertTrue(changed and unchanged)

        def shown(b):
            return tuple(round(c, 3) for c in b.LinkedObject.ViewObject.ShapeColor[:3])

        lego = {shown(b) for b in unchanged}
        for b in changed:
            self.assertNotIn(shown(b), lego, b.Label)
        for b in unchanged:  # unchanged bricks look as before the edit
            self.assertEqual(tuple(b.LinkedObject.ViewObject.ShapeColor[:3]), colour[b.BrickId])
        ghosts = fab().ghosts(f)
        self.assertEqual({g.BrickId for g in ghosts}, {e["id"] for e in changes["take_off"]})
        self.assertTrue(ghosts)
        for g in ghosts:
            self.assertTrue(g.ViewObject.OverrideMaterial)
            self.assertGreater(g.ViewObject.ShapeMaterial.Transparency, 0.5)
            self.assertTrue(g.Visibility)
        group = Gui.getDocument(self.doc.Name).getObject(f.Name)
        self.assertIn(ghosts[0].InList[0], group.claimChildren())
        body.ViewObject.Visibility = False
        fit()
        self.assertGreater(screenshot("iteration").stat().st_size, 0)
        Gui.Selection.addSelection(f)
        fab().clear_changes(f)
        settle()
        self.assertEqual(fab().ghosts(f), [])
        self.assertFalse(any(b.Changed for b in fab().bricks(f)))


class TestHeadlessDocument(GuiTestCase):
    def test_document_made_without_gui_opens_with_view_providers_and_colours(self):
        path = self.tmp / "headless.FCStd"
        script = self.tmp / "make.py"
        script.write_text(
            "import os, sys\n"
            f"sys.path.insert(0, {str(ROOT)!r}); sys.path.insert(0, {str(ROOT / 'tests' / 'app')!r})\n"
            f"exec(open({str(ROOT / 'Init.py')!r}).read())\n"
            "import FreeCAD as App, FabrickatorWorkbench as fab\n"
            "from TestFabrickatorApp import padded_body\n"
            "doc = App.newDocument('Headless')\n"
            "body, _, _ = padded_body(doc)\n"
            "f = fab.make_fabrication(body)\n"
            "fab.mark_high_res(f, box=(0, 0, 12.8, 8, 8, 19.2))\n"
            "doc.recompute()\n"
            f"doc.saveAs({str(path)!r})\n"
            "os._exit(0)\n")
        subprocess.run(["freecadcmd", str(script)], capture_output=True, timeout=180)
        self.assertTrue(path.is_file())
        doc = App.openDocument(str(path))
        try:
            settle()
            f = fab().fabrications(doc)[0]
            self.assertEqual(type(f.ViewObject.Proxy).__name__, "ViewProviderFabrication")
            part = fab().printed_parts(f)[0]
            self.assertEqual(type(part.ViewObject.Proxy).__name__, "ViewProviderPrintedPart")
            for b in fab().bricks(f):
                proto = b.LinkedObject
                self.assertEqual(tuple(proto.ViewObject.ShapeColor[:3]), tuple(proto.Color[:3]))
            for obj in fab().bricks(f) + [part]:  # FreeCAD 0.20 opens headless documents hidden
                obj.Visibility = obj.Kind == "lego" if hasattr(obj, "Kind") else True
            shown = Gui.getDocument(doc.Name).ActiveView
            shown.viewIsometric()
            shown.fitAll()
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            settle()
            shown.saveImage(str(ARTIFACTS / "headless_reopened.png"), 800, 600, "White")
        finally:
            App.closeDocument(doc.Name)
from TestFabrickatorFeel import TestAssemblyLabels, TestEscCancels, TestPanelsFit, TestRegionsShowWhileBrushing  # noqa: E402,F401
from TestFabrickatorLook import TestLook  # noqa: E402,F401
from TestFabrickatorUndoGui import TestUndoInTheGui  # noqa: E402,F401
from TestFabrickatorReport import TestReport  # noqa: E402,F401
from TestFabrickatorInstallGui import TestInstallInTheGui  # noqa: E402,F401
from TestFabrickatorStress import TestStress, TestStressReopens  # noqa: E402,F401
from TestFabrickatorEstimate import TestLiveEstimate, TestSlicedLater  # noqa: E402,F401
