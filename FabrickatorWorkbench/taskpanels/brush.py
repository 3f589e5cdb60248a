"""The brush task panel: paint bricks in the 3D view to mark them high-res, merge, split
or unmark them; pick faces of the Source or a region solid.

Pressing the left mouse button over a brick and dragging paints every brick
within the brush radius (in studs) of the point under the cursor.  The
preview updates as you paint: in high-res mode a painted LEGO brick is
replaced by its exact shape (the brick intersected with the Source, as it
will be printed), in the other modes painted bricks show as coloured boxes.
Below the status, the print time and speed-up the painted change would give
show next to the last recompute's (:mod:`core.live_estimate`: the calibrated
estimate, marked as one), updated as the mouse pauses.
OK applies the change and recomputes, as one undo step; Cancel drops it.
The panel holds the painted bricks itself; the document only changes on OK
(the preview object it shows meanwhile is removed again either way).

The Fabrication's high-res regions show while the panel is open (a click
goes through them to the bricks) and hide again when it closes, unless a
region's ``ShowAlways`` says otherwise (:func:`.high_res_region.show`).
"""

from __future__ import annotations

import json
import os

import FreeCAD as App
import FreeCADGui as Gui
import Part
from pivy import coin
from PySide import QtCore, QtGui

from core import picking
from FabrickatorWorkbench import log, make
from FabrickatorWorkbench.objects import fabricate, high_res_region
from FabrickatorWorkbench.taskpanels.closing import close_dialog
from FabrickatorWorkbench.taskpanels.titles import fitting_title

#: Modes and their preview colours.
MODES = {"high-res": (0.96, 0.62, 0.26), "merge": (0.16, 0.62, 0.56),
         "split": (0.48, 0.17, 0.75), "unmark": (0.55, 0.55, 0.55)}

#: The form's radio button of each mode.
BUTTONS = {"high-res": "modeHighRes", "merge": "modeMerge", "split": "modeSplit",
           "unmark": "modeUnmark"}

#: Transaction names per mode.
TITLES = {"high-res": "High-res brush", "merge": "Merge brush", "split": "Split brush",
          "unmark": "Unmark brush"}

#: What each mode does, shown below the modes.
HELP = {"high-res": "Paint bricks that must be exact: they are printed.",
        "merge": "Paint printed parts to join them into one part.",
        "split": "Paint printed bricks to print them as parts of their own.",
        "unmark": "Paint marked bricks to make them LEGO again."}

#: Milliseconds the exact preview waits for the mouse to pause.
PREVIEW_DELAY_MS = 120

#: Milliseconds the live estimate waits for the mouse to pause (a drag's moves come
#: closer together than this).
ESTIMATE_DELAY_MS = 30

UI = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                  "resources", "ui", "brush.ui")


class BrushPanel:
    """Task panel of the brushes for Fabrication ``fab``, starting in ``mode``."""

    def __init__(self, fab, mode: str = "high-res"):
        self.fab = fab
        self.doc = fab.Document
        self.form = Gui.PySideUic.loadUi(UI)
        # the task box keeps the title it opened with: name the Fabrication, the modes
        # below say which brush paints
        self.form.setWindowTitle(fitting_title("Brushes on ", fab.Label, self.form))
        self.form.setToolTip(f"Brushes on {fab.Label}")
        self.button(mode).setChecked(True)
        for name in BUTTONS:
            self.button(name).toggled.connect(self.on_mode)
        self.form.clear.clicked.connect(self.clear)
        self.form.modeHelp.setText(HELP[mode])
        #: the stored layout (the core's view of the bricks) and the brick objects by id
        self.layout = make.layout(fab)
        self.bricks = {b.BrickId: b for b in make.bricks(fab)}
        self.by_name = {b.Name: n for n, b in self.bricks.items()}
        self.boxes = {b.id: self.layout.grid.box_mm(b.cell, b.size) for b in self.layout.bricks}
        self.part_bricks = {p.Name: {n for n, b in self.bricks.items() if b.PrintedPart == p.PartId}
                            for p in make.printed_parts(fab)}
        #: brick ids painted so far
        self.painted: set[int] = set()
        self.faces: list[tuple[str, str]] = []
        self.solids: list[str] = []
        self.exact: dict[int, object] = {}
        self.hidden: dict[str, bool] = {}
        self.pressed = False
        self.doc.openTransaction(TITLES[mode])
        for region in fab.Regions:
            high_res_region.show(region, brushing=True)
        self.preview = self.doc.addObject("Part::Feature", "BrushPreview")
        self.preview.Label = "Brush preview"
        self.timer = QtCore.QTimer()
        self.timer.setSingleShot(True)
        self.timer.timeout.connect(self.update_preview)
        self.estimate_timer = QtCore.QTimer()
        self.estimate_timer.setSingleShot(True)
        self.estimate_timer.timeout.connect(self.show_estimate)
        #: the live estimator (made on first use), or why there is none
        self.estimator = None
        self.estimate_failed: str | None = None
        self.sliced = False
        self.view = Gui.ActiveDocument.ActiveView
        self.callbacks = [
            (coin.SoMouseButtonEvent.getClassTypeId(),
             self.view.addEventCallbackPivy(coin.SoMouseButtonEvent.getClassTypeId(), self.on_button)),
            (coin.SoLocation2Event.getClassTypeId(),
             self.view.addEventCallbackPivy(coin.SoLocation2Event.getClassTypeId(), self.on_move)),
        ]
        self.show_status()
        self.show_estimate()

    # --- modes and state ------------------------------------------------------------

    def button(self, mode: str):
        """The form's radio button of ``mode``, asked from the form each time: the panel
        keeps no wrapper of a widget of its own (:mod:`.closing` says why)."""
        return getattr(self.form, BUTTONS[mode])

    @property
    def mode(self) -> str:
        """The checked mode (while the panel is open)."""
        return next(m for m in BUTTONS if self.button(m).isChecked())

    def on_mode(self, checked: bool) -> None:
        if checked:
            self.form.modeHelp.setText(HELP[self.mode])
            self.refresh()

    def clear(self) -> None:
        """Forget everything painted and picked."""
        self.painted.clear()
        self.faces.clear()
        self.solids.clear()
        Gui.Selection.clearSelection()
        self.refresh()

    def show_status(self) -> None:
        parts = [f"{len(self.painted)} brick(s) painted"]
        if self.faces:
            parts.append(f"{len(self.faces)} face(s)")
        if self.solids:
            parts.append(f"{len(self.solids)} region solid(s)")
        self.form.status.setText(", ".join(parts) + ". Press and drag over bricks in the "
                                 "3D view; OK applies.")

    # --- mouse ----------------------------------------------------------------------

    def on_button(self, callback) -> None:
        event = callback.getEvent()
        if event.getButton() != coin.SoMouseButtonEvent.BUTTON1:
            return
        if event.getState() == coin.SoButtonEvent.DOWN:
            position = event.getPosition().getValue()
            if self.form.pickFaces.isChecked():
                if self.pick(position):
                    callback.setHandled()
                return
            if self.paint_at(position):
                self.pressed = True
                callback.setHandled()
        elif event.getState() == coin.SoButtonEvent.UP and self.pressed:
            self.pressed = False
            callback.setHandled()

    def on_move(self, callback) -> None:
        if self.pressed:
            self.paint_at(callback.getEvent().getPosition().getValue())
            callback.setHandled()

    def paint_at(self, position) -> bool:
        """Paint the brick under ``position`` (:func:`core.picking.brick_at`: a brick, or the
        brick of a printed part or of the preview under the point) and those within the
        brush radius of the point; True if on a brick."""
        info = self.view.getObjectInfo((int(position[0]), int(position[1])))
        if not info:
            return False
        obj = self.doc.getObject(info.get("Object", ""))
        if obj is None or not (obj.Name in self.by_name or obj.Name in self.part_bricks
                               or obj.Name == self.preview.Name):
            return False
        point = (float(info["x"]), float(info["y"]), float(info["z"]))
        if obj.Name in self.by_name:
            hit = {self.by_name[obj.Name]}
        else:
            under = picking.brick_at(self.layout, point, among=self.part_bricks.get(obj.Name))
            hit = set() if under is None else {under}
        radius = self.form.radius.value() * float(self.layout.grid.cell[0])
        if radius > 0:
            hit |= set(picking.bricks_within(self.layout, point, radius))
        new = hit - self.painted
        if new:
            self.painted |= new
            self.refresh()
        return True

    def pick(self, position) -> bool:
        """Faces mode: add the Source face or the region solid under ``position``."""
        info = self.view.getObjectInfo((int(position[0]), int(position[1])))
        if not info:
            return False
        obj = info.get("ParentObject") or self.doc.getObject(info.get("Object", ""))
        component = info.get("Component", "")
        if obj is None or hasattr(obj, "FabrickatorRole"):
            return False
        if obj == self.fab.Source and component.startswith("Face"):
            if (obj.Name, component) not in self.faces:
                self.faces.append((obj.Name, component))
                Gui.Selection.addSelection(obj, component)
        elif obj != self.fab.Source and getattr(obj, "Shape", None) is not None and obj.Shape.Solids:
            if obj.Name not in self.solids:
                self.solids.append(obj.Name)
                Gui.Selection.addSelection(obj)
        else:
            return False
        self.show_status()
        return True

    # --- preview ----------------------------------------------------------------------

    def refresh(self) -> None:
        """Show the painted bricks: hide them (high-res) or colour them, then (re)build the
        preview shape after a short pause of the mouse."""
        high_res = self.mode == "high-res"
        for n in self.painted:
            brick = self.bricks[n]
            if brick.Kind == "lego" and high_res:
                if brick.Name not in self.hidden:
                    self.hidden[brick.Name] = brick.Visibility
                    brick.Visibility = False
            elif brick.Name in self.hidden:
                brick.Visibility = self.hidden.pop(brick.Name)
        for name in [n for n in self.hidden if self.by_name[n] not in self.painted]:
            self.doc.getObject(name).Visibility = self.hidden.pop(name)
        self.preview.ViewObject.ShapeColor = MODES[self.mode]
        self.preview.ViewObject.Transparency = 0 if high_res else 40
        self.timer.start(PREVIEW_DELAY_MS)
        self.estimate_timer.start(ESTIMATE_DELAY_MS)
        self.show_status()

    def update_preview(self) -> None:
        """The preview shape: exact pieces of painted LEGO bricks (high-res) or their boxes."""
        pieces = []
        source = getattr(self.fab.Source, "Shape", None)
        exact = (self.mode == "high-res" and source is not None and not source.isNull()
                 and float(self.fab.Scale) == 1.0)
        for n in sorted(self.painted):
            brick = self.bricks[n]
            if exact and brick.Kind == "lego":
                if n not in self.exact:
                    self.exact[n] = Part.getShape(brick).common(source)
                pieces.append(self.exact[n])
            else:
                lo, hi = self.boxes[n]
                pieces.append(Part.makeBox(*(hi - lo), App.Vector(*lo)))
        self.preview.Shape = Part.makeCompound(pieces) if pieces else Part.Shape()

    # --- live estimate ---------------------------------------------------------------

    def show_estimate(self) -> None:
        """The estimate line: what the painted bricks would give next to the last result
        (:func:`core.live_estimate.words`); "estimate unavailable" and a line in the
        Report view when it cannot be made."""
        from core import live_estimate

        try:
            if self.estimator is None:
                self.estimator, self.sliced = self.new_estimator()
            last = self.estimator.last()
            changed = self.estimator.estimate(self.painted, self.mode) if self.painted else None
            text = live_estimate.words(changed, last, self.sliced)
        except Exception as exc:  # noqa: BLE001 - any failure only costs the estimate
            reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            if reason != self.estimate_failed:
                log.warning(f"{self.fab.Label}: brush estimate unavailable: {reason}")
            self.estimate_failed = reason
            text = "Estimate unavailable (the Report view says why)."
        self.form.estimate.setText(text)

    def new_estimator(self):
        """The live estimator of the Fabrication's stored result, and whether its print
        times were sliced; raises (InputError, ValueError, OSError) when it has none."""
        from core import live_estimate

        if not self.fab.IterationState:
            raise ValueError("the Fabrication has no stored result: recompute it")
        report = json.loads(self.fab.ReportJson or "{}")
        poses = {p["id"]: p.get("pose") for p in report.get("printed_parts", ())}
        parts = make.printed_parts(self.fab)
        last = [live_estimate.LastPart(p.PartId, tuple(int(i) for i in p.BrickIds),
                                       float(p.PrintTime), live_estimate.up_of_pose(poses.get(p.PartId)))
                for p in parts]
        times = report.get("print_time_s") or {}
        sliced = bool(times) and live_estimate.is_sliced(times.get("method")) and all(
            live_estimate.is_sliced(p.PrintTimeMethod) for p in parts)
        estimator = live_estimate.Estimator(
            self.layout, live_estimate.snapshot_mesh(self.fab.IterationState), last,
            times.get("full_model"), float(self.fab.SecondsPerBrick),
            float(self.fab.SecondsPerPart), fabricate.fit(self.fab))
        return estimator, sliced

    def painted_bricks(self) -> list:
        """The painted brick objects."""
        return [self.bricks[n] for n in sorted(self.painted)]

    # --- accept / reject ------------------------------------------------------------------

    def getStandardButtons(self):
        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def accept(self) -> bool:
        """Apply the painted change and recompute; one undo step (dropped if it fails)."""
        mode, bricks = self.mode, self.painted_bricks()
        self.cleanup()
        ok = True
        try:
            if mode == "high-res":
                if bricks:
                    make.mark_high_res(self.fab, bricks=bricks)
                if self.faces:
                    source = self.doc.getObject(self.faces[0][0])
                    make.mark_high_res(self.fab, faces=[(source, [c for _, c in self.faces])])
                for name in self.solids:
                    make.mark_high_res(self.fab, solid=self.doc.getObject(name))
            elif bricks and mode == "merge":
                make.merge_bricks(self.fab, bricks)
            elif bricks and mode == "split":
                make.split_bricks(self.fab, bricks)
            elif bricks and mode == "unmark":
                make.unmark(self.fab, bricks)
            self.fab.touch()
            self.doc.recompute()
            ok = self.fab.Status.startswith("ok")
        except Exception as exc:
            log.failure(TITLES[mode], exc)
            ok = False
        if ok:
            self.doc.commitTransaction()
            log.message(f"{self.fab.Label}: {TITLES[mode]} applied: {self.fab.Status}")
        else:
            self.doc.abortTransaction()
        self.close()
        return True

    def reject(self) -> bool:
        """Drop everything painted: the document is as before the panel opened."""
        self.cleanup()
        self.doc.abortTransaction()
        self.close()
        return True

    def cleanup(self) -> None:
        """Stop listening to the mouse, undo the preview's changes, remove the preview."""
        self.timer.stop()
        self.estimate_timer.stop()
        for kind, callback in self.callbacks:
            self.view.removeEventCallbackPivy(kind, callback)
        self.callbacks = []
        for name, visible in self.hidden.items():
            obj = self.doc.getObject(name)
            if obj is not None:
                obj.Visibility = visible
        self.hidden.clear()
        if self.doc.getObject(self.preview.Name) is not None:
            self.doc.removeObject(self.preview.Name)
        Gui.Selection.clearSelection()

    def close(self) -> None:
        """Close the panel (after its transaction ended: an aborted one would show the
        regions again) and hide the Fabrication's regions; the closed panel has no form
        (:func:`.closing.close_dialog`)."""
        for region in self.fab.Regions:
            high_res_region.show(region)
        proxy = getattr(getattr(self.fab, "ViewObject", None), "Proxy", None)
        if getattr(proxy, "panel", None) is self:
            proxy.panel = None
        close_dialog(self)
        if Gui.ActiveDocument is not None and Gui.ActiveDocument.getInEdit() is not None:
            Gui.ActiveDocument.resetEdit()
