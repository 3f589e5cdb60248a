"""GUI tests that the workbench feels like FreeCAD (issue 13), run by run_gui_tests.py through
TestFabrickatorGui:

* the task panels fit the dock that holds FreeCAD's task view at its default
  width (the Combo View, 264 px, on FreeCAD 0.20; the Tasks dock, 260 px, on
  1.0): every button and label lies inside its panel and is as wide as it asks
  to be (no clipped or hidden widget, no horizontal scrolling), and the panels
  grow with the dock;
* high-res regions show only while the brush panel is open, or when their
  ShowAlways says so, also after saving and reopening;
* the printed parts' ID labels in the assembly view are white on a dark frame;
* Esc stops a long recompute (FreeCAD's own question "Do you really want to
  abort the operation?" answered Yes) and the document keeps its layout; the
  progress bar in the status bar shows while it runs.
"""

from __future__ import annotations

import json
import time

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

from TestFabrickatorGui import ARTIFACTS, GuiTestCase, fab, fit, mouse, settle, top_centre

#: FreeCAD's default width of the dock that holds the task panel, px: the Combo View on
#: FreeCAD 0.20 (tree, properties and tasks as its tabs), the "Tasks" dock on 1.0 (the
#: tree and properties are the "Model" dock beside it), measured with a fresh user
#: configuration on a 1280 px wide screen.
TASK_DOCK_WIDTH = 264 if int(App.Version()[0]) < 1 else 260


def is_task_view(widget) -> bool:
    return widget is not None and widget.metaObject().className() == "Gui::TaskView::TaskView"


def task_dock():
    """The dock widget that holds FreeCAD's task view (Gui.Control's panels)."""
    mw = Gui.getMainWindow()
    docks = [d for d in mw.findChildren(QtGui.QDockWidget)
             if is_task_view(d.widget()) or any(is_task_view(w) for w in d.findChildren(QtGui.QWidget))]
    assert len(docks) == 1, [d.objectName() for d in docks]
    return docks[0]


def set_dock_width(width: int) -> None:
    """Lay the task view's dock out ``width`` pixels wide, as a user dragging its edge would."""
    dock = task_dock()
    dock.show()
    dock.raise_()
    Gui.getMainWindow().resizeDocks([dock], [width], QtCore.Qt.Horizontal)
    settle(0.3)


def task_scroll_area(form):
    """The task view's scroll area that holds ``form``."""
    return next(s for s in task_dock().findChildren(QtGui.QScrollArea) if s.isAncestorOf(form))


def clipped_widgets(form) -> list[str]:
    """The visible buttons and labels of ``form`` that are clipped: outside the form, outside
    the visible part of the task view, or narrower than their size hint (a wrapping label:
    lower than its text needs at its width).  Empty when everything shows whole."""
    viewport = task_scroll_area(form).viewport()
    form_left = form.mapTo(viewport, QtCore.QPoint(0, 0)).x()
    bad = []
    if form_left < 0 or form_left + form.width() > viewport.width():
        bad.append(f"form spans x {form_left}..{form_left + form.width()} of a {viewport.width()} "
                   f"px view")
    for widget in form.findChildren(QtGui.QWidget):
        if not widget.isVisible() or not isinstance(widget, (QtGui.QAbstractButton, QtGui.QLabel)):
            continue
        name = f"{type(widget).__name__} {widget.objectName()!r}"
        rect = QtCore.QRect(widget.mapTo(form, QtCore.QPoint(0, 0)), widget.size())
        if not form.rect().contains(rect):
            bad.append(f"{name} at {rect.getRect()} outside the form {form.rect().getRect()}")
        if isinstance(widget, QtGui.QLabel) and widget.wordWrap():
            if widget.height() < widget.heightForWidth(widget.width()):
                bad.append(f"{name} {widget.height()} px high, needs "
                           f"{widget.heightForWidth(widget.width())}")
        elif widget.width() < widget.sizeHint().width():
            bad.append(f"{name} {widget.width()} px wide, needs {widget.sizeHint().width()}")
    return bad


class TestPanelsFit(GuiTestCase):
    def tearDown(self):
        try:
            set_dock_width(TASK_DOCK_WIDTH)
        finally:
            super().tearDown()

    def check_panel(self, name: str, form) -> None:
        """``form`` shows whole in the task view's dock at its default width and grows with
        a wider dock."""
        set_dock_width(TASK_DOCK_WIDTH)
        self.assertEqual(task_dock().width(), TASK_DOCK_WIDTH)
        self.assertLessEqual(form.minimumSizeHint().width(), 215)
        self.assertEqual(clipped_widgets(form), [])
        self.assertFalse(task_scroll_area(form).horizontalScrollBar().isVisible())
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        task_dock().grab().save(str(ARTIFACTS / f"{name}_{TASK_DOCK_WIDTH}px.png"))
        narrow = form.width()
        set_dock_width(400)
        self.assertEqual(clipped_widgets(form), [])
        self.assertGreater(form.width(), narrow + 100)

    def test_assembly_panel_fits_the_task_dock(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        f.Label = "Bicycle lamp holder, second version"
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Assembly")
        settle()
        panel = f.ViewObject.Proxy.panel
        panel.go(f.Steps)
        panel.form.slider.setValue(f.Steps - 1)
        self.assertEqual(panel.form.stepLabel.text(), f"Step {f.Steps - 1} / {f.Steps}")
        self.check_panel("assembly_panel", panel.form)
        set_dock_width(TASK_DOCK_WIDTH)
        wide = panel.form.next.width()
        set_dock_width(400)
        self.assertGreater(panel.form.next.width(), wide)   # the step buttons take the width
        panel.reject()

    def test_brush_panel_fits_the_task_dock(self):
        f = self.fabrication()
        f.Label = "Bicycle lamp holder, second version"
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_SplitBrush")
        settle()
        panel = f.ViewObject.Proxy.panel
        self.assertTrue(panel.form.windowTitle().startswith("Brushes on Bicycle"))
        self.assertTrue(panel.form.windowTitle().endswith("\u2026"))   # elided to fit
        self.assertIn("own", panel.form.modeHelp.text())
        panel.form.modeHighRes.setChecked(True)
        self.assertIn("printed", panel.form.modeHelp.text())
        self.check_panel("brush_panel", panel.form)
        panel.reject()


def view_point(point) -> QtCore.QPointF:
    """Where the 3D ``point`` is in the 3D view's viewport, in Qt widget coordinates, also
    when Coin's viewport and the widget differ in size (the view then scales the mouse
    positions it gets by their ratio, as it does its drawing)."""
    view = Gui.ActiveDocument.ActiveView
    x, y = view.getPointOnScreen(point)
    width, height = view.getSize()
    qt = view.graphicsView().viewport().size()
    return QtCore.QPointF(x * qt.width() / width, qt.height() - y * qt.height() / height)


class TestRegionsShowWhileBrushing(GuiTestCase):
    def open_brush(self, f):
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_HighResBrush")
        settle()
        return f.ViewObject.Proxy.panel

    def test_regions_show_only_while_the_brush_panel_is_open(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        fab().clear_changes(f)
        region = f.Regions[0]
        self.assertFalse(region.Visibility)
        panel = self.open_brush(f)
        self.assertTrue(region.Visibility)
        panel.reject()
        settle()
        self.assertFalse(region.Visibility)
        panel = self.open_brush(f)
        self.assertTrue(region.Visibility)
        top = [b for b in fab().bricks(f) if b.Kind == "lego" and b.Cell[2] + b.Size[2] == 6]
        point = view_point(top_centre(top[-1]))
        mouse("press", point)
        mouse("release", point)
        self.assertEqual([b.Name for b in panel.painted_bricks()], [top[-1].Name])
        panel.accept()
        settle()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(len(f.Regions), 2)
        self.assertEqual([r.Visibility for r in f.Regions], [False, False])

    def test_the_brush_panel_reopens_while_old_panels_are_kept(self):
        """A closed panel (kept by a macro, or by this test) leaves no wrapper of its
        deleted widgets, which PySide would hand out again for a new panel's widget made
        at the same address: seen on FreeCAD 1.0 as "Internal C++ object already deleted"
        or as a radio button without ``isChecked``."""
        f = self.fabrication()
        kept = []
        for n in range(40):
            panel = self.open_brush(f)
            kept.append(panel)
            self.assertEqual(panel.mode, "high-res")
            mode = ("merge", "split", "unmark", "high-res")[n % 4]
            {"merge": panel.form.modeMerge, "split": panel.form.modeSplit,
             "unmark": panel.form.modeUnmark, "high-res": panel.form.modeHighRes}[mode].setChecked(True)
            self.assertEqual(panel.mode, mode)
            panel.reject()
            settle(0.02)
        self.assertFalse(Gui.Control.activeDialog())

    def test_a_region_painted_over_is_brushed_through(self):
        """A shown region lies over its bricks: a click there paints the brick below it."""
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        fab().clear_changes(f)
        panel = self.open_brush(f)
        printed = [b for b in fab().bricks(f) if b.Kind == "printed"]
        self.assertTrue(printed)
        # a corner of the printed part's top face, where the region's box has its top too
        point = view_point(App.Vector(1.0, 1.0, 19.2))
        mouse("press", point)
        mouse("release", point)
        self.assertTrue(set(b.Name for b in panel.painted_bricks()) & {b.Name for b in printed})
        panel.reject()

    def test_show_always_shows_a_region_also_after_reopening(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        shown, hidden = f.Regions[0], fab().mark_high_res(f, box=(24, 0, 12.8, 32, 8, 19.2))
        self.doc.recompute()
        shown.ShowAlways = True
        self.assertTrue(shown.Visibility)
        self.assertFalse(hidden.Visibility)
        panel = self.open_brush(f)
        self.assertTrue(hidden.Visibility)
        panel.reject()
        settle()
        self.assertEqual((shown.Visibility, hidden.Visibility), (True, False))
        # an older document: its regions have no ShowAlways and were saved shown
        hidden.removeProperty("ShowAlways")
        hidden.Visibility = True
        path = self.tmp / "regions.FCStd"
        self.doc.saveAs(str(path))
        names = (shown.Name, hidden.Name)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(str(path))
        settle()
        shown, hidden = (self.doc.getObject(n) for n in names)
        self.assertTrue(shown.ShowAlways)
        self.assertFalse(hidden.ShowAlways)
        self.assertEqual((shown.Visibility, hidden.Visibility), (True, False))
        self.doc.recompute()
        self.assertEqual((shown.Visibility, hidden.Visibility), (True, False))
        shown.ShowAlways = False
        self.assertFalse(shown.Visibility)
        # a region that lost the property gets it back on its next recompute
        hidden.removeProperty("ShowAlways")
        hidden.touch()
        self.doc.recompute()
        self.assertFalse(hidden.ShowAlways)
        self.assertFalse(hidden.Visibility)

    def test_the_assembly_hides_even_regions_shown_always(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        region = f.Regions[0]
        region.ShowAlways = True
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Assembly")
        settle()
        self.assertFalse(region.Visibility)
        f.ViewObject.Proxy.panel.reject()
        settle()
        self.assertTrue(region.Visibility)

    def test_the_assembly_panel_reopens_while_old_panels_are_kept(self):
        """As the brush panel: a kept, closed assembly panel leaves no stale widget."""
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        kept = []
        for _ in range(25):
            Gui.Selection.clearSelection()
            Gui.Selection.addSelection(f)
            Gui.runCommand("Fabrickator_Assembly")
            settle(0.02)
            panel = f.ViewObject.Proxy.panel
            kept.append(panel)
            panel.form.next.click()
            self.assertEqual(panel.current, 2)
            self.assertEqual(panel.form.stepLabel.text(), f"Step 2 / {f.Steps}")
            panel.reject()
            settle(0.02)
        self.assertFalse(Gui.Control.activeDialog())


def still_camera(timeout_s: float = 5.0) -> str:
    """Wait until the 3D view's camera stands still (FreeCAD 1.0 animates view changes
    such as the isometric view and Fit all); the camera."""
    view = Gui.ActiveDocument.ActiveView
    end = time.monotonic() + timeout_s
    camera = view.getCamera()
    while time.monotonic() < end:
        settle(0.15)
        now = view.getCamera()
        if now == camera:
            return now
        camera = now
    raise AssertionError("the 3D view's camera kept moving")


class TestAssemblyLabels(GuiTestCase):
    def test_printed_part_ids_are_white_on_a_dark_frame(self):
        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        Gui.Selection.addSelection(f)
        Gui.runCommand("Fabrickator_Assembly")
        settle()
        panel = f.ViewObject.Proxy.panel
        part = fab().printed_parts(f)[0]
        panel.go(part.Step)
        fit()
        labels = panel.labels
        from pivy import coin

        self.assertTrue(labels.isOfType(coin.SoAnnotation.getClassTypeId()))
        label = labels.getChild(0).getChild(1)
        self.assertEqual(label.getTypeId(), coin.SoType.fromName("SoFrameLabel"))
        view = Gui.ActiveDocument.ActiveView
        width, height = view.getSize()
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        images = {}
        graph = view.getSceneGraph()
        camera = still_camera()
        for name in ("assembly_label", "assembly_without_label"):
            settle()
            self.assertEqual(view.getCamera(), camera)   # both images from the same view
            view.saveImage(str(ARTIFACTS / f"{name}.png"), width, height, "White")
            images[name] = QtGui.QImage(str(ARTIFACTS / f"{name}.png"))
            graph.removeChild(labels)
        graph.addChild(labels)
        shown, plain = images["assembly_label"], images["assembly_without_label"]
        self.assertEqual((shown.width(), shown.height()), (width, height))
        box = part.Shape.BoundBox
        cx, cy = view.getPointOnScreen(App.Vector(box.Center.x, box.Center.y, box.ZMax + 4.0))
        cy = height - 1 - cy
        near = [(x, y) for x in range(max(0, cx - 80), min(width, cx + 80))
                for y in range(max(0, cy - 50), min(height, cy + 50))]

        def lightness(x, y):
            return QtGui.QColor(shown.pixel(x, y)).lightness()

        # the label's frame: the dark pixels the label adds near the part's top
        frame = [(x, y) for x, y in near if shown.pixel(x, y) != plain.pixel(x, y) and lightness(x, y) < 60]
        self.assertTrue(frame, "no dark frame at the printed part")
        x0, x1 = min(x for x, _ in frame), max(x for x, _ in frame)
        y0, y1 = min(y for _, y in frame), max(y for _, y in frame)
        self.assertTrue(20 <= x1 - x0 <= 120 and 15 <= y1 - y0 <= 60, (x0, y0, x1, y1))
        inside = [lightness(x, y) for x in range(x0, x1 + 1) for y in range(y0, y1 + 1)]
        white = sum(1 for g in inside if g > 230)
        dark = sum(1 for g in inside if g < 60)
        # white text on the dark frame: hardly anything in between but the text's edges
        self.assertGreater(white, 30, "no white text in the label")
        self.assertGreater(dark, 2 * white)
        self.assertGreater(white + dark, 0.7 * len(inside))
        panel.reject()
        settle()
        self.assertIsNone(panel.labels)


def press_escape() -> None:
    """Press and release Esc on FreeCAD's main window, as the window system would."""
    mw = Gui.getMainWindow()
    for kind in (QtCore.QEvent.KeyPress, QtCore.QEvent.KeyRelease):
        QtGui.QApplication.sendEvent(mw, QtGui.QKeyEvent(kind, QtCore.Qt.Key_Escape,
                                                         QtCore.Qt.NoModifier))


class TestEscCancels(GuiTestCase):
    """A recompute long enough to watch (a 160 x 96 x 48 mm part with a printed region
    through its height: its core run takes over 1 s, most of it printing the part);
    FreeCAD hands the GUI its events only now and then during it (at most every
    0.5 s), and that is when the test acts, as a user pressing keys would be heard."""

    def long_fabrication(self):
        from TestFabrickatorApp import padded_body

        body, _, _ = padded_body(self.doc, 160.0, 96.0, 48.0)
        f = fab().make_fabrication(body)
        fab().mark_high_res(f, box=(0, 0, 0, 32, 48, 48))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        return f

    def recompute_pressing_escape(self, f, answer):
        """Change the seed and recompute; at the first moment the GUI gets its events during
        the run, note the status bar and press Esc; answer FreeCAD's question with
        ``answer``.  Returns what was seen: the status bar message and progress bars
        when Esc was pressed, and the question's title and text."""
        seen = {}
        mw = Gui.getMainWindow()

        def during_the_run():
            seen["message"] = mw.statusBar().currentMessage()
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            mw.statusBar().grab().save(str(ARTIFACTS / "recompute_status_bar.png"))
            seen["bars"] = [(b.isVisible(), b.value(), b.maximum())
                            for b in mw.statusBar().findChildren(QtGui.QProgressBar)]
            press_escape()

        def answer_question():
            box = QtGui.QApplication.activeModalWidget()
            if isinstance(box, QtGui.QMessageBox):
                seen["question"] = (box.windowTitle(), box.text())
                box.button(answer).click()

        asking = QtCore.QTimer()
        asking.timeout.connect(answer_question)
        asking.start(50)
        QtCore.QTimer.singleShot(0, during_the_run)
        f.Seed = f.Seed + 1
        self.doc.recompute()
        asking.stop()
        settle()
        return seen

    def test_escape_stops_the_recompute_and_keeps_the_layout(self):
        f = self.long_fabrication()
        before = (f.LayoutJson, f.Seed, sorted((b.Name, tuple(b.Placement.Base)) for b in fab().bricks(f)))
        seen = self.recompute_pressing_escape(f, QtGui.QMessageBox.Yes)
        self.assertEqual(seen.get("question", ("",))[0], "Aborting", seen)
        # Esc came while the core ran: the status bar said which stage, short of the end
        self.assertRegex(seen["message"], rf"^Fabrickator: {f.Label}: [a-z].* \((\d|[1-8]\d) %\)$")
        self.assertIn("Cancelled: stopped with Esc", f.Status)
        self.assertTrue(f.Status.startswith("failed, previous result kept"), f.Status)
        after = (f.LayoutJson, f.Seed, sorted((b.Name, tuple(b.Placement.Base)) for b in fab().bricks(f)))
        self.assertEqual(after, before)
        # and the status bar says so once the recompute ended (within a moment)
        status = Gui.getMainWindow().statusBar()
        end = time.monotonic() + 2.0
        while "stopped with Esc" not in status.currentMessage() and time.monotonic() < end:
            settle(0.05)
        self.assertIn("stopped with Esc", status.currentMessage())

    def test_escape_answered_no_lets_the_recompute_finish(self):
        f = self.long_fabrication()
        seed = f.Seed
        seen = self.recompute_pressing_escape(f, QtGui.QMessageBox.No)
        self.assertEqual(seen.get("question", ("",))[0], "Aborting", seen)
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(f.Seed, seed + 1)
        # the run went to its end with the new seed (this part's layout happens not to
        # depend on the seed): the inputs of the last good recompute have it
        self.assertEqual(json.loads(f.LastGood)["parameters"]["Seed"], seed + 1)
